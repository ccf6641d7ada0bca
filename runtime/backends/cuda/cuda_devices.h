// skintune (internal): CUDA devices as the driver describes them, without a
// context, and their identity (runtime/device_identity.h).
#pragma once

#include <cstdint>
#include <string>

#include "generator/constraints.h"
#include "runtime/device_identity.h"

namespace skintune::internal {

// What the driver says about a device, without a context (QueryCudaDevice).
struct CudaDeviceInfo {
  int index = 0;
  std::string name;
  int major = 0, minor = 0;                  // compute capability
  std::string arch;                          // NvrtcArchFor(major, minor); empty when NVRTC is older
  int multiprocessors = 0;
  int clock_khz = 0;
  std::uint64_t total_memory_bytes = 0;      // cuDeviceTotalMem (0 when the driver lacks it)
  std::uint64_t l2_cache_bytes = 0;
  std::string uuid;                          // cuDeviceGetUuid, 32 hex digits ("" when unknown)
  std::string pci_bus_id;                    // "dddd:bb:dd.0" from the PCI attributes
  int driver_version = 0;                    // cuDriverGetVersion: 13000 = CUDA 13.0
  DeviceLimits limits;                       // threads per block, static __shared__, __constant__, texture width
};

// Throws Error("CUDA setup: ...") when there is no NVRTC, no driver or no such device.
CudaDeviceInfo QueryCudaDevice(int device_index);

// The CUDA device's driver version: "<kernel driver> (CUDA <major>.<minor>)",
// e.g. "580.159.04 (CUDA 13.0)", or "CUDA 13.0" alone when the kernel driver's
// version cannot be found (/proc/driver/nvidia/version, else NVML loaded at
// run time). `cuda_driver_version` is cuDriverGetVersion's (13000 = 13.0).
std::string CudaDriverVersionText(int cuda_driver_version);

// Backend "cuda", platform "CUDA", vendor "NVIDIA", type "gpu", the driver
// version above, the compute capability as the API version, the L2 as the
// last-level cache.
DeviceIdentity IdentityOf(const CudaDeviceInfo& device);

}  // namespace skintune::internal
