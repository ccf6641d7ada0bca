#include "model/skeleton.h"

#include <cfloat>
#include <cmath>
#include <cstdio>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "base/error.h"

namespace skintune::internal {

glm::dmat4 Transform::ToMatrix() const {
  glm::dmat4 m = glm::mat4_cast(glm::normalize(rotation));
  m[0] *= scale.x;
  m[1] *= scale.y;
  m[2] *= scale.z;
  m[3] = glm::dvec4(translation, 1.0);
  return m;
}

namespace {

bool Finite(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

std::string NodeName(const Skeleton& s, int i) {
  std::string name = "nodes[" + std::to_string(i) + "]";
  if (i >= 0 && i < static_cast<int>(s.nodes.size()) && !s.nodes[i].name.empty())
    name += " ('" + s.nodes[i].name + "')";
  return name;
}

}  // namespace

void Skeleton::Validate(const std::string& context) const {
  const int n = static_cast<int>(nodes.size());
  if (joints.empty()) throw Error(context + ": skin has no joints");
  if (joints.size() != inverse_bind.size()) {
    throw Error(context + ": " + std::to_string(joints.size()) + " joints but " +
                std::to_string(inverse_bind.size()) + " inverse bind matrices");
  }
  for (int i = 0; i < n; ++i) {
    const int p = nodes[i].parent;
    if (p < -1 || p >= n || p == i)
      throw Error(context + ": " + NodeName(*this, i) + ": parent " + std::to_string(p) + " out of range");
    if (!Finite(nodes[i].has_matrix ? nodes[i].matrix : nodes[i].rest.ToMatrix()))
      throw Error(context + ": " + NodeName(*this, i) + ": transform is not finite");
  }
  // A cycle shows up as a walk to the root longer than the node count.
  for (int i = 0; i < n; ++i) {
    int steps = 0;
    for (int p = nodes[i].parent; p >= 0; p = nodes[p].parent) {
      if (++steps > n) throw Error(context + ": " + NodeName(*this, i) + ": node hierarchy has a cycle");
    }
  }
  for (std::size_t j = 0; j < joints.size(); ++j) {
    if (joints[j] < 0 || joints[j] >= n) {
      throw Error(context + ": joint " + std::to_string(j) + " refers to node " + std::to_string(joints[j]) +
                  " (" + std::to_string(n) + " nodes)");
    }
    if (!Finite(inverse_bind[j]))
      throw Error(context + ": inverse bind matrix of joint " + std::to_string(j) + " is not finite");
  }
}

Pose Skeleton::RestPose() const {
  Pose pose(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) pose[i] = nodes[i].rest;
  return pose;
}

std::vector<glm::dmat4> Skeleton::GlobalTransforms(const Pose& pose) const {
  const std::size_t n = nodes.size();
  if (pose.size() != n) {
    throw Error("pose has " + std::to_string(pose.size()) + " transforms for " + std::to_string(n) + " nodes");
  }
  std::vector<glm::dmat4> global(n);
  std::vector<char> done(n, 0);
  // Parents may come after children (glTF allows any order): resolve each
  // node's chain iteratively. Validate() guarantees there is no cycle.
  std::vector<int> chain;
  for (std::size_t i = 0; i < n; ++i) {
    chain.clear();
    for (int k = static_cast<int>(i); k >= 0 && !done[k]; k = nodes[k].parent) chain.push_back(k);
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const Node& node = nodes[*it];
      const glm::dmat4 local = node.has_matrix ? node.matrix : pose[*it].ToMatrix();
      global[*it] = node.parent >= 0 ? global[node.parent] * local : local;
      done[*it] = 1;
    }
  }
  return global;
}

namespace {

// Every element of palette entry j finite and, when `float32`, within
// float's range (what kernels read): else Error naming the joint, its node
// and the element.
void CheckPaletteEntry(const Skeleton& s, std::size_t j, const glm::dmat4& m, bool float32) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      const double v = m[c][r];
      if (std::isfinite(v) && (!float32 || std::fabs(v) <= FLT_MAX)) continue;
      char value[40];
      std::snprintf(value, sizeof value, "%.17g", v);
      throw Error("joint " + std::to_string(j) + " (" + NodeName(s, s.joints[j]) + "): palette entry [" +
                  std::to_string(c) + "][" + std::to_string(r) + "] is " + value +
                  (std::isfinite(v) ? ", beyond float32" : "") +
                  " (the node's global transform times its inverse bind matrix)");
    }
  }
}

}  // namespace

std::vector<glm::dmat4> Skeleton::PaletteD(const Pose& pose) const {
  const std::vector<glm::dmat4> global = GlobalTransforms(pose);
  std::vector<glm::dmat4> palette(joints.size());
  for (std::size_t j = 0; j < joints.size(); ++j) {
    palette[j] = global[joints[j]] * inverse_bind[j];
    CheckPaletteEntry(*this, j, palette[j], false);
  }
  return palette;
}

std::vector<glm::mat4> Skeleton::Palette(const Pose& pose) const {
  const std::vector<glm::dmat4> d = PaletteD(pose);
  for (std::size_t j = 0; j < d.size(); ++j) CheckPaletteEntry(*this, j, d[j], true);
  return std::vector<glm::mat4>(d.begin(), d.end());
}

}  // namespace skintune::internal
