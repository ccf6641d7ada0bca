// The palette kernel's float64 gold and its bound, and the instances the
// tests run: shared by the OpenCL/CPU test (palette_kernel_test.cpp) and the
// GL test (tests/runtime/palette_kernel_gl_test.cpp).
//
// The bound: for joint j with gold palette entry P_j = G_j * IB_j (G_j the
// joint's global transform, IB_j its inverse bind matrix), the largest
// |kernel - gold| over P_j's 12 entries must be at most 1e-5 * s_j with
//   s_j = max(1, the Euclidean norms of P_j's four columns (three 3x3 columns
//             and the translation), of G_j's translation, of IB_j's translation).
// The translations of G_j and IB_j are in s_j because float32 cannot do better:
// at a bind pose P_j's translation is G_j's plus G_j's 3x3 times IB_j's, two
// vectors of the model's size that cancel to ~0, so its rounding error is
// float32's epsilon times the model's size (Fox, ~100 units: 1.4e-5 at rest,
// against a P_j of unit scale). Each test prints its worst error over this
// bound and over the bound without those two terms (1e-5 * max(1, P_j's
// column norms)), so both are on record.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "model/asset.h"

namespace skintune::internal::testing {

// "Fox.gltf" of a path.
inline std::string Name(const SkinnedAsset& asset) { return asset.source.substr(asset.source.find_last_of('/') + 1); }

// ------------------------------------------------------------- the gold

// One instance's float64 pose: each clip's pose (the rest pose for
// kAnimRestPose) blended in local space (T, S lerped; R nlerped along the
// shortest path).
inline Pose GoldPose(const SkinnedAsset& asset, const PackedAnimation& packed, const AnimInstance& in) {
  auto pose_of = [&](std::uint16_t clip, float t) {
    return asset.PoseAt(clip == kAnimRestPose ? -1 : packed.clips[clip], static_cast<double>(t));
  };
  Pose pose = pose_of(in.clip, in.time);
  if (in.weight == 0.0f) return pose;
  const Pose other = pose_of(in.clip2, in.time2);
  const double w = in.weight;
  for (std::size_t n = 0; n < pose.size(); ++n) {
    Transform& a = pose[n];
    const glm::dquat ra = glm::normalize(a.rotation);
    glm::dquat rb = glm::normalize(other[n].rotation);
    if (glm::dot(ra, rb) < 0.0) rb = -rb;
    a.translation = glm::mix(a.translation, other[n].translation, w);
    a.scale = glm::mix(a.scale, other[n].scale, w);
    a.rotation = glm::normalize(glm::lerp(ra, rb, w));
  }
  return pose;
}

struct Worst {
  double ratio = 0.0;  // largest error / bound seen
  double error = 0.0, bound = 0.0;
  std::string where;
  double ratio_palette_only = 0.0;  // largest error / (1e-5 * max(1, P_j's column norms))
};

inline double ColumnNorm(const glm::dmat4& m, int c) { return glm::length(glm::dvec3(m[c])); }

// Compares K palettes (kernel rows) with their golds; returns the worst
// error relative to its bound, with where it is.
inline Worst Compare(const SkinnedAsset& asset, const PackedAnimation& packed,
                     const std::vector<AnimInstance>& instances, const std::vector<float>& rows) {
  const std::size_t joints = packed.joints.size();
  EXPECT_EQ(rows.size(), instances.size() * joints * 12);
  Worst worst;
  const Skeleton& skeleton = asset.skeleton;
  for (std::size_t i = 0; i < instances.size() && rows.size() == instances.size() * joints * 12; ++i) {
    const Pose pose = GoldPose(asset, packed, instances[i]);
    const std::vector<glm::dmat4> gold = skeleton.PaletteD(pose), global = skeleton.GlobalTransforms(pose);
    for (std::size_t j = 0; j < joints; ++j) {
      double palette_scale = 1.0, error = 0.0;
      for (int c = 0; c < 4; ++c) palette_scale = std::max(palette_scale, ColumnNorm(gold[j], c));
      const double scale = std::max({palette_scale, ColumnNorm(global[static_cast<std::size_t>(skeleton.joints[j])], 3),
                                     ColumnNorm(skeleton.inverse_bind[j], 3)});
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
          const double v = rows[(i * joints + j) * 12 + 4 * r + c];
          error = std::isfinite(v) ? std::max(error, std::fabs(v - gold[j][c][r])) : INFINITY;
        }
      const double bound = 1e-5 * scale;
      worst.ratio_palette_only = std::max(worst.ratio_palette_only, error / (1e-5 * palette_scale));
      if (error / bound > worst.ratio || !std::isfinite(error)) {
        char where[200];
        std::snprintf(where, sizeof where, "instance %zu (clip %d, t=%.9g; clip2 %d, t2=%.9g, w=%g), joint %zu", i,
                      instances[i].clip, instances[i].time, instances[i].clip2, instances[i].time2, instances[i].weight,
                      j);
        worst = Worst{error / bound, error, bound, where, worst.ratio_palette_only};
      }
    }
  }
  return worst;
}

inline void ExpectWithinBound(const std::string& what, const Worst& worst) {
  std::printf(
      "[ palette  ] %s: max error / bound %.3g (error %.3g, bound %.3g at %s); without the translations "
      "of G and IB in the bound: %.3g\n",
      what.c_str(), worst.ratio, worst.error, worst.bound, worst.where.c_str(), worst.ratio_palette_only);
  EXPECT_LE(worst.ratio, 1.0) << what << ": error " << worst.error << " > bound " << worst.bound << " at "
                              << worst.where;
}

// ------------------------------------------------------------- the instances

// Times of `clip` that cover every case of sampling: before its first key,
// on its first and last keys, on an inner key of a channel, between two keys
// (a midpoint and a quarter point) and after its last key.
inline std::vector<float> TimesOf(const AnimationClip& clip) {
  std::vector<float> times = {static_cast<float>(clip.start - 0.5), static_cast<float>(clip.start),
                              static_cast<float>(clip.end), static_cast<float>(clip.end + 1.0)};
  for (const Channel* c : {&clip.channels.front(), &clip.channels[clip.channels.size() / 2], &clip.channels.back()}) {
    const std::size_t n = c->times.size();
    if (n < 2) continue;
    const std::size_t k = n >= 3 ? n / 2 : 0;  // an inner key where there is one; k + 1 < n
    times.push_back(c->times[k]);
    times.push_back(c->times[k] + 0.5f * (c->times[k + 1] - c->times[k]));
    times.push_back(c->times[0] + 0.25f * (c->times[1] - c->times[0]));
  }
  return times;
}

// One instance per (clip, time) of TimesOf: every clip alone.
inline std::vector<AnimInstance> EveryClipAlone(const SkinnedAsset& asset, const PackedAnimation& packed) {
  std::vector<AnimInstance> instances;
  for (std::size_t c = 0; c < packed.clips.size(); ++c)
    for (const float t : TimesOf(asset.animations[static_cast<std::size_t>(packed.clips[c])]))
      instances.push_back(AnimInstance{static_cast<std::uint16_t>(c), kAnimRestPose, t, 0.0f, 0.0f});
  instances.push_back(AnimInstance{kAnimRestPose, kAnimRestPose, 0.0f, 0.0f, 0.0f});
  return instances;
}

// Two-clip blends: clip c with clip (c + 1) % clips (the rest pose when there
// is one clip) at weights from 0.1 to 1, each clip at its own time.
inline std::vector<AnimInstance> Blends(const SkinnedAsset& asset, const PackedAnimation& packed) {
  std::vector<AnimInstance> instances;
  const std::size_t clips = packed.clips.size();
  for (std::size_t c = 0; c < clips; ++c) {
    const std::uint16_t other = clips > 1 ? static_cast<std::uint16_t>((c + 1) % clips) : kAnimRestPose;
    const std::vector<float> times = TimesOf(asset.animations[static_cast<std::size_t>(packed.clips[c])]);
    const std::vector<float> times2 =
        other == kAnimRestPose ? times : TimesOf(asset.animations[static_cast<std::size_t>(packed.clips[other])]);
    for (std::size_t k = 0; k < times.size(); ++k) {
      const float w = 0.1f + 0.9f * static_cast<float>(k) / static_cast<float>(times.size() - 1);
      instances.push_back(
          AnimInstance{static_cast<std::uint16_t>(c), other, times[k], times2[(k * 3 + 1) % times2.size()], w});
    }
  }
  return instances;
}

}  // namespace skintune::internal::testing
