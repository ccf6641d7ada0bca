// Kernel-time batches at the GPU's clock under load (tuner/clock_guard.h),
// against a GPU model whose clock falls while it idles and rises under load.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "tuner/clock_guard.h"

namespace skintune::internal::tuner_internal {
namespace {

// The GPU: its SM clock now, its boost clock, what each batch does to it.
struct Gpu {
  unsigned mhz = 1980, boost = 1980, cap = 1980;  // cap: the most it reaches under load
  std::vector<unsigned> fall_during_batch;        // the clock after each batch, in turn (none: unchanged)
  int batches = 0, warm_rounds = 0;
};

class ModelClock final : public DeviceClock {
 public:
  explicit ModelClock(Gpu& gpu) : gpu_(gpu) {}
  std::optional<unsigned> SmMhz() override { return gpu_.mhz; }
  std::optional<unsigned> MaxSmMhz() override { return gpu_.boost; }

 private:
  Gpu& gpu_;
};

struct Harness {
  Gpu gpu;
  ClockGuard guard{nullptr};
  explicit Harness(Gpu g) : gpu(g), guard(std::make_unique<ModelClock>(gpu)) {}
  // A batch's samples are its time at the clock it ran at: 10 us at 1980 MHz.
  ClockGuard::Batch Take() {
    return guard.Take(
        [this] {
          const double us = 10.0 * 1980.0 / gpu.mhz;
          const std::size_t b = static_cast<std::size_t>(gpu.batches++);
          if (b < gpu.fall_during_batch.size()) gpu.mhz = gpu.fall_during_batch[b];
          return std::vector<double>(10, us);
        },
        [this] {
          ++gpu.warm_rounds;
          gpu.mhz = std::min(gpu.cap, gpu.mhz + 300);
        },
        "test");
  }
};

TEST(ClockGuard, ABatchAtTheBoostClockIsTakenOnceAndItsClockRecorded) {
  Harness h(Gpu{});
  const ClockGuard::Batch b = h.Take();
  EXPECT_EQ(b.retakes, 0);
  EXPECT_EQ(b.mhz, 1980u);
  EXPECT_EQ(h.gpu.warm_rounds, 0);
  EXPECT_DOUBLE_EQ(b.samples.front(), 10.0);
}

TEST(ClockGuard, AnIdleClockIsWarmedBackBeforeTheBatch) {
  Gpu gpu;
  gpu.mhz = 630;  // idled down, as NVIDIA's Vulkan and GL turns on the H200
  Harness h(gpu);
  const ClockGuard::Batch b = h.Take();
  EXPECT_EQ(h.gpu.warm_rounds, 5) << "630 -> 1980 in steps of 300";
  EXPECT_EQ(b.mhz, 1980u);
  EXPECT_DOUBLE_EQ(b.samples.front(), 10.0) << "the batch ran at the boost clock";
}

TEST(ClockGuard, ABatchDuringWhichTheClockFellIsTakenAgain) {
  Gpu gpu;
  gpu.fall_during_batch = {1110};  // the first batch ends at 1110 MHz
  Harness h(gpu);
  const ClockGuard::Batch b = h.Take();
  EXPECT_EQ(b.retakes, 1);
  EXPECT_EQ(h.gpu.batches, 2);
  EXPECT_GT(h.gpu.warm_rounds, 0) << "warmed before the second batch";
  EXPECT_EQ(b.mhz, 1980u);
}

TEST(ClockGuard, AClockWithinTheToleranceIsAtSpeed) {
  Gpu gpu;
  gpu.mhz = 1935;  // 2.3% below 1980: within kClockTolerance
  gpu.fall_during_batch = {1925};
  Harness h(gpu);
  const ClockGuard::Batch b = h.Take();
  EXPECT_EQ(b.retakes, 0);
  EXPECT_EQ(h.gpu.warm_rounds, 0);
  EXPECT_EQ(b.mhz, 1925u) << "the lower of the two readings";
}

TEST(ClockGuard, AfterKClockRetakesTheLastBatchIsKeptWithItsClock) {
  Gpu gpu;
  gpu.fall_during_batch = {900, 900, 900, 900, 900};
  Harness h(gpu);
  const ClockGuard::Batch b = h.Take();
  EXPECT_EQ(b.retakes, kClockRetakes);
  EXPECT_EQ(h.gpu.batches, kClockRetakes + 1);
  EXPECT_EQ(b.mhz, 900u);
}

TEST(ClockGuard, AGpuThatCannotReachItsBoostUnderLoadBecomesTheReferenceAfterTheCap) {
  Gpu gpu;
  gpu.mhz = 1200;
  gpu.cap = 1755;  // power-limited: under load it runs at 1755 at most
  Harness h(gpu);
  const ClockGuard::Batch b = h.Take();
  EXPECT_EQ(b.mhz, 1755u);
  EXPECT_EQ(h.guard.reference_mhz(), 1755u);
  EXPECT_EQ(b.retakes, 0) << "the batch at the new reference is at speed";
  const int rounds = h.gpu.warm_rounds;
  (void)h.Take();
  EXPECT_EQ(h.gpu.warm_rounds, rounds) << "the next batch is not warmed again for a second";
}

TEST(ClockGuard, AClockHigherThanTheBoostRaisesTheReference) {
  Gpu gpu;
  gpu.boost = 1800;  // the driver's boost figure is below what the GPU reads
  gpu.mhz = 1980;
  Harness h(gpu);
  (void)h.Take();
  EXPECT_EQ(h.guard.reference_mhz(), 1980u);
  h.gpu.mhz = 1800;  // 9% below: not at speed any more
  const ClockGuard::Batch b = h.Take();
  EXPECT_GT(h.gpu.warm_rounds, 0);
  EXPECT_EQ(b.mhz, 1980u);
}

TEST(ClockGuard, WithoutAClockReaderOnlyTheBatchRuns) {
  ClockGuard guard(nullptr);
  int warmed = 0;
  const ClockGuard::Batch b = guard.Take([] { return std::vector<double>{1.0, 2.0}; }, [&] { ++warmed; }, "test");
  EXPECT_FALSE(guard.active());
  EXPECT_EQ(b.samples.size(), 2u);
  EXPECT_EQ(b.mhz, 0u);
  EXPECT_EQ(warmed, 0);
}

}  // namespace
}  // namespace skintune::internal::tuner_internal
