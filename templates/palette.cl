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
#include "skin_params.h"

#define ANIM_REST_POSE 0xffffu

typedef struct {
  float4 row0, row1, row2;  // an affine transform's rows (x, y, z | translation)
} Affine;

typedef struct {
  float4 t, r, s;  // translation, rotation (x, y, z, w), scale
} Trs;

Affine anim_multiply(const Affine a, const Affine b) {
  const float4 unit_w = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
  Affine c;
  c.row0 = a.row0.x * b.row0 + a.row0.y * b.row1 + a.row0.z * b.row2 + a.row0.w * unit_w;
  c.row1 = a.row1.x * b.row0 + a.row1.y * b.row1 + a.row1.z * b.row2 + a.row1.w * unit_w;
  c.row2 = a.row2.x * b.row0 + a.row2.y * b.row1 + a.row2.z * b.row2 + a.row2.w * unit_w;
  return c;
}

float4 anim_normalize_quat(const float4 q) {
  const float length = sqrt(dot(q, q));
  return length > 0.0f ? q / length : q;
}

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

// T * R * S as rows, from a normalised (x, y, z, w) rotation.
Affine anim_to_affine(const Trs x) {
  const float4 q = x.r;
  const float xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
  const float xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z, wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
  Affine m;
  m.row0 = (float4)((1.0f - 2.0f * (yy + zz)) * x.s.x, 2.0f * (xy - wz) * x.s.y, 2.0f * (xz + wy) * x.s.z, x.t.x);
  m.row1 = (float4)(2.0f * (xy + wz) * x.s.x, (1.0f - 2.0f * (xx + zz)) * x.s.y, 2.0f * (yz - wx) * x.s.z, x.t.y);
  m.row2 = (float4)(2.0f * (xz - wy) * x.s.x, 2.0f * (yz + wx) * x.s.y, (1.0f - 2.0f * (xx + yy)) * x.s.z, x.t.z);
  return m;
}

int anim_clip_valid(const uint clip, const uint clip_count) { return clip == ANIM_REST_POSE || clip < clip_count; }

// Time t moved into [start, end] of its clip (range: start, end), looping:
// the clip plays again from its start (a clip of no duration: its start).
float anim_loop_time(const float t, const float4 range) {
  const float length = range.y - range.x;
  if (!(length > 0.0f)) return range.x;
  float u = t - range.x;
  u = fmin(fmax(u - length * floor(u / length), 0.0f), length);
  return range.x + u;
}

// An instance's state advanced by `delta` seconds on its clips' clocks (the
// rest pose and a clip out of range keep theirs).
uint4 anim_advance(__global const float4* restrict clips, uint4 in, const float delta, const uint clip_count) {
  const uint c1 = in.x & 0xffffu, c2 = in.x >> 16;
  if (c1 != ANIM_REST_POSE && c1 < clip_count) in.y = as_uint(anim_loop_time(as_float(in.y) + delta, clips[c1]));
  if (c2 != ANIM_REST_POSE && c2 < clip_count) in.z = as_uint(anim_loop_time(as_float(in.z) + delta, clips[c2]));
  return in;
}

#define ANIM_MAX_NODES 512  // fixed: the launch and the local memory the kernel is written for
// The local memory an instance's nodes take: the model's nodes (a define),
// at most ANIM_MAX_NODES, so that a small rig's groups leave the rest of it,
// and the L1 cache it shares, to others.
#if ANIM_NODE_COUNT < ANIM_MAX_NODES
#define ANIM_LOCAL_NODES ANIM_NODE_COUNT
#else
#define ANIM_LOCAL_NODES ANIM_MAX_NODES
#endif
// The nodes each item composes (its nodes item, item + ANIM_GROUP, ...).
#define ANIM_NODES_PER_ITEM ((ANIM_LOCAL_NODES + ANIM_GROUP - 1) / ANIM_GROUP)

#if ANIM_BAKED
// Baked clips (docs/ANIMATION.md "Baked clips"; cpu_kernels/palette_kernel.cpp
// BakedSample is the same in C++): each joint's skinning transform stored at
// evenly spaced frames as its polar decomposition, a unit rotation q, a
// translation t and a symmetric stretch S (s I for a similarity), frame 0 the
// rest pose. An item per (instance, joint): the two frames around the clip's
// time, q nlerped along the shortest path and t, S lerped, likewise towards
// clip2 by the blend weight, then written as the rows of R(q) S | t. No hierarchy, no search: two loads a
// joint and frame. Launch as the sampled kernel: a group of ANIM_GROUP items
// per instance, joints j = item, item + ANIM_GROUP, ...

// Records of ANIM_BAKED_ROWS float4s: 2 where every transform is a
// similarity (ANIM_BAKED 1: q, then t and s), else 4 (ANIM_BAKED 2: q, t,
// then the symmetric stretch S as (S00, S11, S22, S01), (S02, S12)).
// Baked in local space (ANIM_BAKED 3, 4; docs/ANIMATION.md "Baked in local
// space"), a record is a node's local T R S at the frame: q, then t and a
// uniform s (3), or q, t, then s per axis (4); the kernel mixes them as
// above, then composes the hierarchy as the sampled kernel does (below).
// Hybrid records (ANIM_STEADY 2 or 4, docs/ANIMATION.md "Hybrid records"):
// the same frames' palette records too, in `steady`; an instance that plays
// one clip reads those as the palette-record kernel does and walks nothing.
#if ANIM_BAKED == 2
#define ANIM_BAKED_ROWS 4u
#elif ANIM_BAKED == 4
#define ANIM_BAKED_ROWS 3u
#else
#define ANIM_BAKED_ROWS 2u
#endif
#if ANIM_BAKED >= 3
#define ANIM_BAKED_ITEMS ANIM_NODE_COUNT  // a record a node
#else
#define ANIM_BAKED_ITEMS ANIM_JOINT_COUNT  // a record a joint
#endif

typedef struct {
  float4 q, ts, s0, s1;  // rotation (x, y, z, w); translation (and s); the stretch
} Baked;

// Item j's record of `rows` float4s at `frame`, of `items` a frame (every
// argument but frame and j a constant where it is called).
Baked baked_record(__global const float4* restrict frames, const uint rows, const uint items, const uint frame,
                   const uint j) {
  const size_t at = rows * ((size_t)frame * items + j);
  Baked b;
  b.q = frames[at];
  b.ts = frames[at + 1u];
  b.s0 = rows >= 3u ? frames[at + 2u] : (float4)(0.0f);
  b.s1 = rows == 4u ? frames[at + 3u] : (float4)(0.0f);
  return b;
}

Baked baked_mix(const Baked x, const Baked y, const float u) {
  const float4 q2 = dot(x.q, y.q) < 0.0f ? -y.q : y.q;
  Baked b;
  b.q = anim_normalize_quat(x.q + u * (q2 - x.q));
  b.ts = x.ts + u * (y.ts - x.ts);
  b.s0 = x.s0 + u * (y.s0 - x.s0);
  b.s1 = x.s1 + u * (y.s1 - x.s1);
  return b;
}

// Item j (a joint; a node in local space) of `clip` at time t, clamped to
// the clip's range (start, end, frame count, first frame), from records of
// `rows` float4s, `items` a frame.
Baked baked_sample(__global const float4* restrict frames, const uint rows, const uint items,
                   __global const float4* restrict clips, const uint clip, const float t, const uint j) {
  if (clip == ANIM_REST_POSE) return baked_record(frames, rows, items, 0u, j);
  const float4 range = clips[clip];
  const uint count = as_uint(range.z), first = as_uint(range.w);
  if (count < 2u) return baked_record(frames, rows, items, first, j);
  const float length = range.y - range.x;
  const float u = length > 0.0f ? fmin(fmax((t - range.x) / length, 0.0f), 1.0f) * (float)(count - 1u) : 0.0f;
  const uint k = min((uint)u, count - 2u);
  return baked_mix(baked_record(frames, rows, items, first + k, j),
                   baked_record(frames, rows, items, first + k + 1u, j), u - (float)k);
}

// The rows of R(q) S | t of a palette record of `rows` float4s (2: a
// similarity, S = s I).
Affine baked_affine(const Baked x, const uint rows) {
  Trs trs;
  trs.t = (float4)(x.ts.xyz, 0.0f);
  trs.r = x.q;
  if (rows != 4u) {
    trs.s = (float4)(x.ts.w, x.ts.w, x.ts.w, 0.0f);
    return anim_to_affine(trs);
  }
  trs.s = (float4)(1.0f, 1.0f, 1.0f, 0.0f);
  const Affine r = anim_to_affine(trs);
  const float4 s_row0 = (float4)(x.s0.x, x.s0.w, x.s1.x, 0.0f), s_row1 = (float4)(x.s0.w, x.s0.y, x.s1.y, 0.0f);
  const float4 s_row2 = (float4)(x.s1.x, x.s1.y, x.s0.z, 0.0f);
  Affine m;
  m.row0 = r.row0.x * s_row0 + r.row0.y * s_row1 + r.row0.z * s_row2 + (float4)(0.0f, 0.0f, 0.0f, x.ts.x);
  m.row1 = r.row1.x * s_row0 + r.row1.y * s_row1 + r.row1.z * s_row2 + (float4)(0.0f, 0.0f, 0.0f, x.ts.y);
  m.row2 = r.row2.x * s_row0 + r.row2.y * s_row1 + r.row2.z * s_row2 + (float4)(0.0f, 0.0f, 0.0f, x.ts.z);
  return m;
}

// An instance's joint j from palette records of `rows` float4s: in clip,
// mixed towards clip2's by the weight, written as `rows_out` float4 rows.
void baked_palette_entry(__global const float4* restrict frames, const uint rows,
                         __global const float4* restrict clips, const uint4 in, const uint j,
                         __global float4* restrict out, const uint rows_out) {
  const float w = as_float(in.w);
  Baked x = baked_sample(frames, rows, ANIM_JOINT_COUNT, clips, in.x & 0xffffu, as_float(in.y), j);
  if (w != 0.0f) x = baked_mix(x, baked_sample(frames, rows, ANIM_JOINT_COUNT, clips, in.x >> 16, as_float(in.z), j), w);
  const Affine m = baked_affine(x, rows);
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
  const float w = as_float(in.w);
  const int valid = in_group && anim_clip_valid(in.x & 0xffffu, clip_count) &&
                    (w == 0.0f || anim_clip_valid(in.x >> 16, clip_count));
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
  const int valid = in_group && anim_clip_valid(in.x & 0xffffu, clip_count) &&
                    (as_float(in.w) == 0.0f || anim_clip_valid(in.x >> 16, clip_count));
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
  // 1, 2: each node's local transform from its records around each clip's
  // time, mixed in local space (a fixed-matrix node: its matrix), all in parallel.
  const float w = as_float(in.w);
  for (uint n = item; walk && n < node_count; n += ANIM_GROUP) {
    Affine l;
    if (as_uint(nodes[4u * n].y) != 0u) {
      l.row0 = nodes[4u * n + 1u], l.row1 = nodes[4u * n + 2u], l.row2 = nodes[4u * n + 3u];
    } else {
      Baked x = baked_sample(frames, ANIM_BAKED_ROWS, ANIM_BAKED_ITEMS, clips, in.x & 0xffffu, as_float(in.y), n);
      if (w != 0.0f)
        x = baked_mix(x, baked_sample(frames, ANIM_BAKED_ROWS, ANIM_BAKED_ITEMS, clips, in.x >> 16, as_float(in.z), n), w);
      Trs trs;
      trs.t = (float4)(x.ts.xyz, 0.0f);
      trs.r = x.q;
#if ANIM_BAKED == 4
      trs.s = x.s0;
#else
      trs.s = (float4)(x.ts.w, x.ts.w, x.ts.w, 0.0f);
#endif
      l = anim_to_affine(trs);
    }
    local_rows[3u * n] = l.row0;
    local_rows[3u * n + 1u] = l.row1;
    local_rows[3u * n + 2u] = l.row2;
    local_parent[n] = as_int(nodes[4u * n].x);
  }
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
  // 3: each node's global transform by pointer jumping (Wyllie's list
  // ranking on the tree): after round r a node's rows are the product of its
  // local transforms up to its 2^r-th ancestor, and local_parent is that
  // ancestor, so ANIM_JUMPS = ceil(log2(depth + 1)) rounds reach every root.
  // Each round reads, then writes after a barrier, every node the last
  // round's rows. Why (docs/ANIMATION.md "The walk up the hierarchy"): each
  // joint walking up its own chain took the deepest chain's steps in every
  // warp, depth x 3 warps of dependent products for the 77-joint rig, where
  // this takes 4 rounds of one product.
  for (uint round = 0u; round < ANIM_JUMPS; ++round) {
    Affine up[ANIM_NODES_PER_ITEM];
    int next[ANIM_NODES_PER_ITEM];
    for (uint k = 0u; k < ANIM_NODES_PER_ITEM; ++k) {
      const uint n = item + k * ANIM_GROUP;
      next[k] = -2;  // no jump
      const int p = walk && n < node_count ? local_parent[n] : -1;
      if (p >= 0) {
        up[k].row0 = local_rows[3u * (uint)p], up[k].row1 = local_rows[3u * (uint)p + 1u];
        up[k].row2 = local_rows[3u * (uint)p + 2u];
        next[k] = local_parent[p];
      }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint k = 0u; k < ANIM_NODES_PER_ITEM; ++k) {
      const uint n = item + k * ANIM_GROUP;
      if (next[k] == -2) continue;
      Affine m;
      m.row0 = local_rows[3u * n], m.row1 = local_rows[3u * n + 1u], m.row2 = local_rows[3u * n + 2u];
      m = anim_multiply(up[k], m);
      local_rows[3u * n] = m.row0;
      local_rows[3u * n + 1u] = m.row1;
      local_rows[3u * n + 2u] = m.row2;
      local_parent[n] = next[k];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  // 4: each joint's palette entry, its node's global transform by its inverse bind.
  for (uint j = item; walk && j < joint_count; j += ANIM_GROUP) {
    if (j != item)
      joint0 = joints[4u * j], joint1 = joints[4u * j + 1u], joint2 = joints[4u * j + 2u], joint3 = joints[4u * j + 3u];
    const uint node = as_uint(joint0.x);
    Affine m;
    m.row0 = local_rows[3u * node], m.row1 = local_rows[3u * node + 1u], m.row2 = local_rows[3u * node + 2u];
    Affine inverse_bind;
    inverse_bind.row0 = joint1;
    inverse_bind.row1 = joint2;
    inverse_bind.row2 = joint3;
    m = anim_multiply(m, inverse_bind);
    out[rows * j] = m.row0;
    out[rows * j + 1u] = m.row1;
    out[rows * j + 2u] = m.row2;
    if (rows == 4u) out[rows * j + 3u] = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
  }
  if (in_group && item == 0u) states[i] = in;  // every item read it before the first barrier
}

#endif  // ANIM_BAKED == 1 || ANIM_BAKED == 2
