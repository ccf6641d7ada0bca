// The runner of the machine's first OpenCL device (PoCL here), made once per
// test program, for the tests that run kernels built outside the runtime's
// own paths (from a sidecar, from the generated header).
#pragma once

#include <memory>
#include <string>

#include "runtime/backends/opencl/opencl_devices.h"
#include "runtime/backends/opencl/opencl_runner.h"

namespace skintune::internal::testing {

// Null, with the reason in `why`, on a machine without an OpenCL device.
inline OpenClRunner* FirstOpenClRunner(std::string& why) {
  static std::string reason;
  static const std::unique_ptr<OpenClRunner> runner = []() -> std::unique_ptr<OpenClRunner> {
    const OpenClInventory inventory = EnumerateOpenCl();
    if (inventory.devices.empty()) {
      reason = "no OpenCL device on this machine: " + inventory.status;
      return nullptr;
    }
    return std::make_unique<OpenClRunner>(inventory.devices.front().platform_index,
                                          inventory.devices.front().device_index);
  }();
  why = reason;
  return runner.get();
}

}  // namespace skintune::internal::testing
