// skintune: what OpenCL offers on this machine: every platform that
// clGetPlatformIDs enumerates and every device of every type on each.
//
// A machine with no ICD loader configuration or no platform is not an error:
// the result is empty and `status` says why, so callers report the backend
// as skipped.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/constraints.h"
#include "runtime/device_identity.h"

namespace skintune::internal {

struct OpenClDeviceInfo {
  int platform_index = 0;
  int device_index = 0;
  std::string platform_name, platform_vendor, platform_version;
  std::string name, vendor, driver_version, device_version, opencl_c_version;
  std::string type;  // "gpu", "cpu", "accelerator", "custom" or "default", joined with '+' if several
  std::uint32_t compute_units = 0;
  std::uint32_t max_clock_mhz = 0;
  std::uint64_t global_memory_bytes = 0;
  std::uint64_t global_cache_bytes = 0;
  std::string uuid;        // cl_khr_device_uuid's CL_DEVICE_UUID_KHR, 32 hex digits ("" when not offered)
  std::string pci_bus_id;  // cl_khr_pci_bus_info or cl_nv_device_attribute_query: "dddd:bb:dd.f" ("" when neither)
  std::uint64_t local_memory_bytes = 0;
  std::uint64_t constant_buffer_bytes = 0;
  std::uint64_t max_allocation_bytes = 0;
  std::size_t max_work_group_size = 0;
  bool image_support = false;
  std::uint64_t image_buffer_max_pixels = 0;
  std::string extensions;
};

struct OpenClInventory {
  std::vector<OpenClDeviceInfo> devices;
  int platform_count = 0;
  std::string status;  // empty when at least one platform answered; otherwise why none
  std::vector<std::string> warnings;  // a platform or device that failed a query
};

OpenClInventory EnumerateOpenCl();

// One device the caller already has (a cl_device_id), with its platform's
// name, vendor and version; platform_index and device_index are -1. Throws
// Error when the handle is not a device OpenCL knows.
OpenClDeviceInfo DescribeOpenClDevice(void* cl_device);

// Whether the context (a cl_context) was created for a GL context: its
// properties include CL_GL_CONTEXT_KHR (cl_khr_gl_sharing).
bool OpenClContextSharesGl(void* cl_context);

// The limits the generator's constraints need, from the device's own answers.
DeviceLimits LimitsOf(const OpenClDeviceInfo& device);

// Backend "opencl": the platform's name, the device's vendor, name, driver
// version, OpenCL version and type, CL_DEVICE_GLOBAL_MEM_CACHE_SIZE as the
// last-level cache.
DeviceIdentity IdentityOf(const OpenClDeviceInfo& device);

// The devices `pattern` matches by the one --device rule (MatchesDevice,
// runtime/device_identity.h, on IdentityOf); an empty pattern matches every device.
std::vector<OpenClDeviceInfo> MatchDevices(const OpenClInventory& inventory, const std::string& pattern);

void to_json(nlohmann::json& out, const OpenClDeviceInfo& device);

}  // namespace skintune::internal
