// skintune: which devices a tuning run may measure at the same time.
//
// Two devices that share hardware must never be timed at once: the same GPU
// seen through OpenCL, CUDA and GL is one chip, and every CPU device (PoCL,
// llvmpipe) runs on the host's cores. Devices that share nothing (a CPU
// OpenCL device and a GPU, or two GPUs) are independent: their workers run
// side by side.
//
// The rule, from DeviceIdentity alone: a device whose type names "cpu" is the
// host; two CPU devices share it, a CPU device and a GPU share nothing. Two
// GPUs are different chips only when the identities say so: both have a UUID
// and they differ, or, without two UUIDs, both have a PCI bus id and they
// differ (runtime/physical_device.h matches chips the same way). A GPU whose
// API tells neither may be any chip, so it shares with every GPU: never
// wrong, only slower.
#pragma once

#include <cstddef>
#include <vector>

#include "runtime/device_identity.h"

namespace skintune::internal {

// Whether `a` and `b` may share hardware (the rule above).
bool MayShareHardware(const DeviceIdentity& a, const DeviceIdentity& b);

// The devices (indices into `devices`) grouped so that devices that may share
// hardware, directly or through others, are in one group: groups in the
// order of their first device, each group's devices in their order. The
// devices of a group are tuned one after another; the groups at the same time.
std::vector<std::vector<std::size_t>> IndependentGroups(const std::vector<DeviceIdentity>& devices);

}  // namespace skintune::internal
