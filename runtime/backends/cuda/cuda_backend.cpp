// CUDA in the backend table (runtime/backend_table.h): every device the
// driver offers (none, with the reason, without a driver or NVRTC),
// OpenBest's rank, and Device::FromCuda on the caller's context and stream.
#include <memory>

#include "runtime/api_errors.h"
#include "runtime/backend_table.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/cuda/cuda_devices.h"
#include "runtime/backends/cuda/cuda_runner.h"
#include "runtime/device.h"
#include "runtime/skinner.h"

namespace skintune::internal {

namespace {

void Discover(Discovered& out) {
  const CudaAvailability cuda = Probe();
  if (!cuda.CanRun()) {
    out.skipped.push_back("cuda: skipped: " + cuda.Describe());
    return;
  }
  for (int d = 0; d < cuda.device_count; ++d) {
    try {
      const CudaDeviceInfo info = QueryCudaDevice(d);
      FoundDevice found;
      found.identity = IdentityOf(info);
      found.limits = info.limits;
      found.max_allocation_bytes = info.total_memory_bytes;  // CUDA has no maximum allocation query
      found.open = [d]() -> std::unique_ptr<Runner> { return std::make_unique<CudaRunner>(d); };
      found.open_own = [d]() -> std::unique_ptr<Runner> { return std::make_unique<CudaRunner>(d, CudaRunner::OwnContext{}); };
      out.devices.push_back(std::move(found));
    } catch (const std::exception& e) {
      // A device the driver cannot describe is not offered.
      out.skipped.push_back("cuda: device " + std::to_string(d) + ": skipped: " + e.what());
    }
  }
}

// First of all: a CUDA device is a GPU.
int Preference(const DeviceIdentity&) { return 0; }

}  // namespace

// runtime/backends/cuda/skinner_cuda.cpp: RunnerSkinner with CUDA-GL interop.
std::unique_ptr<SkinnerBackend> MakeCudaSkinner(DeviceState& device, const PackedMesh& mesh,
                                                const std::vector<KernelSource>& kernels, const SkinnerSetup& setup);

BackendEntry CudaEntry() { return {"cuda", "CUDA", {Lang::kCuda}, Discover, Preference, MakeCudaSkinner}; }

}  // namespace skintune::internal

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

Result<Device> Device::FromCuda(void* cu_context, void* cu_stream, const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    const CudaAvailability available = Probe();
    if (!available.driver) FailWith(ErrorCode::kUnavailable, "Device::FromCuda: " + available.driver_missing);
    if (!available.nvrtc) FailWith(ErrorCode::kUnavailable, "Device::FromCuda: " + available.nvrtc_missing);
    if (!cu_context) FailWith(ErrorCode::kInvalidArgument, "Device::FromCuda: a null CUcontext");
    auto runner = std::make_unique<CudaRunner>(cu_context, cu_stream);
    const DeviceIdentity identity = IdentityOf(runner->info());
    const DeviceLimits limits = runner->limits();
    return MakeDevice(options, identity, limits, std::move(runner));
  });
}

}  // namespace skintune
