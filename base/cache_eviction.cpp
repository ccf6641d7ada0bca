#include "base/cache_eviction.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define SKINTUNE_X86 1
#endif

namespace skintune::internal {

namespace {

#if SKINTUNE_X86
constexpr std::size_t kLine = 64;

// Each line of `bytes`, and the last (a buffer's end need not be line-aligned).
template <typename Flush>
void EachLine(std::span<const std::uint8_t> bytes, Flush flush) {
  for (std::size_t o = 0; o < bytes.size(); o += kLine) flush(bytes.data() + o);
  flush(bytes.data() + bytes.size() - 1);
}

__attribute__((target("clflushopt"))) void EvictByClflushopt(std::span<const std::uint8_t> bytes) {
  EachLine(bytes, [](const std::uint8_t* p) __attribute__((target("clflushopt"))) {
    _mm_clflushopt(const_cast<std::uint8_t*>(p));
  });
}
#endif

}  // namespace

void EvictFromCaches(std::span<const std::span<const std::uint8_t>> buffers) {
#if SKINTUNE_X86
  static const bool opt = __builtin_cpu_supports("clflushopt");
  for (const std::span<const std::uint8_t> b : buffers) {
    if (b.empty()) continue;
    if (opt) {
      EvictByClflushopt(b);
    } else {
      EachLine(b, [](const std::uint8_t* p) { _mm_clflush(p); });
    }
  }
  _mm_mfence();  // orders the flushes before later loads
#else
  (void)buffers;
#endif
}

}  // namespace skintune::internal
