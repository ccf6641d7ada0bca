// The CPU kernel table compiled for one instruction set (its -march in
// reference/CMakeLists.txt); cpu_kernels.cpp picks the table this CPU runs.
#define CPU_KERNELS_TABLE CpuKernelsBaseline
#include "reference/cpu_kernels.inc"
