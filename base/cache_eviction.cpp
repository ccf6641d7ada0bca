#include "base/cache_eviction.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define SKINTUNE_X86 1
#endif

namespace skintune::internal {

namespace {

constexpr std::size_t kLine = 64;

#if SKINTUNE_X86
__attribute__((target("clflushopt"))) void EvictByClflushopt(std::span<const std::uint8_t> bytes) {
  for (std::size_t o = 0; o < bytes.size(); o += kLine) _mm_clflushopt(const_cast<std::uint8_t*>(bytes.data() + o));
}
#endif

void Evict(std::span<const std::uint8_t> bytes) {
  if (bytes.empty()) return;
#if SKINTUNE_X86
  static const bool opt = __builtin_cpu_supports("clflushopt");
  if (opt) {
    EvictByClflushopt(bytes);
    // The last partial line (a buffer's end need not be line-aligned).
    _mm_clflush(bytes.data() + bytes.size() - 1);
  } else {
    for (std::size_t o = 0; o < bytes.size(); o += kLine) _mm_clflush(bytes.data() + o);
    _mm_clflush(bytes.data() + bytes.size() - 1);
  }
#endif
}

void Fence() {
#if SKINTUNE_X86
  _mm_mfence();  // orders clflushopt before later loads
#endif
}

}  // namespace

void EvictFromCaches(std::span<const std::uint8_t> bytes) {
  Evict(bytes);
  Fence();
}

void EvictFromCaches(std::span<const std::span<const std::uint8_t>> buffers) {
  for (const std::span<const std::uint8_t> b : buffers) Evict(b);
  Fence();
}

}  // namespace skintune::internal
