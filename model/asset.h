// skintune: everything needed to skin a model at any time of any clip.
#pragma once

#include <string>
#include <vector>

#include "model/animation.h"
#include "model/mesh.h"
#include "model/skeleton.h"

namespace skintune::internal {

struct SkinnedAsset {
  std::string source;  // file name or dataset key: used in error messages
  SkinnedMesh mesh;
  Skeleton skeleton;
  std::vector<AnimationClip> animations;

  // Resolves an animation by exact name, or by index when `name_or_index` is a
  // decimal number. Throws Error naming the source and listing what exists.
  int FindAnimation(const std::string& name_or_index) const;
  // Pose at time t of clip `animation` (-1: the rest pose).
  Pose PoseAt(int animation, double t) const;
  // PoseAt(animation, t) blended toward PoseAt(animation2, t2) by `weight`
  // in each node's local space, in float64: translations and scales lerped,
  // rotations nlerped along the shortest path. The palette kernel's blend
  // (docs/ANIMATION.md "Blends"); weight 0 is PoseAt(animation, t).
  Pose BlendedPoseAt(int animation, double t, int animation2, double t2, double weight) const;
  // Throws Error("<source>: rest pose: joint J ...") / ("<source>: animation A
  // 'name' at t=T s: joint J ...") for a palette entry that is not finite in
  // float32 (Skeleton::Palette).
  std::vector<glm::mat4> PaletteAt(int animation, double t) const;

  // The morph target weights at time t of clip `animation` (-1: the defaults).
  std::vector<double> MorphWeightsAt(int animation, double t) const;
  // The mesh with its targets' weights at that time (what a kernel that
  // skins morph targets packs and the gold morphs): a copy.
  SkinnedMesh MeshWithMorphWeightsAt(int animation, double t) const;
  // The mesh with the morph targets applied at those weights and none left
  // (MorphApplied: a copy).
  SkinnedMesh MeshAt(int animation, double t) const;
};

}  // namespace skintune::internal
