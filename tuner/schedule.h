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

#include <atomic>
#include <cstddef>
#include <functional>
#include <vector>

#include "runtime/device_identity.h"

namespace skintune::internal {

// Whether `d` is the host's CPU (its type names "cpu", any case): its work
// takes the host's cores (tuner/host_lock.h), and its times move more than
// a GPU's (TimingOptions::host_tie_margin).
bool IsHostCpu(const DeviceIdentity& d);
// Whether `d` is a GL or Vulkan device that is the host's CPU emulating a GPU
// (Mesa's llvmpipe and lavapipe): tuned only when asked for (tuner/plan.h).
bool IsSoftwareRasterizer(const DeviceIdentity& d);

// Whether `a` and `b` may share hardware (the rule above).
bool MayShareHardware(const DeviceIdentity& a, const DeviceIdentity& b);

// The devices (indices into `devices`) grouped so that devices that may share
// hardware, directly or through others, are in one group: groups in the
// order of their first device, each group's devices in their order. The
// devices of a group are tuned one after another; the groups at the same time.
std::vector<std::vector<std::size_t>> IndependentGroups(const std::vector<DeviceIdentity>& devices);

// When a tuning run measures its devices.
struct Schedule {
  // Indices into the devices scheduled: the groups run at the same time,
  // each group's devices one after another, but for a group that shares a chip.
  std::vector<std::vector<std::size_t>> groups;
  // Per group: its devices are GPUs (one chip seen through several APIs, or
  // GPUs that cannot be told apart), tuned at the same time, each API's
  // worker holding the chip's lock for its work on it (tuner/host_lock.h
  // ChipLock), so that one API's compiles, start-up and host work overlap
  // another's measurements. Only where no CPU device is tuned beside them:
  // on the H200 machine (2026-11-28, three cold default runs) the GPU's five
  // languages at once ended after 52-69 s instead of 61-69, but their four
  // workers' host work, waited for by PoCL's timing (the host lock), made
  // PoCL 52 s instead of 40-48, the run 71-74 s instead of 63-72, and three
  // of PoCL's rows name different winners in the three runs.
  std::vector<bool> shares_chip;
  // A CPU device is tuned at the same time as another group: the workers
  // share a lock on the host's cores (tuner/host_lock.h), so that no GPU's
  // host work runs while a CPU device is timing.
  bool shares_host = false;
};

// The devices' IndependentGroups, a group of GPUs sharing its chip; with
// `parallel` false, one group of every device in order (one device after
// another, sharing nothing). A chip's APIs keep discovery order (NVIDIA's
// OpenCL first): taking it last, so that its slow compiles (78-104 ms a
// kernel, one at a time) ran beside the other APIs' turns, made those turns
// twice as long (CUDA 23 s instead of 10-11, Vulkan 35-50 s instead of 22)
// and the run no shorter (97-112 s, H200 machine, 2026-11-29): loading
// NVIDIA OpenCL programs on the chip disturbs whatever is timed on it.
Schedule ScheduleDevices(const std::vector<DeviceIdentity>& devices, bool parallel);

// Runs tune(i) for every device i of `schedule`: each group on a thread of
// its own (the first on the calling thread), its devices in order, or each
// device on a thread of its own where the group shares a chip. Beside a
// group of several devices taken in order, ahead(group, reached) runs on another thread,
// `reached` telling how many of the group's devices have had their turn
// (the group's size once it is done), so that it can prepare the later ones
// (tune.cpp compiles their kernels). Returns when every thread has ended;
// then rethrows the first group's exception, if any.
using GroupAhead = std::function<void(const std::vector<std::size_t>& group, const std::atomic<std::size_t>& reached)>;
void RunSchedule(const Schedule& schedule, const std::function<void(std::size_t device)>& tune, const GroupAhead& ahead);

}  // namespace skintune::internal
