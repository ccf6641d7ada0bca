// The generated fixture header seen from a second translation unit
// (embed_header_second_tu.cpp): the test compares its kernel table and
// FindKernel's answers with the first unit's.
#pragma once

#include <cstddef>

namespace fixture_kernels {
struct Kernel;
}

const fixture_kernels::Kernel* SecondUnitKernelTable();
const fixture_kernels::Kernel* SecondUnitFindKernel(const char* lang, int influences, std::size_t vertex_count,
                                                    int joint_count);
