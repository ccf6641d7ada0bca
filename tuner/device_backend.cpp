// skintune: the tuner's Backend on any device of any API: identity, limits
// and languages from the runtime's discovery (runtime/backend_table.h),
// Measure and the copy bandwidth through the runner driver (runtime/runner.h).
#include <memory>
#include <utility>

#include "tuner/backends_internal.h"

namespace skintune::tuner_internal {

namespace {

class DeviceBackend final : public Backend {
 public:
  DeviceBackend(FoundDevice device, std::vector<Lang> languages, int index)
      : device_(std::move(device)), languages_(std::move(languages)) {
    device_.identity.index = index;
  }

  const DeviceIdentity& identity() const override { return device_.identity; }
  DeviceLimits limits() const override { return device_.limits; }
  std::vector<Lang> languages() const override { return languages_; }

  Measurement Measure(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options) override {
    return MeasureWith(Executor(), datasets_, device_.identity, limits(), languages(), variant, dataset, options);
  }

  double CopyBandwidthGBps(std::size_t bytes) override {
    const std::size_t size = CopyBytesCapped(bytes, device_.max_allocation_bytes);
    // One set (a copy this large is far beyond any cache), bursts of a few frames.
    return CopyGBps(size, Executor().TimeCopy(languages_.front(), 2 * size, 1, 2, 10, 4));
  }

 private:
  RunnerExecutor& Executor() {
    if (!runner_) {
      runner_ = device_.open();
      executor_ = std::make_unique<RunnerExecutor>(*runner_);
    }
    return *executor_;
  }

  FoundDevice device_;
  std::vector<Lang> languages_;
  std::unique_ptr<skintune::Runner> runner_;  // made on first use
  std::unique_ptr<RunnerExecutor> executor_;  // over runner_: remembers the copies it timed
  DatasetCache datasets_;
};

}  // namespace

std::unique_ptr<Backend> MakeDeviceBackend(FoundDevice device, std::vector<Lang> languages, int index) {
  return std::make_unique<DeviceBackend>(std::move(device), std::move(languages), index);
}

}  // namespace skintune::tuner_internal
