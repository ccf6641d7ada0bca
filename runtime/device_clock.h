// skintune (internal): a GPU's SM clock as its driver reports it, so that the
// tuner times kernels only at the clock the GPU runs at under load.
//
// A kernel of 5k-100k vertices takes 3-8 us on an H200, mostly latency, so
// its time follows the SM clock. NVIDIA's driver lowers that clock whenever
// the GPU idles for a few milliseconds, and a tuner's GL or Vulkan worker,
// alone on the chip between its compiles and verifications, kept it there:
// in three cold default runs on the H200 machine (2026-11-29) the SM clock
// read 630-1500 MHz instead of 1980 through parts of those turns, and the
// same winners' kernel times moved up to 47% between the runs. CUDA's and
// NVIDIA OpenCL's turns stayed at 1980 MHz throughout.
//
// On NVIDIA GPUs the clock is read through NVML (runtime/backends/cuda/nvml.h:
// part of the driver, loaded at run time like libcuda), the GPU matched by
// the UUID or the PCI bus id its API reported. Other GPUs have no such
// reader: Open says why.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "runtime/device_identity.h"

namespace skintune::internal {

class DeviceClock {
 public:
  virtual ~DeviceClock() = default;
  // The SM clock now, MHz; nothing when the driver does not answer.
  virtual std::optional<unsigned> SmMhz() = 0;
  // The highest SM clock the GPU may run at (its boost), MHz; nothing when unknown.
  virtual std::optional<unsigned> MaxSmMhz() = 0;

  // The clock of `device` (an NVIDIA GPU with a UUID or PCI bus id), or
  // null with the reason in `why` (a CPU device, another vendor, no NVML,
  // the GPU not found by NVML).
  static std::unique_ptr<DeviceClock> Open(const DeviceIdentity& device, std::string* why);
};

// Holds NVIDIA GPUs at the clocks a compute context gets, for as long as it
// lives: an idle CUDA context (each GPU's primary context) on every NVIDIA
// GPU among `devices` (matched by UUID; every CUDA GPU where one of them
// has none). NVIDIA's driver lowers the SM clock of a GPU that only GL or
// Vulkan use whenever it idles for a few milliseconds, and keeps it up
// while a CUDA context exists: on the H200 machine (2026-11-29) a
// Vulkan-only tuning run read the clock below 1920 MHz in 264 of 1164
// samples (20 ms apart; down to 345 MHz), and in none of 863 with a CUDA
// context held by another process. The tuner holds one while it tunes, so
// that GL's and Vulkan's kernels are timed at the clock CUDA's and OpenCL's
// are. A GPU in an exclusive compute mode is not held (a second context
// would fail its own worker's). Null, with the reason in `why`, when
// nothing is held (no NVIDIA GPU among `devices`, no CUDA driver).
class ClockHold {
 public:
  ~ClockHold();
  ClockHold(const ClockHold&) = delete;
  ClockHold& operator=(const ClockHold&) = delete;
  static std::unique_ptr<ClockHold> ForDevices(const std::vector<DeviceIdentity>& devices, std::string* why);
  std::size_t held() const { return held_.size(); }  // GPUs held

 private:
  ClockHold() = default;
  std::vector<int> held_;  // CUDA device handles (CUdevice) whose primary context is retained
};

// NVML's name of a UUID given as 32 hex digits: "GPU-8-4-4-4-12"; "" when
// `hex32` is not 32 hex digits.
std::string NvmlUuid(const std::string& hex32);

}  // namespace skintune::internal
