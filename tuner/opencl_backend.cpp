// skintune: the OpenCL backend: one per OpenCL device (every platform, every
// device type), measuring `opencl` variants through OpenClRunner.
#include <memory>

#include "runtime/backends/opencl/opencl_devices.h"
#include "runtime/backends/opencl/opencl_runner.h"
#include "tuner/backends_internal.h"

namespace skintune::tuner_internal {

namespace {

class OpenClBackend final : public Backend {
 public:
  OpenClBackend(const OpenClDeviceInfo& device, int index) : device_(device) {
    identity_.backend = "opencl";
    identity_.index = index;
    identity_.platform = device.platform_name;
    identity_.vendor = device.vendor;
    identity_.name = device.name;
    identity_.driver_version = device.driver_version;
    identity_.api_version = device.device_version;
    identity_.type = device.type;
    identity_.compute_units = device.compute_units;
    identity_.global_memory_bytes = device.global_memory_bytes;
    identity_.local_memory_bytes = device.local_memory_bytes;
    identity_.constant_memory_bytes = device.constant_buffer_bytes;
    identity_.last_level_cache_bytes = device.global_cache_bytes;  // CL_DEVICE_GLOBAL_MEM_CACHE_SIZE
  }

  const DeviceIdentity& identity() const override { return identity_; }
  DeviceLimits limits() const override { return LimitsOf(device_); }
  std::vector<Lang> languages() const override { return {Lang::kOpenCl}; }

  Measurement Measure(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options) override {
    RunnerExecutor<OpenClRunner> executor{Runner()};
    return MeasureWith(executor, datasets_, identity_, limits(), languages(), variant, dataset, options);
  }

  double CopyBandwidthGBps(std::size_t bytes) override {
    const std::size_t size = CopyBytesCapped(bytes, device_.max_allocation_bytes);
    return CopyGBps(size, Runner().TimeCopy(size, 2, 10));
  }

 private:
  OpenClRunner& Runner() {
    if (!runner_) runner_ = std::make_unique<OpenClRunner>(device_.platform_index, device_.device_index);
    return *runner_;
  }

  OpenClDeviceInfo device_;
  DeviceIdentity identity_;
  std::unique_ptr<OpenClRunner> runner_;  // made on first use
  DatasetCache datasets_;
};

}  // namespace

std::unique_ptr<Backend> MakeOpenClBackend(const OpenClDeviceInfo& device, int index) {
  return std::make_unique<OpenClBackend>(device, index);
}

}  // namespace skintune::tuner_internal
