// skintune: a tuning run: a config (space, datasets, timing, strategy,
// tuner/config.h), every device found, each device's work in a child process
// with a time limit per variant, every measurement appended to the cache as
// it is taken. tune.cpp says how the run is put together: a plan
// (tuner/plan.h), a schedule (tuner/schedule.h), each device's tuning
// (tuner/device_tuning.h) through its worker (tuner/worker.h).
#pragma once

#include <string>

#include "tuner/config.h"
#include "tuner/report.h"

namespace skintune::internal {

// Runs the whole tuning; every measurement goes through the cache (a recorded
// one is reused, never re-measured). Throws Error for bad set-up (empty space
// after constraints on every device, unwritable cache) before any device
// measures.
TuningReport RunTuning(const TuneConfig& config, const TuneOptions& options);

// The child process: `skintune tune-worker --device-index N [--device-id ID]
// [--host-lock PATH] [--chip-lock CHIP] [--discover-only API]` (ID, when
// given, selects the device and N is ignored; PATH: the host lock shared with
// the other workers, CHIP: the lock of the GPU shared with its other APIs'
// workers, tuner/host_lock.h; API: the only API whose devices it looks for,
// tuner/worker.h DiscoversAlone) reads one JSON request per line on stdin
// ({"variant": ..., "dataset": ..., "timing": ...}) and writes one
// Measurement JSON per line on stdout (tuner/worker.h has the whole protocol).
int RunTuneWorker(int device_index, const std::string& device_id = "", const std::string& host_lock = "",
                  const std::string& chip_lock = "", const std::string& discover_only = "");

}  // namespace skintune::internal
