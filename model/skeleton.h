// skintune: a node hierarchy with a skin (joints + inverse bind matrices), and
// the palette it produces for a pose.
//
// Follows glTF 2.0 semantics: every node has a local transform (TRS, or a fixed
// matrix that cannot be animated); global = parent's global * local; the
// palette entry of joint j is global(joints[j]) * inverse_bind[j]. The
// transform of the node that carries the mesh is ignored, as glTF requires.
// All maths in double; the palette handed to skinning is float32, as on a GPU.
#pragma once

#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

namespace skintune::internal {

struct Transform {
  glm::dvec3 translation{0.0};
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};  // w, x, y, z
  glm::dvec3 scale{1.0};
  glm::dmat4 ToMatrix() const;  // T * R * S
};

struct Node {
  std::string name;
  int parent = -1;           // index into Skeleton::nodes, -1 for a root
  Transform rest;            // local rest transform (ignored when has_matrix)
  bool has_matrix = false;   // glTF `matrix` nodes: fixed, never animated
  glm::dmat4 matrix{1.0};
};

// The local transform of every node: what an animation overwrites.
using Pose = std::vector<Transform>;

struct Skeleton {
  std::vector<Node> nodes;
  std::vector<int> joints;                // joint j -> node index
  std::vector<glm::dmat4> inverse_bind;   // one per joint

  int joint_count() const { return static_cast<int>(joints.size()); }

  // Throws Error("<context>: ...") for: no joints, joints/inverse_bind size
  // mismatch, node or parent index out of range, a cycle in the hierarchy,
  // non-finite transforms.
  void Validate(const std::string& context) const;

  Pose RestPose() const;
  // Model-space transform of every node for `pose` (one entry per node).
  std::vector<glm::dmat4> GlobalTransforms(const Pose& pose) const;
  // Palette in double (gold) and float (what kernels read). Throws
  // Error("joint J (nodes[N] 'name'): palette entry [c][r] is inf ...") for an
  // entry that is not finite (transforms that overflow when multiplied), and
  // Palette also for one beyond float32's range (1e308 is finite in double,
  // infinite in float): such a palette skins every vertex it moves to NaN.
  std::vector<glm::dmat4> PaletteD(const Pose& pose) const;
  std::vector<glm::mat4> Palette(const Pose& pose) const;
};

}  // namespace skintune::internal
