// skintune: the CUDA backend: one per CUDA device (driver API + NVRTC loaded
// at run time), measuring `cuda` variants through CudaRunner.
#include <memory>

#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/cuda/cuda_runner.h"
#include "runtime/device_identity.h"
#include "tuner/backends_internal.h"

namespace skintune::tuner_internal {

namespace {

class CudaBackend final : public Backend {
 public:
  CudaBackend(const CudaDeviceInfo& device, int index) : device_(device) {
    identity_.backend = "cuda";
    identity_.index = index;
    identity_.platform = "CUDA";
    identity_.vendor = "NVIDIA";
    identity_.name = device.name;
    identity_.driver_version = CudaDriverVersionText(device.driver_version);
    identity_.api_version = std::to_string(device.major) + "." + std::to_string(device.minor);
    identity_.type = "gpu";
    identity_.compute_units = static_cast<std::uint32_t>(device.multiprocessors);
    identity_.global_memory_bytes = device.total_memory_bytes;
    identity_.local_memory_bytes = device.limits.local_memory_bytes;
    identity_.constant_memory_bytes = device.limits.constant_memory_bytes;
    identity_.last_level_cache_bytes = device.l2_cache_bytes;  // CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE
  }

  const DeviceIdentity& identity() const override { return identity_; }
  // CudaRunner::limits() comes from the same query (QueryCudaDevice).
  DeviceLimits limits() const override { return runner_ ? runner_->limits() : device_.limits; }
  std::vector<Lang> languages() const override { return {Lang::kCuda}; }

  Measurement Measure(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options) override {
    RunnerExecutor<CudaRunner> executor{Runner()};
    return MeasureWith(executor, datasets_, identity_, limits(), languages(), variant, dataset, options);
  }

  double CopyBandwidthGBps(std::size_t bytes) override {
    // No maximum allocation query in CUDA: the device's memory stands for it.
    const std::size_t size = CopyBytesCapped(bytes, device_.total_memory_bytes);
    return CopyGBps(size, Runner().TimeCopy(size, 2, 10));
  }

 private:
  CudaRunner& Runner() {
    if (!runner_) runner_ = std::make_unique<CudaRunner>(device_.index);
    return *runner_;
  }

  CudaDeviceInfo device_;
  DeviceIdentity identity_;
  std::unique_ptr<CudaRunner> runner_;  // made on first use (retains the primary context)
  DatasetCache datasets_;
};

}  // namespace

std::unique_ptr<Backend> MakeCudaBackend(int cuda_device, int index) {
  return std::make_unique<CudaBackend>(QueryCudaDevice(cuda_device), index);
}

}  // namespace skintune::tuner_internal
