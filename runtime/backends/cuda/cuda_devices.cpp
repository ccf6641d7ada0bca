// CUDA devices: what the driver says about one (QueryCudaDevice), its
// identity, and the CUDA part of discovery (runtime/backend_table.h).
#include "runtime/backends/cuda/cuda_devices.h"

#include <dlfcn.h>

#include <cctype>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "base/error.h"
#include "runtime/backends/cuda/nvml.h"
#include "runtime/physical_device.h"
#include "runtime/backends/cuda/cuda_api.h"

namespace skintune::internal {

namespace {

using cuda::Check;
using cuda::Fail;

// Device attributes beyond cuda_api.h's.
constexpr int kAttributeClockRate = 13;          // CU_DEVICE_ATTRIBUTE_CLOCK_RATE (kHz)
constexpr int kAttributeMultiprocessorCount = 16;  // CU_DEVICE_ATTRIBUTE_MULTIPROCESSOR_COUNT
constexpr int kAttributeL2CacheSize = 38;        // CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE (bytes)
constexpr int kAttributePciBusId = 33;          // CU_DEVICE_ATTRIBUTE_PCI_BUS_ID
constexpr int kAttributePciDeviceId = 34;       // CU_DEVICE_ATTRIBUTE_PCI_DEVICE_ID
constexpr int kAttributePciDomainId = 50;       // CU_DEVICE_ATTRIBUTE_PCI_DOMAIN_ID
constexpr int kAttributeMaxGridDimY = 6;         // CU_DEVICE_ATTRIBUTE_MAX_GRID_DIM_Y (instances per launch)

// cuDeviceTotalMem_v2 from the driver library Probe() loaded (cuda_api.h
// does not declare it); 0 when it cannot be found.
std::uint64_t TotalMemory(const std::string& library, cuda::Device device) {
  void* handle = dlopen(library.c_str(), RTLD_LAZY | RTLD_NOLOAD);
  if (!handle) return 0;
  using TotalMem = cuda::Result (*)(std::size_t*, cuda::Device);
  const auto total_mem = reinterpret_cast<TotalMem>(dlsym(handle, "cuDeviceTotalMem_v2"));
  std::size_t bytes = 0;
  const bool ok = total_mem && total_mem(&bytes, device) == cuda::kSuccess;
  dlclose(handle);  // drops the reference RTLD_NOLOAD added; the driver stays loaded
  return ok ? bytes : 0;
}

// The kernel driver's version ("580.159.04"): from /proc/driver/nvidia/version,
// else from NVML (nvml.h: loaded at run time like the rest of CUDA;
// containers often have no /proc entry), else empty (the CUDA version then
// stands alone). Looked up once per process.
std::string KernelDriverVersion() {
  static const std::string version = []() -> std::string {
    std::ifstream in("/proc/driver/nvidia/version");
    std::string line;
    if (std::getline(in, line)) {
      // "NVRM version: NVIDIA UNIX x86_64 Kernel Module  580.159.04  Tue ..."
      std::istringstream words(line);
      std::string word, previous;
      while (words >> word) {
        if (previous == "Module" && std::isdigit(static_cast<unsigned char>(word[0]))) return word;
        previous = word;
      }
    }
    const nvml::Api* api = nvml::Library();
    std::string found;
    char text[96] = {};
    if (api && api->driver_version && api->driver_version(text, sizeof text - 1) == 0) found = text;
    return found;
  }();
  return version;
}

std::string CudaVersion(int version) {
  return "CUDA " + std::to_string(version / 1000) + "." + std::to_string(version % 1000 / 10);
}

}  // namespace

CudaDeviceInfo QueryCudaDevice(int device_index) {
  const CudaAvailability available = Probe();
  if (!available.nvrtc) Fail("setup", available.nvrtc_missing);
  if (!available.driver) Fail("setup", available.driver_missing);
  const cuda::DriverApi* api = cuda::Driver();
  if (!api) Fail("setup", available.driver_missing);
  if (device_index < 0 || device_index >= available.device_count)
    Fail("setup", "no device " + std::to_string(device_index) + " (" + std::to_string(available.device_count) +
                      " devices" + (available.device_count == 0 ? ": " + available.driver_missing : "") + ")");
  cuda::Device device = 0;
  Check(api->cuDeviceGet(&device, device_index), "setup", "cuDeviceGet " + std::to_string(device_index));
  CudaDeviceInfo info;
  info.index = device_index;
  char text[256] = {};
  Check(api->cuDeviceGetName(text, sizeof text - 1, device), "setup", "cuDeviceGetName");
  info.name = text;
  auto attribute = [&](int which, const char* what) {
    int value = 0;
    Check(api->cuDeviceGetAttribute(&value, which, device), "setup", std::string("cuDeviceGetAttribute ") + what);
    return value;
  };
  info.major = attribute(cuda::kAttributeComputeCapabilityMajor, "(compute capability)");
  info.minor = attribute(cuda::kAttributeComputeCapabilityMinor, "(compute capability)");
  info.multiprocessors = attribute(kAttributeMultiprocessorCount, "(multiprocessors)");
  info.clock_khz = attribute(kAttributeClockRate, "(clock rate)");
  info.l2_cache_bytes = static_cast<std::uint64_t>(attribute(kAttributeL2CacheSize, "(L2 cache size)"));
  unsigned char uuid[16] = {};
  if (api->cuDeviceGetUuid && api->cuDeviceGetUuid(uuid, device) == cuda::kSuccess) info.uuid = UuidHex(uuid);
  char pci[32];
  std::snprintf(pci, sizeof pci, "%04x:%02x:%02x.0", attribute(kAttributePciDomainId, "(PCI domain)"),
                attribute(kAttributePciBusId, "(PCI bus)"), attribute(kAttributePciDeviceId, "(PCI device)"));
  info.pci_bus_id = pci;
  info.total_memory_bytes = TotalMemory(available.driver_library, device);
  info.driver_version = available.driver_version;
  info.limits.max_wg_size = static_cast<std::size_t>(attribute(cuda::kAttributeMaxThreadsPerBlock, "(threads per block)"));
  info.limits.local_memory_bytes =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeMaxSharedMemoryPerBlock, "(shared memory per block)"));
  info.limits.constant_memory_bytes =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeTotalConstantMemory, "(constant memory)"));
  info.limits.image_support = true;  // texture objects: every device CUDA 11+ runs on
  info.limits.image_buffer_max_texels =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeMaxTexture1dLinearWidth, "(1D linear texture width)"));
  info.limits.max_grid_y = static_cast<std::uint64_t>(attribute(kAttributeMaxGridDimY, "(grid y)"));
  info.arch = NvrtcArchFor(info.major, info.minor);
  return info;
}

std::string CudaDriverVersionText(int cuda_driver_version) {
  const std::string kernel_driver = KernelDriverVersion();
  const std::string cuda = CudaVersion(cuda_driver_version);
  return kernel_driver.empty() ? cuda : kernel_driver + " (" + cuda + ")";
}

DeviceIdentity IdentityOf(const CudaDeviceInfo& device) {
  DeviceIdentity d;
  d.backend = "cuda";
  d.platform = "CUDA";
  d.vendor = "NVIDIA";
  d.name = device.name;
  d.driver_version = CudaDriverVersionText(device.driver_version);
  d.api_version = std::to_string(device.major) + "." + std::to_string(device.minor);
  d.type = "gpu";
  d.compute_units = static_cast<std::uint32_t>(device.multiprocessors);
  d.global_memory_bytes = device.total_memory_bytes;
  d.local_memory_bytes = device.limits.local_memory_bytes;
  d.constant_memory_bytes = device.limits.constant_memory_bytes;
  d.last_level_cache_bytes = device.l2_cache_bytes;  // CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE
  d.uuid = device.uuid;
  d.pci_bus_id = device.pci_bus_id;
  return d;
}

}  // namespace skintune::internal
