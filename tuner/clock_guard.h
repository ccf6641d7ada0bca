// skintune (internal to tuner/): kernel-time samples taken only at the SM
// clock a GPU runs at under load (docs/TUNING.md "Kernel time", the clock).
//
// The driver lowers an idle GPU's clock within milliseconds, and a kernel
// of 5k-100k vertices, mostly latency, takes as much longer: on the H200
// machine (2026-11-29) the GL and Vulkan workers' batches ran at 630-1500
// MHz instead of 1980 in parts of their turns, and winners' kernel times
// moved up to 47% between cold runs (runtime/device_clock.h). Where the
// driver tells the clock (DeviceClock), every batch of samples is taken
// between two readings of it:
// - before the batch, a clock below kClockTolerance of the reference (the
//   highest clock read, at first the GPU's boost clock) is raised by warm
//   frames (untimed cold frames of the variant itself) until it is back, at
//   most kClockWarmCapMs; a GPU that stays below after that long under load
//   runs as fast as it can now (power or heat), and its clock becomes the
//   reference;
// - after it, a clock that fell below the tolerance means the batch ran
//   slower than the GPU can: it is dropped and taken again, at most
//   kClockRetakes times, and then kept.
// The lowest clock read around the batches kept is recorded with the
// measurement (timing.sm_clock_mhz). Without a reader nothing changes.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "runtime/device_clock.h"

namespace skintune::internal::tuner_internal {

inline constexpr double kClockTolerance = 0.03;
inline constexpr double kClockWarmCapMs = 1000.0;
inline constexpr int kClockRetakes = 3;
// Untimed cold frames per warm round: each reads the flush (twice the
// last-level cache), so 64 of them keep an H200 busy about 2 ms.
inline constexpr int kClockWarmFrames = 64;

class ClockGuard {
 public:
  // `clock` may be null: Take then only runs `take`.
  explicit ClockGuard(std::unique_ptr<DeviceClock> clock);

  struct Batch {
    std::vector<double> samples;
    unsigned mhz = 0;  // the lower reading around the batch kept; 0: not read
    int retakes = 0;   // batches dropped for a fallen clock
  };
  // One batch of samples by `take`, at the GPU's clock under load; `warm`
  // keeps the GPU busy a few milliseconds (untimed frames); `what` names
  // the batch in the timing log (SKINTUNE_TIMING_LOG).
  Batch Take(const std::function<std::vector<double>()>& take, const std::function<void()>& warm,
             const std::string& what);

  bool active() const { return clock_ != nullptr; }
  unsigned reference_mhz() const { return reference_; }

 private:
  unsigned Read();  // the clock now (0: no answer), raising the reference
  bool AtSpeed(unsigned mhz) const;
  unsigned WarmUp(const std::function<void()>& warm, const std::string& what);

  std::unique_ptr<DeviceClock> clock_;
  unsigned reference_ = 0;
};

}  // namespace skintune::internal::tuner_internal
