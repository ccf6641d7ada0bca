#version 430 core
// skintune: linear blend skinning, every glsl-compute variant in one GL 4.3
// compute shader: the same algorithm on the same bytes as templates/skin.cl.
//
//   v' = sum_i w_i * M[d_i] * (v, 1)                    (positions)
//   n' = normalize(N(A) * n), A = upper3x3(sum_i w_i * M[d_i])   (normals;
//        N(A) = sign(det A) * cofactor(A), the inverse transpose's direction)
//
// The generator (generator/emit.cpp) puts one #define per parameter right
// after the #version line; every parameter has its default in skin_params.h,
// so this file compiles alone once its includes are expanded (ExpandedTemplate
// in generator/emit.h). docs/VARIANTS.md is the interface: every buffer is an
// array of 32-bit words (narrower formats packed little-endian, unpacked here
// with shifts), bound in argument order:
//   aos:            records                                  binding 0
//   soa, soa-split: positions, indices, weights[, normals[, tangents]]   bindings 0..
//   palette:        the next binding: a std140 uniform block (STORAGE 0
//                   constant), a std430 buffer (2 global; 1 local: copied
//                   into shared memory by each work-group) or a samplerBuffer
//                   on texture unit = that binding (3 image, RGBA32F texels);
//   outputs:        out_positions[, out_normals[, out_tangents]]: the next bindings, written
//                   at first + v;
//   uniforms:       uint n (vertices of this launch), uint first.
// Compiled to SPIR-V for Vulkan (language `vulkan`), the same text: bindings
// are descriptor set 0, the palette's samplerBuffer a uniform texel buffer,
// and n, first, vertex_count a push-constant block (skin_body.glsl).
// INSTANCED (docs/VARIANTS.md "Instancing"): glDispatchCompute(groups, K, 1)
// skins K instances; instance i = gl_WorkGroupID.y reads palette rows
// i*JOINTS*PALETTE_ROWS.. and writes vertex v at i*vertex_count + first + v
// (uniform uint vertex_count: the whole mesh, every launch together).
// Invocation g handles vertices g*N .. g*N+N-1 (contiguous) or g, g+G, ..,
// g+(N-1)G with G the number of invocations (strided). Invocations past n do
// nothing but still take part in the work-group's palette copy.
//
// The parameters (skin_params.h, shared by every template) and the skinning
// itself (skin_body.glsl: bindings, loads, palette access, blending, shared
// with skin.vert) are included below; GLSL has no #include, so the generator
// replaces those lines by the files' text.

#define SKIN_COMPUTE_STAGE 1

#include "skin_params.h"
#include "skin_body.glsl"
#include "anim_records.glsl"

// ---------------------------------------------------------------- outputs

#if WG_SIZE < 1
#error "glsl-compute needs a work-group size (WG_SIZE)"
#endif
layout(local_size_x = WG_SIZE) in;

#if NORMALS && NORMAL_FORMAT != 0
// Packed normals (and tangents): one word a vertex.
layout(std430, binding = BINDING_OUT_NORMALS) writeonly restrict buffer OutNormals { uint out_normals[]; };
#define STORE_NORMAL(at, value) out_normals[at] = pack_normal(value)
#endif

#if POSITION_FLOAT4
layout(std430, binding = BINDING_OUT_POSITIONS) writeonly restrict buffer OutPositions { vec4 out_positions[]; };
#if NORMALS && NORMAL_FORMAT == 0
layout(std430, binding = BINDING_OUT_NORMALS) writeonly restrict buffer OutNormals { vec4 out_normals[]; };
#define STORE_NORMAL(at, value) out_normals[at] = vec4((value), 0.0)
#endif
#define STORE_POSITION(at, value) out_positions[at] = vec4((value), 1.0)
#else
layout(std430, binding = BINDING_OUT_POSITIONS) writeonly restrict buffer OutPositions { float out_positions[]; };
#if NORMALS && NORMAL_FORMAT == 0
layout(std430, binding = BINDING_OUT_NORMALS) writeonly restrict buffer OutNormals { float out_normals[]; };
#endif
void store_position(uint at, vec3 value) {
  out_positions[3u * at] = value.x;
  out_positions[3u * at + 1u] = value.y;
  out_positions[3u * at + 2u] = value.z;
}
#define STORE_POSITION(at, value) store_position((at), (value))
#if NORMALS && NORMAL_FORMAT == 0
void store_normal(uint at, vec3 value) {
  out_normals[3u * at] = value.x;
  out_normals[3u * at + 1u] = value.y;
  out_normals[3u * at + 2u] = value.z;
}
#define STORE_NORMAL(at, value) store_normal((at), (value))
#endif
#endif

#if TANGENTS && NORMAL_FORMAT == 0
layout(std430, binding = BINDING_OUT_TANGENTS) writeonly restrict buffer OutTangents { vec4 out_tangents[]; };
#define STORE_TANGENT(at, value) out_tangents[at] = (value)
#elif TANGENTS
layout(std430, binding = BINDING_OUT_TANGENTS) writeonly restrict buffer OutTangents { uint out_tangents[]; };
#define STORE_TANGENT(at, value) out_tangents[at] = pack_tangent(value)
#endif

// ---------------------------------------------------------------- kernel

#if INSTANCED && !defined(VULKAN)
uniform uint vertex_count;  // vertices of one instance in the outputs (the whole mesh; Vulkan: a push constant)
#endif

// Skins vertex v, loaded, and stores what the kernel writes at out_first + v.
void skin_and_store(VertexIn loaded, uint v, uint out_first) {
  vec3 skinned_position, skinned_normal;
  vec4 skinned_tangent;
  skin_loaded(loaded, skinned_position, skinned_normal, skinned_tangent);
  STORE_POSITION(out_first + v, skinned_position);
#if NORMALS
  STORE_NORMAL(out_first + v, normalize(skinned_normal));
#endif
#if TANGENTS
  STORE_TANGENT(out_first + v, vec4(normalize(skinned_tangent.xyz), skinned_tangent.w));
#endif
}

void main() {
#if INSTANCED
  uint out_first = INSTANCE * vertex_count + first;
#else
  uint out_first = first;
#endif
#if STORAGE == 1 && ANIM_FUSED
  // Made below, once the first vertex's loads are issued.
#if INSTANCED
  uvec4 instance_state = instances[INSTANCE];
#else
  uvec4 instance_state = instances[0];
#endif
#elif STORAGE == 1
#if INSTANCED
  uint palette_first = INSTANCE * uint(PALETTE_FLOAT4S);  // this instance's palette
#else
  uint palette_first = 0u;
#endif
  // Every invocation of the group copies, including those past n: no return before the barrier.
  for (uint k = gl_LocalInvocationID.x; k < uint(PALETTE_FLOAT4S); k += uint(WG_SIZE))
    palette_local[k] = palette_rows[palette_first + k];
  memoryBarrierShared();
  barrier();
#endif

  uint slot_stride = slot_stride_of(n);
  uint item = gl_GlobalInvocationID.x;
#if STRIDED
  uint items = gl_NumWorkGroups.x * uint(WG_SIZE);
#endif

#if STORAGE == 1 && ANIM_FUSED
  // The first vertex's loads go out before the palette records' so that the
  // two latencies overlap, then every invocation makes its share of the
  // palette and reaches the barrier. On an H200 (2026-11-30, 64 x 25k-b4,
  // v8s.wg256) GL compute's pipelined fused frame took 26.9-27.2 us this way against
  // 27.9-28.9 with the palette made first. The two compilers want it written
  // differently (H200, 2026-12-01, the same crowd): Vulkan's fused Skin-only
  // frame took 26.9-27.1 us with the barrier inside the loop's first turn
  // and 24.8 with the first vertex skinned before the loop, GL compute's
  // 26.4-26.5 the first way and 27.4-27.5 the second. skin.cl and skin.cu keep
  // the palette first: this order made their frames slower (OpenCL 20.0 ->
  // 22.1 us, CUDA 18.4 -> 19.2).
#endif
#if STORAGE == 1 && ANIM_FUSED && defined(VULKAN)
#if STRIDED
  uint v0 = item;
#else
  uint v0 = item * uint(VERTICES_PER_ITEM);
#endif
  VertexIn first_loaded;
  if (v0 < n) first_loaded = load_vertex(v0, slot_stride);
  anim_fused_palette(anim_advance(instance_state, elapsed));  // anim_records.glsl
  memoryBarrierShared();
  barrier();
  if (v0 >= n) return;
  skin_and_store(first_loaded, v0, out_first);
  for (uint k = 1u; k < uint(VERTICES_PER_ITEM); ++k) {
#else
  for (uint k = 0u; k < uint(VERTICES_PER_ITEM); ++k) {
#endif
#if STRIDED
    uint v = item + k * items;
#else
    uint v = item * uint(VERTICES_PER_ITEM) + k;
#endif
#if STORAGE == 1 && ANIM_FUSED && !defined(VULKAN)
    bool live = v < n;  // every invocation reaches the barrier, none leaves the loop before it
    VertexIn loaded;
    if (live) loaded = load_vertex(v, slot_stride);
    if (k == 0u) {
      anim_fused_palette(anim_advance(instance_state, elapsed));  // anim_records.glsl
      memoryBarrierShared();
      barrier();
    }
    if (!live) break;
    skin_and_store(loaded, v, out_first);
#else
    if (v >= n) break;
    skin_and_store(load_vertex(v, slot_stride), v, out_first);
#endif
  }
}
