// skintune: the palette kernel (OpenCL C 1.2): every instance's bone palette
// from an animation packed once (generator/clip_packer.h; the buffers'
// bytes: docs/ANIMATION.md). cpu_kernels/palette_kernel.cpp is the same
// algorithm in C++ (the cpu device's kernel), function for function; its
// opening comment says how sampling follows model/animation.cpp.
//
// Launch: a 2-D NDRange of work-groups of ANIM_GROUP items, one group
// per instance: global size (ANIM_GROUP, K), local size (ANIM_GROUP, 1), for
// K instances. In four steps, each all in parallel, with barriers between:
// the group's items sample every (node, path) of their instance once, into
// local memory (at most ANIM_MAX_NODES nodes: ValidateAnimation refuses
// more), with the node's parent; each node's local transform is made from its
// translation, rotation and scale there; the nodes' global transforms are
// composed there by pointer jumping, ANIM_JUMPS rounds of one product a node
// (the cpu device walks each joint's ancestors instead: the same product,
// associated otherwise); then each item writes its joints (j = item,
// item + ANIM_GROUP, ...), instance i's joint j as ANIM_PALETTE_ROWS float4 rows at
// (i * ANIM_JOINT_COUNT + j) * ANIM_PALETTE_ROWS + r: the palette the skin
// kernels read (`mat3x4`, or `mat4`), K palettes one after another.
// Why (docs/ANIMATION.md, measured on an H200, 2026-11-29): sampling is
// binary searches in global memory, a chain of dependent loads, so each
// (node, path) is sampled once and all at the same time; and the hierarchy
// is composed in local memory (walking it in global memory, 64 instances of
// a 77-joint rig took 15.6 us a launch; re-sampling every ancestor per
// joint, 49 us).
// An instance whose clip index is neither a packed clip nor 0xffff (the
// rest pose) gets NaN rows instead of a read out of bounds.

// The animation's counts and the palette's rows per joint (ANIM_NODE_COUNT,
// ANIM_JOINT_COUNT, ANIM_CLIP_COUNT, ANIM_PALETTE_ROWS): the generator defines
// them for the packed animation the kernel runs (generator/palette_kernel.h),
// skin_params.h gives their defaults.
#define ANIM_PALETTE_KERNEL 1  // the prelude's palette-kernel part (anim_records.clh)
#include "skin_params.h"
#include "anim_records.clh"


// Shortest-path spherical interpolation of two (x, y, z, w) quaternions.
float4 anim_slerp(const float4 a, float4 b, const float u) {
  float cos_theta = dot(a, b);
  if (cos_theta < 0.0f) {  // q and -q are the same rotation: take the short way
    b = -b;
    cos_theta = -cos_theta;
  }
  if (cos_theta > 1.0f - 1e-6f) return anim_normalize_quat(a + u * (b - a));
  const float theta = acos(fmin(cos_theta, 1.0f));
  const float sin_theta = sin(theta);
  return anim_normalize_quat((sin((1.0f - u) * theta) / sin_theta) * a + (sin(u * theta) / sin_theta) * b);
}

// The value of a channel with keys (h: interpolation, key count, time offset,
// value offset) at time t; rotations not yet normalised.
float4 anim_sample_channel(__global const float* restrict times_all, __global const float4* restrict values_all,
                           const uint4 h, const int rotation, const float t) {
  __global const float* times = times_all + h.z;
  __global const float4* values = values_all + h.w;
  const uint n = h.y;
  const int cubic = h.x == 2u;
  const uint per_key = cubic ? 3u : 1u, middle = cubic ? 1u : 0u;  // CUBICSPLINE: in, value, out
  if (n == 1u || !(t > times[0])) return values[middle];
  if (t >= times[n - 1u]) return values[(n - 1u) * per_key + middle];
  // The key interval: first guessed as if the keys were evenly spaced (exact
  // for the evenly sampled clips exporters write: one round of loads instead
  // of a binary search's chain of dependent ones), then, where the guess
  // misses, a binary search on the side of it that holds t. Either way the
  // interval found is the one with times[lo] <= t < times[lo + 1].
  const float first = times[0], last = times[n - 1u];
  uint lo = min((uint)((t - first) / (last - first) * (float)(n - 1u)), n - 2u), hi = lo + 1u;
  if (times[lo] > t) {
    hi = lo;
    lo = 0u;
  } else if (times[hi] <= t) {
    lo = hi;
    hi = n - 1u;
  }  // times[lo] <= t < times[hi]
  while (hi - lo > 1u) {
    const uint mid = (lo + hi) / 2u;
    if (times[mid] <= t)
      lo = mid;
    else
      hi = mid;
  }
  const float interval = times[hi] - times[lo];
  const float u = (t - times[lo]) / interval;
  if (h.x == 0u) return values[lo];
  if (!cubic) return rotation ? anim_slerp(values[lo], values[hi], u) : values[lo] + u * (values[hi] - values[lo]);
  const float4 p0 = values[3u * lo + 1u], m0 = interval * values[3u * lo + 2u];
  const float4 p1 = values[3u * hi + 1u], m1 = interval * values[3u * hi];
  const float u2 = u * u, u3 = u2 * u;
  return (2.0f * u3 - 3.0f * u2 + 1.0f) * p0 + (u3 - 2.0f * u2 + u) * m0 + (-2.0f * u3 + 3.0f * u2) * p1 +
         (u3 - u2) * m1;
}

// Path `path` (0 translation, 1 rotation, 2 scale) of node `node` in
// `clip` at time t: its rest value, or the clip's channel's (a rotation
// normalised).
float4 anim_path_value(const uint node_count, __global const float4* restrict nodes,
                       __global const uint4* restrict channels, __global const float* restrict times,
                       __global const float4* restrict values, const uint node, const uint path, const uint clip,
                       const float t) {
  const float4 rest = nodes[4u * node + 1u + path];
  if (clip == ANIM_REST_POSE) return rest;
  const uint4 h = channels[(clip * node_count + node) * 3u + path];
  if (h.y == 0u) return rest;
  const float4 v = anim_sample_channel(times, values, h, path == 1u, t);
  return path == 1u ? anim_normalize_quat(v) : v;
}

// The path's value for an instance (in: clips, time, time2, weight): in
// clip, blended towards clip2's by weight (T, S lerped; R nlerped along the
// shortest path).
float4 anim_path(const uint node_count, __global const float4* restrict nodes, __global const uint4* restrict channels,
                 __global const float* restrict times, __global const float4* restrict values, const uint node,
                 const uint path, const uint4 in) {
  float4 x = anim_path_value(node_count, nodes, channels, times, values, node, path, in.x & 0xffffu, as_float(in.y));
  const float w = as_float(in.w);
  if (w == 0.0f) return x;
  const float4 y = anim_path_value(node_count, nodes, channels, times, values, node, path, in.x >> 16, as_float(in.z));
  if (path != 1u) return x + w * (y - x);
  const float4 r2 = dot(x, y) < 0.0f ? -y : y;
  return anim_normalize_quat(x + w * (r2 - x));
}


#if ANIM_BAKED
// An instance's joint j from palette records of `rows` float4s: in clip,
// mixed towards clip2's by the weight, written as `rows_out` float4 rows.
void baked_palette_entry(__global const float4* restrict frames, const uint rows,
                         __global const float4* restrict clips, const uint4 in, const uint j,
                         __global float4* restrict out, const uint rows_out) {
  const Affine m = baked_affine(baked_instance(frames, rows, ANIM_JOINT_COUNT, clips, in, j), rows);
  out[rows_out * j] = m.row0;
  out[rows_out * j + 1u] = m.row1;
  out[rows_out * j + 2u] = m.row2;
  if (rows_out == 4u) out[rows_out * j + 3u] = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
}
#endif  // ANIM_BAKED

#if ANIM_BAKED == 1 || ANIM_BAKED == 2

__kernel __attribute__((reqd_work_group_size(ANIM_GROUP, 1, 1)))
void skintune_palette(__global const float4* restrict frames, __global const uint4* restrict instances,
                      __global float4* restrict palette, __global const float4* restrict clips,
                      __global uint4* restrict states, const float delta, const uint fresh) {
  const uint joint_count = ANIM_JOINT_COUNT, clip_count = ANIM_CLIP_COUNT, rows = ANIM_PALETTE_ROWS;
  const uint item = (uint)get_local_id(0), i = (uint)get_group_id(1);
  const int in_group = get_group_id(0) == 0;
  uint4 in = in_group ? (fresh != 0u ? instances[i] : states[i]) : (uint4)(0u);
  if (in_group && fresh == 0u) in = anim_advance(clips, in, delta, clip_count);
  __global float4* out = palette + (size_t)i * joint_count * rows;
  const int valid = in_group && anim_state_valid(in, clip_count);
  for (uint j = item; in_group && j < joint_count; j += ANIM_GROUP) {
    if (!valid) {
      for (uint r = 0u; r < rows; ++r) out[rows * j + r] = (float4)(NAN);
      continue;
    }
    baked_palette_entry(frames, ANIM_BAKED_ROWS, clips, in, j, out, rows);
  }
  barrier(CLK_GLOBAL_MEM_FENCE);  // every item has read the state before it is kept
  if (in_group && item == 0u) states[i] = in;
}

#else  // the clips sampled from their channels, or baked in local space: the hierarchy walked

__kernel __attribute__((reqd_work_group_size(ANIM_GROUP, 1, 1)))
void skintune_palette(__global const float4* restrict nodes,
#if ANIM_BAKED
                      __global const float4* restrict frames,
#if ANIM_STEADY
                      __global const float4* restrict steady,
#endif
#else
                      __global const uint4* restrict channels, __global const float* restrict times,
                      __global const float4* restrict values,
#endif
                      __global const float4* restrict joints,
                      __global const uint4* restrict instances, __global float4* restrict palette,
                      __global const float4* restrict clips, __global uint4* restrict states, const float delta,
                      const uint fresh) {
  // Node n's sampled translation, rotation and scale at rows 3n .. 3n + 2,
  // then its local transform's rows there; and its parent.
  __local float4 local_rows[3 * ANIM_LOCAL_NODES];
  __local int local_parent[ANIM_LOCAL_NODES];
  const uint node_count = ANIM_NODE_COUNT, joint_count = ANIM_JOINT_COUNT, clip_count = ANIM_CLIP_COUNT;
  const uint rows = ANIM_PALETTE_ROWS;
  const uint item = (uint)get_local_id(0), i = (uint)get_group_id(1);
  // No return before the barrier (every item of a group reaches it, as PoCL's
  // work-group loops need): a group beyond the first along dimension 0, or an
  // instance with a clip out of range, only skips the work (uniformly).
  const int in_group = get_group_id(0) == 0 && node_count <= ANIM_MAX_NODES;
  // The instance's state: the frame's upload (fresh), or the last frame's
  // kept on the device, advanced by delta; kept again at the end.
  uint4 in = in_group ? (fresh != 0u ? instances[i] : states[i]) : (uint4)(0u);
  if (in_group && fresh == 0u) in = anim_advance(clips, in, delta, clip_count);
  __global float4* out = palette + (size_t)i * joint_count * rows;
  const int valid = in_group && anim_state_valid(in, clip_count);
  if (in_group && !valid)
    for (uint r = item; r < joint_count * rows; r += ANIM_GROUP) out[r] = (float4)(NAN);
#if ANIM_STEADY
  // Hybrid records: an instance that plays one clip reads its joints'
  // palette records, two a joint and no walk; one that cross-fades walks
  // (uniform in the group: every item read the same state).
  const int walk = valid && as_float(in.w) != 0.0f;
  for (uint j = item; valid && !walk && j < joint_count; j += ANIM_GROUP)
    baked_palette_entry(steady, ANIM_STEADY, clips, in, j, out, rows);
#else
  const int walk = valid;
#endif
  // The item's first joint (its node, its inverse bind), loaded before the
  // nodes are: its latency overlaps theirs, where after the barrier it would
  // add a round trip to memory to every instance.
  float4 joint0 = (float4)(0.0f), joint1 = joint0, joint2 = joint0, joint3 = joint0;
  if (walk && item < joint_count)
    joint0 = joints[4u * item], joint1 = joints[4u * item + 1u], joint2 = joints[4u * item + 2u],
    joint3 = joints[4u * item + 3u];
#if ANIM_BAKED
  // 1, 2: each node's local transform from its records, mixed in local space (anim_records.clh).
  if (walk) anim_local_from_records(nodes, frames, clips, in, item, local_rows, local_parent);
#else
  // 1: every (node, path) sampled once, all in parallel: row 3 node + path.
  for (uint task = item; walk && task < 3u * node_count; task += ANIM_GROUP) {
    const uint node = task / 3u, path = task - 3u * node;
    local_rows[task] = anim_path(node_count, nodes, channels, times, values, node, path, in);
    if (path == 0u) local_parent[node] = as_int(nodes[4u * node].x);
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  // 2: each node's local transform, T * R * S (a fixed-matrix node: its matrix), in place.
  for (uint n = item; walk && n < node_count; n += ANIM_GROUP) {
    Affine l;
    if (as_uint(nodes[4u * n].y) != 0u) {
      l.row0 = nodes[4u * n + 1u], l.row1 = nodes[4u * n + 2u], l.row2 = nodes[4u * n + 3u];
    } else {
      Trs x;
      x.t = local_rows[3u * n], x.r = local_rows[3u * n + 1u], x.s = local_rows[3u * n + 2u];
      l = anim_to_affine(x);
    }
    local_rows[3u * n] = l.row0;
    local_rows[3u * n + 1u] = l.row1;
    local_rows[3u * n + 2u] = l.row2;
  }
#endif  // ANIM_BAKED
  barrier(CLK_LOCAL_MEM_FENCE);
  // 3: each node's global transform by pointer jumping (anim_records.clh says how and why).
  anim_jump(walk, item, local_rows, local_parent);
  // 4: each joint's palette entry, its node's global transform by its inverse bind.
  for (uint j = item; walk && j < joint_count; j += ANIM_GROUP) {
    if (j != item)
      joint0 = joints[4u * j], joint1 = joints[4u * j + 1u], joint2 = joints[4u * j + 2u], joint3 = joints[4u * j + 3u];
    const Affine m = anim_joint_entry(local_rows, joint0, joint1, joint2, joint3);
    out[rows * j] = m.row0;
    out[rows * j + 1u] = m.row1;
    out[rows * j + 2u] = m.row2;
    if (rows == 4u) out[rows * j + 3u] = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
  }
  if (in_group && item == 0u) states[i] = in;  // every item read it before the first barrier
}

#endif  // ANIM_BAKED == 1 || ANIM_BAKED == 2
