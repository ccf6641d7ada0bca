// skintune (internal to runtime/backends/vulkan/): Vulkan instances, the
// physical devices they offer, who each one is (IdentityOf: the device UUID
// and PCI bus id, so the same GPU seen through CUDA, OpenCL and GL is one
// chip: runtime/physical_device.h) and what it allows (LimitsOf, from
// VkPhysicalDeviceLimits).
//
// Validation: an instance made with `validation` (or with
// $SKINTUNE_VULKAN_VALIDATION=1) enables VK_LAYER_KHRONOS_validation and a
// VK_EXT_debug_utils messenger that records every warning and error
// message; tests fail on any (VulkanInstance::messages()).
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "runtime/backends/vulkan/vulkan_loader.h"
#include "runtime/device_identity.h"

namespace skintune::internal::vk {

class VulkanInstance {
 public:
  // A new instance (Vulkan 1.1); throws Error("Vulkan setup: ...").
  explicit VulkanInstance(bool validation);
  // The caller's instance, never destroyed here; `get_instance_proc_addr`
  // null: the system loader's.
  VulkanInstance(VkInstance adopted, PFN_vkGetInstanceProcAddr get_instance_proc_addr);
  ~VulkanInstance();
  VulkanInstance(const VulkanInstance&) = delete;
  VulkanInstance& operator=(const VulkanInstance&) = delete;

  VkInstance get() const { return instance_; }
  const GlobalFunctions& global() const { return global_; }
  const InstanceFunctions& fn() const { return fn_; }
  bool owned() const { return owned_; }
  bool validation() const { return messenger_ != VK_NULL_HANDLE; }
  // The validation messages (warnings and errors) so far, each "<severity>: <id>: <text>".
  std::vector<std::string> messages() const;
  void RecordMessage(std::string message);

  std::vector<VkPhysicalDevice> PhysicalDevices() const;

 private:
  VkInstance instance_ = VK_NULL_HANDLE;
  bool owned_ = true;
  GlobalFunctions global_;
  InstanceFunctions fn_;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  mutable std::mutex mutex_;
  std::vector<std::string> messages_;
};

// Whether $SKINTUNE_VULKAN_VALIDATION asks for the validation layer.
bool ValidationRequested();

// What skintune reads of one physical device.
struct VulkanDeviceInfo {
  std::string name, vendor, driver_version, api_version, type;  // type: "gpu", "cpu", "other"
  std::string uuid;        // VkPhysicalDeviceIDProperties::deviceUUID, 32 hex digits ("" if all zero)
  std::string pci_bus_id;  // "dddd:bb:dd.f" (VK_EXT_pci_bus_info), "" when the driver does not say
  std::uint32_t compute_family = UINT32_MAX;  // ComputeFamily's choice (UINT32_MAX: none)
  std::uint32_t timestamp_valid_bits = 0;     // of that family
  bool pci_bus_info = false;                  // VK_EXT_pci_bus_info offered
  double timestamp_period_ns = 1.0;
  std::uint64_t device_local_bytes = 0;  // the largest device-local heap
  VkPhysicalDeviceLimits limits{};
};

VulkanDeviceInfo QueryDevice(const VulkanInstance& instance, VkPhysicalDevice device);

// The queue family skintune submits to on a device it opens: a compute family
// without graphics that has timestamps (NVIDIA's asynchronous compute queues),
// else the first family with compute and timestamps, else the first with
// compute; UINT32_MAX when none has compute. On NVIDIA's H200 a crowd's
// frames ran 4-10% faster there than on the graphics family (2026-12-01,
// docs/PERFORMANCE.md "The frame loop").
std::uint32_t ComputeFamily(std::span<const VkQueueFamilyProperties> families);
DeviceIdentity IdentityOf(const VulkanDeviceInfo& info);
DeviceLimits LimitsOf(const VulkanDeviceInfo& info);

}  // namespace skintune::internal::vk
