// skintune (internal to runtime/backends/vulkan/): the Vulkan loader
// (libvulkan.so.1) opened at run time, like CUDA's driver (cuda/cuda_api.h):
// a machine without it still runs every other API, and discovery says
// "vulkan: skipped: <why>" instead of the process failing to start. The
// functions skintune calls are listed once (the X-macro lists below) and
// loaded through vkGetInstanceProcAddr / vkGetDeviceProcAddr; a caller's
// instance may come with its own vkGetInstanceProcAddr (Device::FromVulkan).
#pragma once

#ifndef VK_NO_PROTOTYPES
#define VK_NO_PROTOTYPES
#endif
#include <vulkan/vulkan.h>

#include <string>

namespace skintune::internal::vk {

// Global commands (no instance).
#define SKINTUNE_VK_GLOBAL_FUNCTIONS(X) \
  X(vkCreateInstance)                   \
  X(vkEnumerateInstanceExtensionProperties) \
  X(vkEnumerateInstanceLayerProperties) \
  X(vkEnumerateInstanceVersion)

// Instance commands. vkCreateDebugUtilsMessengerEXT and its destroy may be
// null (VK_EXT_debug_utils not enabled).
#define SKINTUNE_VK_INSTANCE_FUNCTIONS(X)      \
  X(vkDestroyInstance)                         \
  X(vkEnumeratePhysicalDevices)                \
  X(vkGetPhysicalDeviceProperties)             \
  X(vkGetPhysicalDeviceProperties2)            \
  X(vkGetPhysicalDeviceQueueFamilyProperties)  \
  X(vkGetPhysicalDeviceMemoryProperties)       \
  X(vkEnumerateDeviceExtensionProperties)      \
  X(vkCreateDevice)                            \
  X(vkGetDeviceProcAddr)                       \
  X(vkCreateDebugUtilsMessengerEXT)            \
  X(vkDestroyDebugUtilsMessengerEXT)

// Device commands.
#define SKINTUNE_VK_DEVICE_FUNCTIONS(X) \
  X(vkDestroyDevice)                    \
  X(vkGetDeviceQueue)                   \
  X(vkQueueSubmit)                      \
  X(vkQueueWaitIdle)                    \
  X(vkDeviceWaitIdle)                   \
  X(vkCreateBuffer)                     \
  X(vkDestroyBuffer)                    \
  X(vkGetBufferMemoryRequirements)      \
  X(vkAllocateMemory)                   \
  X(vkFreeMemory)                       \
  X(vkBindBufferMemory)                 \
  X(vkMapMemory)                        \
  X(vkUnmapMemory)                      \
  X(vkCreateBufferView)                 \
  X(vkDestroyBufferView)                \
  X(vkCreateShaderModule)               \
  X(vkDestroyShaderModule)              \
  X(vkCreateDescriptorSetLayout)        \
  X(vkDestroyDescriptorSetLayout)       \
  X(vkCreatePipelineLayout)             \
  X(vkDestroyPipelineLayout)            \
  X(vkCreateComputePipelines)           \
  X(vkDestroyPipeline)                  \
  X(vkCreateDescriptorPool)             \
  X(vkDestroyDescriptorPool)            \
  X(vkAllocateDescriptorSets)           \
  X(vkUpdateDescriptorSets)             \
  X(vkCreateCommandPool)                \
  X(vkDestroyCommandPool)               \
  X(vkAllocateCommandBuffers)           \
  X(vkFreeCommandBuffers)               \
  X(vkBeginCommandBuffer)               \
  X(vkEndCommandBuffer)                 \
  X(vkCmdBindPipeline)                  \
  X(vkCmdBindDescriptorSets)            \
  X(vkCmdPushConstants)                 \
  X(vkCmdDispatch)                      \
  X(vkCmdPipelineBarrier)               \
  X(vkCmdCopyBuffer)                    \
  X(vkCmdWriteTimestamp)                \
  X(vkCmdResetQueryPool)                \
  X(vkCreateQueryPool)                  \
  X(vkDestroyQueryPool)                 \
  X(vkGetQueryPoolResults)              \
  X(vkCreateFence)                      \
  X(vkDestroyFence)                     \
  X(vkGetFenceStatus)                   \
  X(vkResetFences)                      \
  X(vkWaitForFences)

#define SKINTUNE_VK_DECLARE(name) PFN_##name name = nullptr;

struct GlobalFunctions {
  PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr = nullptr;
  SKINTUNE_VK_GLOBAL_FUNCTIONS(SKINTUNE_VK_DECLARE)
};
struct InstanceFunctions {
  SKINTUNE_VK_INSTANCE_FUNCTIONS(SKINTUNE_VK_DECLARE)
};
struct DeviceFunctions {
  SKINTUNE_VK_DEVICE_FUNCTIONS(SKINTUNE_VK_DECLARE)
};

// libvulkan.so.1, opened once per process (never closed).
struct Loader {
  bool ok = false;
  std::string reason;  // when not ok: "libvulkan.so.1 not found (...)", "the loader offers Vulkan 1.0 only ..."
  GlobalFunctions global;
};
const Loader& SystemLoader();

// The global commands through `get_instance_proc_addr`.
GlobalFunctions GlobalsOf(PFN_vkGetInstanceProcAddr get_instance_proc_addr);
// The instance commands of `instance`; throws Error("Vulkan setup: ...") naming a missing one.
InstanceFunctions InstanceFunctionsOf(const GlobalFunctions& global, VkInstance instance);
// The device commands of `device`; throws likewise.
DeviceFunctions DeviceFunctionsOf(const InstanceFunctions& instance, VkDevice device);

// "VK_ERROR_OUT_OF_DEVICE_MEMORY", or the number.
std::string ResultName(VkResult result);
// Throws Error("Vulkan <stage>: <what>: <result name>") unless `result` is VK_SUCCESS;
// stage "lost" for VK_ERROR_DEVICE_LOST, whatever the caller's.
void Check(VkResult result, const std::string& stage, const std::string& what);
[[noreturn]] void Fail(const std::string& stage, const std::string& message);

}  // namespace skintune::internal::vk
