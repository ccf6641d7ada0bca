#version 430 core
// skintune: the palette kernel as a GL 4.3 compute shader, the twin of
// templates/palette.cl (same buffers, bytes and algorithm; the layout:
// docs/ANIMATION.md; why each node is sampled once per instance:
// templates/palette.cl).
//
// Bindings, in palette.cl's argument order: shader storage buffers 0 nodes,
// 1 channels, 2 times, 3 values, 4 joints, 5 instances, 6 palette (output)
// (Vulkan: descriptor set 0 at those bindings). No uniforms: the counts are
// the generator's defines (below). glDispatchCompute(1, K, 1) for K
// instances: work-group i (gl_WorkGroupID.y) writes instance i's joints,
// joint j as ANIM_PALETTE_ROWS vec4 rows at
// (i * ANIM_JOINT_COUNT + j) * ANIM_PALETTE_ROWS + r. An instance whose clip index is neither a
// packed clip nor 0xffff (the rest pose) gets NaN rows.

// The animation's counts and the palette's rows per joint (ANIM_NODE_COUNT,
// ANIM_JOINT_COUNT, ANIM_CLIP_COUNT, ANIM_PALETTE_ROWS): the generator defines
// them for the packed animation the kernel runs (generator/palette_kernel.h),
// skin_params.h gives their defaults.
#define ANIM_PALETTE_KERNEL 1  // the prelude's palette-kernel part (anim_records.glsl)
#include "skin_params.h"

#if ANIM_BAKED >= 3 && ANIM_STEADY
// Hybrid records (docs/ANIMATION.md "Hybrid records"): bindings 0 nodes,
// 1 frames, 2 steady, 3 joints, 4 instances, 5 palette (output), 6 clips, 7 states.
layout(std430, binding = 0) readonly buffer Nodes { vec4 nodes[]; };
layout(std430, binding = 1) readonly buffer Frames { vec4 frames[]; };
layout(std430, binding = 2) readonly buffer Steady { vec4 steady[]; };
layout(std430, binding = 3) readonly buffer Joints { vec4 joints[]; };
layout(std430, binding = 4) readonly buffer Instances { uvec4 instances[]; };
layout(std430, binding = 5) writeonly buffer Palette { vec4 palette[]; };
layout(std430, binding = 6) readonly buffer Clips { vec4 clips[]; };
layout(std430, binding = 7) buffer States { uvec4 states[]; };
#elif ANIM_BAKED >= 3
// Clips baked in local space (docs/ANIMATION.md "Baked clips"): bindings 0
// nodes, 1 frames, 2 joints, 3 instances, 4 palette (output), 5 clips, 6 states.
layout(std430, binding = 0) readonly buffer Nodes { vec4 nodes[]; };
layout(std430, binding = 1) readonly buffer Frames { vec4 frames[]; };
layout(std430, binding = 2) readonly buffer Joints { vec4 joints[]; };
layout(std430, binding = 3) readonly buffer Instances { uvec4 instances[]; };
layout(std430, binding = 4) writeonly buffer Palette { vec4 palette[]; };
layout(std430, binding = 5) readonly buffer Clips { vec4 clips[]; };
layout(std430, binding = 6) buffer States { uvec4 states[]; };
#elif ANIM_BAKED
// Baked clips (docs/ANIMATION.md "Baked clips"): bindings 0 frames, 1 instances,
// 2 palette (output), 3 clips, 4 states.
layout(std430, binding = 0) readonly buffer Frames { vec4 frames[]; };
layout(std430, binding = 1) readonly buffer Instances { uvec4 instances[]; };
layout(std430, binding = 2) writeonly buffer Palette { vec4 palette[]; };
layout(std430, binding = 3) readonly buffer Clips { vec4 clips[]; };
layout(std430, binding = 4) buffer States { uvec4 states[]; };
#else
layout(std430, binding = 0) readonly buffer Nodes { vec4 nodes[]; };
layout(std430, binding = 1) readonly buffer Channels { uvec4 channels[]; };
layout(std430, binding = 2) readonly buffer Times { float times[]; };
layout(std430, binding = 3) readonly buffer Values { vec4 values[]; };
layout(std430, binding = 4) readonly buffer Joints { vec4 joints[]; };
layout(std430, binding = 5) readonly buffer Instances { uvec4 instances[]; };
layout(std430, binding = 6) writeonly buffer Palette { vec4 palette[]; };
layout(std430, binding = 7) readonly buffer Clips { vec4 clips[]; };
layout(std430, binding = 8) buffer States { uvec4 states[]; };
#endif

#ifdef VULKAN
// Vulkan (GL_KHR_vulkan_glsl predefines VULKAN): the frame's scalars are a
// push-constant block, bytes 0 and 4.
layout(push_constant) uniform Frame {
  float delta;
  uint fresh;
};
#else
uniform float delta;
uniform uint fresh;
#endif


layout(local_size_x = ANIM_GROUP) in;
const uint node_count = uint(ANIM_NODE_COUNT);
const uint joint_count = uint(ANIM_JOINT_COUNT);
const uint clip_count = uint(ANIM_CLIP_COUNT);
const uint rows = uint(ANIM_PALETTE_ROWS);

#include "anim_records.glsl"

#if !ANIM_BAKED
// Shortest-path spherical interpolation of two (x, y, z, w) quaternions.
vec4 anim_slerp(vec4 a, vec4 b, float u) {
  float cos_theta = dot(a, b);
  if (cos_theta < 0.0) {  // q and -q are the same rotation: take the short way
    b = -b;
    cos_theta = -cos_theta;
  }
  if (cos_theta > 1.0 - 1e-6) return anim_normalize_quat(a + u * (b - a));
  float theta = acos(min(cos_theta, 1.0));
  float sin_theta = sin(theta);
  return anim_normalize_quat((sin((1.0 - u) * theta) / sin_theta) * a + (sin(u * theta) / sin_theta) * b);
}

// The value of a channel with keys (h: interpolation, key count, time offset,
// value offset) at time t; rotations not yet normalised.
vec4 anim_sample_channel(uvec4 h, bool rotation, float t) {
  uint n = h.y, t0 = h.z, v0 = h.w;
  bool cubic = h.x == 2u;
  uint per_key = cubic ? 3u : 1u, middle = cubic ? 1u : 0u;  // CUBICSPLINE: in, value, out
  if (n == 1u || !(t > times[t0])) return values[v0 + middle];
  if (t >= times[t0 + n - 1u]) return values[v0 + (n - 1u) * per_key + middle];
  // The key interval: first guessed as if the keys were evenly spaced (exact
  // for the evenly sampled clips exporters write: one round of loads instead
  // of a binary search's chain of dependent ones), then, where the guess
  // misses, a binary search on the side of it that holds t. Either way the
  // interval found is the one with times[lo] <= t < times[lo + 1].
  float first = times[t0], last = times[t0 + n - 1u];
  uint lo = min(uint((t - first) / (last - first) * float(n - 1u)), n - 2u), hi = lo + 1u;
  if (times[t0 + lo] > t) {
    hi = lo;
    lo = 0u;
  } else if (times[t0 + hi] <= t) {
    lo = hi;
    hi = n - 1u;
  }  // times[lo] <= t < times[hi]
  while (hi - lo > 1u) {
    uint mid = (lo + hi) / 2u;
    if (times[t0 + mid] <= t) lo = mid;
    else hi = mid;
  }
  float interval = times[t0 + hi] - times[t0 + lo];
  float u = (t - times[t0 + lo]) / interval;
  if (h.x == 0u) return values[v0 + lo];
  if (!cubic) {
    vec4 a = values[v0 + lo], b = values[v0 + hi];
    return rotation ? anim_slerp(a, b, u) : a + u * (b - a);
  }
  vec4 p0 = values[v0 + 3u * lo + 1u], m0 = interval * values[v0 + 3u * lo + 2u];
  vec4 p1 = values[v0 + 3u * hi + 1u], m1 = interval * values[v0 + 3u * hi];
  float u2 = u * u, u3 = u2 * u;
  return (2.0 * u3 - 3.0 * u2 + 1.0) * p0 + (u3 - 2.0 * u2 + u) * m0 + (-2.0 * u3 + 3.0 * u2) * p1 + (u3 - u2) * m1;
}

// Path `path` (0 translation, 1 rotation, 2 scale) of node `node` in
// `clip` at time t: its rest value, or the clip's channel's (a rotation
// normalised).
vec4 anim_path_value(uint node, uint path, uint clip, float t) {
  vec4 rest = nodes[4u * node + 1u + path];
  if (clip == kRestPose) return rest;
  uvec4 h = channels[(clip * node_count + node) * 3u + path];
  if (h.y == 0u) return rest;
  vec4 v = anim_sample_channel(h, path == 1u, t);
  return path == 1u ? anim_normalize_quat(v) : v;
}

// The path's value for an instance (in_: clips, time, time2, weight): in
// clip, blended towards clip2's by weight (T, S lerped; R nlerped along the
// shortest path).
vec4 anim_path(uint node, uint path, uvec4 in_) {
  vec4 x = anim_path_value(node, path, in_.x & 0xffffu, uintBitsToFloat(in_.y));
  float w = uintBitsToFloat(in_.w);
  if (w == 0.0) return x;
  vec4 y = anim_path_value(node, path, in_.x >> 16, uintBitsToFloat(in_.z));
  if (path != 1u) return x + w * (y - x);
  vec4 r2 = dot(x, y) < 0.0 ? -y : y;
  return anim_normalize_quat(x + w * (r2 - x));
}
#endif  // !ANIM_BAKED


// An instance's joint j from palette records of `rows_` vec4s, written at
// palette[base + rows * j ..] (palette.cl).
#if ANIM_BAKED
void baked_palette_entry(bool from_steady, uint rows_, uvec4 in_, uint j, uint base) {
  Affine m = baked_affine(baked_instance(from_steady, rows_, joint_count, in_, j), rows_);
  palette[base + rows * j] = m.row0;
  palette[base + rows * j + 1u] = m.row1;
  palette[base + rows * j + 2u] = m.row2;
  if (rows == 4u) palette[base + rows * j + 3u] = vec4(0.0, 0.0, 0.0, 1.0);
}
#endif  // ANIM_BAKED

#if ANIM_BAKED == 1 || ANIM_BAKED == 2

void main() {
  uint item = gl_LocalInvocationID.x, i = gl_WorkGroupID.y;
  bool in_group = gl_WorkGroupID.x == 0u;
  uvec4 in_ = in_group ? (fresh != 0u ? instances[i] : states[i]) : uvec4(0u);
  if (in_group && fresh == 0u) in_ = anim_advance(in_, delta);
  uint base = i * joint_count * rows;
  bool valid = in_group && anim_state_valid(in_);
  for (uint j = item; in_group && j < joint_count; j += uint(ANIM_GROUP)) {
    if (!valid) {
      for (uint r = 0u; r < rows; ++r) palette[base + rows * j + r] = vec4(uintBitsToFloat(0x7fc00000u));
      continue;
    }
    baked_palette_entry(false, kBakedRows, in_, j, base);
  }
  barrier();  // every invocation has read the state before it is kept
  if (in_group && item == 0u) states[i] = in_;
}

#else  // the clips sampled from their channels, or baked in local space: the hierarchy walked

// One work-group of ANIM_GROUP per instance (glDispatchCompute(1, K, 1)), in
// palette.cl's three steps: every (node, path) sampled once into shared
// memory, each node's local transform made there, then each invocation's
// joints composed up their ancestors there (templates/palette.cl says why).
void main() {
  uint item = gl_LocalInvocationID.x, i = gl_WorkGroupID.y;
  // No return before the barrier (GLSL allows none in main before one): a
  // group beyond the first along x, or an instance with a clip out of range,
  // only skips the work (uniformly).
  bool in_group = gl_WorkGroupID.x == 0u && node_count <= uint(ANIM_MAX_NODES);
  // The instance's state: the frame's upload (fresh), or the last frame's
  // kept on the device, advanced by delta; kept again at the end.
  uvec4 in_ = in_group ? (fresh != 0u ? instances[i] : states[i]) : uvec4(0u);
  if (in_group && fresh == 0u) in_ = anim_advance(in_, delta);
  uint out_ = i * joint_count * rows;
  bool valid = in_group && anim_state_valid(in_);
  if (in_group && !valid) {
    vec4 nan = vec4(uintBitsToFloat(0x7fc00000u));
    for (uint r = item; r < joint_count * rows; r += uint(ANIM_GROUP)) palette[out_ + r] = nan;
  }
#if ANIM_STEADY
  // Hybrid records: an instance that plays one clip reads palette records,
  // one that cross-fades walks (palette.cl).
  bool walk = valid && uintBitsToFloat(in_.w) != 0.0;
  for (uint j = item; valid && !walk && j < joint_count; j += uint(ANIM_GROUP))
    baked_palette_entry(true, uint(ANIM_STEADY), in_, j, out_);
#else
  bool walk = valid;
#endif
  // The invocation's first joint, loaded before the nodes are (palette.cl says why).
  vec4 joint0 = vec4(0.0), joint1 = joint0, joint2 = joint0, joint3 = joint0;
  if (walk && item < joint_count) {
    joint0 = joints[4u * item];
    joint1 = joints[4u * item + 1u];
    joint2 = joints[4u * item + 2u];
    joint3 = joints[4u * item + 3u];
  }
#if ANIM_BAKED
  // 1, 2: each node's local transform from its records, mixed in local space (anim_records.glsl).
  if (walk) anim_local_from_records(in_, item);
#else
  // 1: every (node, path) sampled once, all in parallel: row 3 node + path.
  for (uint task = item; walk && task < 3u * node_count; task += uint(ANIM_GROUP)) {
    uint node = task / 3u, path = task - 3u * node;
    local_rows[task] = anim_path(node, path, in_);
    if (path == 0u) local_parent[node] = floatBitsToInt(nodes[4u * node].x);
  }
  memoryBarrierShared();
  barrier();
  // 2: each node's local transform, T * R * S (a fixed-matrix node: its matrix), in place.
  for (uint n = item; walk && n < node_count; n += uint(ANIM_GROUP)) {
    Affine l = floatBitsToUint(nodes[4u * n].y) != 0u
                   ? Affine(nodes[4u * n + 1u], nodes[4u * n + 2u], nodes[4u * n + 3u])
                   : anim_to_affine(Trs(local_rows[3u * n], local_rows[3u * n + 1u], local_rows[3u * n + 2u]));
    local_rows[3u * n] = l.row0;
    local_rows[3u * n + 1u] = l.row1;
    local_rows[3u * n + 2u] = l.row2;
  }
#endif  // ANIM_BAKED
  memoryBarrierShared();
  barrier();
  // 3: each node's global transform by pointer jumping (anim_records.glsl, palette.cl).
  anim_jump(walk, item);
  // 4: each joint's palette entry, its node's global transform by its inverse bind.
  for (uint j = item; walk && j < joint_count; j += uint(ANIM_GROUP)) {
    if (j != item) {
      joint0 = joints[4u * j];
      joint1 = joints[4u * j + 1u];
      joint2 = joints[4u * j + 2u];
      joint3 = joints[4u * j + 3u];
    }
    Affine m = anim_joint_entry(joint0, joint1, joint2, joint3);
    palette[out_ + rows * j] = m.row0;
    palette[out_ + rows * j + 1u] = m.row1;
    palette[out_ + rows * j + 2u] = m.row2;
    if (rows == 4u) palette[out_ + rows * j + 3u] = vec4(0.0, 0.0, 0.0, 1.0);
  }
  if (in_group && item == 0u) states[i] = in_;  // every invocation read it before the first barrier
}

#endif  // ANIM_BAKED == 1 || ANIM_BAKED == 2
