// skintune: what CUDA's palette kernel (palette.cu) and a skin kernel that
// makes its palette itself (ANIM_FUSED, skin.cu) share: the float4 arithmetic
// OpenCL has built in, affine rows from translation, rotation and scale, the
// clips' clocks, and the baked records' reads and mixes (docs/ANIMATION.md
// "Baked clips"; the algorithm's words are templates/palette.cl's). A
// prelude (templates/README.md): its text is in every CUDA skin kernel, and
// compiled only in the palette kernel (ANIM_PALETTE_KERNEL) and a fused one.
#if defined(ANIM_PALETTE_KERNEL) || ANIM_FUSED

#define ANIM_REST_POSE 0xffffu

__device__ __forceinline__ float4 operator+(const float4 a, const float4 b) {
  return make_float4(a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w);
}
__device__ __forceinline__ float4 operator-(const float4 a, const float4 b) {
  return make_float4(a.x - b.x, a.y - b.y, a.z - b.z, a.w - b.w);
}
__device__ __forceinline__ float4 operator-(const float4 a) { return make_float4(-a.x, -a.y, -a.z, -a.w); }
__device__ __forceinline__ float4 operator*(const float s, const float4 a) {
  return make_float4(s * a.x, s * a.y, s * a.z, s * a.w);
}
__device__ __forceinline__ float dot4(const float4 a, const float4 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w;
}

struct Affine {
  float4 row0, row1, row2;  // an affine transform's rows (x, y, z | translation)
};

struct Trs {
  float4 t, r, s;  // translation, rotation (x, y, z, w), scale
};
__device__ float4 anim_normalize_quat(const float4 q) {
  const float length = sqrtf(dot4(q, q));
  return length > 0.0f ? (1.0f / length) * q : q;
}

// T * R * S as rows, from a normalised (x, y, z, w) rotation.
__device__ Affine anim_to_affine(const Trs& x) {
  const float4 q = x.r;
  const float xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
  const float xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z, wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
  Affine m;
  m.row0 = make_float4((1.0f - 2.0f * (yy + zz)) * x.s.x, 2.0f * (xy - wz) * x.s.y, 2.0f * (xz + wy) * x.s.z, x.t.x);
  m.row1 = make_float4(2.0f * (xy + wz) * x.s.x, (1.0f - 2.0f * (xx + zz)) * x.s.y, 2.0f * (yz - wx) * x.s.z, x.t.y);
  m.row2 = make_float4(2.0f * (xz - wy) * x.s.x, 2.0f * (yz + wx) * x.s.y, (1.0f - 2.0f * (xx + yy)) * x.s.z, x.t.z);
  return m;
}

__device__ bool anim_clip_valid(const unsigned clip, const unsigned clip_count) {
  return clip == ANIM_REST_POSE || clip < clip_count;
}

// Whether an instance's state names clips there are: its clip, and its second where it blends.
__device__ bool anim_state_valid(const uint4 in, const unsigned clip_count) {
  return anim_clip_valid(in.x & 0xffffu, clip_count) &&
         (__uint_as_float(in.w) == 0.0f || anim_clip_valid(in.x >> 16, clip_count));
}

// Time t moved into [start, end] of its clip, looping (palette.cl).
__device__ float anim_loop_time(const float t, const float4 range) {
  const float length = range.y - range.x;
  if (!(length > 0.0f)) return range.x;
  float u = t - range.x;
  u = fminf(fmaxf(u - length * floorf(u / length), 0.0f), length);
  return range.x + u;
}

// An instance's state advanced by `delta` seconds on its clips' clocks (palette.cl).
__device__ uint4 anim_advance(const float4* __restrict__ clips, uint4 in, const float delta, const unsigned clip_count) {
  const unsigned c1 = in.x & 0xffffu, c2 = in.x >> 16;
  if (c1 != ANIM_REST_POSE && c1 < clip_count) in.y = __float_as_uint(anim_loop_time(__uint_as_float(in.y) + delta, clips[c1]));
  if (c2 != ANIM_REST_POSE && c2 < clip_count) in.z = __float_as_uint(anim_loop_time(__uint_as_float(in.z) + delta, clips[c2]));
  return in;
}

#if ANIM_BAKED
// Baked clips: palette.cl's baked kernel (docs/ANIMATION.md "Baked clips").
// Records of ANIM_BAKED_ROWS float4s, of joints or (local space,
// ANIM_BAKED 3 and 4) nodes (palette.cl says which).
#if ANIM_BAKED == 2
#define ANIM_BAKED_ROWS 4u
#elif ANIM_BAKED == 4
#define ANIM_BAKED_ROWS 3u
#else
#define ANIM_BAKED_ROWS 2u
#endif
#if ANIM_BAKED >= 3
#define ANIM_BAKED_ITEMS ANIM_NODE_COUNT
#else
#define ANIM_BAKED_ITEMS ANIM_JOINT_COUNT
#endif

struct Baked {
  float4 q, ts, s0, s1;  // rotation (x, y, z, w); translation (and s); the stretch
};

// Item j's record of `rows` float4s at `frame`, of `items` a frame (palette.cl).
__device__ Baked baked_record(const float4* __restrict__ frames, const unsigned rows, const unsigned items,
                              const unsigned frame, const unsigned j) {
  const unsigned long long at = rows * (static_cast<unsigned long long>(frame) * items + j);
  const float4 zero = make_float4(0.0f, 0.0f, 0.0f, 0.0f);
  return Baked{frames[at], frames[at + 1u], rows >= 3u ? frames[at + 2u] : zero, rows == 4u ? frames[at + 3u] : zero};
}

__device__ Baked baked_mix(const Baked& x, const Baked& y, const float u) {
  const float4 q2 = dot4(x.q, y.q) < 0.0f ? -y.q : y.q;
  return Baked{anim_normalize_quat(x.q + u * (q2 - x.q)), x.ts + u * (y.ts - x.ts), x.s0 + u * (y.s0 - x.s0),
               x.s1 + u * (y.s1 - x.s1)};
}

__device__ Baked baked_sample(const float4* __restrict__ frames, const unsigned rows, const unsigned items,
                              const float4* __restrict__ clips, const unsigned clip, const float t, const unsigned j) {
  if (clip == ANIM_REST_POSE) return baked_record(frames, rows, items, 0u, j);
  const float4 range = clips[clip];
  const unsigned count = __float_as_uint(range.z), first = __float_as_uint(range.w);
  if (count < 2u) return baked_record(frames, rows, items, first, j);
  const float length = range.y - range.x;
  const float u = length > 0.0f ? fminf(fmaxf((t - range.x) / length, 0.0f), 1.0f) * static_cast<float>(count - 1u)
                                : 0.0f;
  const unsigned k = min(static_cast<unsigned>(u), count - 2u);
  return baked_mix(baked_record(frames, rows, items, first + k, j), baked_record(frames, rows, items, first + k + 1u, j),
                   u - static_cast<float>(k));
}

// The rows of R(q) S | t of a palette record of `rows` float4s (2: a
// similarity, S = s I).
__device__ Affine baked_affine(const Baked& x, const unsigned rows) {
  Trs trs;
  trs.t = make_float4(x.ts.x, x.ts.y, x.ts.z, 0.0f);
  trs.r = x.q;
  if (rows != 4u) {
    trs.s = make_float4(x.ts.w, x.ts.w, x.ts.w, 0.0f);
    return anim_to_affine(trs);
  }
  trs.s = make_float4(1.0f, 1.0f, 1.0f, 0.0f);
  const Affine r = anim_to_affine(trs);
  const float4 s_row0 = make_float4(x.s0.x, x.s0.w, x.s1.x, 0.0f), s_row1 = make_float4(x.s0.w, x.s0.y, x.s1.y, 0.0f);
  const float4 s_row2 = make_float4(x.s1.x, x.s1.y, x.s0.z, 0.0f);
  Affine m;
  m.row0 = r.row0.x * s_row0 + r.row0.y * s_row1 + r.row0.z * s_row2 + make_float4(0.0f, 0.0f, 0.0f, x.ts.x);
  m.row1 = r.row1.x * s_row0 + r.row1.y * s_row1 + r.row1.z * s_row2 + make_float4(0.0f, 0.0f, 0.0f, x.ts.y);
  m.row2 = r.row2.x * s_row0 + r.row2.y * s_row1 + r.row2.z * s_row2 + make_float4(0.0f, 0.0f, 0.0f, x.ts.z);
  return m;
}

// Joint (or node) j of an instance (in: clips, time, time2, weight) from its
// records: its clip's sample, mixed towards its second clip's by the weight.
__device__ Baked baked_instance(const float4* __restrict__ frames, const unsigned rows, const unsigned items,
                                const float4* __restrict__ clips, const uint4 in, const unsigned j) {
  const float w = __uint_as_float(in.w);
  const Baked x = baked_sample(frames, rows, items, clips, in.x & 0xffffu, __uint_as_float(in.y), j);
  if (w == 0.0f) return x;
  return baked_mix(x, baked_sample(frames, rows, items, clips, in.x >> 16, __uint_as_float(in.z), j), w);
}
#endif  // ANIM_BAKED

// ---------------------------------------------------------------- the hierarchy
// What the kernels that walk the hierarchy share (anim_records.clh says
// which, and palette.cl how): a block of ANIM_GROUP threads over one
// instance, its nodes' rows in shared memory.

__device__ Affine anim_multiply(const Affine& a, const Affine& b) {
  const float4 unit_w = make_float4(0.0f, 0.0f, 0.0f, 1.0f);
  Affine c;
  c.row0 = a.row0.x * b.row0 + a.row0.y * b.row1 + a.row0.z * b.row2 + a.row0.w * unit_w;
  c.row1 = a.row1.x * b.row0 + a.row1.y * b.row1 + a.row1.z * b.row2 + a.row1.w * unit_w;
  c.row2 = a.row2.x * b.row0 + a.row2.y * b.row1 + a.row2.z * b.row2 + a.row2.w * unit_w;
  return c;
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
#define ANIM_NODES_PER_ITEM ((ANIM_LOCAL_NODES + ANIM_GROUP - 1) / ANIM_GROUP)  // item, item + ANIM_GROUP, ...

// Each node's global transform by pointer jumping, ANIM_JUMPS rounds
// (anim_records.clh). Every thread of the block calls it (it waits at
// barriers); `walk`, the same in every thread, says whether there is work.
__device__ void anim_jump(const bool walk, const unsigned item, float4* local_rows, int* local_parent) {
  for (unsigned round = 0u; round < ANIM_JUMPS; ++round) {
    Affine up[ANIM_NODES_PER_ITEM];
    int next[ANIM_NODES_PER_ITEM];
    for (unsigned k = 0u; k < ANIM_NODES_PER_ITEM; ++k) {
      const unsigned n = item + k * ANIM_GROUP;
      next[k] = -2;  // no jump
      const int p = walk && n < ANIM_NODE_COUNT ? local_parent[n] : -1;
      if (p >= 0) {
        up[k].row0 = local_rows[3u * p], up[k].row1 = local_rows[3u * p + 1u], up[k].row2 = local_rows[3u * p + 2u];
        next[k] = local_parent[p];
      }
    }
    __syncthreads();
    for (unsigned k = 0u; k < ANIM_NODES_PER_ITEM; ++k) {
      const unsigned n = item + k * ANIM_GROUP;
      if (next[k] == -2) continue;
      Affine m;
      m.row0 = local_rows[3u * n], m.row1 = local_rows[3u * n + 1u], m.row2 = local_rows[3u * n + 2u];
      m = anim_multiply(up[k], m);
      local_rows[3u * n] = m.row0, local_rows[3u * n + 1u] = m.row1, local_rows[3u * n + 2u] = m.row2;
      local_parent[n] = next[k];
    }
    __syncthreads();
  }
}

// A joint's palette entry once the walk is done: its node's global transform
// (joint0.x: the node) by its inverse bind (joint1..3: its rows).
__device__ Affine anim_joint_entry(const float4* local_rows, const float4 joint0, const float4 joint1,
                                   const float4 joint2, const float4 joint3) {
  const unsigned node = __float_as_uint(joint0.x);
  Affine m, inverse_bind;
  m.row0 = local_rows[3u * node], m.row1 = local_rows[3u * node + 1u], m.row2 = local_rows[3u * node + 2u];
  inverse_bind.row0 = joint1, inverse_bind.row1 = joint2, inverse_bind.row2 = joint3;
  return anim_multiply(m, inverse_bind);
}

#if ANIM_BAKED >= 3
// Each node's local transform from its records, mixed in local space, with
// its parent (anim_records.clh): the thread's nodes item, item + ANIM_GROUP, ...
__device__ void anim_local_from_records(const float4* __restrict__ nodes, const float4* __restrict__ frames,
                                        const float4* __restrict__ clips, const uint4 in, const unsigned item,
                                        float4* local_rows, int* local_parent) {
  const float w = __uint_as_float(in.w);
  for (unsigned n = item; n < ANIM_NODE_COUNT; n += ANIM_GROUP) {
    Affine l;
    if (__float_as_uint(nodes[4u * n].y) != 0u) {
      l.row0 = nodes[4u * n + 1u], l.row1 = nodes[4u * n + 2u], l.row2 = nodes[4u * n + 3u];
    } else {
      Baked x = baked_sample(frames, ANIM_BAKED_ROWS, ANIM_BAKED_ITEMS, clips, in.x & 0xffffu, __uint_as_float(in.y), n);
      if (w != 0.0f)
        x = baked_mix(x, baked_sample(frames, ANIM_BAKED_ROWS, ANIM_BAKED_ITEMS, clips, in.x >> 16,
                                      __uint_as_float(in.z), n), w);
      Trs trs;
      trs.t = make_float4(x.ts.x, x.ts.y, x.ts.z, 0.0f);
      trs.r = x.q;
#if ANIM_BAKED == 4
      trs.s = x.s0;
#else
      trs.s = make_float4(x.ts.w, x.ts.w, x.ts.w, 0.0f);
#endif
      l = anim_to_affine(trs);
    }
    local_rows[3u * n] = l.row0;
    local_rows[3u * n + 1u] = l.row1;
    local_rows[3u * n + 2u] = l.row2;
    local_parent[n] = __float_as_int(nodes[4u * n].x);
  }
}
#endif  // ANIM_BAKED >= 3

#if ANIM_FUSED
// The records a fused skin kernel makes its palette from, as parameters and
// arguments, in EmitFused's order (anim_records.clh).
#if ANIM_BAKED >= 3 && ANIM_STEADY
#define ANIM_RECORDS_PARAMS                                                                      \
  const float4 *__restrict__ nodes, const float4 *__restrict__ frames, const float4 *__restrict__ steady, \
      const float4 *__restrict__ joints
#define ANIM_RECORDS_ARGS nodes, frames, steady, joints
#elif ANIM_BAKED >= 3
#define ANIM_RECORDS_PARAMS \
  const float4 *__restrict__ nodes, const float4 *__restrict__ frames, const float4 *__restrict__ joints
#define ANIM_RECORDS_ARGS nodes, frames, joints
#else
#define ANIM_RECORDS_PARAMS const float4* __restrict__ frames
#define ANIM_RECORDS_ARGS frames
#endif

// Joint j's entry in a fused kernel's shared palette (PALETTE_ROWS float4s a joint).
__device__ void anim_store_entry(float4* palette_out, const unsigned j, const Affine& m) {
  palette_out[j * PALETTE_ROWS] = m.row0;
  palette_out[j * PALETTE_ROWS + 1u] = m.row1;
  palette_out[j * PALETTE_ROWS + 2u] = m.row2;
#if PALETTE_ROWS == 4
  palette_out[j * PALETTE_ROWS + 3u] = make_float4(0.0f, 0.0f, 0.0f, 1.0f);
#endif
}

// An instance's palette in `palette_out` (PALETTE_ROWS float4s a joint),
// made by the block's threads from its records at `state` (its clocks
// already advanced), ready for a barrier; NaN rows for a state that names
// clips there are not (anim_records.clh). Every thread of the block calls it.
__device__ void anim_fused_palette(ANIM_RECORDS_PARAMS, const float4* __restrict__ clips, const uint4 state,
                                   float4* palette_out) {
  const unsigned item = threadIdx.x;
  const bool valid = anim_state_valid(state, ANIM_CLIP_COUNT);
#if ANIM_BAKED >= 3 && ANIM_STEADY
  const bool walk = valid && __uint_as_float(state.w) != 0.0f;  // one clip: palette records; a cross-fade walks
#elif ANIM_BAKED >= 3
  const bool walk = valid;
#else
  const bool walk = false;
#endif
  for (unsigned j = item; !walk && j < JOINTS; j += ANIM_GROUP) {
    const float nan = __int_as_float(0x7fffffff);
    const float4 nan_row = make_float4(nan, nan, nan, nan);
    Affine m = {nan_row, nan_row, nan_row};
#if ANIM_BAKED >= 3 && ANIM_STEADY
    if (valid) m = baked_affine(baked_instance(steady, ANIM_STEADY, JOINTS, clips, state, j), ANIM_STEADY);
#elif ANIM_BAKED < 3
    if (valid) m = baked_affine(baked_instance(frames, ANIM_BAKED_ROWS, JOINTS, clips, state, j), ANIM_BAKED_ROWS);
#endif
    anim_store_entry(palette_out, j, m);
  }
#if ANIM_BAKED >= 3
  // The hierarchy walked in the block's shared memory, as the palette kernel walks it.
  __shared__ float4 local_rows[3 * ANIM_LOCAL_NODES];
  __shared__ int local_parent[ANIM_LOCAL_NODES];
  if (!walk) return;  // the same in every thread: the whole block walks or none does (anim_records.clh)
  anim_local_from_records(nodes, frames, clips, state, item, local_rows, local_parent);
  __syncthreads();
  anim_jump(true, item, local_rows, local_parent);
  for (unsigned j = item; j < JOINTS; j += ANIM_GROUP) {
    const Affine m = anim_joint_entry(local_rows, __ldg(joints + 4u * j), __ldg(joints + 4u * j + 1u),
                                      __ldg(joints + 4u * j + 2u), __ldg(joints + 4u * j + 3u));
    anim_store_entry(palette_out, j, m);
  }
#endif  // ANIM_BAKED >= 3
}
#endif  // ANIM_FUSED
#endif  // ANIM_PALETTE_KERNEL || ANIM_FUSED
