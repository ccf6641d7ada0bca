// skintune: the copy kernel every measurement is judged against (OpenCL C 1.2).
// It moves n 16-byte items from copy_in to out_positions (at first + i): the
// bytes of a frame, read once and written once, nothing else done. Each work
// item copies VERTICES_PER_ITEM items, strided: item g copies g, g+G, ..
// with G the work items. generator/copy_kernel.h; docs/TUNING.md "Same-size copy".
#include "skin_params.h"  // WG_SIZE, VERTICES_PER_ITEM (the generator defines both)
__kernel __attribute__((reqd_work_group_size(WG_SIZE, 1, 1)))
void skintune_copy(const uint n, const uint first, __global const uint4* restrict copy_in,
                   __global uint4* restrict out_positions) {
  const uint g = (uint)get_global_id(0), items = (uint)get_global_size(0);
  for (uint k = 0; k < VERTICES_PER_ITEM; ++k) {
    const uint i = g + k * items;
#ifdef SKINTUNE_FLUSH
    // The flush (generator/copy_kernel.h EmitFlush): every item read, none written.
    if (i < n) {
      const uint4 v = copy_in[i];
      if ((v.x & v.y & v.z & v.w) == 0xffffffffu) out_positions[first + i] = v;
    }
#else
    if (i < n) out_positions[first + i] = copy_in[i];
#endif
  }
}
