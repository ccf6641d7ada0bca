// skintune: the copy kernel every measurement is judged against (CUDA C++ for
// NVRTC).
// It moves n 16-byte items from copy_in to out_positions (at first + i): the
// bytes of a frame, read once and written once, nothing else done. Each work
// item copies VERTICES_PER_ITEM items, strided: item g copies g, g+G, ..
// with G the work items. generator/copy_kernel.h; docs/TUNING.md "Same-size copy".
#include "skin_params.h"  // WG_SIZE, VERTICES_PER_ITEM (the generator defines both)
extern "C" __global__ void __launch_bounds__(WG_SIZE)
skintune_copy(unsigned n, unsigned first, const uint4* __restrict__ copy_in, uint4* __restrict__ out_positions) {
  const unsigned g = blockIdx.x * WG_SIZE + threadIdx.x, items = gridDim.x * WG_SIZE;
  for (unsigned k = 0; k < VERTICES_PER_ITEM; ++k) {
    const unsigned i = g + k * items;
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
