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
#include <bit>
#include <cstdint>
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
  const auto clip_of = [&](std::uint16_t clip) { return clip == kAnimRestPose ? -1 : packed.clips[clip]; };
  return asset.BlendedPoseAt(clip_of(in.clip), in.time, clip_of(in.clip2), in.time2, in.weight);
}

struct Worst {
  double ratio = 0.0;  // largest error / bound seen
  double error = 0.0, bound = 0.0;
  std::string where;
  double ratio_palette_only = 0.0;  // largest error / (1e-5 * max(1, P_j's column norms))
};

inline double ColumnNorm(const glm::dmat4& m, int c) { return glm::length(glm::dvec3(m[c])); }

// The largest |row entry - gold| of one joint's three kernel rows (infinite
// where an entry is not finite).
inline double EntryError(const float* rows, const glm::dmat4& gold) {
  double error = 0.0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      const double v = rows[4 * r + c];
      error = std::isfinite(v) ? std::max(error, std::fabs(v - gold[c][r])) : INFINITY;
    }
  return error;
}

// Keeps (error, bound) at instance i joint j in `worst` where it is the worst yet.
inline void NoteWorst(Worst& worst, double error, double bound, const AnimInstance& in, std::size_t i, std::size_t j) {
  if (!(error / bound > worst.ratio) && std::isfinite(error)) return;
  char where[200];
  std::snprintf(where, sizeof where, "instance %zu (clip %d, t=%.9g; clip2 %d, t2=%.9g, w=%g), joint %zu", i, in.clip,
                in.time, in.clip2, in.time2, in.weight, j);
  worst = Worst{error / bound, error, bound, where, worst.ratio_palette_only};
}

// Compares K palettes (kernel rows) with the golds of their poses
// (pose_of(instance)); returns the worst error relative to its bound, with
// where it is.
// The frame positions a baked kernel may compute (BakedGoldSample's nudge):
// float32's quotient, and the neighbours within this many ulps of it, as
// GLSL's and Vulkan's division is exact to 2.5 ulp (their specifications'
// precision; NVIDIA's GL on an H200 took a neighbour, 2026-11-30).
inline constexpr int kQuotientUlps = 3;
inline std::vector<int> QuotientNudges() {
  std::vector<int> nudges;
  for (int n = -kQuotientUlps; n <= kQuotientUlps; ++n) nudges.push_back(n);
  return nudges;
}

template <typename PoseOf>
Worst ComparePoses(const SkinnedAsset& asset, const std::vector<AnimInstance>& instances,
                   const std::vector<float>& rows, const PoseOf& pose_of, const std::vector<int>& nudges = {0}) {
  const std::size_t joints = asset.skeleton.joints.size();
  EXPECT_EQ(rows.size(), instances.size() * joints * 12);
  Worst worst;
  const Skeleton& skeleton = asset.skeleton;
  for (std::size_t i = 0; i < instances.size() && rows.size() == instances.size() * joints * 12; ++i) {
    const Pose pose = pose_of(instances[i], 0);
    const std::vector<glm::dmat4> gold = skeleton.PaletteD(pose), global = skeleton.GlobalTransforms(pose);
    std::vector<std::vector<glm::dmat4>> nudged;  // the golds of the other frame positions the kernel may take
    for (const int n : nudges)
      if (n != 0) nudged.push_back(skeleton.PaletteD(pose_of(instances[i], n)));
    for (std::size_t j = 0; j < joints; ++j) {
      double palette_scale = 1.0, error = 0.0;
      for (int c = 0; c < 4; ++c) palette_scale = std::max(palette_scale, ColumnNorm(gold[j], c));
      const double scale = std::max({palette_scale, ColumnNorm(global[static_cast<std::size_t>(skeleton.joints[j])], 3),
                                     ColumnNorm(skeleton.inverse_bind[j], 3)});
      error = EntryError(rows.data() + (i * joints + j) * 12, gold[j]);
      for (const std::vector<glm::dmat4>& other : nudged)
        error = std::min(error, EntryError(rows.data() + (i * joints + j) * 12, other[j]));
      worst.ratio_palette_only = std::max(worst.ratio_palette_only, error / (1e-5 * palette_scale));
      NoteWorst(worst, error, 1e-5 * scale, instances[i], i, j);
    }
  }
  return worst;
}

// K palettes of sampled clips against the float64 sampling (GoldPose).
inline Worst Compare(const SkinnedAsset& asset, const PackedAnimation& packed,
                     const std::vector<AnimInstance>& instances, const std::vector<float>& rows) {
  return ComparePoses(asset, instances, rows, [&](const AnimInstance& in, int) { return GoldPose(asset, packed, in); });
}

inline void ExpectWithinBound(const std::string& what, const Worst& worst) {
  std::printf(
      "[ palette  ] %s: max error / bound %.3g (error %.3g, bound %.3g at %s); without the translations "
      "of G and IB in the bound: %.3g\n",
      what.c_str(), worst.ratio, worst.error, worst.bound, worst.where.c_str(), worst.ratio_palette_only);
  EXPECT_LE(worst.ratio, 1.0) << what << ": error " << worst.error << " > bound " << worst.bound << " at "
                              << worst.where;
}

// ------------------------------------------------------------- baked clips

// One baked record in float64: q, t, the stretch S (cpu_kernels/palette_kernel.h).
struct BakedGoldRecord {
  glm::dquat q;
  glm::dvec3 t;
  glm::dmat3 s;
};

// Item j's record (a joint's; a node's baked in local space, whose S is the
// diagonal of its scale) at `frame`.
inline BakedGoldRecord BakedRecordOf(const PackedAnimation& baked, std::uint32_t frame, std::size_t j) {
  const float* p = baked.frames.data() + 4 * baked.baked_rows * (std::size_t{frame} * baked.View().baked_items() + j);
  BakedGoldRecord r{glm::dquat(p[3], p[0], p[1], p[2]), glm::dvec3(p[4], p[5], p[6]), glm::dmat3(double{p[7]})};
  if (baked.baked_rows == kBakedRowsAffine) r.s = glm::dmat3(p[8], p[11], p[12], p[11], p[9], p[13], p[12], p[13], p[10]);
  if (baked.baked_rows == kBakedRowsLocalScaled)
    r.s = glm::dmat3(glm::dvec3(p[8], 0.0, 0.0), glm::dvec3(0.0, p[9], 0.0), glm::dvec3(0.0, 0.0, p[10]));
  return r;
}

inline BakedGoldRecord BakedGoldMix(const BakedGoldRecord& x, const BakedGoldRecord& y, double u) {
  const glm::dquat q2 = glm::dot(x.q, y.q) < 0.0 ? -y.q : y.q;
  return {glm::normalize(x.q + u * (q2 - x.q)), x.t + u * (y.t - x.t), x.s + u * (y.s - x.s)};
}

// docs/ANIMATION.md "Baked clips", in float64: the frames around t, mixed.
// nudge: the quotient (t - start) / length taken that many ulps up (down,
// negative) from float32's (kQuotientUlps).
inline BakedGoldRecord BakedGoldSample(const PackedAnimation& baked, std::uint16_t clip, double t, std::size_t j,
                                       int nudge = 0) {
  if (clip == kAnimRestPose) return BakedRecordOf(baked, 0, j);
  const float* range = baked.clip_ranges.data() + 4 * std::size_t{clip};
  const auto frames = std::bit_cast<std::uint32_t>(range[2]), first = std::bit_cast<std::uint32_t>(range[3]);
  if (frames < 2) return BakedRecordOf(baked, first, j);
  // The frame position u from the float32 time and range, as the kernels
  // compute it (docs/ANIMATION.md "Baked clips"): it is the input's
  // precision, not the kernel's arithmetic. Where a STEP jump is baked
  // between two frames the records change by the whole jump within a frame,
  // so u's float32 rounding alone moved the deep rig's chains 64 nodes deep
  // by up to 4.3e-5 (0.9 to 1.5 times the bound) against a float64 u; and
  // GLSL's quotient may be a neighbour of float32's (kQuotientUlps).
  const float length = range[1] - range[0];
  float quotient = length > 0.0f ? (static_cast<float>(t) - range[0]) / length : 0.0f;
  for (int n = 0; n < std::abs(nudge); ++n) quotient = std::nextafter(quotient, nudge > 0 ? 2.0f : -1.0f);
  const double u = length > 0.0f ? double{std::fmin(std::fmax(quotient, 0.0f), 1.0f) * static_cast<float>(frames - 1)}
                                 : 0.0;
  const auto k = std::min(static_cast<std::uint32_t>(u), frames - 2);
  return BakedGoldMix(BakedRecordOf(baked, first + k, j), BakedRecordOf(baked, first + k + 1, j), u - k);
}

// An instance's palette from baked clips, in float64.
inline std::vector<glm::dmat4> BakedGoldPalette(const PackedAnimation& baked, const AnimInstance& in, int nudge = 0) {
  std::vector<glm::dmat4> palette(baked.joints.size());
  for (std::size_t j = 0; j < palette.size(); ++j) {
    BakedGoldRecord x = BakedGoldSample(baked, in.clip, in.time, j, nudge);
    if (in.weight != 0.0f) x = BakedGoldMix(x, BakedGoldSample(baked, in.clip2, in.time2, j, nudge), in.weight);
    palette[j] = glm::dmat4(glm::mat3_cast(x.q) * x.s);  // R(q) S
    palette[j][3] = glm::dvec4(x.t, 1.0);
  }
  return palette;
}

// An instance's float64 pose from clips baked in local space
// (docs/ANIMATION.md "Baked in local space"): each node's records around
// each clip's time mixed, the two clips mixed by the weight, as a local TRS
// (a fixed-matrix node keeps its matrix: Skeleton::PaletteD reads it).
inline Pose LocalBakedGoldPose(const SkinnedAsset& asset, const PackedAnimation& baked, const AnimInstance& in,
                               int nudge = 0) {
  Pose pose = asset.skeleton.RestPose();
  for (std::size_t n = 0; n < pose.size(); ++n) {
    BakedGoldRecord x = BakedGoldSample(baked, in.clip, in.time, n, nudge);
    if (in.weight != 0.0f) x = BakedGoldMix(x, BakedGoldSample(baked, in.clip2, in.time2, n, nudge), in.weight);
    pose[n] = Transform{x.t, x.q, glm::dvec3(x.s[0][0], x.s[1][1], x.s[2][2])};
  }
  return pose;
}

// A hybrid animation's palette records (PackedAnimation::steady) as a
// packing of palette records, which the golds above read.
inline PackedAnimation SteadyPart(const PackedAnimation& hybrid) {
  PackedAnimation steady = hybrid;
  steady.frames = hybrid.steady;
  steady.baked_rows = hybrid.steady_rows;
  steady.baked_local = false;
  steady.steady.clear();
  steady.steady_rows = 0;
  return steady;
}

// An instance's float64 palette from baked clips of any form: palette
// records; local ones (their pose's palette); hybrid: palette records for
// an instance that plays one clip, local ones for one that cross-fades
// (docs/ANIMATION.md "Hybrid records").
inline std::vector<glm::dmat4> BakedGoldPaletteOf(const SkinnedAsset& asset, const PackedAnimation& baked,
                                                  const AnimInstance& in) {
  if (!baked.steady.empty() && in.weight == 0.0f) return BakedGoldPalette(SteadyPart(baked), in);
  return baked.baked_local ? asset.skeleton.PaletteD(LocalBakedGoldPose(asset, baked, in)) : BakedGoldPalette(baked, in);
}

// K palettes of clips baked in local space against the float64 evaluation
// of their frames (LocalBakedGoldPose), with the sampled kernel's bound.
inline Worst CompareLocalBaked(const SkinnedAsset& asset, const PackedAnimation& baked,
                               const std::vector<AnimInstance>& instances, const std::vector<float>& rows) {
  return ComparePoses(
      asset, instances, rows, [&](const AnimInstance& in, int nudge) { return LocalBakedGoldPose(asset, baked, in, nudge); },
      QuotientNudges());
}

// K palettes (kernel rows) against the float64 evaluation of their baked
// frames: the kernel's float32 rounding only, within 1e-5 of each entry's
// scale (max(1, its columns' norms)).
inline Worst CompareBaked(const PackedAnimation& baked, const std::vector<AnimInstance>& instances,
                          const std::vector<float>& rows) {
  const std::size_t joints = baked.joints.size();
  EXPECT_EQ(rows.size(), instances.size() * joints * 12);
  Worst worst;
  for (std::size_t i = 0; i < instances.size() && rows.size() == instances.size() * joints * 12; ++i) {
    const std::vector<glm::dmat4> gold = BakedGoldPalette(baked, instances[i]);
    std::vector<std::vector<glm::dmat4>> nudged;  // the golds of the other frame positions the kernel may take
    for (const int n : QuotientNudges())
      if (n != 0) nudged.push_back(BakedGoldPalette(baked, instances[i], n));
    for (std::size_t j = 0; j < joints; ++j) {
      double scale = 1.0;
      for (int c = 0; c < 4; ++c) scale = std::max(scale, ColumnNorm(gold[j], c));
      double error = EntryError(rows.data() + (i * joints + j) * 12, gold[j]);
      for (const std::vector<glm::dmat4>& other : nudged)
        error = std::min(error, EntryError(rows.data() + (i * joints + j) * 12, other[j]));
      worst.ratio_palette_only = std::max(worst.ratio_palette_only, error / (1e-5 * scale));
      NoteWorst(worst, error, 1e-5 * scale, instances[i], i, j);
    }
  }
  return worst;
}

// K palettes of hybrid records (docs/ANIMATION.md "Hybrid records"): the
// instances that play one clip against their palette records
// (CompareBaked), those that cross-fade against their local ones
// (CompareLocalBaked); the worse of the two.
inline Worst CompareHybrid(const SkinnedAsset& asset, const PackedAnimation& hybrid,
                           const std::vector<AnimInstance>& instances, const std::vector<float>& rows) {
  EXPECT_FALSE(hybrid.steady.empty());
  const std::size_t per_instance = hybrid.joints.size() * 12;
  EXPECT_EQ(rows.size(), instances.size() * per_instance);
  std::vector<AnimInstance> steady, fading;
  std::vector<float> steady_rows, fading_rows;
  for (std::size_t i = 0; i < instances.size() && rows.size() == instances.size() * per_instance; ++i) {
    const bool one_clip = instances[i].weight == 0.0f;
    (one_clip ? steady : fading).push_back(instances[i]);
    std::vector<float>& to = one_clip ? steady_rows : fading_rows;
    to.insert(to.end(), rows.begin() + static_cast<std::ptrdiff_t>(i * per_instance),
              rows.begin() + static_cast<std::ptrdiff_t>((i + 1) * per_instance));
  }
  const Worst a = CompareBaked(SteadyPart(hybrid), steady, steady_rows);
  const Worst b = CompareLocalBaked(asset, hybrid, fading, fading_rows);
  return a.ratio >= b.ratio ? a : b;
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
