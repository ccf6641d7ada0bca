// Vulkan instances, physical devices, identities and limits (vulkan_devices.h).
#include "runtime/backends/vulkan/vulkan_devices.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "runtime/physical_device.h"

namespace skintune::internal::vk {

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

VKAPI_ATTR VkBool32 VKAPI_CALL OnMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                         VkDebugUtilsMessageTypeFlagsEXT,
                                         const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  const char* level = severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error" : "warning";
  std::string message = std::string(level) + ": " + (data->pMessageIdName ? data->pMessageIdName : "?") + ": " +
                        (data->pMessage ? data->pMessage : "");
  static_cast<VulkanInstance*>(user)->RecordMessage(std::move(message));
  return VK_FALSE;
}

bool HasLayer(const GlobalFunctions& g, const char* name) {
  std::uint32_t count = 0;
  if (g.vkEnumerateInstanceLayerProperties(&count, nullptr) != VK_SUCCESS) return false;
  std::vector<VkLayerProperties> layers(count);
  g.vkEnumerateInstanceLayerProperties(&count, layers.data());
  return std::any_of(layers.begin(), layers.end(), [&](const VkLayerProperties& l) { return std::strcmp(l.layerName, name) == 0; });
}

std::string VersionText(std::uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
         std::to_string(VK_API_VERSION_PATCH(v));
}

std::string VendorName(std::uint32_t id) {
  switch (id) {
    case 0x10de: return "NVIDIA";
    case 0x1002: return "AMD";
    case 0x8086: return "Intel";
    case 0x10005: return "Mesa";
    case 0x13b5: return "ARM";
    case 0x5143: return "Qualcomm";
    default: {
      char text[16];
      std::snprintf(text, sizeof text, "0x%04x", id);
      return text;
    }
  }
}

}  // namespace

bool ValidationRequested() {
  const char* env = std::getenv("SKINTUNE_VULKAN_VALIDATION");
  return env && *env && std::string(env) != "0";
}

VulkanInstance::VulkanInstance(bool validation) {
  const Loader& loader = SystemLoader();
  if (!loader.ok) Fail("setup", loader.reason);
  global_ = loader.global;
  validation = validation || ValidationRequested();
  if (validation && !HasLayer(global_, kValidationLayer))
    Fail("setup", std::string("validation asked for, but no ") + kValidationLayer +
                      " (Debian's vulkan-validationlayers)");
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "skintune";
  app.apiVersion = VK_API_VERSION_1_2;
  std::vector<const char*> layers, extensions;
  if (validation) {
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  VkDebugUtilsMessengerCreateInfoEXT messenger{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  messenger.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messenger.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                          VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messenger.pfnUserCallback = OnMessage;
  messenger.pUserData = this;
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  info.pApplicationInfo = &app;
  info.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
  info.ppEnabledLayerNames = layers.data();
  info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();
  if (validation) info.pNext = &messenger;  // also reports vkCreateInstance / vkDestroyInstance
  Check(global_.vkCreateInstance(&info, nullptr, &instance_), "setup", "vkCreateInstance");
  try {
    fn_ = InstanceFunctionsOf(global_, instance_);
    if (validation) {
      if (!fn_.vkCreateDebugUtilsMessengerEXT) Fail("setup", "no vkCreateDebugUtilsMessengerEXT with validation on");
      Check(fn_.vkCreateDebugUtilsMessengerEXT(instance_, &messenger, nullptr, &messenger_), "setup",
            "vkCreateDebugUtilsMessengerEXT");
    }
  } catch (...) {
    auto destroy = reinterpret_cast<PFN_vkDestroyInstance>(global_.vkGetInstanceProcAddr(instance_, "vkDestroyInstance"));
    if (destroy) destroy(instance_, nullptr);
    throw;
  }
}

VulkanInstance::VulkanInstance(VkInstance adopted, PFN_vkGetInstanceProcAddr get_instance_proc_addr)
    : instance_(adopted), owned_(false) {
  if (get_instance_proc_addr) {
    global_ = GlobalsOf(get_instance_proc_addr);
  } else {
    const Loader& loader = SystemLoader();
    if (!loader.ok) Fail("setup", loader.reason);
    global_ = loader.global;
  }
  fn_ = InstanceFunctionsOf(global_, instance_);
}

VulkanInstance::~VulkanInstance() {
  if (!owned_ || !instance_) return;
  if (messenger_) fn_.vkDestroyDebugUtilsMessengerEXT(instance_, messenger_, nullptr);
  fn_.vkDestroyInstance(instance_, nullptr);
}

std::vector<std::string> VulkanInstance::messages() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return messages_;
}

void VulkanInstance::RecordMessage(std::string message) {
  std::lock_guard<std::mutex> lock(mutex_);
  messages_.push_back(std::move(message));
}

std::vector<VkPhysicalDevice> VulkanInstance::PhysicalDevices() const {
  std::uint32_t count = 0;
  Check(fn_.vkEnumeratePhysicalDevices(instance_, &count, nullptr), "setup", "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> devices(count);
  Check(fn_.vkEnumeratePhysicalDevices(instance_, &count, devices.data()), "setup", "vkEnumeratePhysicalDevices");
  devices.resize(count);
  return devices;
}

VulkanDeviceInfo QueryDevice(const VulkanInstance& instance, VkPhysicalDevice device) {
  const InstanceFunctions& fn = instance.fn();
  VulkanDeviceInfo info;
  std::uint32_t count = 0;
  fn.vkEnumerateDeviceExtensionProperties(device, nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> extensions(count);
  fn.vkEnumerateDeviceExtensionProperties(device, nullptr, &count, extensions.data());
  for (const VkExtensionProperties& e : extensions)
    if (std::strcmp(e.extensionName, VK_EXT_PCI_BUS_INFO_EXTENSION_NAME) == 0) info.pci_bus_info = true;

  VkPhysicalDeviceProperties plain{};
  fn.vkGetPhysicalDeviceProperties(device, &plain);
  VkPhysicalDeviceIDProperties id{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ID_PROPERTIES};
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDevicePCIBusInfoPropertiesEXT pci{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PCI_BUS_INFO_PROPERTIES_EXT};
  VkPhysicalDeviceProperties2 properties{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  properties.pNext = &id;
  const bool has_driver_properties = plain.apiVersion >= VK_API_VERSION_1_2;
  void** tail = &id.pNext;
  if (has_driver_properties) {
    *tail = &driver;
    tail = &driver.pNext;
  }
  if (info.pci_bus_info) *tail = &pci;
  fn.vkGetPhysicalDeviceProperties2(device, &properties);
  const VkPhysicalDeviceProperties& p = properties.properties;

  info.name = p.deviceName;
  info.vendor = VendorName(p.vendorID);
  info.api_version = VersionText(p.apiVersion);
  info.driver_version = has_driver_properties && driver.driverInfo[0] != '\0'
                            ? std::string(driver.driverName) + " " + driver.driverInfo
                            : "driver 0x" + [&] {
                                char text[16];
                                std::snprintf(text, sizeof text, "%08x", p.driverVersion);
                                return std::string(text);
                              }();
  switch (p.deviceType) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: info.type = "gpu"; break;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: info.type = "cpu"; break;
    default: info.type = "other"; break;
  }
  info.uuid = UuidHex(id.deviceUUID);
  if (info.pci_bus_info) {
    char text[32];
    std::snprintf(text, sizeof text, "%04x:%02x:%02x.%x", pci.pciDomain, pci.pciBus, pci.pciDevice, pci.pciFunction);
    info.pci_bus_id = text;
  }
  info.limits = p.limits;
  info.timestamp_period_ns = static_cast<double>(p.limits.timestampPeriod);

  fn.vkGetPhysicalDeviceQueueFamilyProperties(device, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  fn.vkGetPhysicalDeviceQueueFamilyProperties(device, &count, families.data());
  info.compute_family = ComputeFamily(families);
  if (info.compute_family != UINT32_MAX) info.timestamp_valid_bits = families[info.compute_family].timestampValidBits;
  VkPhysicalDeviceMemoryProperties memory{};
  fn.vkGetPhysicalDeviceMemoryProperties(device, &memory);
  for (std::uint32_t h = 0; h < memory.memoryHeapCount; ++h)
    if (memory.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
      info.device_local_bytes = std::max<std::uint64_t>(info.device_local_bytes, memory.memoryHeaps[h].size);
  return info;
}

std::uint32_t ComputeFamily(std::span<const VkQueueFamilyProperties> families) {
  const auto first = [&](auto&& fits) {
    for (std::uint32_t f = 0; f < families.size(); ++f)
      if ((families[f].queueFlags & VK_QUEUE_COMPUTE_BIT) && families[f].queueCount > 0 && fits(families[f])) return f;
    return UINT32_MAX;
  };
  for (const std::uint32_t f :
       {first([](const VkQueueFamilyProperties& p) { return !(p.queueFlags & VK_QUEUE_GRAPHICS_BIT) && p.timestampValidBits > 0; }),
        first([](const VkQueueFamilyProperties& p) { return p.timestampValidBits > 0; }),
        first([](const VkQueueFamilyProperties&) { return true; })})
    if (f != UINT32_MAX) return f;
  return UINT32_MAX;
}

DeviceIdentity IdentityOf(const VulkanDeviceInfo& info) {
  DeviceIdentity d;
  d.backend = "vulkan";
  d.platform = "Vulkan";
  d.vendor = info.vendor;
  d.name = info.name;
  d.driver_version = info.driver_version;
  d.api_version = info.api_version;
  d.type = info.type;
  d.global_memory_bytes = info.device_local_bytes;
  d.local_memory_bytes = info.limits.maxComputeSharedMemorySize;
  d.constant_memory_bytes = info.limits.maxUniformBufferRange;
  d.uuid = info.uuid;
  d.pci_bus_id = info.pci_bus_id;
  return d;  // compute units, last-level cache: Vulkan does not say (0)
}

DeviceLimits LimitsOf(const VulkanDeviceInfo& info) {
  const VkPhysicalDeviceLimits& l = info.limits;
  DeviceLimits limits;
  limits.max_wg_size = std::min(l.maxComputeWorkGroupInvocations, l.maxComputeWorkGroupSize[0]);
  limits.local_memory_bytes = l.maxComputeSharedMemorySize;
  limits.constant_memory_bytes = l.maxUniformBufferRange;
  limits.uniform_block_bytes = l.maxUniformBufferRange;
  limits.image_support = l.maxTexelBufferElements > 0;
  limits.image_buffer_max_texels = l.maxTexelBufferElements;
  limits.vertex_shader_storage_blocks = true;  // no vertex stage in the language vulkan
  limits.max_grid_y = l.maxComputeWorkGroupCount[1];
  return limits;
}

}  // namespace skintune::internal::vk
