// OpenCL in the backend table (runtime/backend_table.h): every device of
// every platform, OpenBest's rank, and the public Device constructors on
// handles the caller has (Device::FromOpenCl, Device::OpenClForCurrentGl).
#include <memory>

#include "runtime/api_errors.h"
#include "runtime/backend_table.h"
#include "runtime/backends/opencl/opencl_devices.h"
#include "runtime/backends/opencl/opencl_gl_sharing.h"
#include "runtime/backends/opencl/opencl_runner.h"
#include "runtime/device.h"
#include "runtime/skinner.h"

namespace skintune::internal {

// skinner_opencl.cpp
std::unique_ptr<SkinnerBackend> MakeOpenClSkinner(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, const SkinnerSetup& setup);

namespace {

void Discover(Discovered& out) {
  const OpenClInventory inventory = EnumerateOpenCl();
  if (inventory.devices.empty()) out.skipped.push_back("opencl: skipped: " + inventory.status);
  for (const std::string& warning : inventory.warnings) out.skipped.push_back("opencl: skipped: " + warning);
  for (const OpenClDeviceInfo& d : inventory.devices) {
    FoundDevice found;
    found.identity = IdentityOf(d);
    found.limits = LimitsOf(d);
    found.max_allocation_bytes = d.max_allocation_bytes;
    found.open = [platform = d.platform_index, device = d.device_index]() -> std::unique_ptr<Runner> {
      return std::make_unique<OpenClRunner>(platform, device);
    };
    // Each runner has a cl_context of its own, and NVIDIA's differ as CUDA's
    // do (docs/TUNING.md "Kernel time"): a GPU's kernels are timed on the
    // quickest of several (a CPU device's never are: tuner/runner_device.h).
    if (d.type.find("gpu") != std::string::npos) found.open_own = found.open;
    out.devices.push_back(std::move(found));
  }
}

// After CUDA (0) and GL on a GPU (2): OpenCL GPUs 1, CPUs 3, other devices 4.
int Preference(const DeviceIdentity& d) {
  if (d.type.find("gpu") != std::string::npos) return 1;
  return d.type.find("cpu") != std::string::npos ? 3 : 4;
}

}  // namespace

BackendEntry OpenClEntry() { return {"opencl", "OpenCL", {Lang::kOpenCl}, Discover, Preference, MakeOpenClSkinner}; }

}  // namespace skintune::internal

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

Result<Device> Device::FromOpenCl(void* cl_device, void* cl_context, void* cl_queue, const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kInvalidArgument, [&] {
    const OpenClDeviceInfo described = DescribeOpenClDevice(cl_device);
    auto runner = std::make_unique<OpenClRunner>(cl_device, cl_context, cl_queue);
    const bool gl_sharing = OpenClContextSharesGl(cl_context);
    return MakeDevice(options, IdentityOf(described), LimitsOf(described), std::move(runner), gl_sharing);
  });
}

Result<Device> Device::OpenClForCurrentGl(const DeviceOptions& options) {
  std::string why;
  const OpenClGlHandles handles = OpenClContextForCurrentGl(why);
  if (!handles.context) return Status(ErrorCode::kUnavailable, "Device::OpenClForCurrentGl: " + why);
  Result<Device> device = FromOpenCl(handles.device, handles.context, handles.queue, options);
  Release(handles);  // the Device holds its own references
  return device;
}

}  // namespace skintune
