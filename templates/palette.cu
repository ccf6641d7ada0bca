// skintune: the palette kernel in CUDA C++ for NVRTC, the twin of
// templates/palette.cl (same buffers, argument order and algorithm; the
// buffers' bytes: docs/ANIMATION.md; why each node is sampled once per
// instance: templates/palette.cl). No system headers: NVRTC provides float4,
// uint4 and the float intrinsics; the float4 arithmetic OpenCL has built in
// is the few operators below.
//
// Launch: grid (1, K) for K instances, of blocks of (ANIM_GROUP, 1) =
// (ANIM_GROUP, 1) threads, one block per instance, in palette.cl's three steps:
// every (node, path) sampled once into shared memory (at most
// ANIM_MAX_NODES nodes) with the node's parent, each node's local transform
// made there, then each thread composes its joints j = thread, thread + ANIM_GROUP,
// ... up their ancestors there and writes instance i's joint j as
// ANIM_PALETTE_ROWS float4 rows at (i * ANIM_JOINT_COUNT + j) *
// ANIM_PALETTE_ROWS + r (templates/palette.cl says why). An instance whose
// clip index is neither a packed clip nor 0xffff (the rest pose) gets NaN rows.

// The animation's counts and the palette's rows per joint (ANIM_NODE_COUNT,
// ANIM_JOINT_COUNT, ANIM_CLIP_COUNT, ANIM_PALETTE_ROWS): the generator defines
// them for the packed animation the kernel runs (generator/palette_kernel.h),
// skin_params.h gives their defaults.
#define ANIM_PALETTE_KERNEL 1  // the prelude's palette-kernel part (anim_records.cuh)
#include "skin_params.h"
#include "anim_records.cuh"



// Shortest-path spherical interpolation of two (x, y, z, w) quaternions.
__device__ float4 anim_slerp(const float4 a, float4 b, const float u) {
  float cos_theta = dot4(a, b);
  if (cos_theta < 0.0f) {  // q and -q are the same rotation: take the short way
    b = -b;
    cos_theta = -cos_theta;
  }
  if (cos_theta > 1.0f - 1e-6f) return anim_normalize_quat(a + u * (b - a));
  const float theta = acosf(fminf(cos_theta, 1.0f));
  const float sin_theta = sinf(theta);
  return anim_normalize_quat((sinf((1.0f - u) * theta) / sin_theta) * a + (sinf(u * theta) / sin_theta) * b);
}

// The value of a channel with keys (h: interpolation, key count, time offset,
// value offset) at time t; rotations not yet normalised.
__device__ float4 anim_sample_channel(const float* __restrict__ times_all, const float4* __restrict__ values_all,
                                      const uint4 h, const bool rotation, const float t) {
  const float* times = times_all + h.z;
  const float4* values = values_all + h.w;
  const unsigned n = h.y;
  const bool cubic = h.x == 2u;
  const unsigned per_key = cubic ? 3u : 1u, middle = cubic ? 1u : 0u;  // CUBICSPLINE: in, value, out
  if (n == 1u || !(t > times[0])) return values[middle];
  if (t >= times[n - 1u]) return values[(n - 1u) * per_key + middle];
  // The key interval: first guessed as if the keys were evenly spaced (exact
  // for the evenly sampled clips exporters write: one round of loads instead
  // of a binary search's chain of dependent ones), then, where the guess
  // misses, a binary search on the side of it that holds t. Either way the
  // interval found is the one with times[lo] <= t < times[lo + 1].
  const float first = times[0], last = times[n - 1u];
  unsigned lo = min(static_cast<unsigned>((t - first) / (last - first) * static_cast<float>(n - 1u)), n - 2u), hi = lo + 1u;
  if (times[lo] > t) {
    hi = lo;
    lo = 0u;
  } else if (times[hi] <= t) {
    lo = hi;
    hi = n - 1u;
  }  // times[lo] <= t < times[hi]
  while (hi - lo > 1u) {
    const unsigned mid = (lo + hi) / 2u;
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

// The packed animation, as the kernel's arguments give it.
struct Animation {
  unsigned node_count;
  const float4* __restrict__ nodes;
  const uint4* __restrict__ channels;
  const float* __restrict__ times;
  const float4* __restrict__ values;
};

// Path `path` (0 translation, 1 rotation, 2 scale) of node `node` in
// `clip` at time t: its rest value, or the clip's channel's (a rotation
// normalised).
__device__ float4 anim_path_value(const Animation& a, const unsigned node, const unsigned path, const unsigned clip,
                                  const float t) {
  const float4 rest = a.nodes[4u * node + 1u + path];
  if (clip == ANIM_REST_POSE) return rest;
  const uint4 h = a.channels[(clip * a.node_count + node) * 3u + path];
  if (h.y == 0u) return rest;
  const float4 v = anim_sample_channel(a.times, a.values, h, path == 1u, t);
  return path == 1u ? anim_normalize_quat(v) : v;
}

// The path's value for an instance (in: clips, time, time2, weight): in
// clip, blended towards clip2's by weight (T, S lerped; R nlerped along the
// shortest path).
__device__ float4 anim_path(const Animation& a, const unsigned node, const unsigned path, const uint4 in) {
  const float4 x = anim_path_value(a, node, path, in.x & 0xffffu, __uint_as_float(in.y));
  const float w = __uint_as_float(in.w);
  if (w == 0.0f) return x;
  const float4 y = anim_path_value(a, node, path, in.x >> 16, __uint_as_float(in.z));
  if (path != 1u) return x + w * (y - x);
  const float4 r2 = dot4(x, y) < 0.0f ? -y : y;
  return anim_normalize_quat(x + w * (r2 - x));
}


// An instance's joint j from palette records of `rows` float4s, written as
// `rows_out` float4 rows (palette.cl).
#if ANIM_BAKED
__device__ void baked_palette_entry(const float4* __restrict__ frames, const unsigned rows,
                                    const float4* __restrict__ clips, const uint4 in, const unsigned j,
                                    float4* __restrict__ out, const unsigned rows_out) {
  const Affine m = baked_affine(baked_instance(frames, rows, ANIM_JOINT_COUNT, clips, in, j), rows);
  out[rows_out * j] = m.row0;
  out[rows_out * j + 1u] = m.row1;
  out[rows_out * j + 2u] = m.row2;
  if (rows_out == 4u) out[rows_out * j + 3u] = make_float4(0.0f, 0.0f, 0.0f, 1.0f);
}
#endif  // ANIM_BAKED

#if ANIM_BAKED == 1 || ANIM_BAKED == 2

extern "C" __global__ void __launch_bounds__(ANIM_GROUP)
skintune_palette(const float4* __restrict__ frames, const uint4* __restrict__ instances,
                 float4* __restrict__ palette, const float4* __restrict__ clips, uint4* __restrict__ states,
                 const float delta, const unsigned fresh) {
  const unsigned joint_count = ANIM_JOINT_COUNT, clip_count = ANIM_CLIP_COUNT, rows = ANIM_PALETTE_ROWS;
  const unsigned item = threadIdx.x, i = blockIdx.y;
  const bool in_group = blockIdx.x == 0;
  uint4 in = in_group ? (fresh != 0u ? instances[i] : states[i]) : make_uint4(0u, 0u, 0u, 0u);
  if (in_group && fresh == 0u) in = anim_advance(clips, in, delta, clip_count);
  float4* out = palette + (unsigned long long)i * joint_count * rows;
  const bool valid = in_group && anim_state_valid(in, clip_count);
  for (unsigned j = item; in_group && j < joint_count; j += ANIM_GROUP) {
    if (!valid) {
      const float nan = __int_as_float(0x7fffffff);
      for (unsigned r = 0u; r < rows; ++r) out[rows * j + r] = make_float4(nan, nan, nan, nan);
      continue;
    }
    baked_palette_entry(frames, ANIM_BAKED_ROWS, clips, in, j, out, rows);
  }
  __syncthreads();  // every thread has read the state before it is kept
  if (in_group && item == 0u) states[i] = in;
}

#else  // the clips sampled from their channels, or baked in local space: the hierarchy walked

extern "C" __global__ void __launch_bounds__(ANIM_GROUP)
skintune_palette(const float4* __restrict__ nodes,
#if ANIM_BAKED
                 const float4* __restrict__ frames,
#if ANIM_STEADY
                 const float4* __restrict__ steady,
#endif
#else
                 const uint4* __restrict__ channels, const float* __restrict__ times,
                 const float4* __restrict__ values,
#endif
                 const float4* __restrict__ joints, const uint4* __restrict__ instances,
                 float4* __restrict__ palette, const float4* __restrict__ clips, uint4* __restrict__ states,
                 const float delta, const unsigned fresh) {
  // Node n's sampled translation, rotation and scale at rows 3n .. 3n + 2,
  // then its local transform's rows there; and its parent (palette.cl).
  __shared__ float4 local_rows[3 * ANIM_LOCAL_NODES];
  __shared__ int local_parent[ANIM_LOCAL_NODES];
  const unsigned node_count = ANIM_NODE_COUNT, joint_count = ANIM_JOINT_COUNT, clip_count = ANIM_CLIP_COUNT;
  const unsigned rows = ANIM_PALETTE_ROWS;
  const unsigned item = threadIdx.x, i = blockIdx.y;
  // No return before the barrier, as in palette.cl: a block beyond the first
  // along x, or an instance with a clip out of range, only skips the work
  // (uniformly).
  const bool in_group = blockIdx.x == 0 && node_count <= ANIM_MAX_NODES;
  // The instance's state: the frame's upload (fresh), or the last frame's
  // kept on the device, advanced by delta; kept again at the end.
  uint4 in = in_group ? (fresh != 0u ? instances[i] : states[i]) : make_uint4(0u, 0u, 0u, 0u);
  if (in_group && fresh == 0u) in = anim_advance(clips, in, delta, clip_count);
  float4* out = palette + (unsigned long long)i * joint_count * rows;
  const bool valid = in_group && anim_state_valid(in, clip_count);
  if (in_group && !valid) {
    const float nan = __int_as_float(0x7fffffff);
    for (unsigned r = item; r < joint_count * rows; r += ANIM_GROUP) out[r] = make_float4(nan, nan, nan, nan);
  }
#if ANIM_STEADY
  // Hybrid records: an instance that plays one clip reads palette records,
  // one that cross-fades walks (palette.cl).
  const bool walk = valid && __uint_as_float(in.w) != 0.0f;
  for (unsigned j = item; valid && !walk && j < joint_count; j += ANIM_GROUP)
    baked_palette_entry(steady, ANIM_STEADY, clips, in, j, out, rows);
#else
  const bool walk = valid;
#endif
  // The thread's first joint, loaded before the nodes are (palette.cl says why).
  float4 joint0 = make_float4(0.0f, 0.0f, 0.0f, 0.0f), joint1 = joint0, joint2 = joint0, joint3 = joint0;
  if (walk && item < joint_count)
    joint0 = joints[4u * item], joint1 = joints[4u * item + 1u], joint2 = joints[4u * item + 2u],
    joint3 = joints[4u * item + 3u];
#if ANIM_BAKED
  // 1, 2: each node's local transform from its records, mixed in local space (anim_records.cuh).
  if (walk) anim_local_from_records(nodes, frames, clips, in, item, local_rows, local_parent);
#else
  const Animation a = {node_count, nodes, channels, times, values};
  // 1: every (node, path) sampled once, all in parallel: row 3 node + path.
  for (unsigned task = item; walk && task < 3u * node_count; task += ANIM_GROUP) {
    const unsigned node = task / 3u, path = task - 3u * node;
    local_rows[task] = anim_path(a, node, path, in);
    if (path == 0u) local_parent[node] = __float_as_int(nodes[4u * node].x);
  }
  __syncthreads();
  // 2: each node's local transform, T * R * S (a fixed-matrix node: its matrix), in place.
  for (unsigned n = item; walk && n < node_count; n += ANIM_GROUP) {
    Affine l;
    if (__float_as_uint(nodes[4u * n].y) != 0u) {
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
  __syncthreads();
  // 3: each node's global transform by pointer jumping (anim_records.cuh, palette.cl).
  anim_jump(walk, item, local_rows, local_parent);
  // 4: each joint's palette entry, its node's global transform by its inverse bind.
  for (unsigned j = item; walk && j < joint_count; j += ANIM_GROUP) {
    if (j != item)
      joint0 = joints[4u * j], joint1 = joints[4u * j + 1u], joint2 = joints[4u * j + 2u], joint3 = joints[4u * j + 3u];
    const Affine m = anim_joint_entry(local_rows, joint0, joint1, joint2, joint3);
    out[rows * j] = m.row0;
    out[rows * j + 1u] = m.row1;
    out[rows * j + 2u] = m.row2;
    if (rows == 4u) out[rows * j + 3u] = make_float4(0.0f, 0.0f, 0.0f, 1.0f);
  }
  if (in_group && item == 0u) states[i] = in;  // every thread read it before the first barrier
}

#endif  // ANIM_BAKED == 1 || ANIM_BAKED == 2
