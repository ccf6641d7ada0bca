// A seeded synthetic rig for the palette kernel's tests: a root with five
// chains of 64 nodes (321 nodes, every one a joint, the deepest 64 levels
// below the root), rest rotations of up to 15 degrees and scales within 1%,
// one fixed-matrix node, inverse binds of the rest pose; two clips:
//   0 "every interpolation": chain 0 STEP, chain 1 LINEAR, chain 2
//     CUBICSPLINE, chain 3 a different one per path, chain 4 LINEAR
//     rotations on every other node; the root translates;
//   1 "second": every chain rotates, CUBICSPLINE and LINEAR alternating,
//     on its own key times.
// Keys are 2..8 per channel at irregular times, and rotation keys are
// negated at random (q and -q: the shortest path matters).
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "model/asset.h"

namespace skintune::internal::testing {

inline constexpr int kDeepRigChains = 5;
inline constexpr int kDeepRigChainLength = 64;
inline constexpr int kDeepRigFixedNode = 1 + 4 * kDeepRigChainLength + 10;  // chain 4, level 11

class DeepRigBuilder {
 public:
  SkinnedAsset Build() {
    SkinnedAsset asset;
    asset.source = "deep-rig";
    Skeleton& s = asset.skeleton;
    s.nodes.push_back(Node{"root", -1, Transform{}, false, glm::dmat4(1.0)});
    for (int chain = 0; chain < kDeepRigChains; ++chain) {
      int parent = 0;
      for (int level = 0; level < kDeepRigChainLength; ++level) {
        Node node{"c" + std::to_string(chain) + "." + std::to_string(level), parent, RestTransform(), false,
                  glm::dmat4(1.0)};
        parent = static_cast<int>(s.nodes.size());
        if (parent == kDeepRigFixedNode) {
          node.has_matrix = true;
          node.matrix = node.rest.ToMatrix();
        }
        s.nodes.push_back(node);
      }
    }
    const std::vector<glm::dmat4> rest = s.GlobalTransforms(s.RestPose());
    for (std::size_t i = 0; i < s.nodes.size(); ++i) {
      s.joints.push_back(static_cast<int>(i));
      s.inverse_bind.push_back(glm::inverse(rest[i]));
    }
    asset.animations.push_back(EveryInterpolation(s));
    asset.animations.push_back(Second(s));
    for (AnimationClip& clip : asset.animations) clip.UpdateRange();
    return asset;
  }

 private:
  double Uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(random_); }
  int Keys() { return std::uniform_int_distribution<int>(2, 8)(random_); }

  glm::dquat RandomRotation(double max_degrees) {
    const glm::dvec3 axis =
        glm::normalize(glm::dvec3(Uniform(-1, 1), Uniform(-1, 1), Uniform(-1, 1)) + glm::dvec3(0, 0, 1e-3));
    return glm::angleAxis(glm::radians(Uniform(-max_degrees, max_degrees)), axis);
  }

  Transform RestTransform() {
    Transform t;
    t.translation = glm::dvec3(Uniform(-0.01, 0.01), 0.05, Uniform(-0.01, 0.01));
    t.rotation = RandomRotation(15.0);
    t.scale = glm::dvec3(Uniform(0.99, 1.01), Uniform(0.99, 1.01), Uniform(0.99, 1.01));
    return t;
  }

  glm::dvec4 Value(ChannelPath path, const Node& node) {
    if (path == ChannelPath::kTranslation)
      return glm::dvec4(
          node.rest.translation + glm::dvec3(Uniform(-0.02, 0.02), Uniform(-0.02, 0.02), Uniform(-0.02, 0.02)), 0.0);
    if (path == ChannelPath::kScale) return glm::dvec4(Uniform(0.9, 1.1), Uniform(0.9, 1.1), Uniform(0.9, 1.1), 0.0);
    const glm::dquat q = node.rest.rotation * RandomRotation(40.0);
    const double sign = Uniform(0, 1) < 0.3 ? -1.0 : 1.0;
    return sign * glm::dvec4(q.x, q.y, q.z, q.w);
  }

  glm::dvec4 Tangent(ChannelPath path) {
    const double size = path == ChannelPath::kRotation ? 0.5 : 0.05;
    return glm::dvec4(Uniform(-size, size), Uniform(-size, size), Uniform(-size, size),
                      path == ChannelPath::kRotation ? Uniform(-size, size) : 0.0);
  }

  Channel MakeChannel(const Skeleton& s, int node, ChannelPath path, Interpolation interpolation, double start) {
    Channel c;
    c.node = node;
    c.path = path;
    c.interpolation = interpolation;
    double t = start;
    for (int k = Keys(); k > 0; --k) {
      c.times.push_back(static_cast<float>(t));
      t += Uniform(0.1, 0.5);
      if (interpolation == Interpolation::kCubicSpline) c.values.push_back(Tangent(path));
      c.values.push_back(Value(path, s.nodes[static_cast<std::size_t>(node)]));
      if (interpolation == Interpolation::kCubicSpline) c.values.push_back(Tangent(path));
    }
    return c;
  }

  static int NodeOf(int chain, int level) { return 1 + chain * kDeepRigChainLength + level; }

  AnimationClip EveryInterpolation(const Skeleton& s) {
    AnimationClip clip;
    clip.name = "every interpolation";
    clip.channels.push_back(MakeChannel(s, 0, ChannelPath::kTranslation, Interpolation::kLinear, 0.2));
    const Interpolation per_chain[] = {Interpolation::kStep, Interpolation::kLinear, Interpolation::kCubicSpline};
    const ChannelPath paths[] = {ChannelPath::kTranslation, ChannelPath::kRotation, ChannelPath::kScale};
    for (int chain = 0; chain < kDeepRigChains; ++chain) {
      for (int level = 0; level < kDeepRigChainLength; ++level) {
        const int node = NodeOf(chain, level);
        if (node == kDeepRigFixedNode) continue;
        if (chain == 4) {
          if (level % 2 == 0)
            clip.channels.push_back(
                MakeChannel(s, node, ChannelPath::kRotation, Interpolation::kLinear, Uniform(0, 0.5)));
          continue;
        }
        for (int p = 0; p < 3; ++p) {
          if (paths[p] != ChannelPath::kRotation && level % 3 != 0) continue;  // T and S on every third node
          const Interpolation interpolation = chain < 3 ? per_chain[chain] : per_chain[(p + 1) % 3];
          clip.channels.push_back(MakeChannel(s, node, paths[p], interpolation, Uniform(0, 0.5)));
        }
      }
    }
    return clip;
  }

  AnimationClip Second(const Skeleton& s) {
    AnimationClip clip;
    clip.name = "second";
    for (int chain = 0; chain < kDeepRigChains; ++chain) {
      for (int level = 0; level < kDeepRigChainLength; ++level) {
        const int node = NodeOf(chain, level);
        if (node == kDeepRigFixedNode) continue;
        const Interpolation interpolation = level % 2 ? Interpolation::kLinear : Interpolation::kCubicSpline;
        clip.channels.push_back(MakeChannel(s, node, ChannelPath::kRotation, interpolation, Uniform(0.3, 1.0)));
      }
    }
    return clip;
  }

  std::mt19937_64 random_{20261129};
};

inline const SkinnedAsset& DeepRig() {
  static const SkinnedAsset asset = DeepRigBuilder().Build();
  return asset;
}

// The deep rig with its nodes in reverse order, so that every child comes
// before its parent (glTF allows any order): the same skeleton, skin and
// clips, node n renumbered N - 1 - n in the hierarchy, the joints and the
// channels. A kernel that composed the hierarchy in node order would fail it.
inline const SkinnedAsset& ReversedDeepRig() {
  static const SkinnedAsset asset = [] {
    SkinnedAsset reversed = DeepRig();
    reversed.source = "deep-rig-reversed";
    std::vector<Node>& nodes = reversed.skeleton.nodes;
    const int n = static_cast<int>(nodes.size());
    const auto renumber = [n](int node) { return node < 0 ? node : n - 1 - node; };
    std::reverse(nodes.begin(), nodes.end());
    for (Node& node : nodes) node.parent = renumber(node.parent);
    for (int& joint : reversed.skeleton.joints) joint = renumber(joint);
    for (AnimationClip& clip : reversed.animations)
      for (Channel& channel : clip.channels) channel.node = renumber(channel.node);
    return reversed;
  }();
  return asset;
}

}  // namespace skintune::internal::testing
