// A C++17 program of two translation units that both include the generated
// fixture header (this one and embed_header_second_tu.cpp), built and run by
// embed_header_test.cpp's EmbedHeader.CompilesAsCxx17WithWarningsAsErrorsAndLinksTwoUnits.
// Exit code 0: one kernel table for the whole program.
#include "skintune_kernels.h"  // first: the header needs nothing before it

#include "embed_header_second_tu.h"

int main() {
  if (fixture_kernels::kKernelCount < 1) return 1;
  if (SecondUnitKernelTable() != fixture_kernels::kKernels) return 2;
  const fixture_kernels::Kernel* here = fixture_kernels::FindKernel("opencl", 4, 100000, 77);
  if (here == nullptr || SecondUnitFindKernel("opencl", 4, 100000, 77) != here) return 3;
  return 0;
}
