// skintune (internal): what a Device and the Skinners made from it share.
//
// A Device holds a shared_ptr to its DeviceState and every Skinner holds
// another, so a Skinner keeps its device's context, queue and compiled
// programs alive even after the Device object is gone. The runner (of the
// API of `backend`, runtime/backend_table.h) owns (or retains) the API
// objects and holds the compiled programs, which is what makes a second
// Skinner of the same variant on the same Device a memory hit of the program
// cache.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/backend_table.h"
#include "runtime/device_identity.h"
#include "runtime/program_cache.h"
#include "runtime/runner.h"
#include "skintune/skintune.h"

namespace skintune::internal {

struct DeviceState {
  explicit DeviceState(const DeviceOptions& options) : cache(options.program_cache_dir) {}

  DeviceInfo info;
  DeviceLimits limits;
  std::vector<Lang> langs;               // preferred first
  const BackendEntry* backend = nullptr;  // the API's entry
  ProgramCache cache;                    // declared before the runner, which points at it
  std::unique_ptr<Runner> runner;
  bool gl_sharing = false;  // OpenCL context created for the current GL context (cl_khr_gl_sharing)
};

struct DeviceAccess {
  static Device Make(std::shared_ptr<DeviceState> state);
  // The state, or null for a moved-from (or default-constructed) Device.
  static const std::shared_ptr<DeviceState>* State(const Device& device);
};

// The public identity of a device (skintune::Backend is its entry's position
// in the backend table).
DeviceInfo PublicInfo(const DeviceIdentity& identity);

// A Device on `runner` (made for the device `identity` names): its
// languages, limits and program cache. The backends' Device::From* use it.
Device MakeDevice(const DeviceOptions& options, const DeviceIdentity& identity, const DeviceLimits& limits,
                  std::unique_ptr<Runner> runner, bool gl_sharing = false);

}  // namespace skintune::internal

namespace skintune {

struct Device::Impl {
  std::shared_ptr<internal::DeviceState> state;
};

}  // namespace skintune
