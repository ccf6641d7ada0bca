// The Vulkan loader opened at run time (vulkan_loader.h).
#include "runtime/backends/vulkan/vulkan_loader.h"

#include <dlfcn.h>

#include "base/error.h"

namespace skintune::internal::vk {

void Fail(const std::string& stage, const std::string& message) { throw Error("Vulkan " + stage + ": " + message); }

std::string ResultName(VkResult result) {
  switch (result) {
#define SKINTUNE_VK_RESULT(r) \
  case r: return #r;
    SKINTUNE_VK_RESULT(VK_SUCCESS)
    SKINTUNE_VK_RESULT(VK_NOT_READY)
    SKINTUNE_VK_RESULT(VK_TIMEOUT)
    SKINTUNE_VK_RESULT(VK_INCOMPLETE)
    SKINTUNE_VK_RESULT(VK_ERROR_OUT_OF_HOST_MEMORY)
    SKINTUNE_VK_RESULT(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    SKINTUNE_VK_RESULT(VK_ERROR_INITIALIZATION_FAILED)
    SKINTUNE_VK_RESULT(VK_ERROR_DEVICE_LOST)
    SKINTUNE_VK_RESULT(VK_ERROR_MEMORY_MAP_FAILED)
    SKINTUNE_VK_RESULT(VK_ERROR_LAYER_NOT_PRESENT)
    SKINTUNE_VK_RESULT(VK_ERROR_EXTENSION_NOT_PRESENT)
    SKINTUNE_VK_RESULT(VK_ERROR_FEATURE_NOT_PRESENT)
    SKINTUNE_VK_RESULT(VK_ERROR_INCOMPATIBLE_DRIVER)
    SKINTUNE_VK_RESULT(VK_ERROR_TOO_MANY_OBJECTS)
    SKINTUNE_VK_RESULT(VK_ERROR_FORMAT_NOT_SUPPORTED)
    SKINTUNE_VK_RESULT(VK_ERROR_FRAGMENTED_POOL)
    SKINTUNE_VK_RESULT(VK_ERROR_OUT_OF_POOL_MEMORY)
    SKINTUNE_VK_RESULT(VK_ERROR_INVALID_SHADER_NV)
#undef SKINTUNE_VK_RESULT
    default: return "VkResult " + std::to_string(static_cast<int>(result));
  }
}

void Check(VkResult result, const std::string& stage, const std::string& what) {
  // A lost device stays lost: stage "lost" (the tuner's worker then exits), whatever the caller's.
  if (result != VK_SUCCESS) Fail(result == VK_ERROR_DEVICE_LOST ? "lost" : stage, what + ": " + ResultName(result));
}

GlobalFunctions GlobalsOf(PFN_vkGetInstanceProcAddr get_instance_proc_addr) {
  GlobalFunctions g;
  g.vkGetInstanceProcAddr = get_instance_proc_addr;
#define SKINTUNE_VK_LOAD(name) g.name = reinterpret_cast<PFN_##name>(get_instance_proc_addr(VK_NULL_HANDLE, #name));
  SKINTUNE_VK_GLOBAL_FUNCTIONS(SKINTUNE_VK_LOAD)
#undef SKINTUNE_VK_LOAD
  return g;
}

namespace {

bool Optional(const char* name) {
  const std::string n = name;
  return n.find("DebugUtils") != std::string::npos;
}

}  // namespace

InstanceFunctions InstanceFunctionsOf(const GlobalFunctions& global, VkInstance instance) {
  InstanceFunctions f;
#define SKINTUNE_VK_LOAD(name)                                                                        \
  f.name = reinterpret_cast<PFN_##name>(global.vkGetInstanceProcAddr(instance, #name));               \
  if (!f.name && !Optional(#name)) Fail("setup", "the Vulkan loader has no " #name " for the instance");
  SKINTUNE_VK_INSTANCE_FUNCTIONS(SKINTUNE_VK_LOAD)
#undef SKINTUNE_VK_LOAD
  return f;
}

DeviceFunctions DeviceFunctionsOf(const InstanceFunctions& instance, VkDevice device) {
  DeviceFunctions f;
#define SKINTUNE_VK_LOAD(name)                                                          \
  f.name = reinterpret_cast<PFN_##name>(instance.vkGetDeviceProcAddr(device, #name)); \
  if (!f.name) Fail("setup", "the Vulkan device has no " #name);
  SKINTUNE_VK_DEVICE_FUNCTIONS(SKINTUNE_VK_LOAD)
#undef SKINTUNE_VK_LOAD
  return f;
}

const Loader& SystemLoader() {
  static const Loader loader = [] {
    Loader l;
    void* library = dlopen("libvulkan.so.1", RTLD_NOW | RTLD_LOCAL);
    if (!library) {
      const char* why = dlerror();
      l.reason = std::string("libvulkan.so.1 (the Vulkan loader, Debian's libvulkan1) not found: ") +
                 (why ? why : "dlopen failed");
      return l;
    }
    auto get = reinterpret_cast<PFN_vkGetInstanceProcAddr>(dlsym(library, "vkGetInstanceProcAddr"));
    if (!get) {
      l.reason = "libvulkan.so.1 has no vkGetInstanceProcAddr";
      return l;
    }
    l.global = GlobalsOf(get);
    std::uint32_t version = VK_API_VERSION_1_0;
    if (l.global.vkEnumerateInstanceVersion) l.global.vkEnumerateInstanceVersion(&version);
    if (!l.global.vkCreateInstance || version < VK_API_VERSION_1_1) {
      l.reason = "the Vulkan loader offers Vulkan 1.0 only (skintune needs 1.1: device UUIDs, properties2)";
      return l;
    }
    l.ok = true;
    return l;
  }();
  return loader;
}

}  // namespace skintune::internal::vk
