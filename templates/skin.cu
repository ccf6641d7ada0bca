// skintune: linear blend skinning, every CUDA variant in one kernel file.
//
//   v' = sum_i w_i * M[d_i] * (v, 1)                    (positions)
//   n' = normalize(N(A) * n), A = upper3x3(sum_i w_i * M[d_i])   (normals;
//        N(A) = sign(det A) * cofactor(A), the inverse transpose's direction)
//   t' = (normalize(A * t.xyz), sign(det A) * t.w)                 (tangents:
//        they follow the surface; a mirroring blend flips the handedness)
//
// The CUDA twin of templates/skin.cl: the same #define parameters (from
// skin_params.h, shared by every template; the generator, generator/emit.cpp,
// prepends one #define per parameter and replaces the #include by the file's
// text), the same buffers, argument order and launch geometry
// (docs/VARIANTS.md), the same loads. Every parameter has a default, so this
// file compiles alone: expanded by the generator (ExpandedTemplate in
// generator/emit.h) with NVRTC and no options, or as `nvcc -c
// templates/skin.cu`. It includes no system header: NVRTC provides float4,
// uint4, __ldg and tex1Dfetch itself.
//
// Kernel `extern "C" skin(unsigned n, unsigned first, <inputs>, palette, <outputs>)`:
//   aos:            records
//   soa, soa-split: positions, indices, weights[, normals[, tangents]]
//   MORPH:          then morph_offsets, morph_targets (sparse), morph_positions[,
//                   morph_normals[, morph_tangents]], morph_weights
//   outputs:        out_positions[, out_normals[, out_tangents]], written at first + v.
// Launch blocks of exactly WG_SIZE threads (the work-group size); item g =
// blockIdx.x * WG_SIZE + threadIdx.x handles vertices g*N .. g*N+N-1
// (contiguous) or g, g+G, .., g+(N-1)G with G the number of items (strided).
// Items past n do nothing but still take part in the block's palette copy
// (STORAGE local).
//
// INSTANCED (docs/VARIANTS.md "Instancing"): one launch skins K instances of
// the mesh, each with its own palette. The kernel takes one more scalar,
// `skin(unsigned n, unsigned first, unsigned vertex_count, ...)`; the grid's
// y dimension is the instance i = blockIdx.y (grid (blocks, K)); instance i
// reads palette rows i*JOINTS*PALETTE_ROWS.. (the K palettes one after
// another) and writes vertex v at i*vertex_count + first + v (vertex_count:
// the whole mesh, every launch together). For STORAGE constant the symbol
// holds PALETTE_INSTANCES palettes (K <= PALETTE_INSTANCES).
//
// Where the palette is (STORAGE):
//   0 constant: the module symbol `skintune_palette`, a __constant__ array of
//     JOINTS*PALETTE_ROWS float4 rows. The host copies the palette rows into it
//     (cuModuleGetGlobal("skintune_palette") + cuMemcpyHtoD) before launching;
//     the `palette` argument stays in the argument list, so every storage binds
//     the same arguments, but is not read (pass the palette buffer or 0).
//   1 local:    `palette` (device buffer) copied once per block into __shared__.
//   2 global:   `palette` read through the read-only data cache (__ldg).
//   3 image:    `palette` is a cudaTextureObject_t over the palette buffer as
//     linear memory of float4 texels (cuTexObjectCreate: CU_RESOURCE_TYPE_LINEAR,
//     CU_AD_FORMAT_FLOAT, 4 channels), read with tex1Dfetch<float4>.
// Buffers are device allocations (cuMemAlloc: 256-byte aligned), so the
// alignments the loads below assume hold.

#include "skin_params.h"
#include "anim_records.cuh"

// NVRTC has no <cstdint>.
typedef unsigned int u32;
typedef unsigned short u16;
typedef unsigned char u8;
typedef unsigned long long u64;

// Element types of the soa arguments and the outputs.
#if INDEX_FORMAT == 0
#define INDEX_T int
#elif INDEX_FORMAT == 1
#define INDEX_T u16
#else
#define INDEX_T u8
#endif

#if WEIGHT_FORMAT == 0
#define WEIGHT_T float
#elif WEIGHT_FORMAT == 1
#define WEIGHT_T u16
#else
#define WEIGHT_T u8
#endif

#if POSITION_FLOAT4
#define POSITION_T float4
#else
#define POSITION_T float
#endif

#define DEVICE static __device__ __forceinline__

// ---------------------------------------------------------------- vectors
//
// CUDA defines no arithmetic on its vector types; these few helpers are the
// OpenCL built-ins the OpenCL template uses. Each is defined only where it is
// used (NVRTC warns about unreferenced static functions).

#if BLEND == 1 || NORMALS || MORPH
DEVICE float3 scale3(const float s, const float3 a) { return make_float3(s * a.x, s * a.y, s * a.z); }
#endif
#if BLEND == 1 || MORPH
DEVICE float3 add3(const float3 a, const float3 b) { return make_float3(a.x + b.x, a.y + b.y, a.z + b.z); }
#endif
// The blended matrix (BLEND 1: for normals and tangents only; BLEND 2: the dual quaternion).
DEVICE float4 scale4(const float s, const float4 a) { return make_float4(s * a.x, s * a.y, s * a.z, s * a.w); }
// acc + s * a
DEVICE float4 madd4(const float s, const float4 a, const float4 acc) {
  return make_float4(acc.x + s * a.x, acc.y + s * a.y, acc.z + s * a.z, acc.w + s * a.w);
}

// ---------------------------------------------------------------- loads
//
// Alignment (in bytes, up to 16) that every address p0 + k*stride has, for
// buffers whose base is at least 16-byte aligned: the lowest set bit of
// (stride | offset). All arguments are compile-time constants, so after
// inlining the compiler keeps exactly one branch of each loader.
#define LOWEST_BIT(x) ((x) & (~(x) + 1u))
#define ALIGNMENT(stride_or_offset) (LOWEST_BIT((u32)(stride_or_offset) | 16u))

// The little-endian 32-bit word at any byte address.
DEVICE u32 load_unaligned_word(const u8* p) {
  return (u32)p[0] | ((u32)p[1] << 8) | ((u32)p[2] << 16) | ((u32)p[3] << 24);
}

// xyz of a float4 or float3 at p (w, when stored, is not read: positions are
// transformed as (x, y, z, 1) and normals as directions).
DEVICE float3 load_xyz(const u8* p, const u32 align) {
#if POSITION_FLOAT4
  if (align >= 16) {
    const float4 v = *reinterpret_cast<const float4*>(p);
    return make_float3(v.x, v.y, v.z);
  }
#endif
  if (align >= 4) {
    const float* f = reinterpret_cast<const float*>(p);
    return make_float3(f[0], f[1], f[2]);
  }
  return make_float3(__uint_as_float(load_unaligned_word(p)), __uint_as_float(load_unaligned_word(p + 4)),
                     __uint_as_float(load_unaligned_word(p + 8)));
}

#if TANGENTS && LAYOUT == 0
// The 4 floats at p (a tangent: xyz and the handedness w).
DEVICE float4 load_xyzw(const u8* p, const u32 align) {
  if (align >= 16) return *reinterpret_cast<const float4*>(p);
  if (align >= 4) {
    const float* f = reinterpret_cast<const float*>(p);
    return make_float4(f[0], f[1], f[2], f[3]);
  }
  return make_float4(__uint_as_float(load_unaligned_word(p)), __uint_as_float(load_unaligned_word(p + 4)),
                     __uint_as_float(load_unaligned_word(p + 8)), __uint_as_float(load_unaligned_word(p + 12)));
}
#endif

#if LAYOUT != 2
// The INFLUENCES little-endian unsigned values of `bytes` bytes each that
// start at p, zero-extended to 32 bits. A run that starts on a 32-bit word is
// read as whole words (uint4 / uint2 / u32 loads), then split, when it ends
// on a word too or when `in_record`: an aos record starts on a word and its
// size is a multiple of 4, so the word holding the run's last byte is inside
// the record.
DEVICE void load_run(const u8* p, const u32 bytes, const u32 align, const bool in_record, u32 out[INFLUENCES]) {
  const u32 run = INFLUENCES * bytes;
  if (align >= 4 && (run % 4 == 0 || in_record)) {
    u32 words[INFLUENCES];  // ceil(run / 4) <= INFLUENCES words
    const u32 count = (run + 3) / 4;
    if (align >= 16 && count % 4 == 0) {
#pragma unroll
      for (u32 k = 0; k < count; k += 4) {
        const uint4 w = reinterpret_cast<const uint4*>(p)[k / 4];
        words[k] = w.x, words[k + 1] = w.y, words[k + 2] = w.z, words[k + 3] = w.w;
      }
    } else if (align >= 8 && count % 2 == 0) {
#pragma unroll
      for (u32 k = 0; k < count; k += 2) {
        const uint2 w = reinterpret_cast<const uint2*>(p)[k / 2];
        words[k] = w.x, words[k + 1] = w.y;
      }
    } else {
#pragma unroll
      for (u32 k = 0; k < count; ++k) words[k] = reinterpret_cast<const u32*>(p)[k];
    }
    const u32 mask = bytes == 4 ? 0xffffffffu : (1u << (8u * bytes)) - 1u;
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) out[i] = (words[i * bytes / 4] >> (8u * (i * bytes % 4))) & mask;
  } else if (bytes == 1) {
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) out[i] = p[i];
  } else if (bytes == 2 && align >= 2) {
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) out[i] = reinterpret_cast<const u16*>(p)[i];
  } else if (bytes == 4 && align >= 4) {
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) out[i] = reinterpret_cast<const u32*>(p)[i];
  } else {
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) {
      u32 value = 0;
      for (u32 b = 0; b < bytes; ++b) value |= (u32)p[i * bytes + b] << (8u * b);
      out[i] = value;
    }
  }
}
#endif

#if LAYOUT == 2
// One element of `bytes` bytes at p (naturally aligned: soa-split slots).
DEVICE u32 load_element(const u8* p, const u32 bytes) {
  if (bytes == 1) return *p;
  if (bytes == 2) return *reinterpret_cast<const u16*>(p);
  return *reinterpret_cast<const u32*>(p);
}
#endif

DEVICE float weight_of(const u32 raw) {
#if WEIGHT_FORMAT == 0
  return __uint_as_float(raw);
#elif WEIGHT_FORMAT == 1
  return (float)raw * (1.0f / 65535.0f);
#else
  return (float)raw * (1.0f / 255.0f);
#endif
}

// ---------------------------------------------------------------- palette
//
// Joint j's row r is float4 number j*PALETTE_ROWS + r. Row 3 of mat4 (0 0 0 1
// for the affine palettes skinning uses) is never read: outputs are xyz.

#if STORAGE == 0
#if INSTANCED
__constant__ float4 skintune_palette[PALETTE_INSTANCES * PALETTE_FLOAT4S];
#else
__constant__ float4 skintune_palette[PALETTE_FLOAT4S];
#endif
#define PALETTE_PARAM const float4* __restrict__ palette  // not read: the rows are in skintune_palette
#define PALETTE_REF_PARAM int
#define PALETTE_REF 0
#define ROW(pal, k) skintune_palette[k]
#elif STORAGE == 1
#if ANIM_FUSED  // the records the copy is made from (anim_records.cuh)
#define PALETTE_PARAM ANIM_RECORDS_PARAMS, const uint4* __restrict__ instances, const float4* __restrict__ clips
#else
#define PALETTE_PARAM const float4* __restrict__ palette
#endif
#define PALETTE_REF_PARAM const float4* pal
#define PALETTE_REF palette_shared
#define ROW(pal, k) (pal)[k]
#elif STORAGE == 2
#define PALETTE_PARAM const float4* __restrict__ palette
#define PALETTE_REF_PARAM const float4* __restrict__ pal
#define PALETTE_REF palette
#define ROW(pal, k) __ldg((pal) + (k))
#else
#define PALETTE_PARAM const cudaTextureObject_t palette
#define PALETTE_REF_PARAM const cudaTextureObject_t pal
#define PALETTE_REF palette
#define ROW(pal, k) tex1Dfetch<float4>((pal), (int)(k))
#endif

// (x, y, z, 1) by the three rows.
#if MORPH
// Morph offset e of a stream (docs/VARIANTS.md "Morph targets"): float32
// x, y, z (12 bytes), or binary16 x, y, z and a zero (8 bytes, one load;
// converted by PTX's cvt, so no header is needed).
#if MORPH_HALF
typedef uint2 MORPH_T;
DEVICE float half_value(const u32 bits) {
  float f;
  asm("cvt.f32.f16 %0, %1;" : "=f"(f) : "h"((u16)bits));
  return f;
}
DEVICE float3 morph_offset(const MORPH_T* p, const u64 e) {
  const uint2 h = __ldg(p + e);
  return make_float3(half_value(h.x & 0xffffu), half_value(h.x >> 16), half_value(h.y & 0xffffu));
}
#else
typedef float MORPH_T;
DEVICE float3 morph_offset(const MORPH_T* p, const u64 e) {
  return make_float3(__ldg(p + 3 * e), __ldg(p + 3 * e + 1), __ldg(p + 3 * e + 2));
}
#endif
#endif

DEVICE float3 transform_point(const float4 r0, const float4 r1, const float4 r2, const float3 p) {
  return make_float3(r0.x * p.x + r0.y * p.y + r0.z * p.z + r0.w, r1.x * p.x + r1.y * p.y + r1.z * p.z + r1.w,
                     r2.x * p.x + r2.y * p.y + r2.z * p.z + r2.w);
}

#if NORMALS || BLEND == 2
// a x b of the rows' xyz.
DEVICE float3 cross3(const float4 a, const float4 b) {
  return make_float3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
#endif
#if NORMALS
// a . b.
DEVICE float dot3(const float3 a, const float3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// The normal matrix's product (reference/skinning.h NormalMatrix): sign(det A)
// * cofactor(A) * d, for A's rows a0..a2 (xyz): the direction of the inverse
// transpose's, right under non-uniform scale and shear.
DEVICE float3 transform_normal(const float4 a0, const float4 a1, const float4 a2, const float3 d) {
  const float3 c0 = cross3(a1, a2);
  const float3 n = make_float3(dot3(c0, d), dot3(cross3(a2, a0), d), dot3(cross3(a0, a1), d));
  return dot3(make_float3(a0.x, a0.y, a0.z), c0) < 0.0f ? make_float3(-n.x, -n.y, -n.z) : n;
}

// d / |d|, and d itself when it is zero (as OpenCL's normalize and the gold).
DEVICE float3 normalize3(const float3 d) {
  const float length2 = d.x * d.x + d.y * d.y + d.z * d.z;
  return length2 > 0.0f ? scale3(rsqrtf(length2), d) : d;
}
#endif

#if TANGENTS
// The tangent's product: A * t.xyz, and t.w flipped where A mirrors (det A < 0).
DEVICE float4 transform_tangent(const float4 a0, const float4 a1, const float4 a2, const float4 t) {
  const float3 d = make_float3(t.x, t.y, t.z);
  const float det = dot3(make_float3(a0.x, a0.y, a0.z), cross3(a1, a2));
  return make_float4(dot3(make_float3(a0.x, a0.y, a0.z), d), dot3(make_float3(a1.x, a1.y, a1.z), d),
                     dot3(make_float3(a2.x, a2.y, a2.z), d), det < 0.0f ? -t.w : t.w);
}
#endif

#if BLEND == 2
DEVICE float dot4(const float4 a, const float4 b) { return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w; }
// The rigid map of a unit dual quaternion (skin.cl's dual_quaternion_rows).
DEVICE void dual_quaternion_rows(const float4 r, const float4 d, float4* m0, float4* m1, float4* m2) {
  const float3 c = cross3(r, d);
  const float tx = 2.0f * (r.w * d.x - d.w * r.x + c.x), ty = 2.0f * (r.w * d.y - d.w * r.y + c.y),
              tz = 2.0f * (r.w * d.z - d.w * r.z + c.z);
  const float x = r.x, y = r.y, z = r.z, w = r.w;
  *m0 = make_float4(1.0f - 2.0f * (y * y + z * z), 2.0f * (x * y - w * z), 2.0f * (x * z + w * y), tx);
  *m1 = make_float4(2.0f * (x * y + w * z), 1.0f - 2.0f * (x * x + z * z), 2.0f * (y * z - w * x), ty);
  *m2 = make_float4(2.0f * (x * z - w * y), 2.0f * (y * z + w * x), 1.0f - 2.0f * (x * x + y * y), tz);
}
#endif

// Skins one vertex's position given its joints and weights, and gives the
// blended matrix's rows (*a0..*a2) that normals and tangents are turned by
// (dead code without NORMALS). BLEND 2: the blended dual quaternion's rigid
// map, each influence on the side of the first's (skin.cl's blend).
DEVICE void blend(PALETTE_REF_PARAM, const u32 joint[INFLUENCES], const float weight[INFLUENCES],
                  const float3 position, float3* out_position, float4* a0, float4* a1, float4* a2) {
#if BLEND == 2
  const u32 k0 = joint[0] * PALETTE_ROWS;
  const float4 q0 = ROW(pal, k0);
  float4 r = scale4(weight[0], q0), d = scale4(weight[0], ROW(pal, k0 + 1));
#pragma unroll
  for (u32 i = 1; i < INFLUENCES; ++i) {
    const u32 k = joint[i] * PALETTE_ROWS;
    const float4 q = ROW(pal, k);
    const float w = dot4(q0, q) < 0.0f ? -weight[i] : weight[i];
    r = madd4(w, q, r);
    d = madd4(w, ROW(pal, k + 1), d);
  }
  const float inverse_length = rsqrtf(dot4(r, r));
  float4 m0, m1, m2;
  dual_quaternion_rows(scale4(inverse_length, r), scale4(inverse_length, d), &m0, &m1, &m2);
  *out_position = transform_point(m0, m1, m2, position);
#elif BLEND == 1
  u32 k = joint[0] * PALETTE_ROWS;
  float4 r0 = ROW(pal, k), r1 = ROW(pal, k + 1), r2 = ROW(pal, k + 2);
  float3 p = scale3(weight[0], transform_point(r0, r1, r2, position));
  float4 m0 = scale4(weight[0], r0), m1 = scale4(weight[0], r1), m2 = scale4(weight[0], r2);
#pragma unroll
  for (u32 i = 1; i < INFLUENCES; ++i) {
    k = joint[i] * PALETTE_ROWS;
    r0 = ROW(pal, k), r1 = ROW(pal, k + 1), r2 = ROW(pal, k + 2);
    p = add3(p, scale3(weight[i], transform_point(r0, r1, r2, position)));
    m0 = madd4(weight[i], r0, m0), m1 = madd4(weight[i], r1, m1), m2 = madd4(weight[i], r2, m2);
  }
  *out_position = p;
#else
  const u32 k0 = joint[0] * PALETTE_ROWS;
  float4 m0 = scale4(weight[0], ROW(pal, k0)), m1 = scale4(weight[0], ROW(pal, k0 + 1)),
         m2 = scale4(weight[0], ROW(pal, k0 + 2));
#pragma unroll
  for (u32 i = 1; i < INFLUENCES; ++i) {
    const u32 k = joint[i] * PALETTE_ROWS;
    m0 = madd4(weight[i], ROW(pal, k), m0);
    m1 = madd4(weight[i], ROW(pal, k + 1), m1);
    m2 = madd4(weight[i], ROW(pal, k + 2), m2);
  }
  *out_position = transform_point(m0, m1, m2, position);
#endif
  *a0 = m0, *a1 = m1, *a2 = m2;
}

// Outputs: float4 with w = 1 (positions) / 0 (normals), or packed float3.
#if POSITION_FLOAT4
#define STORE_XYZ(out, at, value, w) ((out)[at] = make_float4((value).x, (value).y, (value).z, (w)))
#else
#define STORE_XYZ(out, at, value, w) store_xyz3((out), (at), (value))
DEVICE void store_xyz3(float* out, const u32 at, const float3 value) {
  float* p = out + (u64)at * 3;
  p[0] = value.x, p[1] = value.y, p[2] = value.z;
}
#endif

// Normals and tangents: float32 (as positions; tangents float4), or one
// packed word each (docs/VARIANTS.md "Packed normals and tangents": the rule
// skintune's packer and the emitted header's PackNormal run too).
#if NORMAL_FORMAT == 0
#define NORMAL_OUT_T POSITION_T
#define TANGENT_OUT_T float4
#define STORE_NORMAL(out, at, n) STORE_XYZ(out, at, n, 0.0f)
#define STORE_TANGENT(out, at, t) ((out)[at] = (t))
#else
#define NORMAL_OUT_T u32
#define TANGENT_OUT_T u32
#define STORE_NORMAL(out, at, n) ((out)[at] = pack_normal(n))
#define STORE_TANGENT(out, at, t) ((out)[at] = pack_tangent(t))
#endif
#if NORMAL_FORMAT == 1
DEVICE float sign_not_zero(const float v) { return v >= 0.0f ? 1.0f : -1.0f; }
DEVICE u32 unorm16(const float v) { return (u32)floorf(fminf(fmaxf(v, 0.0f), 1.0f) * 65535.0f + 0.5f); }
// The octahedral coordinates of a unit vector, each in [0, 1].
DEVICE float2 octahedral(const float3 n) {
  const float s = fabsf(n.x) + fabsf(n.y) + fabsf(n.z);
  float u = n.x / s, v = n.y / s;
  if (n.z < 0.0f) {
    const float fu = (1.0f - fabsf(v)) * sign_not_zero(u);
    v = (1.0f - fabsf(u)) * sign_not_zero(v);
    u = fu;
  }
  return make_float2(u * 0.5f + 0.5f, v * 0.5f + 0.5f);
}
DEVICE u32 pack_normal(const float3 n) {
  const float2 o = octahedral(n);
  return unorm16(o.x) | unorm16(o.y) << 16;
}
#if TANGENTS
// y keeps the handedness: at least 1/2 for +1, below for -1.
DEVICE u32 pack_tangent(const float4 t) {
  const float2 o = octahedral(make_float3(t.x, t.y, t.z));
  float y = fmaxf(o.y, 1.0f / 32767.0f) * 0.5f + 0.5f;
  if (t.w < 0.0f) y = 1.0f - y;
  u32 x16 = unorm16(o.x);
  const u32 y16 = unorm16(y);
  if (x16 == 0u && y16 == 65535u) x16 = 65535u;
  return x16 | y16 << 16;
}
#endif
#elif NORMAL_FORMAT == 2
DEVICE u32 snorm8(const float v) { return (u32)((int)floorf(fminf(fmaxf(v, -1.0f), 1.0f) * 127.0f + 0.5f) & 0xff); }
DEVICE u32 pack_tangent(const float4 t) { return snorm8(t.x) | snorm8(t.y) << 8 | snorm8(t.z) << 16 | snorm8(t.w) << 24; }
DEVICE u32 pack_normal(const float3 n) { return pack_tangent(make_float4(n.x, n.y, n.z, 0.0f)); }
#endif

// ---------------------------------------------------------------- kernel

extern "C" __global__ void __launch_bounds__(WG_SIZE)
skin(const u32 n, const u32 first,
#if INSTANCED
     const u32 vertex_count,
#endif
#if LAYOUT == 0
     const u32* __restrict__ records,
#else
     const POSITION_T* __restrict__ positions,
     const INDEX_T* __restrict__ indices,
     const WEIGHT_T* __restrict__ weights,
#if NORMALS
     const POSITION_T* __restrict__ normals,
#endif
#if TANGENTS
     const float4* __restrict__ tangents,
#endif
#endif
#if MORPH
#if MORPH_LAYOUT == 2
     const u32* __restrict__ morph_offsets,
     const u32* __restrict__ morph_targets,
#endif
     const MORPH_T* __restrict__ morph_positions,
#if NORMALS
     const MORPH_T* __restrict__ morph_normals,
#endif
#if TANGENTS
     const MORPH_T* __restrict__ morph_tangents,
#endif
     const float* __restrict__ morph_weights,
#endif
     PALETTE_PARAM,
#if TANGENTS
     POSITION_T* __restrict__ out_positions,
     NORMAL_OUT_T* __restrict__ out_normals,
     TANGENT_OUT_T* __restrict__ out_tangents
#elif NORMALS
     POSITION_T* __restrict__ out_positions,
     NORMAL_OUT_T* __restrict__ out_normals
#else
     POSITION_T* __restrict__ out_positions
#endif
#if ANIM_FUSED
     , const float elapsed  // seconds since the instances' upload, added to their clocks
#endif
     ) {
#if INSTANCED
  // Instance i: its palette starts at joint i*JOINTS (added to the joint
  // indices, or to where the shared copy reads), its outputs at i*vertex_count.
  const u32 instance = blockIdx.y;
  const u32 joint_base = instance * JOINTS;
  const u32 out_first = instance * vertex_count + first;
#else
  const u32 out_first = first;
#endif
#if MORPH && INSTANCED
  morph_weights += instance * MORPH_TARGETS;  // this instance's weights
#endif
#if STORAGE == 1
  // Every thread of the block copies, including those past n: no return before the barrier.
  __shared__ float4 palette_shared[PALETTE_FLOAT4S];
#if ANIM_FUSED
  {
#if INSTANCED
    (void)joint_base;  // the copy is the instance's own
#endif
    // The copy made from the instance's records instead (skin.cl says why).
#if INSTANCED
    const uint4 state = anim_advance(clips, __ldg(instances + instance), elapsed, ANIM_CLIP_COUNT);
#else
    const uint4 state = anim_advance(clips, __ldg(instances), elapsed, ANIM_CLIP_COUNT);
#endif
    anim_fused_palette(ANIM_RECORDS_ARGS, clips, state, palette_shared);
  }
#else
#if INSTANCED
  palette += joint_base * PALETTE_ROWS;
#endif
  for (u32 k = threadIdx.x; k < PALETTE_FLOAT4S; k += WG_SIZE) palette_shared[k] = __ldg(palette + k);
#endif
  __syncthreads();
#elif STORAGE == 0
  (void)palette;
#endif

#if LAYOUT == 2
  const u32 slot_stride = ROUND_UP(max(n, 1u), (u32)SLOT_STRIDE_MULTIPLE);
#endif
  const u32 item = blockIdx.x * WG_SIZE + threadIdx.x;
#if STRIDED
  const u32 items = gridDim.x * WG_SIZE;
#endif

#pragma unroll
  for (u32 k = 0; k < VERTICES_PER_ITEM; ++k) {
#if STRIDED
    const u32 v = item + k * items;
#else
    const u32 v = item * VERTICES_PER_ITEM + k;
#endif
    if (v >= n) break;

    float3 position, normal = make_float3(0.0f, 0.0f, 0.0f);
    float4 tangent = make_float4(0.0f, 0.0f, 0.0f, 0.0f);
    u32 joint[INFLUENCES], raw_weight[INFLUENCES];
#if LAYOUT == 0
    const u8* record = reinterpret_cast<const u8*>(records) + (u64)v * AOS_RECORD_BYTES;
    position = load_xyz(record + AOS_POSITION_OFFSET, ALIGNMENT(AOS_RECORD_BYTES | AOS_POSITION_OFFSET));
    load_run(record + AOS_INDICES_OFFSET, INDEX_BYTES, ALIGNMENT(AOS_RECORD_BYTES | AOS_INDICES_OFFSET), true, joint);
    load_run(record + AOS_WEIGHTS_OFFSET, WEIGHT_BYTES, ALIGNMENT(AOS_RECORD_BYTES | AOS_WEIGHTS_OFFSET), true,
             raw_weight);
#if NORMALS
    normal = load_xyz(record + AOS_NORMAL_OFFSET, ALIGNMENT(AOS_RECORD_BYTES | AOS_NORMAL_OFFSET));
#endif
#if TANGENTS
    tangent = load_xyzw(record + AOS_TANGENT_OFFSET, ALIGNMENT(AOS_RECORD_BYTES | AOS_TANGENT_OFFSET));
#endif
#else
    position = load_xyz(reinterpret_cast<const u8*>(positions) + (u64)v * POSITION_BYTES, ALIGNMENT(POSITION_BYTES));
#if NORMALS
    normal = load_xyz(reinterpret_cast<const u8*>(normals) + (u64)v * POSITION_BYTES, ALIGNMENT(POSITION_BYTES));
#endif
#if TANGENTS
    tangent = tangents[v];
#endif
#if LAYOUT == 1
    load_run(reinterpret_cast<const u8*>(indices) + (u64)v * (INFLUENCES * INDEX_BYTES), INDEX_BYTES,
             ALIGNMENT(INFLUENCES * INDEX_BYTES), false, joint);
    load_run(reinterpret_cast<const u8*>(weights) + (u64)v * (INFLUENCES * WEIGHT_BYTES), WEIGHT_BYTES,
             ALIGNMENT(INFLUENCES * WEIGHT_BYTES), false, raw_weight);
#else
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) {
      const u64 e = (u64)i * slot_stride + v;
      joint[i] = load_element(reinterpret_cast<const u8*>(indices) + e * INDEX_BYTES, INDEX_BYTES);
      raw_weight[i] = load_element(reinterpret_cast<const u8*>(weights) + e * WEIGHT_BYTES, WEIGHT_BYTES);
    }
#endif
#endif

#if MORPH
    // The morph targets first, at their weights, in target order.
#if MORPH_LAYOUT == 1
    for (u32 t = 0; t < MORPH_TARGETS; ++t) {
      const float w = __ldg(morph_weights + t);
      const u64 e = (u64)t * n + v;
#else
    const u32 morph_end = __ldg(morph_offsets + v + 1);
    for (u32 e = __ldg(morph_offsets + v); e < morph_end; ++e) {
      const float w = __ldg(morph_weights + __ldg(morph_targets + e));
#endif
      if (w == 0.0f) continue;
      position = add3(position, scale3(w, morph_offset(morph_positions, e)));
#if NORMALS
      normal = add3(normal, scale3(w, morph_offset(morph_normals, e)));
#endif
#if TANGENTS
      const float3 dt = scale3(w, morph_offset(morph_tangents, e));
      tangent = make_float4(tangent.x + dt.x, tangent.y + dt.y, tangent.z + dt.z, tangent.w);
#endif
    }
#endif

    float weight[INFLUENCES];
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) weight[i] = weight_of(raw_weight[i]);
#if INSTANCED && STORAGE != 1
#pragma unroll
    for (u32 i = 0; i < INFLUENCES; ++i) joint[i] += joint_base;  // this instance's palette
#endif

    float3 skinned_position;
    float4 a0, a1, a2;
    blend(PALETTE_REF, joint, weight, position, &skinned_position, &a0, &a1, &a2);
    STORE_XYZ(out_positions, out_first + v, skinned_position, 1.0f);
#if NORMALS
    STORE_NORMAL(out_normals, out_first + v, normalize3(transform_normal(a0, a1, a2, normal)));
#endif
#if TANGENTS
    const float4 t = transform_tangent(a0, a1, a2, tangent);
    const float3 t3 = normalize3(make_float3(t.x, t.y, t.z));
    STORE_TANGENT(out_tangents, out_first + v, make_float4(t3.x, t3.y, t3.z, t.w));
#endif
  }
}
