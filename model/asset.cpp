#include "model/asset.h"

#include <charconv>

#include <glm/gtc/quaternion.hpp>

#include "base/error.h"

namespace skintune::internal {

int SkinnedAsset::FindAnimation(const std::string& name_or_index) const {
  for (std::size_t i = 0; i < animations.size(); ++i)
    if (animations[i].name == name_or_index) return static_cast<int>(i);
  int index = -1;
  const char* end = name_or_index.data() + name_or_index.size();
  auto [ptr, ec] = std::from_chars(name_or_index.data(), end, index);
  if (ec == std::errc() && ptr == end && !name_or_index.empty()) {
    if (index >= 0 && index < static_cast<int>(animations.size())) return index;
  }
  std::string known;
  for (std::size_t i = 0; i < animations.size(); ++i) {
    known += (i ? ", " : "") + std::to_string(i);
    if (!animations[i].name.empty()) known += " '" + animations[i].name + "'";
  }
  throw Error(source + ": no animation '" + name_or_index + "' (" +
              (animations.empty() ? std::string("it has no animations") : "it has: " + known) + ")");
}

Pose SkinnedAsset::PoseAt(int animation, double t) const {
  Pose pose = skeleton.RestPose();
  if (animation >= 0) animations.at(animation).Sample(t, pose);
  return pose;
}

Pose SkinnedAsset::BlendedPoseAt(int animation, double t, int animation2, double t2, double weight) const {
  Pose pose = PoseAt(animation, t);
  if (weight == 0.0) return pose;
  const Pose other = PoseAt(animation2, t2);
  for (std::size_t n = 0; n < pose.size(); ++n) {
    Transform& a = pose[n];
    const glm::dquat ra = glm::normalize(a.rotation);
    glm::dquat rb = glm::normalize(other[n].rotation);
    if (glm::dot(ra, rb) < 0.0) rb = -rb;
    a.translation = glm::mix(a.translation, other[n].translation, weight);
    a.scale = glm::mix(a.scale, other[n].scale, weight);
    a.rotation = glm::normalize(glm::lerp(ra, rb, weight));
  }
  return pose;
}

std::vector<glm::mat4> SkinnedAsset::PaletteAt(int animation, double t) const {
  const Pose pose = PoseAt(animation, t);
  try {
    return skeleton.Palette(pose);
  } catch (const Error& e) {
    const std::string when = animation < 0 ? std::string("rest pose")
                                           : "animation " + std::to_string(animation) +
                                                 (animations[animation].name.empty() ? "" : " '" + animations[animation].name + "'") +
                                                 " at t=" + std::to_string(t) + " s";
    throw Error(source + ": " + when + ": " + e.what());
  }
}

std::vector<double> SkinnedAsset::MorphWeightsAt(int animation, double t) const {
  std::vector<double> weights = mesh.morph.weights;
  weights.resize(mesh.morph.count(), 0.0);
  if (animation >= 0) animations.at(animation).SampleMorphWeights(t, weights);
  return weights;
}

SkinnedMesh SkinnedAsset::MeshWithMorphWeightsAt(int animation, double t) const {
  SkinnedMesh out = mesh;
  if (mesh.has_morph()) out.morph.weights = MorphWeightsAt(animation, t);
  return out;
}

SkinnedMesh SkinnedAsset::MeshAt(int animation, double t) const {
  return MorphApplied(MeshWithMorphWeightsAt(animation, t));
}

}  // namespace skintune::internal
