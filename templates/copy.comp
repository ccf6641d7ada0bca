#version 430 core
// skintune: the copy kernel every measurement is judged against (GLSL 4.30
// compute, and Vulkan's SPIR-V from the same text; copy_in at binding 0,
// out_positions at binding 1).
// It moves n 16-byte items from copy_in to out_positions (at first + i): the
// bytes of a frame, read once and written once, nothing else done. Each work
// item copies VERTICES_PER_ITEM items, strided: item g copies g, g+G, ..
// with G the work items. generator/copy_kernel.h; docs/TUNING.md "Same-size copy".
#include "skin_params.h"  // WG_SIZE, VERTICES_PER_ITEM (the generator defines both)
layout(local_size_x = WG_SIZE) in;
layout(std430, binding = 0) readonly restrict buffer CopyIn { uvec4 copy_in[]; };
layout(std430, binding = 1) writeonly restrict buffer CopyOut { uvec4 out_positions[]; };
#ifdef VULKAN
// Vulkan (GL_KHR_vulkan_glsl predefines VULKAN): the scalars as skin_body.glsl has them.
layout(push_constant) uniform SkinScalars {
  uint n;
  uint first;
  uint vertex_count;
};
#else
uniform uint n;
uniform uint first;
#endif
void main() {
  uint g = gl_GlobalInvocationID.x, items = gl_NumWorkGroups.x * uint(WG_SIZE);
  for (uint k = 0u; k < uint(VERTICES_PER_ITEM); ++k) {
    uint i = g + k * items;
#ifdef SKINTUNE_FLUSH
    // The flush (generator/copy_kernel.h EmitFlush): every item read, none written.
    if (i < n) {
      uvec4 v = copy_in[i];
      if ((v.x & v.y & v.z & v.w) == 0xffffffffu) out_positions[first + i] = v;
    }
#else
    if (i < n) out_positions[first + i] = copy_in[i];
#endif
  }
}
