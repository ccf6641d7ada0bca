// skintune (internal): the layout of the CPU kernel table (cpu_kernels.h),
// shared by the slices of cpu_kernels.inc and cpu_kernels.cpp, which
// assembles one table per instruction set from its 8 slices.
// Slot = (((B - 1) x 3 + index) x 3 + weight) x 5 + form, where the form is
// the palette and blend: 0 mat4 matrix, 1 mat4 point, 2 mat3x4 matrix,
// 3 mat3x4 point, 4 dualquat dq. Dual quaternions exist with 2 rows only, so
// they are one form, not a third blend of every palette (which would compile
// 4 kernels per (B, index, weight) that no key reaches).
#pragma once

#include <array>
#include <cstddef>

#include "cpu_kernels/cpu_kernels.h"

namespace skintune::internal::cpu_detail {

inline constexpr std::size_t kIndexFormats = 3;
inline constexpr std::size_t kWeightFormats = 3;
inline constexpr std::size_t kPaletteForms = 5;  // (rows, blend): see the slot above
inline constexpr std::size_t kDualQuaternionForm = 4;
inline constexpr std::size_t kCpuKernelCount = kCpuMaxInfluences * kIndexFormats * kWeightFormats * kPaletteForms;
using CpuKernelTable = std::array<CpuKernelFn, kCpuKernelCount>;

// The slot of a key the table holds (FindCpuKernel checks it first).
constexpr std::size_t SlotOf(const CpuKernelKey& k) {
  std::size_t slot = static_cast<std::size_t>(k.influences - 1);
  slot = slot * kIndexFormats + static_cast<std::size_t>(k.index);
  slot = slot * kWeightFormats + static_cast<std::size_t>(k.weight);
  const std::size_t form =
      k.dual_quaternion ? kDualQuaternionForm : (k.palette_rows == 3 ? 2 : 0) + (k.point_blend ? 1 : 0);
  return slot * kPaletteForms + form;
}
constexpr CpuKernelKey KeyOfSlot(std::size_t slot) {
  CpuKernelKey key;
  const std::size_t form = slot % kPaletteForms;
  key.dual_quaternion = form == kDualQuaternionForm;
  key.palette_rows = key.dual_quaternion ? 2 : form >= 2 ? 3 : 4;
  key.point_blend = !key.dual_quaternion && form % 2 == 1;
  slot /= kPaletteForms;
  key.weight = static_cast<CpuWeight>(slot % kWeightFormats);
  slot /= kWeightFormats;
  key.index = static_cast<CpuIndex>(slot % kIndexFormats);
  key.influences = static_cast<int>(slot / kIndexFormats) + 1;
  return key;
}

// The instruction sets a table is compiled for (cpu_kernels/CMakeLists.txt
// gives each its -march; elsewhere than x86-64 all three are the baseline).
enum class CpuIsa { kAvx512, kAvx2, kBaseline };

// One slice of a table: the slots of one influence count B, in table order
// (slot SlotOf(key) of the table is slot SlotOf(key) - (B - 1) x
// kSlotsPerInfluenceCount of B's slice).
inline constexpr std::size_t kSlotsPerInfluenceCount = kIndexFormats * kWeightFormats * kPaletteForms;
static_assert(kCpuKernelCount == kCpuMaxInfluences * kSlotsPerInfluenceCount);
using CpuKernelSlice = std::array<CpuKernelFn, kSlotsPerInfluenceCount>;

// The slice of instruction set kIsa and influence count kB (1..8), defined in
// cpu_kernels.inc and instantiated once per (kIsa, kB) by cpu_kernels_slice.cpp,
// compiled 24 times with that ISA's -march: 24 small objects that build in
// parallel, where one table per ISA was one object of 70-120 s at -O3 that
// the rest of the build waited for (2-core development machine, 2026-11).
template <CpuIsa kIsa, int kB>
const CpuKernelSlice& CpuKernelSliceOf();

}  // namespace skintune::internal::cpu_detail
