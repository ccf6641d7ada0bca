// skintune: the palette kernel on the CPU (palette_kernel.h), float32.
//
// Form: every node of an instance sampled once, then one walk per joint: the
// joint's node's local transform, multiplied on the left by each ancestor's
// (global = parent's global * local, so M <- local(parent) * M), then the
// inverse bind matrix. The device kernels (templates/palette.cl, .cu, .comp)
// do the same with a work-group per instance, the locals in local memory
// (docs/ANIMATION.md says why, with the H200's figures): the same products
// in the same order, so the same float results. One thread, 2-core
// development machine, 2026-11-29, a timing loop over 256 instances of clip
// 0: CesiumMan (19 joints) 2.6 us per instance (7.7 us re-sampling each
// ancestor in the walk; the host's float64 PaletteAt: 3.1 us); the tests'
// 321-joint rig 64 levels deep 98 us (599 us; PaletteAt: 30-41 us).
// Instances are independent: a caller may split them over threads (a
// subspan of instances, and the palette from its first instance's rows).
//
// Numerics follow model/animation.cpp (the float64 gold): keys found by
// binary search, t clamped to the first/last key, STEP holds key k, LINEAR
// lerps T/S and slerps R along the shortest path (nlerp when the keys are
// within ~0.08 degrees, where slerp and nlerp agree to float precision),
// CUBICSPLINE is glTF's Hermite with tangents scaled by the key interval;
// rotations are normalised after sampling. Two clips are blended in local
// space: T and S lerped, R nlerped along the shortest path.
#include "cpu_kernels/palette_kernel.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "base/error.h"

namespace skintune::internal {
namespace {

using glm::vec4;

// An affine transform as its three rows (x, y, z | translation).
struct Affine {
  vec4 row[3];
};

// a * b of two affine transforms (the implied fourth rows are 0 0 0 1).
Affine Multiply(const Affine& a, const Affine& b) {
  Affine c;
  for (int r = 0; r < 3; ++r)
    c.row[r] =
        a.row[r].x * b.row[0] + a.row[r].y * b.row[1] + a.row[r].z * b.row[2] + vec4(0.0f, 0.0f, 0.0f, a.row[r].w);
  return c;
}

vec4 Load(const float* p) { return vec4(p[0], p[1], p[2], p[3]); }

vec4 NormalizeQuat(const vec4& q) {
  const float length = std::sqrt(glm::dot(q, q));
  return length > 0.0f ? q / length : q;
}

// Shortest-path spherical interpolation of two (x, y, z, w) quaternions.
vec4 Slerp(const vec4& a, vec4 b, float u) {
  float cos_theta = glm::dot(a, b);
  if (cos_theta < 0.0f) {  // q and -q are the same rotation: take the short way
    b = -b;
    cos_theta = -cos_theta;
  }
  if (cos_theta > 1.0f - 1e-6f) return NormalizeQuat(a + u * (b - a));
  const float theta = std::acos(std::fmin(cos_theta, 1.0f));
  const float sin_theta = std::sin(theta);
  return NormalizeQuat((std::sin((1.0f - u) * theta) / sin_theta) * a + (std::sin(u * theta) / sin_theta) * b);
}

// The value of a channel with key_count > 0 at time t (rotations not yet normalised).
vec4 SampleChannel(const AnimationView& a, const AnimChannelHeader& h, bool rotation, float t) {
  const float* times = a.times.data() + h.time_offset;
  const float* values = a.values.data() + 4 * static_cast<std::size_t>(h.value_offset);
  const std::uint32_t n = h.key_count;
  const bool cubic = h.interpolation == static_cast<std::uint32_t>(AnimInterpolation::kCubicSpline);
  const std::uint32_t per_key = cubic ? 3 : 1, middle = cubic ? 1 : 0;  // CUBICSPLINE: in, value, out
  auto key = [&](std::uint32_t k) { return Load(values + 4 * (k * per_key + middle)); };
  if (n == 1 || !(t > times[0])) return key(0);
  if (t >= times[n - 1]) return key(n - 1);
  std::uint32_t lo = 0, hi = n - 1;  // times[lo] <= t < times[hi]
  while (hi - lo > 1) {
    const std::uint32_t mid = (lo + hi) / 2;
    if (times[mid] <= t)
      lo = mid;
    else
      hi = mid;
  }
  const float interval = times[hi] - times[lo];
  const float u = (t - times[lo]) / interval;
  if (h.interpolation == static_cast<std::uint32_t>(AnimInterpolation::kStep)) return key(lo);
  if (!cubic) return rotation ? Slerp(key(lo), key(hi), u) : key(lo) + u * (key(hi) - key(lo));
  const vec4 p0 = Load(values + 4 * (3 * lo + 1)), m0 = interval * Load(values + 4 * (3 * lo + 2));
  const vec4 p1 = Load(values + 4 * (3 * hi + 1)), m1 = interval * Load(values + 4 * (3 * hi));
  const float u2 = u * u, u3 = u2 * u;
  return (2.0f * u3 - 3.0f * u2 + 1.0f) * p0 + (u3 - 2.0f * u2 + u) * m0 + (-2.0f * u3 + 3.0f * u2) * p1 +
         (u3 - u2) * m1;
}

struct Trs {
  vec4 t, r, s;
};

Trs BakedLocal(const AnimationView& a, std::uint32_t node, std::uint16_t clip, float t);

// Node `node`'s local TRS in `clip` at time t: its rest values, overwritten
// by the clip's channels.
Trs SampleLocal(const AnimationView& a, std::uint32_t node, std::uint16_t clip, float t) {
  if (a.baked_local) return BakedLocal(a, node, clip, t);
  const AnimNodeRecord& n = a.nodes[node];
  Trs x{Load(n.rows[0]), Load(n.rows[1]), Load(n.rows[2])};
  if (clip == kAnimRestPose) return x;
  const AnimChannelHeader* h = &a.channels[(static_cast<std::size_t>(clip) * a.nodes.size() + node) * kAnimPaths];
  if (h[0].key_count > 0) x.t = SampleChannel(a, h[0], false, t);
  if (h[1].key_count > 0) x.r = NormalizeQuat(SampleChannel(a, h[1], true, t));
  if (h[2].key_count > 0) x.s = SampleChannel(a, h[2], false, t);
  return x;
}

// T * R * S as rows, from a normalised (x, y, z, w) rotation.
Affine ToAffine(const Trs& x) {
  const vec4& q = x.r;
  const float xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
  const float xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z, wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
  Affine m;
  m.row[0] = vec4((1.0f - 2.0f * (yy + zz)) * x.s.x, 2.0f * (xy - wz) * x.s.y, 2.0f * (xz + wy) * x.s.z, x.t.x);
  m.row[1] = vec4(2.0f * (xy + wz) * x.s.x, (1.0f - 2.0f * (xx + zz)) * x.s.y, 2.0f * (yz - wx) * x.s.z, x.t.y);
  m.row[2] = vec4(2.0f * (xz - wy) * x.s.x, 2.0f * (yz + wx) * x.s.y, (1.0f - 2.0f * (xx + yy)) * x.s.z, x.t.z);
  return m;
}

// Node `node`'s local transform for instance `in`: a fixed matrix, or its
// TRS in clip, blended towards clip2's by weight.
Affine LocalOf(const AnimationView& a, std::uint32_t node, const AnimInstance& in) {
  const AnimNodeRecord& n = a.nodes[node];
  if (n.fixed != 0) return Affine{{Load(n.rows[0]), Load(n.rows[1]), Load(n.rows[2])}};
  Trs x = SampleLocal(a, node, in.clip, in.time);
  if (in.weight != 0.0f) {
    const Trs y = SampleLocal(a, node, in.clip2, in.time2);
    const float w = in.weight;
    x.t += w * (y.t - x.t);
    x.s += w * (y.s - x.s);
    const vec4 r2 = glm::dot(x.r, y.r) < 0.0f ? -y.r : y.r;
    x.r = NormalizeQuat(x.r + w * (r2 - x.r));
  }
  return ToAffine(x);
}

// The work item (instance, joint j): its palette entry. local(n) is node
// n's local transform for the instance.
template <typename Local>
Affine JointPalette(const AnimationView& a, std::size_t j, const Local& local) {
  const AnimJointRecord& joint = a.joints[j];
  const std::uint32_t node = static_cast<std::uint32_t>(joint.node);
  Affine m = local(node);
  for (std::int32_t p = a.nodes[node].parent; p >= 0; p = a.nodes[static_cast<std::uint32_t>(p)].parent)
    m = Multiply(local(static_cast<std::uint32_t>(p)), m);
  const Affine inverse_bind{{Load(joint.inverse_bind[0]), Load(joint.inverse_bind[1]), Load(joint.inverse_bind[2])}};
  return Multiply(m, inverse_bind);
}

// A baked record: the rotation; translation and (similar) scale; the
// symmetric stretch's diagonal and S01; S02, S12 (affine records).
struct Baked {
  vec4 q, ts, s0, s1;
};

// Item j's record (a joint's; a node's baked in local space) at `frame`.
Baked BakedRecord(const AnimationView& a, std::uint32_t frame, std::size_t j) {
  const float* p = a.frames.data() + 4 * a.baked_rows * (std::size_t{frame} * a.baked_items() + j);
  if (a.baked_rows == kBakedRowsSimilar) return {Load(p), Load(p + 4), vec4(0.0f), vec4(0.0f)};
  if (a.baked_rows == kBakedRowsLocalScaled) return {Load(p), Load(p + 4), Load(p + 8), vec4(0.0f)};
  return {Load(p), Load(p + 4), Load(p + 8), Load(p + 12)};
}

// x towards y by u: the rotation nlerped along the shortest path, the rest
// lerped (templates/palette.cl baked_mix).
Baked BakedMix(const Baked& x, const Baked& y, float u) {
  const vec4 q2 = glm::dot(x.q, y.q) < 0.0f ? -y.q : y.q;
  return {NormalizeQuat(x.q + u * (q2 - x.q)), x.ts + u * (y.ts - x.ts), x.s0 + u * (y.s0 - x.s0),
          x.s1 + u * (y.s1 - x.s1)};
}

std::uint32_t Bits(float v) { return std::bit_cast<std::uint32_t>(v); }

// Joint j of clip `clip` at time t (clamped to the clip's range): between
// the two frames around t (templates/palette.cl baked_sample).
Baked BakedSample(const AnimationView& a, std::uint16_t clip, float t, std::size_t j) {
  if (clip == kAnimRestPose) return BakedRecord(a, 0, j);
  const float* range = a.clip_ranges.data() + 4 * std::size_t{clip};
  const std::uint32_t frames = Bits(range[2]), first = Bits(range[3]);
  if (frames < 2) return BakedRecord(a, first, j);
  const float length = range[1] - range[0];
  const float u = length > 0.0f ? std::fmin(std::fmax((t - range[0]) / length, 0.0f), 1.0f) *
                                      static_cast<float>(frames - 1)
                                : 0.0f;
  const std::uint32_t k = std::min(static_cast<std::uint32_t>(u), frames - 2);
  return BakedMix(BakedRecord(a, first + k, j), BakedRecord(a, first + k + 1, j), u - static_cast<float>(k));
}

// Node `node`'s local TRS baked in local space, in `clip` at time t (the
// rest pose: frame 0). A blend mixes two of them as LocalOf mixes sampled
// ones, which is what BakedMix does to records (templates/palette.cl).
Trs BakedLocal(const AnimationView& a, std::uint32_t node, std::uint16_t clip, float t) {
  const Baked b = BakedSample(a, clip, t, node);
  const vec4 s = a.baked_rows == kBakedRowsSimilar ? vec4(b.ts.w, b.ts.w, b.ts.w, 0.0f) : b.s0;
  return Trs{vec4(b.ts.x, b.ts.y, b.ts.z, 0.0f), b.q, s};
}

// Rows of R(q) S | t (similar records: S = s I).
Affine BakedAffine(const Baked& b, std::uint32_t rows) {
  if (rows == kBakedRowsSimilar)
    return ToAffine(Trs{vec4(b.ts.x, b.ts.y, b.ts.z, 0.0f), b.q, vec4(b.ts.w, b.ts.w, b.ts.w, 0.0f)});
  const Affine r = ToAffine(Trs{vec4(0.0f), b.q, vec4(1.0f, 1.0f, 1.0f, 0.0f)});
  const vec4 s_rows[3] = {vec4(b.s0.x, b.s0.w, b.s1.x, 0.0f), vec4(b.s0.w, b.s0.y, b.s1.y, 0.0f),
                          vec4(b.s1.x, b.s1.y, b.s0.z, 0.0f)};
  Affine m;
  for (int i = 0; i < 3; ++i)
    m.row[i] = r.row[i].x * s_rows[0] + r.row[i].y * s_rows[1] + r.row[i].z * s_rows[2] + vec4(0.0f, 0.0f, 0.0f, b.ts[i]);
  return m;
}

const char* PathName(std::size_t path) {
  static const char* const kNames[] = {"translation", "rotation", "scale"};
  return kNames[path];
}

// Header h (clip c, node n, path p): its keys and values within the arrays,
// its times finite and strictly increasing.
void ValidateChannel(const AnimationView& a, std::size_t index) {
  const AnimChannelHeader& h = a.channels[index];
  const std::size_t nodes = a.nodes.size();
  const std::string where = "packed animation: channels[" + std::to_string(index) + "] (clip " +
                            std::to_string(index / (nodes * kAnimPaths)) + ", node " +
                            std::to_string(index / kAnimPaths % nodes) + ", " + PathName(index % kAnimPaths) + ")";
  if (h.key_count == 0) return;
  if (h.interpolation > static_cast<std::uint32_t>(AnimInterpolation::kCubicSpline))
    throw Error(where + ": interpolation " + std::to_string(h.interpolation) +
                " is none of 0 (STEP), 1 (LINEAR), 2 (CUBICSPLINE)");
  const std::uint64_t per_key = h.interpolation == static_cast<std::uint32_t>(AnimInterpolation::kCubicSpline) ? 3 : 1;
  if (std::uint64_t{h.time_offset} + h.key_count > a.times.size())
    throw Error(where + ": keys " + std::to_string(h.time_offset) + ".." +
                std::to_string(std::uint64_t{h.time_offset} + h.key_count - 1) + " beyond the " +
                std::to_string(a.times.size()) + " times");
  if (std::uint64_t{h.value_offset} + per_key * h.key_count > a.values.size() / 4)
    throw Error(where + ": " + std::to_string(per_key * h.key_count) + " values from " +
                std::to_string(h.value_offset) + " beyond the " + std::to_string(a.values.size() / 4) + " values");
  const float* times = a.times.data() + h.time_offset;
  for (std::uint32_t k = 0; k < h.key_count; ++k) {
    if (!std::isfinite(times[k])) throw Error(where + ": time of key " + std::to_string(k) + " is not finite");
    if (k > 0 && !(times[k] > times[k - 1]))
      throw Error(where + ": times not strictly increasing at key " + std::to_string(k));
  }
}

void ValidateHierarchy(const AnimationView& a) {
  const std::int64_t n = static_cast<std::int64_t>(a.nodes.size());
  for (std::int64_t i = 0; i < n; ++i) {
    std::int64_t steps = 0;
    for (std::int64_t p = a.nodes[i].parent; p != -1; p = a.nodes[p].parent) {
      if (p < -1 || p >= n)
        throw Error("packed animation: nodes[" + std::to_string(i) + "]: ancestor index " + std::to_string(p) +
                    " out of range (" + std::to_string(n) + " nodes)");
      if (++steps > n)
        throw Error("packed animation: nodes[" + std::to_string(i) + "]: the node hierarchy has a cycle");
    }
  }
  if (a.joints.empty()) throw Error("packed animation: no joints");
  for (std::size_t j = 0; j < a.joints.size(); ++j) {
    if (a.joints[j].node < 0 || a.joints[j].node >= n)
      throw Error("packed animation: joints[" + std::to_string(j) + "]: node " + std::to_string(a.joints[j].node) +
                  " out of range (" + std::to_string(n) + " nodes)");
  }
}

std::string Number(float v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", static_cast<double>(v));
  return text;
}

// Every record of a's frames finite, its rotation of unit length; `buffer`
// names the buffer in the message ("frames[F] joint J: ...").
void ValidateRecords(const AnimationView& a, const char* buffer) {
  const std::size_t joints = a.baked_items(), floats = 4 * std::size_t{a.baked_rows};
  for (std::size_t r = 0; r < a.frames.size() / floats; ++r) {
    const float* p = a.frames.data() + floats * r;
    const std::string what = std::string("baked animation: ") + buffer + "[" + std::to_string(r / joints) +
                             (a.baked_local ? "] node " : "] joint ") + std::to_string(r % joints);
    for (std::size_t k = 0; k < floats; ++k)
      if (!std::isfinite(p[k])) throw Error(what + ": " + Number(p[k]) + " is not finite");
    const float length = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]);
    if (std::fabs(length - 1.0f) > 1e-3f)
      throw Error(what + ": rotation of length " + Number(length) + ", not a unit quaternion");
  }
}

}  // namespace

void ValidateAnimation(const AnimationView& a) {
  if (a.nodes.size() > kAnimMaxNodes)
    throw Error("packed animation: " + std::to_string(a.nodes.size()) + " nodes (the device palette kernels hold at most " +
                std::to_string(kAnimMaxNodes) + " in local memory)");
  if (a.clip_count > kAnimMaxClips)
    throw Error("packed animation: " + std::to_string(a.clip_count) + " clips (at most " +
                std::to_string(kAnimMaxClips) + ")");
  if (a.clip_ranges.size() != std::size_t{a.clip_count} * 4)
    throw Error("packed animation: " + std::to_string(a.clip_ranges.size()) + " clip-range floats for " +
                std::to_string(a.clip_count) + " clips (4 each: start, end, 0, 0)");
  for (std::uint32_t c = 0; c < a.clip_count; ++c) {
    const float start = a.clip_ranges[4u * c], end = a.clip_ranges[4u * c + 1u];
    if (!std::isfinite(start) || !std::isfinite(end) || end < start)
      throw Error("packed animation: clips[" + std::to_string(c) + "]: range " + std::to_string(start) + " .. " +
                  std::to_string(end) + " is not finite and increasing");
  }
  const std::uint64_t headers = std::uint64_t{a.clip_count} * a.nodes.size() * kAnimPaths;
  if (a.channels.size() != headers)
    throw Error("packed animation: " + std::to_string(a.channels.size()) + " channel headers for " +
                std::to_string(a.clip_count) + " clips x " + std::to_string(a.nodes.size()) +
                " nodes x 3 paths (expected " + std::to_string(headers) + ")");
  if (a.values.size() % 4 != 0)
    throw Error("packed animation: " + std::to_string(a.values.size()) + " value floats, not whole float4s");
  ValidateHierarchy(a);
  for (std::size_t i = 0; i < a.channels.size(); ++i) ValidateChannel(a, i);
}

void ValidateBakedAnimation(const AnimationView& a) {
  if (!a.baked()) return ValidateAnimation(a);
  const std::size_t joints = a.baked_items();
  if (a.joints.empty()) throw Error("baked animation: no joints");
  if ((!a.steady.empty() || a.steady_rows != 0) && !a.baked_local)
    throw Error("baked animation: steady records beside records not in local space (hybrid records are local "
                "records with the same frames' palette records)");
  if (a.baked_local) {  // the kernel walks the hierarchy, as a sampled one does
    if (a.nodes.size() > kAnimMaxNodes)
      throw Error("baked animation: " + std::to_string(a.nodes.size()) + " nodes (the device palette kernels hold at most " +
                  std::to_string(kAnimMaxNodes) + " in local memory)");
    ValidateHierarchy(a);
  }
  if (a.clip_count > kAnimMaxClips)
    throw Error("baked animation: " + std::to_string(a.clip_count) + " clips (at most " +
                std::to_string(kAnimMaxClips) + ")");
  const std::uint32_t other_rows = a.baked_local ? kBakedRowsLocalScaled : kBakedRowsAffine;
  if (a.baked_rows != kBakedRowsSimilar && a.baked_rows != other_rows)
    throw Error("baked animation: " + std::to_string(a.baked_rows) + " float4s a record (2 or " +
                std::to_string(other_rows) + (a.baked_local ? " in local space)" : ")"));
  const std::size_t floats = 4 * std::size_t{a.baked_rows};
  if (a.frames.size() % (floats * joints) != 0)
    throw Error("baked animation: " + std::to_string(a.frames.size()) + " frame floats, not whole frames of " +
                std::to_string(joints) + (a.baked_local ? " nodes x " : " joints x ") + std::to_string(floats) +
                " floats");
  const std::size_t total = a.frames.size() / (floats * joints);
  if (a.clip_ranges.size() != std::size_t{a.clip_count} * 4)
    throw Error("baked animation: " + std::to_string(a.clip_ranges.size()) + " clip-range floats for " +
                std::to_string(a.clip_count) + " clips (4 each: start, end, frames, first frame)");
  for (std::uint32_t c = 0; c < a.clip_count; ++c) {
    const float start = a.clip_ranges[4u * c], end = a.clip_ranges[4u * c + 1u];
    const std::uint64_t frames = Bits(a.clip_ranges[4u * c + 2u]), first = Bits(a.clip_ranges[4u * c + 3u]);
    const std::string what = "baked animation: clips[" + std::to_string(c) + "]";
    if (!std::isfinite(start) || !std::isfinite(end) || end < start)
      throw Error(what + ": range " + Number(start) + " .. " + Number(end) + " is not finite and increasing");
    if (frames < (end > start ? 2u : 1u) || first == 0 || first + frames > total)
      throw Error(what + ": frames " + std::to_string(first) + " .. " + std::to_string(first + frames) + " of " +
                  std::to_string(total) + " (frame 0 is the rest pose; at least 2 frames where the clip lasts)");
  }
  ValidateRecords(a, "frames");
  if (a.steady.empty() && a.steady_rows == 0) return;
  // Hybrid: palette records of the same frames beside the local ones.
  const AnimationView steady = SteadyView(a);
  if (steady.baked_rows != kBakedRowsSimilar && steady.baked_rows != kBakedRowsAffine)
    throw Error("baked animation: steady records of " + std::to_string(steady.baked_rows) + " float4s (2 or 4)");
  const std::size_t steady_floats = 4 * std::size_t{steady.baked_rows} * a.joints.size();
  if (steady.frames.size() != total * steady_floats)
    throw Error("baked animation: " + std::to_string(steady.frames.size()) + " steady floats, not the " +
                std::to_string(total) + " frames of `frames` x " + std::to_string(a.joints.size()) + " joints x " +
                std::to_string(4 * steady.baked_rows) + " floats");
  ValidateRecords(steady, "steady");
}

AnimationView SteadyView(const AnimationView& a) {
  AnimationView steady = a;
  steady.frames = a.steady;
  steady.baked_rows = a.steady_rows;
  steady.baked_local = false;
  steady.steady = {};
  steady.steady_rows = 0;
  return steady;
}

void ValidateAnimInstances(const AnimationView& a, std::span<const AnimInstance> instances) {
  auto check_clip = [&](std::size_t i, const char* field, std::uint16_t clip) {
    if (clip != kAnimRestPose && clip >= a.clip_count)
      throw Error("instances[" + std::to_string(i) + "]: " + field + " " + std::to_string(clip) + " out of range (" +
                  std::to_string(a.clip_count) + " clips packed; " + std::to_string(kAnimRestPose) +
                  " is the rest pose)");
  };
  auto check_finite = [&](std::size_t i, const char* field, float v) {
    if (!std::isfinite(v))
      throw Error("instances[" + std::to_string(i) + "]: " + field + " " + Number(v) + " is not finite");
  };
  for (std::size_t i = 0; i < instances.size(); ++i) {
    const AnimInstance& in = instances[i];
    check_clip(i, "clip", in.clip);
    check_finite(i, "time", in.time);
    check_finite(i, "weight", in.weight);
    if (in.weight < 0.0f || in.weight > 1.0f)
      throw Error("instances[" + std::to_string(i) + "]: weight " + Number(in.weight) + " outside [0, 1]");
    if (in.weight != 0.0f) {
      check_clip(i, "clip2", in.clip2);
      check_finite(i, "time2", in.time2);
    }
  }
}

float AnimLoopTime(float t, float start, float end) {
  const float length = end - start;
  if (!(length > 0.0f)) return start;
  float u = t - start;
  u = std::fmin(std::fmax(u - length * std::floor(u / length), 0.0f), length);
  return start + u;
}

void AdvanceAnimInstances(const AnimationView& a, std::span<AnimInstance> states, float delta) {
  const auto advance = [&](std::uint16_t clip, float& t) {
    if (clip == kAnimRestPose || clip >= a.clip_count) return;
    t = AnimLoopTime(t + delta, a.clip_ranges[4u * clip], a.clip_ranges[4u * clip + 1u]);
  };
  for (AnimInstance& s : states) {
    advance(s.clip, s.time);
    advance(s.clip2, s.time2);
  }
}

void RunPaletteKernel(const AnimationView& a, std::span<const AnimInstance> instances, float* palette, int rows) {
  if (rows != 3 && rows != 4) throw Error("palette kernel: " + std::to_string(rows) + " rows per joint (3 or 4)");
  ValidateAnimInstances(a, instances);
  const std::size_t joints = a.joints.size(), stride = 4 * static_cast<std::size_t>(rows);
  const auto put = [&](float* out, const Affine& m) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) out[4 * r + c] = m.row[r][c];
    if (rows == 4) {  // a mat4's last row
      out[12] = out[13] = out[14] = 0.0f;
      out[15] = 1.0f;
    }
  };
  // Palette records: two a joint and clip. Hybrid: an instance that plays
  // one clip reads the steady ones so, one that cross-fades walks its nodes.
  const auto from_records = [&](const AnimationView& records, std::size_t i) {
    const AnimInstance& in = instances[i];
    for (std::size_t j = 0; j < joints; ++j) {
      Baked x = BakedSample(records, in.clip, in.time, j);
      if (in.weight != 0.0f) x = BakedMix(x, BakedSample(records, in.clip2, in.time2, j), in.weight);
      put(palette + stride * (i * joints + j), BakedAffine(x, records.baked_rows));
    }
  };
  if (a.baked() && !a.baked_local) {
    for (std::size_t i = 0; i < instances.size(); ++i) from_records(a, i);
    return;
  }
  const AnimationView steady = SteadyView(a);
  std::vector<Affine> locals(a.nodes.size());
  for (std::size_t i = 0; i < instances.size(); ++i) {
    if (!a.steady.empty() && instances[i].weight == 0.0f) {
      from_records(steady, i);
      continue;
    }
    for (std::uint32_t n = 0; n < locals.size(); ++n) locals[n] = LocalOf(a, n, instances[i]);
    const auto local = [&](std::uint32_t n) -> const Affine& { return locals[n]; };
    for (std::size_t j = 0; j < joints; ++j) put(palette + stride * (i * joints + j), JointPalette(a, j, local));
  }
}

}  // namespace skintune::internal
