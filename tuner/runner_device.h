// skintune (internal to tuner/): the tuner's one TunedDevice, over the
// runtime's runner driver (runtime/runner.h) on any device its discovery
// finds (runtime/backend_table.h), whatever the API.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "generator/variant.h"
#include "runtime/backend_table.h"
#include "runtime/device_identity.h"
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

// The bytes of input sets a device's runner keeps across the measurements of
// one data set (Runner::ShareTimedInputs): an eighth of the device's memory,
// at most 1 GiB (8 sets of a 6400k-vertex mesh's inputs: 8 x ~100 MB);
// 256 MiB where the device does not say.
std::size_t SharedInputBytes(const DeviceIdentity& d);

}  // namespace skintune::internal::tuner_internal
