// skintune: which devices a tuning run may measure at the same time.
//
// Two devices that share hardware must never be timed at once: the same GPU
// seen through OpenCL, CUDA and GL is one chip, and every CPU device (PoCL,
// llvmpipe) runs on the host's cores. Devices that share nothing (a CPU
// OpenCL device and a GPU) are independent: their workers run side by side.
//
// The rule, from DeviceIdentity alone: every device whose type names "cpu"
// is the host; every other device is "a GPU", and all GPUs are taken to be
// one chip. DeviceIdentity carries no UUID or PCI bus id yet
// (runtime/physical_device.h matches them, but discovery does not record
// them), so two GPUs of one machine are tuned one after the other: never
// wrong, only slower on a multi-GPU machine.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "runtime/device_identity.h"

namespace skintune {

// The hardware a device runs on: "host" for CPU devices, "gpu" otherwise.
std::string HardwareOf(const DeviceIdentity& device);

// The devices (indices into `devices`) grouped by HardwareOf, groups in the
// order of their first device, each group's devices in their order. The
// devices of a group are tuned one after another; the groups at the same time.
std::vector<std::vector<std::size_t>> IndependentGroups(const std::vector<DeviceIdentity>& devices);

}  // namespace skintune
