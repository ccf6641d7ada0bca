#include <gtest/gtest.h>

#include <atomic>
#include <vector>

#include "reference/thread_pool.h"

namespace skintune::internal {
namespace {

TEST(ThreadPool, ParallelForVisitsEveryIndexExactlyOnce) {
  ThreadPool pool(4);
  for (std::size_t count : {0u, 1u, 7u, 1000u, 100003u}) {
    for (std::size_t grain : {1u, 64u, 5000u}) {
      std::vector<std::atomic<int>> hits(count);
      pool.ParallelFor(count, grain, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) hits[i]++;
      });
      for (std::size_t i = 0; i < count; ++i) ASSERT_EQ(hits[i].load(), 1) << count << "/" << grain << " at " << i;
    }
  }
}

TEST(ThreadPool, RunsManyLoopsBackToBack) {
  ThreadPool pool(3);
  std::atomic<long> sum{0};
  for (int loop = 0; loop < 500; ++loop) {
    pool.ParallelFor(100, 7, [&](std::size_t b, std::size_t e) { sum += long(e - b); });
  }
  EXPECT_EQ(sum.load(), 500 * 100);
}

}  // namespace
}  // namespace skintune::internal
