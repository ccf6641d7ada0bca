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
#endif  // ANIM_PALETTE_KERNEL || ANIM_FUSED
