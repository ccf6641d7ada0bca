#include "runtime/backends/opencl/opencl_devices.h"

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include <algorithm>
#include <cctype>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "runtime/backends/opencl/opencl_info.h"
#include "runtime/physical_device.h"

namespace skintune::internal {

namespace {

constexpr cl_int kPlatformNotFoundKhr = -1001;  // CL_PLATFORM_NOT_FOUND_KHR from cl_ext.h

template <typename T>
T DeviceValue(cl_device_id device, cl_device_info what) {
  T value{};
  if (clGetDeviceInfo(device, what, sizeof(T), &value, nullptr) != CL_SUCCESS) return T{};
  return value;
}

std::string TypeName(cl_device_type type) {
  std::string name;
  auto add = [&](cl_device_type bit, const char* text) {
    if (type & bit) name += (name.empty() ? "" : "+") + std::string(text);
  };
  add(CL_DEVICE_TYPE_GPU, "gpu");
  add(CL_DEVICE_TYPE_CPU, "cpu");
  add(CL_DEVICE_TYPE_ACCELERATOR, "accelerator");
  add(CL_DEVICE_TYPE_CUSTOM, "custom");
  return name.empty() ? "default" : name;
}

// Which chip the device is, so the same GPU seen through other APIs is
// recognised (runtime/physical_device.h): its UUID (cl_khr_device_uuid) and
// PCI address (cl_khr_pci_bus_info, else NVIDIA's cl_nv_device_attribute_query).
void IdentifyChip(cl_device_id device, OpenClDeviceInfo& d) {
  const auto has = [&](const char* extension) { return d.extensions.find(extension) != std::string::npos; };
  constexpr cl_device_info kDeviceUuidKhr = 0x106A;     // CL_DEVICE_UUID_KHR
  constexpr cl_device_info kPciBusInfoKhr = 0x410F;     // CL_DEVICE_PCI_BUS_INFO_KHR
  constexpr cl_device_info kPciBusIdNv = 0x4008;        // CL_DEVICE_PCI_BUS_ID_NV
  constexpr cl_device_info kPciSlotIdNv = 0x4009;       // CL_DEVICE_PCI_SLOT_ID_NV
  constexpr cl_device_info kPciDomainIdNv = 0x400A;     // CL_DEVICE_PCI_DOMAIN_ID_NV
  if (has("cl_khr_device_uuid")) {
    unsigned char uuid[16] = {};
    if (clGetDeviceInfo(device, kDeviceUuidKhr, sizeof uuid, uuid, nullptr) == CL_SUCCESS) d.uuid = UuidHex(uuid);
  }
  char pci[32] = {};
  if (has("cl_khr_pci_bus_info")) {
    cl_uint bus_info[4] = {};  // cl_device_pci_bus_info_khr: domain, bus, device, function
    if (clGetDeviceInfo(device, kPciBusInfoKhr, sizeof bus_info, bus_info, nullptr) == CL_SUCCESS) {
      std::snprintf(pci, sizeof pci, "%04x:%02x:%02x.%x", bus_info[0], bus_info[1], bus_info[2], bus_info[3]);
      d.pci_bus_id = pci;
      return;
    }
  }
  if (has("cl_nv_device_attribute_query")) {
    cl_uint bus = 0, slot = 0, domain = 0;
    if (clGetDeviceInfo(device, kPciBusIdNv, sizeof bus, &bus, nullptr) == CL_SUCCESS &&
        clGetDeviceInfo(device, kPciSlotIdNv, sizeof slot, &slot, nullptr) == CL_SUCCESS) {
      if (clGetDeviceInfo(device, kPciDomainIdNv, sizeof domain, &domain, nullptr) != CL_SUCCESS) domain = 0;
      // The slot id packs device (bits 3..7) and function (bits 0..2).
      std::snprintf(pci, sizeof pci, "%04x:%02x:%02x.%x", domain, bus, slot >> 3, slot & 7);
      d.pci_bus_id = pci;
    }
  }
}

OpenClDeviceInfo Describe(cl_device_id device) {
  OpenClDeviceInfo d;
  d.name = DeviceString(device, CL_DEVICE_NAME);
  d.vendor = DeviceString(device, CL_DEVICE_VENDOR);
  d.driver_version = DeviceString(device, CL_DRIVER_VERSION);
  d.device_version = DeviceString(device, CL_DEVICE_VERSION);
  d.opencl_c_version = DeviceString(device, CL_DEVICE_OPENCL_C_VERSION);
  d.extensions = DeviceString(device, CL_DEVICE_EXTENSIONS);
  d.type = TypeName(DeviceValue<cl_device_type>(device, CL_DEVICE_TYPE));
  d.compute_units = DeviceValue<cl_uint>(device, CL_DEVICE_MAX_COMPUTE_UNITS);
  d.max_clock_mhz = DeviceValue<cl_uint>(device, CL_DEVICE_MAX_CLOCK_FREQUENCY);
  d.global_memory_bytes = DeviceValue<cl_ulong>(device, CL_DEVICE_GLOBAL_MEM_SIZE);
  d.global_cache_bytes = DeviceValue<cl_ulong>(device, CL_DEVICE_GLOBAL_MEM_CACHE_SIZE);
  d.local_memory_bytes = DeviceValue<cl_ulong>(device, CL_DEVICE_LOCAL_MEM_SIZE);
  d.constant_buffer_bytes = DeviceValue<cl_ulong>(device, CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE);
  d.max_allocation_bytes = DeviceValue<cl_ulong>(device, CL_DEVICE_MAX_MEM_ALLOC_SIZE);
  d.max_work_group_size = DeviceValue<std::size_t>(device, CL_DEVICE_MAX_WORK_GROUP_SIZE);
  d.image_support = DeviceValue<cl_bool>(device, CL_DEVICE_IMAGE_SUPPORT) == CL_TRUE;
  d.image_buffer_max_pixels = DeviceValue<std::size_t>(device, CL_DEVICE_IMAGE_MAX_BUFFER_SIZE);
  IdentifyChip(device, d);
  return d;
}

// `query`'s string answer (clGetPlatformInfo, clGetDeviceInfo) up to its NUL; "" where it fails.
template <typename Handle>
std::string InfoString(cl_int (*query)(Handle, cl_uint, std::size_t, void*, std::size_t*), Handle handle, cl_uint what) {
  std::size_t size = 0;
  if (query(handle, what, 0, nullptr, &size) != CL_SUCCESS || size == 0) return {};
  std::string value(size, '\0');
  if (query(handle, what, size, value.data(), nullptr) != CL_SUCCESS) return {};
  value.resize(value.find('\0') == std::string::npos ? value.size() : value.find('\0'));
  return value;
}

}  // namespace

std::string PlatformString(cl_platform_id platform, cl_platform_info what) {
  return InfoString(clGetPlatformInfo, platform, what);
}

std::string DeviceString(cl_device_id device, cl_device_info what) { return InfoString(clGetDeviceInfo, device, what); }

OpenClInventory EnumerateOpenCl() {
  OpenClInventory inventory;
  cl_uint count = 0;
  const cl_int err = clGetPlatformIDs(0, nullptr, &count);
  if (err == kPlatformNotFoundKhr || (err == CL_SUCCESS && count == 0)) {
    inventory.status = "no OpenCL platform found (no ICD registered in /etc/OpenCL/vendors)";
    return inventory;
  }
  if (err != CL_SUCCESS) {
    inventory.status = "clGetPlatformIDs failed with error " + std::to_string(err);
    return inventory;
  }
  std::vector<cl_platform_id> platforms(count);
  clGetPlatformIDs(count, platforms.data(), nullptr);
  inventory.platform_count = static_cast<int>(count);
  for (cl_uint p = 0; p < count; ++p) {
    cl_uint device_count = 0;
    const cl_int derr = clGetDeviceIDs(platforms[p], CL_DEVICE_TYPE_ALL, 0, nullptr, &device_count);
    const std::string platform_name = PlatformString(platforms[p], CL_PLATFORM_NAME);
    if (derr == CL_DEVICE_NOT_FOUND || device_count == 0) {
      inventory.warnings.push_back("platform '" + platform_name + "' has no devices");
      continue;
    }
    if (derr != CL_SUCCESS) {
      inventory.warnings.push_back("platform '" + platform_name + "': clGetDeviceIDs failed with error " +
                                   std::to_string(derr));
      continue;
    }
    std::vector<cl_device_id> devices(device_count);
    clGetDeviceIDs(platforms[p], CL_DEVICE_TYPE_ALL, device_count, devices.data(), nullptr);
    for (cl_uint d = 0; d < device_count; ++d) {
      OpenClDeviceInfo info = Describe(devices[d]);
      info.platform_index = static_cast<int>(p);
      info.device_index = static_cast<int>(d);
      info.platform_name = platform_name;
      info.platform_vendor = PlatformString(platforms[p], CL_PLATFORM_VENDOR);
      info.platform_version = PlatformString(platforms[p], CL_PLATFORM_VERSION);
      inventory.devices.push_back(std::move(info));
    }
  }
  return inventory;
}

OpenClDeviceInfo DescribeOpenClDevice(void* cl_device) {
  const auto device = static_cast<cl_device_id>(cl_device);
  if (!device) throw Error("OpenCL setup: a null cl_device_id");
  cl_platform_id platform = nullptr;
  const cl_int err = clGetDeviceInfo(device, CL_DEVICE_PLATFORM, sizeof platform, &platform, nullptr);
  if (err != CL_SUCCESS)
    throw Error("OpenCL setup: the cl_device_id is not a device (clGetDeviceInfo failed with error " +
                std::to_string(err) + ")");
  OpenClDeviceInfo info = Describe(device);
  info.platform_index = -1;
  info.device_index = -1;
  info.platform_name = PlatformString(platform, CL_PLATFORM_NAME);
  info.platform_vendor = PlatformString(platform, CL_PLATFORM_VENDOR);
  info.platform_version = PlatformString(platform, CL_PLATFORM_VERSION);
  return info;
}

bool OpenClContextSharesGl(void* context_handle) {
  constexpr cl_context_properties kGlContextKhr = 0x2008;  // CL_GL_CONTEXT_KHR from cl_gl.h
  const auto context = static_cast<cl_context>(context_handle);
  std::size_t size = 0;
  if (!context || clGetContextInfo(context, CL_CONTEXT_PROPERTIES, 0, nullptr, &size) != CL_SUCCESS) return false;
  std::vector<cl_context_properties> properties(size / sizeof(cl_context_properties));
  if (properties.empty() ||
      clGetContextInfo(context, CL_CONTEXT_PROPERTIES, size, properties.data(), nullptr) != CL_SUCCESS)
    return false;
  for (std::size_t i = 0; i + 1 < properties.size(); i += 2) {
    if (properties[i] == 0) break;
    if (properties[i] == kGlContextKhr && properties[i + 1] != 0) return true;
  }
  return false;
}

DeviceIdentity IdentityOf(const OpenClDeviceInfo& device) {
  DeviceIdentity d;
  d.backend = "opencl";
  d.platform = device.platform_name;
  d.vendor = device.vendor;
  d.name = device.name;
  d.driver_version = device.driver_version;
  d.api_version = device.device_version;
  d.type = device.type;
  d.compute_units = device.compute_units;
  d.global_memory_bytes = device.global_memory_bytes;
  d.local_memory_bytes = device.local_memory_bytes;
  d.constant_memory_bytes = device.constant_buffer_bytes;
  d.last_level_cache_bytes = device.global_cache_bytes;  // CL_DEVICE_GLOBAL_MEM_CACHE_SIZE
  d.uuid = device.uuid;
  d.pci_bus_id = device.pci_bus_id;
  return d;
}

DeviceLimits LimitsOf(const OpenClDeviceInfo& d) {
  DeviceLimits limits;
  limits.max_wg_size = d.max_work_group_size;
  limits.local_memory_bytes = d.local_memory_bytes;
  limits.constant_memory_bytes = d.constant_buffer_bytes;
  limits.image_support = d.image_support;
  limits.image_buffer_max_texels = d.image_support ? d.image_buffer_max_pixels : 0;
  return limits;
}

std::vector<OpenClDeviceInfo> MatchDevices(const OpenClInventory& inventory, const std::string& pattern) {
  std::vector<OpenClDeviceInfo> matches;
  for (const OpenClDeviceInfo& d : inventory.devices)
    if (MatchesDevice(pattern, IdentityOf(d))) matches.push_back(d);
  return matches;
}

void to_json(nlohmann::json& out, const OpenClDeviceInfo& d) {
  out = {{"platform_index", d.platform_index},
         {"device_index", d.device_index},
         {"platform", {{"name", d.platform_name}, {"vendor", d.platform_vendor}, {"version", d.platform_version}}},
         {"name", d.name},
         {"vendor", d.vendor},
         {"driver_version", d.driver_version},
         {"device_version", d.device_version},
         {"opencl_c_version", d.opencl_c_version},
         {"type", d.type},
         {"compute_units", d.compute_units},
         {"max_clock_mhz", d.max_clock_mhz},
         {"global_memory_bytes", d.global_memory_bytes},
         {"global_cache_bytes", d.global_cache_bytes},
         {"uuid", d.uuid},
         {"pci_bus_id", d.pci_bus_id},
         {"local_memory_bytes", d.local_memory_bytes},
         {"constant_buffer_bytes", d.constant_buffer_bytes},
         {"max_allocation_bytes", d.max_allocation_bytes},
         {"max_work_group_size", d.max_work_group_size},
         {"image_support", d.image_support},
         {"image_buffer_max_pixels", d.image_buffer_max_pixels}};
}

}  // namespace skintune::internal
