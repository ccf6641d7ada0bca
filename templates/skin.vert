#version 430 core
// skintune: linear blend skinning, every glsl-vertex variant in one GL 4.3
// vertex shader (the paper's GLSL form): the same algorithm on the same bytes
// as templates/skin.cl and templates/skin.comp, one vertex per invocation.
//
//   v' = sum_i w_i * M[d_i] * (v, 1)                    (positions)
//   n' = normalize(N(A) * n), A = upper3x3(sum_i w_i * M[d_i])   (normals;
//        N(A) = sign(det A) * cofactor(A), the inverse transpose's direction)
//   t' = (normalize(A * t.xyz), sign(det A) * t.w)                 (tangents)
//
// The generator (generator/emit.cpp) puts one #define per parameter right
// after the #version line; every parameter has its default in skin_params.h,
// so this file compiles alone once its includes are expanded (ExpandedTemplate
// in generator/emit.h). docs/VARIANTS.md is the interface.
//
// Inputs are storage buffers (std430, 32-bit words), bound exactly as in
// skin.comp: records (aos) or positions, indices, weights[, normals[, tangents]] at
// bindings 0.., then the palette at the next binding: a std140 uniform block
// (STORAGE 0 constant), a std430 buffer (2 global) or a samplerBuffer on
// texture unit = that binding (3 image). STORAGE 1 (local) is rejected: a
// vertex shader has no shared memory. VERTICES_PER_ITEM must be 1 and
// WG_SIZE is ignored (glsl-vertex is v1c.wg0).
//
// How a launch runs (runtime/gl_runner.cpp does this):
//   - vertex v of the launch is gl_VertexID: glDrawArrays(GL_POINTS, 0, n)
//     with GL_RASTERIZER_DISCARD enabled, so v = 0 .. n-1 reads the launch's
//     own input buffers at v, as every other language does;
//   - the outputs are the vertex outputs `out_position` (and `out_normal`,
//     `out_tangent`): vec4 (w = 1 / 0) for float4, vec3 for float3, and the
//     tangent always vec4 (w: its handedness), captured by transform feedback
//     with GL_SEPARATE_ATTRIBS: out_position into transform feedback buffer
//     binding 0, out_normal into binding 1, out_tangent into binding 2;
//   - `first` is applied by the capture range, not by the shader: binding 0
//     (and 1) is glBindBufferRange(GL_TRANSFORM_FEEDBACK_BUFFER, b, buffer,
//     first * stride, n * stride), stride = 16 (float4) or 12 (float3) bytes,
//     so vertex v lands at first + v. The uniform `first` is declared as in
//     skin.comp but not read here; `n` gives soa-split's slot stride S.
// INSTANCED (docs/VARIANTS.md "Instancing"): glDrawArraysInstanced(GL_POINTS,
// 0, n, K) skins K instances; instance i = gl_InstanceID reads palette rows
// i*JOINTS*PALETTE_ROWS.., and the capture holds the K instances' n vertices
// one instance after another (range first*stride.. of K*n*stride when the
// mesh takes one draw; the runner places each bucket's instances otherwise).
// The sidecar says so: out_positions / out_normals / out_tangents carry
// "transform_feedback_buffer" 0 / 1 / 2 and their "varying" name, not a binding.
//
// The parameters (skin_params.h, shared by every template) and the skinning
// itself (skin_body.glsl: bindings, loads, palette access, blending, shared
// with skin.comp) are included below; GLSL has no #include, so the generator
// replaces those lines by the files' text.

#define SKIN_COMPUTE_STAGE 0

#include "skin_params.h"
#include "skin_body.glsl"

// ---------------------------------------------------------------- outputs

#if VERTICES_PER_ITEM != 1 || STRIDED
#error "glsl-vertex skins one vertex per invocation (v1c)"
#endif

#if POSITION_FLOAT4
out vec4 out_position;
#if NORMALS && NORMAL_FORMAT == 0
out vec4 out_normal;
#endif
#else
out vec3 out_position;
#if NORMALS && NORMAL_FORMAT == 0
out vec3 out_normal;
#endif
#endif
#if TANGENTS && NORMAL_FORMAT == 0
out vec4 out_tangent;
#endif
#if NORMAL_FORMAT != 0
// Packed normals and tangents: one word each (integer outputs are flat).
#if NORMALS
flat out uint out_normal;
#endif
#if TANGENTS
flat out uint out_tangent;
#endif
#endif

// ---------------------------------------------------------------- kernel

void main() {
  uint v = uint(gl_VertexID);  // 0 .. n-1: the draw starts at vertex 0
  vec3 skinned_position, skinned_normal;
  vec4 skinned_tangent;
  skin_vertex(v, slot_stride_of(n), skinned_position, skinned_normal, skinned_tangent);
#if NORMAL_FORMAT != 0
#if TANGENTS
  out_tangent = pack_tangent(vec4(normalize(skinned_tangent.xyz), skinned_tangent.w));
#endif
#if NORMALS
  out_normal = pack_normal(normalize(skinned_normal));
#endif
#elif TANGENTS
  out_tangent = vec4(normalize(skinned_tangent.xyz), skinned_tangent.w);
#endif
#if POSITION_FLOAT4
  out_position = vec4(skinned_position, 1.0);
#if NORMALS && NORMAL_FORMAT == 0
  out_normal = vec4(normalize(skinned_normal), 0.0);
#endif
#else
  out_position = skinned_position;
#if NORMALS && NORMAL_FORMAT == 0
  out_normal = normalize(skinned_normal);
#endif
#endif
}
