// skintune (internal): the runner driver (runtime/runner.h) on Vulkan: the
// language `vulkan` (templates/skin.comp compiled to SPIR-V with shaderc).
// Its DeviceApi (vulkan_runner.cpp):
//
// - Build: each distinct KernelSource is compiled to SPIR-V once per runner
//   (shaderc, Vulkan 1.1 target; the SPIR-V words are what the program cache
//   stores, runtime/program_cache.h), then a shader module and, per launch
//   plan, a compute pipeline whose layout is descriptor set 0 (the kernel's
//   buffers and palette in argument order: the sidecar's "binding") and one
//   12-byte push-constant range (n, first, vertex_count). A failure throws
//   Error("Vulkan build: ...") with the first lines of the log.
// - Buffers live in device-local memory; inputs are uploaded through
//   host-visible staging buffers (or written directly where device-local
//   memory is host-visible: lavapipe, resizable BAR). Palette: STORAGE
//   constant -> uniform buffer; local/global -> storage buffer; image -> a
//   VK_FORMAT_R32G32B32A32_SFLOAT uniform texel buffer view.
// - Outputs are POISONED and GUARDED by the driver: the whole buffer (guard
//   included) is bound, so a kernel that writes past the end is caught.
// - Launches: vkCmdDispatch(GlobalItems(n) / wg, K, 1). Run's frame and
//   Time's frames are one command buffer each, every launch between two
//   vkCmdWriteTimestamp (ms = ticks x timestampPeriod / 1e6); a pipeline
//   barrier only before a frame whose input set an earlier frame of the same
//   command buffer used (the outputs are written again). The kernel time's
//   frames (kCold): the flush and a timestamp, then per launch a compute
//   barrier, the dispatch and a timestamp (BOTTOM_OF_PIPE: the end of the
//   command before; vulkan_runner.cpp RunCold says why).
// - On a GPU the driver first warms up until two bursts of frames take the
//   same time (TimingPolicy::warm_until_stable), as for GL on NVIDIA.
// - Limits (VkPhysicalDeviceLimits): maxUniformBufferRange (constant),
//   maxTexelBufferElements (image), maxStorageBufferRange (every storage
//   buffer), maxComputeWorkGroupCount x and y (groups, instances).
// - Skinning: WritePalette writes a host-visible palette slot in place, or
//   the slot's host-visible staging buffer, whose vkCmdCopyBuffer the next
//   frame's command buffer records before its dispatches; LaunchSet queues
//   the set's launches without waiting (on a device skintune opened, frames
//   queued while earlier ones still run share a submission, up to 8), or
//   records them into the caller's command buffer (RecordInto), framed by
//   barriers. The ring's fences are
//   submission numbers (their VkFences), or the queue idle after a caller's
//   command buffer; read-backs go through a kept host-visible buffer.
// - Adopted handles (Device::FromVulkan): the caller's instance, device and
//   queue are used and never destroyed; skintune creates no device there.
// Errors name the stage: "Vulkan setup", "build", "launch" or "guard".
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "runtime/backends/vulkan/vulkan_devices.h"
#include "runtime/runner.h"

namespace skintune::internal {

namespace vk {
class VulkanApi;
}

// The caller's handles (Device::FromVulkan).
struct VulkanAdopted {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  PFN_vkGetInstanceProcAddr get_instance_proc_addr = nullptr;  // null: libvulkan.so.1's
};

class VulkanRunner final : public Runner {
 public:
  // Physical device `device_index` of a new instance (validation layer and
  // messenger when `validation` or $SKINTUNE_VULKAN_VALIDATION); throws
  // Error("Vulkan setup: <why>").
  explicit VulkanRunner(int device_index = 0, bool validation = false);
  // On the caller's handles, adopted (never destroyed).
  explicit VulkanRunner(const VulkanAdopted& adopted);

  const vk::VulkanDeviceInfo& info() const;
  // The validation layer's warnings and errors so far (none without validation).
  std::vector<std::string> validation_messages() const;
  // Records LaunchSet's launches into `command_buffer` (the caller's, in the
  // recording state, outside a render pass) instead of submitting them;
  // VK_NULL_HANDLE: submit on the runner's queue again.
  void RecordInto(VkCommandBuffer command_buffer);
  // vkQueueSubmit calls so far (live frames are batched: VulkanApi::OpenFrames).
  std::uint64_t submissions() const;
  // The command buffers the last TimeCold's frames were recorded into, in
  // order (VulkanApi::kColdCommandBuffers, taken in turn).
  std::vector<std::uintptr_t> cold_command_buffers() const;

 private:
  vk::VulkanApi& vk_api() const;
};

}  // namespace skintune::internal
