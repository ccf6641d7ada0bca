// skintune: everything needed to skin a model at any time of any clip.
#pragma once

#include <string>
#include <vector>

#include "model/animation.h"
#include "model/mesh.h"
#include "model/skeleton.h"

namespace skintune::internal {

// The skinned mesh's morph targets (glTF `targets`): per target, a position
// (and normal) offset per vertex of the mesh, zero where a primitive has
// none; applied before skinning, weighted: p = p0 + sum_k w_k dp_k.
struct MorphTargets {
  std::vector<std::vector<glm::vec3>> positions;  // [target][vertex]
  std::vector<std::vector<glm::vec3>> normals;    // [target][vertex]; empty without normals
  std::vector<std::vector<glm::vec3>> tangents;   // [target][vertex] (xyz offsets); empty without tangents
  std::vector<double> weights;                    // default weights (the node's, else the mesh's, else 0)
  std::string where;                              // e.g. "meshes[0].primitives[0].targets"
  std::size_t count() const { return positions.size(); }
};

struct SkinnedAsset {
  std::string source;  // file name or dataset key: used in error messages
  SkinnedMesh mesh;
  Skeleton skeleton;
  std::vector<AnimationClip> animations;
  MorphTargets morph;

  // Resolves an animation by exact name, or by index when `name_or_index` is a
  // decimal number. Throws Error naming the source and listing what exists.
  int FindAnimation(const std::string& name_or_index) const;
  // Pose at time t of clip `animation` (-1: the rest pose).
  Pose PoseAt(int animation, double t) const;
  // Throws Error("<source>: rest pose: joint J ...") / ("<source>: animation A
  // 'name' at t=T s: joint J ...") for a palette entry that is not finite in
  // float32 (Skeleton::Palette).
  std::vector<glm::mat4> PaletteAt(int animation, double t) const;

  // The morph target weights at time t of clip `animation` (-1: the defaults).
  std::vector<double> MorphWeightsAt(int animation, double t) const;
  // The mesh with the morph targets applied at those weights (a copy; the mesh
  // itself where there are no targets).
  SkinnedMesh MeshAt(int animation, double t) const;
  // Why the morph targets move vertices ("meshes[0].weights[1] is 0.25",
  // "animations[0] animates their weights"), or "" where they cannot: what
  // skins only `mesh` (the GPU kernels, the tuner, the runtime) must refuse
  // an asset for which this is not empty (RequireNoMorphInUse).
  std::string MorphInUse() const;
  // Throws Error("<source>: <where>: N morph targets move its vertices (...),
  // which <who> does not apply ...") when MorphInUse() is not empty.
  void RequireNoMorphInUse(const std::string& who) const;
};

}  // namespace skintune::internal
