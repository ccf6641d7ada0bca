// The generated fixture header in a second translation unit of
// emit_embed_header_test, compiled with -Wpedantic -Wshadow -Wconversion
// -Wsign-conversion -Werror (tests/tools/emit/CMakeLists.txt); the C++17 test in
// embed_header_test.cpp links it with embed_header_main17.cpp.
#include "skintune_kernels.h"  // first: the header needs nothing before it

#include "embed_header_second_tu.h"

const fixture_kernels::Kernel* SecondUnitKernelTable() { return fixture_kernels::kKernels; }

const fixture_kernels::Kernel* SecondUnitFindKernel(const char* lang, int influences, std::size_t vertex_count,
                                                    int joint_count) {
  return fixture_kernels::FindKernel(lang, influences, vertex_count, joint_count);
}
