// One slice of the CPU kernel table: influence count CPU_KERNELS_B (1..8)
// compiled for instruction set CPU_KERNELS_ISA (a cpu_detail::CpuIsa), with
// that set's -march. cpu_kernels/CMakeLists.txt compiles this file once per
// pair; cpu_kernels.cpp assembles the tables from the slices.
#include "cpu_kernels/cpu_kernels.inc"

#if !defined(CPU_KERNELS_ISA) || !defined(CPU_KERNELS_B)
#error "cpu_kernels_slice.cpp is compiled with CPU_KERNELS_ISA and CPU_KERNELS_B defined"
#endif

namespace skintune::internal::cpu_detail {
template const CpuKernelSlice& CpuKernelSliceOf<CpuIsa::CPU_KERNELS_ISA, CPU_KERNELS_B>();
}  // namespace skintune::internal::cpu_detail
