// skintune: kernel-time batches at the GPU's clock under load (tuner/clock_guard.h).
#include "tuner/clock_guard.h"

#include <algorithm>
#include <chrono>

#include "runtime/runner.h"  // TimingLog

namespace skintune::internal::tuner_internal {

ClockGuard::ClockGuard(std::unique_ptr<DeviceClock> clock) : clock_(std::move(clock)) {
  if (clock_) reference_ = clock_->MaxSmMhz().value_or(0);
}

unsigned ClockGuard::Read() {
  const unsigned mhz = clock_->SmMhz().value_or(0);
  reference_ = std::max(reference_, mhz);
  return mhz;
}

bool ClockGuard::AtSpeed(unsigned mhz) const {
  return mhz == 0 || static_cast<double>(mhz) >= (1.0 - kClockTolerance) * static_cast<double>(reference_);
}

unsigned ClockGuard::WarmUp(const std::function<void()>& warm, const std::string& what) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const unsigned from = Read();
  unsigned mhz = from;
  int rounds = 0;
  double ms = 0.0;
  while (!AtSpeed(mhz) && ms < kClockWarmCapMs) {
    warm();
    ++rounds;
    mhz = Read();
    ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  }
  const bool capped = !AtSpeed(mhz);
  if (capped) reference_ = mhz;  // as fast as it runs now, after a second under load
  TimingLog([&] {
    return what + " clock warm-up: " + std::to_string(from) + " -> " + std::to_string(mhz) + " MHz in " +
           std::to_string(ms) + " ms, " + std::to_string(rounds) + " rounds" +
           (capped ? "; capped, the reference is now " + std::to_string(reference_) + " MHz" : "");
  });
  return mhz;
}

ClockGuard::Batch ClockGuard::Take(const std::function<std::vector<double>()>& take, const std::function<void()>& warm,
                                   const std::string& what) {
  Batch batch;
  if (!clock_) {
    batch.samples = take();
    return batch;
  }
  for (;;) {
    unsigned before = Read();
    if (!AtSpeed(before)) before = WarmUp(warm, what);
    batch.samples = take();
    const unsigned after = Read();
    batch.mhz = before == 0 || after == 0 ? std::max(before, after) : std::min(before, after);
    if (AtSpeed(batch.mhz) || batch.retakes == kClockRetakes) return batch;
    ++batch.retakes;
    TimingLog([&] {
      return what + " clock fell during a batch: " + std::to_string(before) + " -> " + std::to_string(after) +
             " MHz (reference " + std::to_string(reference_) + "); taken again";
    });
  }
}

}  // namespace skintune::internal::tuner_internal
