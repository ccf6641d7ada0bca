// skintune: a tuning run: a config (space, datasets, timing, strategy,
// tuner/config.h), every device found, each device's work in a child process
// with a time limit per variant, every measurement appended to the cache as
// it is taken. tune.cpp says how the run is put together: a plan
// (tuner/plan.h), a schedule (tuner/schedule.h), each device's tuning
// (tuner/device_tuning.h) through its worker (tuner/worker.h).
#pragma once

#include <cstdint>
#include <string>

#include "tuner/config.h"
#include "tuner/report.h"

namespace skintune::internal {

// Runs the whole tuning; every measurement goes through the cache (a recorded
// one is reused, never re-measured). Throws Error for bad set-up (empty space
// after constraints on every device, unwritable cache) before any device
// measures.
TuningReport RunTuning(const TuneConfig& config, const TuneOptions& options);

// What the child process is told (`skintune tune-worker --device-index N
// [--device-id ID] [--host-lock PATH] [--chip-lock CHIP] [--discover-only API]
// [--cache-bytes B --cache-source TEXT]`; tuner/worker.h WorkerArguments).
struct TuneWorkerArgs {
  int device_index = 0;        // a hint when device_id is given
  std::string device_id;       // selects the device
  std::string host_lock;       // the host lock shared with the other workers (tuner/host_lock.h)
  std::string chip_lock;       // the lock of the GPU shared with its other APIs' workers
  std::string discover_only;   // the only API whose devices it looks for ("": every API's)
  std::uint64_t cache_bytes = 0;  // the device's last-level cache as the parent resolved it (0: its own API's)
  std::string cache_source;       // where the parent's figure came from
};

// The child process reads one JSON request per line on stdin ({"variant":
// ..., "dataset": ..., "timing": ...}) and writes one Measurement JSON per
// line on stdout (tuner/worker.h has the whole protocol).
int RunTuneWorker(const TuneWorkerArgs& args);

}  // namespace skintune::internal
