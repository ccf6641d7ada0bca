// skintune: keyframed animation clips (glTF 2.0 animation semantics).
//
// A clip is a set of channels; each drives the translation, rotation or scale
// of one node with STEP, LINEAR (rotations: shortest-path slerp) or
// CUBICSPLINE (Hermite, glTF's in-tangent/value/out-tangent triplets)
// interpolation. Sampling outside the keyed range clamps to the first/last key.
// A `weights` channel drives the morph target weights of the skinned mesh,
// four targets per Channel (SampleMorphWeights).
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "model/skeleton.h"

namespace skintune::internal {

enum class ChannelPath { kTranslation, kRotation, kScale, kWeights };
enum class Interpolation { kStep, kLinear, kCubicSpline };

// "translation", "rotation", "scale", "weights": glTF's names, in messages.
const char* ChannelPathName(ChannelPath path);

struct Channel {
  int node = -1;
  ChannelPath path = ChannelPath::kRotation;
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<float> times;        // strictly increasing
  // One value per key (xyz for T/S, quaternion as (x, y, z, w) for R, the
  // weights of targets first_target.. first_target + 3 for W, unused lanes 0),
  // or three per key for CUBICSPLINE: in-tangent, value, out-tangent.
  std::vector<glm::dvec4> values;
  int first_target = 0;  // kWeights only
};

struct AnimationClip {
  std::string name;
  std::vector<Channel> channels;
  double start = 0.0;  // first key time over all channels
  double end = 0.0;    // last key time over all channels
  double duration() const { return end - start; }

  // Throws Error("<context>: ...") on: node out of range, empty or
  // non-increasing times, value count not matching the key count, non-finite values.
  void Validate(int node_count, const std::string& context) const;
  // Overwrites the animated components of `pose` with the clip sampled at
  // time t (seconds, clip time: keys are at their own times, not shifted).
  void Sample(double t, Pose& pose) const;
  // Overwrites the weights of the morph targets the clip animates (kWeights
  // channels) with their values at time t; the others keep theirs.
  void SampleMorphWeights(double t, std::vector<double>& weights) const;
  // Recomputes start/end from the channels.
  void UpdateRange();
};

}  // namespace skintune::internal
