// Evicting a buffer's lines from every cache (base/cache_eviction.h): its
// pieces cover every byte once, and spread over a pool's threads the lines
// are gone (a chase through them then reads memory, not cache).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <numeric>
#include <random>
#include <span>
#include <vector>

#include "base/cache_eviction.h"
#include "base/thread_pool.h"

namespace skintune::internal {
namespace {

TEST(CacheEviction, PiecesCoverEveryByteOnceEachBuffersEndIncluded) {
  std::vector<std::uint8_t> a(1000), b(64), c(0), d(257);
  const std::vector<std::span<const std::uint8_t>> buffers = {a, b, c, d};
  const std::vector<std::span<const std::uint8_t>> pieces = EvictionPieces(buffers, 256);
  std::vector<int> seen_a(a.size()), seen_b(b.size()), seen_d(d.size());
  for (const std::span<const std::uint8_t> p : pieces) {
    EXPECT_LE(p.size(), 256u);
    EXPECT_GT(p.size(), 0u);
    for (const std::uint8_t& byte : p) {
      if (&byte >= a.data() && &byte < a.data() + a.size()) ++seen_a[&byte - a.data()];
      if (&byte >= b.data() && &byte < b.data() + b.size()) ++seen_b[&byte - b.data()];
      if (&byte >= d.data() && &byte < d.data() + d.size()) ++seen_d[&byte - d.data()];
    }
  }
  EXPECT_EQ(pieces.size(), 4u + 1u + 0u + 2u);  // 1000 = 3 x 256 + 232; 64; none; 257 = 256 + 1
  for (const std::vector<int>* seen : {&seen_a, &seen_b, &seen_d})
    EXPECT_TRUE(std::all_of(seen->begin(), seen->end(), [](int n) { return n == 1; }));
  EXPECT_EQ(pieces.back().data() + pieces.back().size(), d.data() + d.size());
}

// Nanoseconds a line to chase `order`'s lines of `buffer` (each line holds
// the index of the next), the quickest of `trials`, each after `before`.
template <typename Before>
double ChaseNs(std::vector<std::uint64_t>& buffer, const std::vector<std::size_t>& order, int trials, Before before) {
  constexpr std::size_t kWordsPerLine = 64 / sizeof(std::uint64_t);
  for (std::size_t i = 0; i < order.size(); ++i)
    buffer[order[i] * kWordsPerLine] = order[(i + 1) % order.size()];
  double best = 1e30;
  for (int t = 0; t < trials; ++t) {
    before();
    const auto start = std::chrono::steady_clock::now();
    std::uint64_t at = order.front();
    for (std::size_t i = 0; i < order.size(); ++i) at = buffer[at * kWordsPerLine];
    const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(at, order.front());
    best = std::min(best, ns / static_cast<double>(order.size()));
  }
  return best;
}

TEST(CacheEviction, LinesEvictedOnAPoolsThreadsAreReadFromMemory) {
  // 4 MiB (16 pieces), 4096 of its lines in a random order: warm, they sit
  // in the caches the chase just filled; evicted, each read waits for memory.
  std::vector<std::uint64_t> buffer((std::size_t{4} << 20) / sizeof(std::uint64_t));
  const std::size_t lines = buffer.size() * sizeof(std::uint64_t) / 64;
  std::vector<std::size_t> order(lines);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937_64(7));
  order.resize(4096);
  ThreadPool pool(4);
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(buffer.data()),
                                            buffer.size() * sizeof(std::uint64_t));
  const double warm = ChaseNs(buffer, order, 5, [] {});
  const double evicted = ChaseNs(buffer, order, 5, [&] { EvictFromCaches({&bytes, 1}, pool); });
  EXPECT_GT(evicted, 1.5 * warm) << "warm " << warm << " ns a line, evicted " << evicted;
}

}  // namespace
}  // namespace skintune::internal
