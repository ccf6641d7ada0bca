#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "base/thread_pool.h"

namespace skintune::internal {
namespace {

// Sleeping workers, and workers that poll for the next loop (the runtime's pool).
class ThreadPoolSpin : public ::testing::TestWithParam<int> {};

TEST_P(ThreadPoolSpin, ParallelForVisitsEveryIndexExactlyOnce) {
  ThreadPool pool(4, std::chrono::microseconds(GetParam()));
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

TEST_P(ThreadPoolSpin, RunsManyLoopsBackToBack) {
  ThreadPool pool(3, std::chrono::microseconds(GetParam()));
  std::atomic<long> sum{0};
  for (int loop = 0; loop < 500; ++loop) {
    pool.ParallelFor(100, 7, [&](std::size_t b, std::size_t e) { sum += long(e - b); });
  }
  EXPECT_EQ(sum.load(), 500 * 100);
}

// Many short loops, each of a different chunk count, back to back: a worker
// still busy with (or just done with) one loop never claims a chunk of the
// next one as if it were its own, and none is skipped or run twice.
TEST_P(ThreadPoolSpin, ShortLoopsOfEveryChunkCountRunEachChunkOnce) {
  ThreadPool pool(5, std::chrono::microseconds(GetParam()));
  std::vector<std::atomic<int>> hits(40);
  for (int loop = 0; loop < 4000; ++loop) {
    const std::size_t count = 1 + static_cast<std::size_t>(loop * 7 % 40);
    for (auto& h : hits) h.store(0, std::memory_order_relaxed);
    pool.ParallelFor(count, 1 + loop % 3, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) hits[i].fetch_add(1, std::memory_order_relaxed);
    });
    for (std::size_t i = 0; i < hits.size(); ++i)
      ASSERT_EQ(hits[i].load(), i < count ? 1 : 0) << "loop " << loop << ", index " << i;
  }
}

// A loop started after the workers went back to sleep (past their spin) still
// reaches them: every chunk runs, some on a thread other than the caller's.
TEST_P(ThreadPoolSpin, WakesWorkersThatStoppedSpinning) {
  ThreadPool pool(4, std::chrono::microseconds(GetParam()));
  for (int loop = 0; loop < 3; ++loop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    std::atomic<int> chunks{0};
    pool.ParallelFor(64, 1, [&](std::size_t, std::size_t) {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      ++chunks;
    });
    EXPECT_EQ(chunks.load(), 64);
  }
}

// Ready (every worker woken, each holding a chunk until all do) returns,
// whether the workers slept or polled, for pools of every size, and leaves
// the pool's loops as they were.
TEST_P(ThreadPoolSpin, ReadyReturnsOnceEveryThreadRunsAndLoopsFollowIt) {
  for (const unsigned threads : {1u, 2u, 3u, 8u}) {
    ThreadPool pool(threads, std::chrono::microseconds(GetParam()));
    std::atomic<long> sum{0};
    for (int loop = 0; loop < 100; ++loop) {
      if (loop % 25 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(3));  // past any spin: asleep
      pool.Ready();
      pool.ParallelFor(40, 3, [&](std::size_t b, std::size_t e) { sum += long(e - b); });
    }
    EXPECT_EQ(sum.load(), 100 * 40) << threads << " threads";
  }
}

INSTANTIATE_TEST_SUITE_P(SleepOrSpin, ThreadPoolSpin, ::testing::Values(0, 50, 2000),
                         [](const ::testing::TestParamInfo<int>& p) { return "spin" + std::to_string(p.param) + "us"; });

}  // namespace
}  // namespace skintune::internal
