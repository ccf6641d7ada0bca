// Vulkan in the backend table (runtime/backend_table.h): every physical
// device of a new instance (none, with the reason, without a loader),
// OpenBest's rank, Device::FromVulkan on the caller's handles, and the
// Skinner that can record into the caller's command buffer.
#include <memory>

#include "runtime/api_errors.h"
#include "runtime/backend_table.h"
#include "runtime/backends/vulkan/vulkan_devices.h"
#include "runtime/backends/vulkan/vulkan_runner.h"
#include "runtime/device.h"
#include "runtime/skinner.h"

namespace skintune::internal {

namespace {

void Discover(Discovered& out) {
  const vk::Loader& loader = vk::SystemLoader();
  if (!loader.ok) {
    out.skipped.push_back("vulkan: skipped: " + loader.reason);
    return;
  }
  const vk::VulkanInstance instance(false);
  const std::vector<VkPhysicalDevice> devices = instance.PhysicalDevices();
  if (devices.empty()) out.skipped.push_back("vulkan: skipped: the loader found no Vulkan driver (ICD)");
  for (std::size_t d = 0; d < devices.size(); ++d) {
    const vk::VulkanDeviceInfo info = vk::QueryDevice(instance, devices[d]);
    if (info.compute_family == UINT32_MAX || info.timestamp_valid_bits == 0) {
      out.skipped.push_back("vulkan: device " + std::to_string(d) + " (" + info.name + "): skipped: " +
                            (info.compute_family == UINT32_MAX ? "no compute queue" : "no timestamps on its compute queue"));
      continue;
    }
    FoundDevice found;
    found.identity = vk::IdentityOf(info);
    found.limits = vk::LimitsOf(info);
    found.max_allocation_bytes = std::min<std::uint64_t>(info.limits.maxStorageBufferRange, info.device_local_bytes);
    const int index = static_cast<int>(d);
    found.open = [index]() -> std::unique_ptr<Runner> { return std::make_unique<VulkanRunner>(index); };
    out.devices.push_back(std::move(found));
  }
}

// Vulkan on a GPU beside GL (2: CUDA and OpenCL first); on a CPU (lavapipe) last of all.
int Preference(const DeviceIdentity& d) { return d.type == "gpu" ? 2 : 6; }

class VulkanSkinner final : public RunnerSkinner {
 public:
  VulkanSkinner(VulkanRunner& runner, Prepared prepared) : RunnerSkinner(runner, std::move(prepared)), vulkan_(runner) {}

  void SkinIntoVulkan(void* command_buffer, void* buffer) override {
    RunOnDevice([&] {
      vulkan_.RecordInto(static_cast<VkCommandBuffer>(command_buffer));
      try {
        runner_.LaunchSet(prepared_, 0, buffer);
      } catch (...) {
        vulkan_.RecordInto(VK_NULL_HANDLE);
        throw;
      }
      vulkan_.RecordInto(VK_NULL_HANDLE);
    });
  }

 private:
  VulkanRunner& vulkan_;
};

std::unique_ptr<SkinnerBackend> MakeVulkanSkinner(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, const SkinnerSetup& setup) {
  auto* runner = dynamic_cast<VulkanRunner*>(device.runner.get());
  if (!runner) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no Vulkan queue");
  Prepared prepared = PrepareSkinnerSet(device, mesh, kernels, setup);
  return std::make_unique<VulkanSkinner>(*runner, std::move(prepared));
}

}  // namespace

BackendEntry VulkanEntry() {
  return {"vulkan", "Vulkan", {Lang::kVulkan}, Discover, Preference, MakeVulkanSkinner};
}

}  // namespace skintune::internal

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

Result<Device> Device::FromVulkan(const VulkanHandles& handles, const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    const vk::Loader& loader = vk::SystemLoader();
    if (!handles.get_instance_proc_addr && !loader.ok)
      FailWith(ErrorCode::kUnavailable, "Device::FromVulkan: " + loader.reason);
    if (!handles.instance || !handles.physical_device || !handles.device || !handles.queue)
      FailWith(ErrorCode::kInvalidArgument,
               "Device::FromVulkan: a null handle (instance, physical_device, device and queue are needed)");
    VulkanAdopted adopted;
    adopted.instance = static_cast<VkInstance>(handles.instance);
    adopted.physical_device = static_cast<VkPhysicalDevice>(handles.physical_device);
    adopted.device = static_cast<VkDevice>(handles.device);
    adopted.queue = static_cast<VkQueue>(handles.queue);
    adopted.queue_family = handles.queue_family;
    adopted.get_instance_proc_addr = reinterpret_cast<PFN_vkGetInstanceProcAddr>(handles.get_instance_proc_addr);
    std::unique_ptr<VulkanRunner> runner;
    try {
      runner = std::make_unique<VulkanRunner>(adopted);
    } catch (const Error& e) {
      FailWith(ErrorCode::kInvalidArgument, std::string("Device::FromVulkan: ") + e.what());
    }
    DeviceIdentity identity = vk::IdentityOf(runner->info());
    identity.platform = "adopted";  // never equal to a tuned id: the database matches it by name downwards
    const DeviceLimits limits = vk::LimitsOf(runner->info());
    return MakeDevice(options, identity, limits, std::move(runner));
  });
}

}  // namespace skintune
