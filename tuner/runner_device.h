// skintune (internal to tuner/): the tuner's one TunedDevice, over the
// runtime's runner driver (runtime/runner.h) on any device its discovery
// finds (runtime/backend_table.h), whatever the API.
#pragma once

#include <memory>
#include <vector>

#include "generator/variant.h"
#include "runtime/backend_table.h"
#include "tuner/executor.h"
#include "tuner/tuned_device.h"

namespace skintune::internal::tuner_internal {

// The TunedDevice of a device discovery found, running `languages`, numbered
// `index`, measuring through the RunnerExecutor over its runner, wrapped in
// `decorate` when given (tuner/fault_injection.h). Its runner is opened on
// the first Measure or copy, so discovery in a worker that serves one device
// sets up only that one.
std::unique_ptr<TunedDevice> MakeRunnerDevice(FoundDevice device, std::vector<Lang> languages, int index,
                                              ExecutorDecorator decorate = {});

// Every device found (DiscoverTunedDevices), each measuring through
// `decorate` when given.
Discovery DiscoverTunedDevices(const ExecutorDecorator& decorate);

}  // namespace skintune::internal::tuner_internal
