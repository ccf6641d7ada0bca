// skintune (internal): NVML, NVIDIA's management library (libnvidia-ml,
// part of the driver), loaded at run time like libcuda and libcupti.
//
// Two readers use it: the kernel driver's version where /proc has none
// (cuda_devices.cpp) and a GPU's SM clock (runtime/device_clock.h). The
// library is SKINTUNE_NVML_LIBRARY (a path or soname) when set, and then
// only it; otherwise libnvidia-ml.so.1. It is loaded and initialised once
// per process and never shut down or unloaded. The few functions used are
// declared here (NVML's C API, stable since 2012); a function the loaded
// library lacks is null, and each reader checks the ones it calls.
#pragma once

#include <string>

namespace skintune::internal::nvml {

using Return = int;    // nvmlReturn_t; 0 = NVML_SUCCESS
using Device = void*;  // nvmlDevice_t
inline constexpr int kClockSm = 1;  // nvmlClockType_t NVML_CLOCK_SM

struct Api {
  Return (*init)();                                                 // nvmlInit_v2
  Return (*by_uuid)(const char* uuid, Device* device);             // nvmlDeviceGetHandleByUUID
  Return (*by_pci_bus_id)(const char* pci_bus_id, Device* device);  // nvmlDeviceGetHandleByPciBusId_v2
  Return (*clock)(Device device, int type, unsigned* mhz);         // nvmlDeviceGetClockInfo
  Return (*max_clock)(Device device, int type, unsigned* mhz);     // nvmlDeviceGetMaxClockInfo
  Return (*driver_version)(char* text, unsigned length);           // nvmlSystemGetDriverVersion
};

// NVML, loaded and initialised; null with the reason in `why` ("NVML not
// found (...)", "nvmlInit_v2 failed (N)") when it cannot be.
const Api* Library(std::string* why = nullptr);

}  // namespace skintune::internal::nvml
