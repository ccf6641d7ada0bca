// skintune: linear blend skinning, every OpenCL variant in one kernel file.
//
//   v' = sum_i w_i * M[d_i] * (v, 1)                    (positions)
//   n' = normalize(N(A) * n), A = upper3x3(sum_i w_i * M[d_i])   (normals;
//        N(A) = sign(det A) * cofactor(A), the inverse transpose's direction)
//   t' = (normalize(A * t.xyz), sign(det A) * t.w)                 (tangents:
//        they follow the surface; a mirroring blend flips the handedness)
//
// The parameters, their defaults and the aos layout are in skin_params.h,
// shared by every template; the generator (generator/emit.cpp) prepends one
// #define per parameter and replaces the #include by the file's text, so the
// emitted kernel is one file. Every parameter has a default, so this file
// compiles alone: expanded by the generator (ExpandedTemplate in
// generator/emit.h, what the tests build) or from templates/, e.g.
//   clang -x cl -cl-std=CL1.2 -Xclang -finclude-default-header -fsyntax-only templates/skin.cl
// docs/VARIANTS.md is the interface this kernel implements: buffers per
// layout, formats, argument order and launch geometry.
//
// Kernel `skin(uint n, uint first, <inputs>, palette, <outputs>)`:
//   aos:            records
//   soa, soa-split: positions, indices, weights[, normals[, tangents]]
//   MORPH:          then morph_offsets, morph_targets (sparse), morph_positions[,
//                   morph_normals[, morph_tangents]], morph_weights
//   outputs:        out_positions[, out_normals[, out_tangents]], written at first + v.
// Inputs belong to the launch (vertex v of the launch is element v); item g
// handles vertices g*N .. g*N+N-1 (contiguous) or g, g+G, .., g+(N-1)G with G
// the number of items (strided). Items past n do nothing but still take part
// in the work-group's palette copy (STORAGE local).
//
// INSTANCED (docs/VARIANTS.md "Instancing"): one launch skins K instances of
// the mesh, each with its own palette. The kernel takes one more scalar,
// `skin(uint n, uint first, uint vertex_count, ...)`; the grid's second
// dimension is the instance i = get_global_id(1) (global size (items, K));
// instance i reads palette rows i*JOINTS*PALETTE_ROWS.. (the K palettes one
// after another) and writes vertex v at i*vertex_count + first + v
// (vertex_count: the whole mesh, every launch together).

#include "skin_params.h"
#include "anim_records.clh"

// ---------------------------------------------------------------- types
//
// Element types of the soa arguments and the outputs.

#if INDEX_FORMAT == 0
#define INDEX_T int
#elif INDEX_FORMAT == 1
#define INDEX_T ushort
#else
#define INDEX_T uchar
#endif

#if WEIGHT_FORMAT == 0
#define WEIGHT_T float
#elif WEIGHT_FORMAT == 1
#define WEIGHT_T ushort
#else
#define WEIGHT_T uchar
#endif

#if POSITION_FLOAT4
#define POSITION_T float4
#else
#define POSITION_T float
#endif

// ---------------------------------------------------------------- loads
//
// Alignment (in bytes, up to 16) that every address p0 + k*stride has, for
// buffers whose base is at least 16-byte aligned: the lowest set bit of
// (stride | offset). All arguments are compile-time constants, so after
// inlining the compiler keeps exactly one branch of each loader.
#define LOWEST_BIT(x) ((x) & (~(x) + 1u))
#define ALIGNMENT(stride_or_offset) \
  (LOWEST_BIT((uint)(stride_or_offset) | 16u))

// xyz of a float4 or float3 at p (w, when stored, is not read: positions are
// transformed as (x, y, z, 1) and normals as directions).
static inline float3 load_xyz(const __global uchar* p, const uint align) {
#if POSITION_FLOAT4
  if (align >= 16) return (*(const __global float4*)p).xyz;
#endif
  if (align >= 4) return vload3(0, (const __global float*)p);
  return (float3)(as_float(vload4(0, p)), as_float(vload4(1, p)), as_float(vload4(2, p)));
}

#if TANGENTS
// The 4 floats at p (a tangent: xyz and the handedness w).
static inline float4 load_xyzw(const __global uchar* p, const uint align) {
  if (align >= 16) return *(const __global float4*)p;
  if (align >= 4) return vload4(0, (const __global float*)p);
  return (float4)(as_float(vload4(0, p)), as_float(vload4(1, p)), as_float(vload4(2, p)), as_float(vload4(3, p)));
}
#endif

#if LAYOUT != 2
// The INFLUENCES little-endian unsigned values of `bytes` bytes each that
// start at p, zero-extended to 32 bits. A run that starts on a 32-bit word is
// read as whole words (uint4 / uint2 / uint loads), then split, when it ends
// on a word too or when `in_record`: an aos record starts on a word and its
// size is a multiple of 4, so the word holding the run's last byte is inside
// the record.
static inline void load_run(const __global uchar* p, const uint bytes, const uint align, const bool in_record,
                            uint out[INFLUENCES]) {
  const uint run = INFLUENCES * bytes;
  if (align >= 4 && (run % 4 == 0 || in_record)) {
    uint words[INFLUENCES];  // ceil(run / 4) <= INFLUENCES words
    const uint count = (run + 3) / 4;
    if (align >= 16 && count % 4 == 0) {
#pragma unroll
      for (uint k = 0; k < count; k += 4) {
        const uint4 w = ((const __global uint4*)p)[k / 4];
        words[k] = w.x, words[k + 1] = w.y, words[k + 2] = w.z, words[k + 3] = w.w;
      }
    } else if (align >= 8 && count % 2 == 0) {
#pragma unroll
      for (uint k = 0; k < count; k += 2) {
        const uint2 w = ((const __global uint2*)p)[k / 2];
        words[k] = w.x, words[k + 1] = w.y;
      }
    } else {
#pragma unroll
      for (uint k = 0; k < count; ++k) words[k] = ((const __global uint*)p)[k];
    }
    const uint mask = bytes == 4 ? 0xffffffffu : (1u << (8u * bytes)) - 1u;
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) out[i] = (words[i * bytes / 4] >> (8u * (i * bytes % 4))) & mask;
  } else if (bytes == 1) {
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) out[i] = p[i];
  } else if (bytes == 2 && align >= 2) {
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) out[i] = ((const __global ushort*)p)[i];
  } else if (bytes == 4 && align >= 4) {
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) out[i] = ((const __global uint*)p)[i];
  } else {
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) {
      uint value = 0;
      for (uint b = 0; b < bytes; ++b) value |= (uint)p[i * bytes + b] << (8u * b);
      out[i] = value;
    }
  }
}
#endif

#if MORPH
// Morph offset e of a stream (docs/VARIANTS.md "Morph targets"): float32
// x, y, z (12 bytes), or binary16 x, y, z and a zero (8 bytes).
#if MORPH_HALF
#define MORPH_T half
static inline float3 morph_offset(const __global half* p, const size_t e) { return vload_half4(e, p).xyz; }
#else
#define MORPH_T float
static inline float3 morph_offset(const __global float* p, const size_t e) { return vload3(e, p); }
#endif
#endif

#if LAYOUT == 2
// One element of `bytes` bytes at p (naturally aligned: soa-split slots).
static inline uint load_element(const __global uchar* p, const uint bytes) {
  if (bytes == 1) return *p;
  if (bytes == 2) return *(const __global ushort*)p;
  return *(const __global uint*)p;
}
#endif

static inline float weight_of(const uint raw) {
#if WEIGHT_FORMAT == 0
  return as_float(raw);
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
#define PALETTE_PARAM __constant float4* restrict palette
#define PALETTE_REF_PARAM __constant float4* pal
#define ROW(pal, k) (pal)[k]
#elif STORAGE == 1
#if ANIM_FUSED  // the records the local copy is made from (anim_records.clh)
#define PALETTE_PARAM \
  ANIM_RECORDS_PARAMS, __global const uint4* restrict instances, __global const float4* restrict clips
#else
#define PALETTE_PARAM const __global float4* restrict palette
#endif
#define PALETTE_REF_PARAM __local const float4* pal
#define ROW(pal, k) (pal)[k]
#elif STORAGE == 2
#define PALETTE_PARAM const __global float4* restrict palette
#define PALETTE_REF_PARAM const __global float4* pal
#define ROW(pal, k) (pal)[k]
#else
#define PALETTE_PARAM __read_only image1d_buffer_t palette
#define PALETTE_REF_PARAM __read_only image1d_buffer_t pal
#define ROW(pal, k) read_imagef(pal, (int)(k))
#endif

// (x, y, z, 1) by the three rows.
static inline float3 transform_point(const float4 r0, const float4 r1, const float4 r2, const float3 p) {
  const float4 h = (float4)(p, 1.0f);
  return (float3)(dot(r0, h), dot(r1, h), dot(r2, h));
}

// The normal matrix's product (reference/skinning.h NormalMatrix): sign(det A)
// * cofactor(A) * d, for A's rows a0..a2 (xyz): the direction of the inverse
// transpose's, right under non-uniform scale and shear.
static inline float3 transform_normal(const float4 a0, const float4 a1, const float4 a2, const float3 d) {
  const float3 c0 = cross(a1.xyz, a2.xyz);
  const float3 n = (float3)(dot(c0, d), dot(cross(a2.xyz, a0.xyz), d), dot(cross(a0.xyz, a1.xyz), d));
  return dot(a0.xyz, c0) < 0.0f ? -n : n;
}

// The tangent's product: A * t.xyz, and t.w flipped where A mirrors (det A < 0).
static inline float4 transform_tangent(const float4 a0, const float4 a1, const float4 a2, const float4 t) {
  const float det = dot(a0.xyz, cross(a1.xyz, a2.xyz));
  return (float4)(dot(a0.xyz, t.xyz), dot(a1.xyz, t.xyz), dot(a2.xyz, t.xyz), det < 0.0f ? -t.w : t.w);
}

#if BLEND == 2
// The rigid map of a unit dual quaternion (real part r = (x, y, z, w), dual
// part d) as three rows: r's rotation matrix and the translation
// 2 (r.w d.xyz - d.w r.xyz + r.xyz x d.xyz), the vector part of 2 d conj(r).
static inline void dual_quaternion_rows(const float4 r, const float4 d, float4* m0, float4* m1, float4* m2) {
  const float3 t = 2.0f * (r.w * d.xyz - d.w * r.xyz + cross(r.xyz, d.xyz));
  const float x = r.x, y = r.y, z = r.z, w = r.w;
  *m0 = (float4)(1.0f - 2.0f * (y * y + z * z), 2.0f * (x * y - w * z), 2.0f * (x * z + w * y), t.x);
  *m1 = (float4)(2.0f * (x * y + w * z), 1.0f - 2.0f * (x * x + z * z), 2.0f * (y * z - w * x), t.y);
  *m2 = (float4)(2.0f * (x * z - w * y), 2.0f * (y * z + w * x), 1.0f - 2.0f * (x * x + y * y), t.z);
}
#endif

// Skins one vertex's position given its joints and weights, and gives the
// blended matrix's rows (*a0..*a2) that normals and tangents are turned by
// (dead code without NORMALS). BLEND 2: the rows of the blended, normalised
// dual quaternion's rigid map (docs/VARIANTS.md "Dual quaternions"), each
// influence's quaternion taken on the side of the first influence's
// (antipodality: q and -q are one rotation, and blending across them cancels).
static inline void blend(PALETTE_REF_PARAM, const uint joint[INFLUENCES], const float weight[INFLUENCES],
                         const float3 position, float3* out_position, float4* a0, float4* a1, float4* a2) {
#if BLEND == 2
  const uint k0 = joint[0] * PALETTE_ROWS;
  const float4 q0 = ROW(pal, k0);
  float4 r = weight[0] * q0, d = weight[0] * ROW(pal, k0 + 1);
#pragma unroll
  for (uint i = 1; i < INFLUENCES; ++i) {
    const uint k = joint[i] * PALETTE_ROWS;
    const float4 q = ROW(pal, k);
    const float w = dot(q0, q) < 0.0f ? -weight[i] : weight[i];
    r += w * q;
    d += w * ROW(pal, k + 1);
  }
  const float inverse_length = rsqrt(dot(r, r));
  float4 m0, m1, m2;
  dual_quaternion_rows(inverse_length * r, inverse_length * d, &m0, &m1, &m2);
  *out_position = transform_point(m0, m1, m2, position);
#elif BLEND == 1
  uint k = joint[0] * PALETTE_ROWS;
  float4 r0 = ROW(pal, k), r1 = ROW(pal, k + 1), r2 = ROW(pal, k + 2);
  float3 p = weight[0] * transform_point(r0, r1, r2, position);
  float4 m0 = weight[0] * r0, m1 = weight[0] * r1, m2 = weight[0] * r2;
#pragma unroll
  for (uint i = 1; i < INFLUENCES; ++i) {
    k = joint[i] * PALETTE_ROWS;
    r0 = ROW(pal, k), r1 = ROW(pal, k + 1), r2 = ROW(pal, k + 2);
    p += weight[i] * transform_point(r0, r1, r2, position);
    m0 += weight[i] * r0, m1 += weight[i] * r1, m2 += weight[i] * r2;
  }
  *out_position = p;
#else
  const uint k0 = joint[0] * PALETTE_ROWS;
  float4 m0 = weight[0] * ROW(pal, k0), m1 = weight[0] * ROW(pal, k0 + 1), m2 = weight[0] * ROW(pal, k0 + 2);
#pragma unroll
  for (uint i = 1; i < INFLUENCES; ++i) {
    const uint k = joint[i] * PALETTE_ROWS;
    m0 += weight[i] * ROW(pal, k);
    m1 += weight[i] * ROW(pal, k + 1);
    m2 += weight[i] * ROW(pal, k + 2);
  }
  *out_position = transform_point(m0, m1, m2, position);
#endif
  *a0 = m0, *a1 = m1, *a2 = m2;
}

// Outputs: float4 with w = 1 (positions) / 0 (normals), or packed float3.
#if POSITION_FLOAT4
#define STORE_XYZ(out, at, value, w) ((out)[at] = (float4)((value), (w)))
#else
#define STORE_XYZ(out, at, value, w) vstore3((value), (at), (out))
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
#define NORMAL_OUT_T uint
#define TANGENT_OUT_T uint
#define STORE_NORMAL(out, at, n) ((out)[at] = pack_normal(n))
#define STORE_TANGENT(out, at, t) ((out)[at] = pack_tangent(t))
#endif
#if NORMAL_FORMAT == 1
float sign_not_zero(float v) { return v >= 0.0f ? 1.0f : -1.0f; }
uint unorm16(float v) { return (uint)floor(clamp(v, 0.0f, 1.0f) * 65535.0f + 0.5f); }
// The octahedral coordinates of a unit vector, each in [0, 1].
float2 octahedral(float3 n) {
  const float s = fabs(n.x) + fabs(n.y) + fabs(n.z);
  float u = n.x / s, v = n.y / s;
  if (n.z < 0.0f) {
    const float fu = (1.0f - fabs(v)) * sign_not_zero(u);
    v = (1.0f - fabs(u)) * sign_not_zero(v);
    u = fu;
  }
  return (float2)(u * 0.5f + 0.5f, v * 0.5f + 0.5f);
}
uint pack_normal(float3 n) {
  const float2 o = octahedral(n);
  return unorm16(o.x) | unorm16(o.y) << 16;
}
// y keeps the handedness: at least 1/2 for +1, below for -1.
uint pack_tangent(float4 t) {
  const float2 o = octahedral(t.xyz);
  float y = fmax(o.y, 1.0f / 32767.0f) * 0.5f + 0.5f;
  if (t.w < 0.0f) y = 1.0f - y;
  uint x16 = unorm16(o.x);
  const uint y16 = unorm16(y);
  if (x16 == 0u && y16 == 65535u) x16 = 65535u;
  return x16 | y16 << 16;
}
#elif NORMAL_FORMAT == 2
uint snorm8(float v) { return (uint)((int)floor(clamp(v, -1.0f, 1.0f) * 127.0f + 0.5f) & 0xff); }
uint pack_tangent(float4 t) { return snorm8(t.x) | snorm8(t.y) << 8 | snorm8(t.z) << 16 | snorm8(t.w) << 24; }
uint pack_normal(float3 n) { return pack_tangent((float4)(n, 0.0f)); }
#endif

// ---------------------------------------------------------------- kernel

__kernel __attribute__((reqd_work_group_size(WG_SIZE, 1, 1)))
void skin(const uint n, const uint first,
#if INSTANCED
          const uint vertex_count,
#endif
#if LAYOUT == 0
          const __global uint* restrict records,
#else
          const __global POSITION_T* restrict positions,
          const __global INDEX_T* restrict indices,
          const __global WEIGHT_T* restrict weights,
#if NORMALS
          const __global POSITION_T* restrict normals,
#endif
#if TANGENTS
          const __global float4* restrict tangents,
#endif
#endif
#if MORPH
#if MORPH_LAYOUT == 2
          const __global uint* restrict morph_offsets,
          const __global uint* restrict morph_targets,
#endif
          const __global MORPH_T* restrict morph_positions,
#if NORMALS
          const __global MORPH_T* restrict morph_normals,
#endif
#if TANGENTS
          const __global MORPH_T* restrict morph_tangents,
#endif
          const __global float* restrict morph_weights,
#endif
          PALETTE_PARAM,
#if TANGENTS
          __global POSITION_T* restrict out_positions,
          __global NORMAL_OUT_T* restrict out_normals,
          __global TANGENT_OUT_T* restrict out_tangents
#elif NORMALS
          __global POSITION_T* restrict out_positions,
          __global NORMAL_OUT_T* restrict out_normals
#else
          __global POSITION_T* restrict out_positions
#endif
#if ANIM_FUSED
          , const float elapsed  // seconds since the instances' upload, added to their clocks
#endif
          ) {
#if INSTANCED
  // Instance i: its palette starts at joint i*JOINTS (added to the joint
  // indices, or to where the local copy reads), its outputs at i*vertex_count.
  const uint instance = get_global_id(1);
  const uint joint_base = instance * JOINTS;
  const uint out_first = instance * vertex_count + first;
#else
  const uint out_first = first;
#endif
#if MORPH && INSTANCED
  morph_weights += instance * MORPH_TARGETS;  // this instance's weights
#endif
#if STORAGE == 1
  // Every item of the group copies, including those past n: no return before the barrier.
  __local float4 palette_local[PALETTE_FLOAT4S];
#if ANIM_FUSED && ANIM_BAKED >= 3
  // Local records: the hierarchy walked in the group's local memory, as the palette kernel walks it.
  __local float4 local_rows[3 * ANIM_LOCAL_NODES];
  __local int local_parent[ANIM_LOCAL_NODES];
#endif
#if ANIM_FUSED
  {
    // The copy made from the instance's records instead (docs/ANIMATION.md "The palette in the skin
    // launch"): every group of the instance makes the same palette, its clocks advanced by `elapsed`,
    // as the records' palette kernel makes it (palette.cl; anim_fused_palette), so no launch before
    // this one writes a palette and none waits for one. Nothing is written but the outputs.
#if INSTANCED
    (void)joint_base;  // the copy is the instance's own
    const uint4 state = anim_advance(clips, instances[instance], elapsed, ANIM_CLIP_COUNT);
#else
    const uint4 state = anim_advance(clips, instances[0], elapsed, ANIM_CLIP_COUNT);
#endif
#if ANIM_BAKED >= 3
    anim_fused_palette(ANIM_RECORDS_ARGS, clips, state, palette_local, local_rows, local_parent);
#else
    anim_fused_palette(ANIM_RECORDS_ARGS, clips, state, palette_local);
#endif
  }
#else
#if INSTANCED
  palette += joint_base * PALETTE_ROWS;
#endif
  for (uint k = get_local_id(0); k < PALETTE_FLOAT4S; k += WG_SIZE) palette_local[k] = palette[k];
#endif
  barrier(CLK_LOCAL_MEM_FENCE);
#define PAL palette_local
#else
#define PAL palette
#endif

#if LAYOUT == 2
  const uint slot_stride = ROUND_UP(max(n, 1u), (uint)SLOT_STRIDE_MULTIPLE);
#endif
  const uint item = get_global_id(0);
#if STRIDED
  const uint items = get_global_size(0);
#endif

#pragma unroll
  for (uint k = 0; k < VERTICES_PER_ITEM; ++k) {
#if STRIDED
    const uint v = item + k * items;
#else
    const uint v = item * VERTICES_PER_ITEM + k;
#endif
    if (v >= n) break;

    float3 position, normal = (float3)(0.0f);
    float4 tangent = (float4)(0.0f);
    uint joint[INFLUENCES], raw_weight[INFLUENCES];
#if LAYOUT == 0
    const __global uchar* record = (const __global uchar*)records + (size_t)v * AOS_RECORD_BYTES;
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
    position = load_xyz((const __global uchar*)positions + (size_t)v * POSITION_BYTES, ALIGNMENT(POSITION_BYTES));
#if NORMALS
    normal = load_xyz((const __global uchar*)normals + (size_t)v * POSITION_BYTES, ALIGNMENT(POSITION_BYTES));
#endif
#if TANGENTS
    tangent = tangents[v];
#endif
#if LAYOUT == 1
    load_run((const __global uchar*)indices + (size_t)v * (INFLUENCES * INDEX_BYTES), INDEX_BYTES,
             ALIGNMENT(INFLUENCES * INDEX_BYTES), false, joint);
    load_run((const __global uchar*)weights + (size_t)v * (INFLUENCES * WEIGHT_BYTES), WEIGHT_BYTES,
             ALIGNMENT(INFLUENCES * WEIGHT_BYTES), false, raw_weight);
#else
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) {
      const size_t e = (size_t)i * slot_stride + v;
      joint[i] = load_element((const __global uchar*)indices + e * INDEX_BYTES, INDEX_BYTES);
      raw_weight[i] = load_element((const __global uchar*)weights + e * WEIGHT_BYTES, WEIGHT_BYTES);
    }
#endif
#endif

#if MORPH
    // The morph targets first, at their weights, in target order.
#if MORPH_LAYOUT == 1
    for (uint t = 0; t < MORPH_TARGETS; ++t) {
      const float w = morph_weights[t];
      const size_t e = (size_t)t * n + v;
#else
    const uint morph_end = morph_offsets[v + 1];
    for (uint e = morph_offsets[v]; e < morph_end; ++e) {
      const float w = morph_weights[morph_targets[e]];
#endif
      if (w == 0.0f) continue;
      position += w * morph_offset(morph_positions, e);
#if NORMALS
      normal += w * morph_offset(morph_normals, e);
#endif
#if TANGENTS
      tangent.xyz += w * morph_offset(morph_tangents, e);
#endif
    }
#endif

    float weight[INFLUENCES];
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) weight[i] = weight_of(raw_weight[i]);
#if INSTANCED && STORAGE != 1
#pragma unroll
    for (uint i = 0; i < INFLUENCES; ++i) joint[i] += joint_base;  // this instance's palette
#endif

    float3 skinned_position;
    float4 a0, a1, a2;
    blend(PAL, joint, weight, position, &skinned_position, &a0, &a1, &a2);
    STORE_XYZ(out_positions, out_first + v, skinned_position, 1.0f);
#if NORMALS
    STORE_NORMAL(out_normals, out_first + v, normalize(transform_normal(a0, a1, a2, normal)));
#endif
#if TANGENTS
    const float4 skinned_tangent = transform_tangent(a0, a1, a2, tangent);
    STORE_TANGENT(out_tangents, out_first + v, (float4)(normalize(skinned_tangent.xyz), skinned_tangent.w));
#endif
  }
}
