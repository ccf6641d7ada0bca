#include "base/cache_eviction.h"

#include <algorithm>

#include "base/thread_pool.h"

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

std::vector<std::span<const std::uint8_t>> EvictionPieces(std::span<const std::span<const std::uint8_t>> buffers,
                                                          std::size_t piece) {
  std::vector<std::span<const std::uint8_t>> pieces;
  if (piece == 0) piece = kEvictionPieceBytes;
  for (const std::span<const std::uint8_t> b : buffers)
    for (std::size_t o = 0; o < b.size(); o += piece) pieces.push_back(b.subspan(o, std::min(piece, b.size() - o)));
  return pieces;
}

void EvictFromCaches(std::span<const std::span<const std::uint8_t>> buffers, ThreadPool& pool) {
  const std::vector<std::span<const std::uint8_t>> pieces = EvictionPieces(buffers, kEvictionPieceBytes);
  if (pieces.size() < 2 || pool.size() < 2) {
    EvictFromCaches(buffers);
    return;
  }
  // Each thread's flushes are waited for on that thread (the mfence of
  // EvictFromCaches); the loop's end, a locked operation, orders them before
  // the caller's next loads.
  pool.ParallelFor(pieces.size(), 1, [&](std::size_t begin, std::size_t end) {
    EvictFromCaches(std::span(pieces).subspan(begin, end - begin));
  });
}

}  // namespace skintune::internal
