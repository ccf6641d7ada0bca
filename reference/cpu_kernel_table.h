// skintune (internal): the layout of the CPU kernel table (cpu_kernels.h),
// shared by the three ISA builds of cpu_kernels.inc and cpu_kernels.cpp.
// Slot = (((B - 1) x 3 + index) x 3 + weight) x 2 + (rows == 3)) x 2 + point_blend.
#pragma once

#include <array>
#include <cstddef>

#include "reference/cpu_kernels.h"

namespace skintune::internal::cpu_detail {

inline constexpr std::size_t kIndexFormats = 3;
inline constexpr std::size_t kWeightFormats = 3;
inline constexpr std::size_t kRowChoices = 2;
inline constexpr std::size_t kBlendChoices = 2;
inline constexpr std::size_t kCpuKernelCount =
    kCpuMaxInfluences * kIndexFormats * kWeightFormats * kRowChoices * kBlendChoices;
using CpuKernelTable = std::array<CpuKernelFn, kCpuKernelCount>;

constexpr std::size_t SlotOf(const CpuKernelKey& k) {
  std::size_t slot = static_cast<std::size_t>(k.influences - 1);
  slot = slot * kIndexFormats + static_cast<std::size_t>(k.index);
  slot = slot * kWeightFormats + static_cast<std::size_t>(k.weight);
  slot = slot * kRowChoices + (k.palette_rows == 3 ? 1 : 0);
  return slot * kBlendChoices + (k.point_blend ? 1 : 0);
}
constexpr CpuKernelKey KeyOfSlot(std::size_t slot) {
  CpuKernelKey key;
  key.point_blend = slot % kBlendChoices == 1;
  slot /= kBlendChoices;
  key.palette_rows = slot % kRowChoices == 1 ? 3 : 4;
  slot /= kRowChoices;
  key.weight = static_cast<CpuWeight>(slot % kWeightFormats);
  slot /= kWeightFormats;
  key.index = static_cast<CpuIndex>(slot % kIndexFormats);
  key.influences = static_cast<int>(slot / kIndexFormats) + 1;
  return key;
}

// One table per instruction set (cpu_kernels_<isa>.cpp).
const CpuKernelTable& CpuKernelsAvx512();
const CpuKernelTable& CpuKernelsAvx2();
const CpuKernelTable& CpuKernelsBaseline();

}  // namespace skintune::internal::cpu_detail
