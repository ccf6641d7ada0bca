// skintune (internal): what a Device and the Skinners made from it share.
//
// A Device holds a shared_ptr to its DeviceState and every Skinner holds
// another, so a Skinner keeps its device's context, queue and compiled
// programs alive even after the Device object is gone. Exactly one runner is
// set, the one of info.backend; the runners own (or retain) the API objects
// and hold the compiled programs, which is what makes a second Skinner of
// the same variant on the same Device a memory hit of the program cache.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/backends/cuda/cuda_runner.h"
#include "runtime/backends/gl/gl_runner.h"
#include "runtime/backends/opencl/opencl_devices.h"
#include "runtime/backends/opencl/opencl_runner.h"
#include "runtime/program_cache.h"
#include "skintune/skintune.h"

namespace skintune {

struct DeviceState {
  explicit DeviceState(const DeviceOptions& options) : cache(options.program_cache_dir) {}

  DeviceInfo info;
  DeviceLimits limits;
  std::vector<Lang> langs;  // preferred first
  ProgramCache cache;       // declared before the runners, which point at it
  std::unique_ptr<OpenClRunner> opencl;
  std::unique_ptr<CudaRunner> cuda;
  std::unique_ptr<GlRunner> gl;
  bool gl_sharing = false;  // OpenCL context created for the current GL context (cl_khr_gl_sharing)
};

struct Device::Impl {
  std::shared_ptr<DeviceState> state;
};

struct DeviceAccess {
  static Device Make(std::shared_ptr<DeviceState> state);
  // The state, or null for a moved-from (or default-constructed) Device.
  static const std::shared_ptr<DeviceState>* State(const Device& device);
};

// The public identity of an OpenCL device (its id as the tuner writes it).
DeviceInfo PublicInfo(const OpenClDeviceInfo& device);

}  // namespace skintune
