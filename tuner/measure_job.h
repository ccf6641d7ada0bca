// skintune (internal to tuner/): the jobs a tuned device runs, in the manner
// of ozz-animation's jobs: a struct of inputs and outputs that Validate()
// checks and Run() carries out, knowing nothing of which device, process or
// test runs it.
//
// - MeasureJob: one variant verified against the float64 gold, then timed
//   (docs/TUNING.md "Timing"); every device's Measure is this job.
// - RaceJob: verified variants measured again, interleaved, until their
//   kernel times separate or prove equal (docs/TUNING.md "Races and ties").
//
// Both reach the device only through an Executor (tuner/executor.h), so a
// test gives them a fake one, and the failure tests a decorated one
// (tuner/fault_injection.h).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/device_identity.h"
#include "tuner/datasets.h"
#include "tuner/executor.h"
#include "tuner/measurement.h"
#include "tuner/timing_options.h"
#include "tuner/tuned_device.h"  // TuningDataset

namespace skintune::internal::tuner_internal {

// ---------------------------------------------------------------- rotation rule

// The last-level cache assumed when a device does not report one.
inline constexpr std::uint64_t kUnknownLastLevelCacheBytes = 64ull << 20;

// Input sets to rotate among while timing, so that no repetition finds its
// inputs in cache: K = ceil(2 * LLC / bytes_per_set), clamped to
// 1..max_input_sets (at least 1 whatever max_input_sets says), with LLC =
// last_level_cache_bytes, or kUnknownLastLevelCacheBytes when that is 0;
// then made even (one up, or one down at max_input_sets) when above 1, so
// the two lanes of CUDA and OpenCL bursts never share a set.
int InputSetsFor(std::uint64_t last_level_cache_bytes, std::uint64_t bytes_per_set, int max_input_sets);

// ---------------------------------------------------------------- the jobs

// Measures one variant on one device: checks it against the device's
// languages and limits and the scene's shape (invalid, naming every broken
// constraint), packs and emits it (invalid when that throws), verifies one
// run against the gold, each instance or batch mesh on its own
// (compile_failed / launch_failed / verify_failed, naming the part), records
// its error against the unquantised source, then measures its kernel time
// (cold samples rotating among InputSetsFor(...) input sets, to the stop
// rule), its frame time, and the same-size copy's kernel time by the same
// method (x_copy).
struct MeasureJob {
  // Where: the device's executor and data sets, its identity, limits and languages.
  Executor* executor = nullptr;
  DatasetCache* datasets = nullptr;
  const DeviceIdentity* device = nullptr;
  DeviceLimits limits;
  std::vector<Lang> languages;
  // What: the variant, on a data set, timed so.
  Variant variant;
  TuningDataset dataset;
  TimingOptions options;
  // Output: the measurement, with the status the variant earned.
  Measurement* measurement = nullptr;

  // Whether the job can run: every pointer given, a data set key, at least
  // one language, and timing options that can work (a tolerance in
  // (0, kMaxTolerance], a stop rule BadStopRule accepts, a positive burst_ms).
  bool Validate() const;
  // False, writing nothing, when Validate() fails. Otherwise true, with
  // *measurement filled whatever the variant did (a kernel's failure is its
  // status, never a throw); throws Error only when the data set cannot be
  // loaded (a set-up problem of the run, not of the variant).
  bool Run() const;
};

// Runs `job` into a measurement of its own (job.measurement is set here)
// and returns it; throws Error naming the variant when the inputs do not
// Validate().
Measurement MeasurementOf(MeasureJob job);

// Races variants already verified: every one prepared, then rounds of one
// batch of cold samples each, candidate after candidate, until JudgeRace
// settles the winner (each with at least min_samples: RaceOutcome::settled,
// judged on the bytes each moves; the errors are the parent's to weigh),
// or max_samples each, or max_ms per candidate of wall time.
struct RaceJob {
  Executor* executor = nullptr;
  DatasetCache* datasets = nullptr;
  const DeviceIdentity* device = nullptr;
  std::vector<Variant> variants;
  TuningDataset dataset;
  TimingOptions options;
  // Output: each variant's kernel-time samples, ms, in the variants' order.
  std::vector<std::vector<double>>* samples = nullptr;

  // Every pointer given, a data set key, at least one variant, a stop rule
  // BadStopRule accepts.
  bool Validate() const;
  // False when Validate() fails; throws Error when a variant cannot be
  // prepared or timed, or the device gives no kernel time.
  bool Run() const;
};

// ---------------------------------------------------------------- what a job records

// Records `t` in `m` (timing's median, interval, samples, clock, input sets,
// footprint and flush; gbps).
void RecordKernelTime(Measurement& m, const KernelTime& t, const Executor& executor, int sets, std::size_t bytes_per_set);

// The status a runner's Error stands for, from the stage its message names
// ("<API> <stage>: ..."): build -> compile_failed, guard -> verify_failed,
// anything else -> launch_failed.
MeasureStatus StatusOfRunnerError(const std::string& message);

// Whether a Measurement's detail is a runner's Error of stage "lost" (after
// an optional "timing: "): the device or its context is gone for this
// process (a GL context the driver reset), so no later measurement in it can
// be trusted (the tune worker then exits, and the parent measures the variant
// again in a fresh one).
bool DeviceLostIn(const std::string& detail);

}  // namespace skintune::internal::tuner_internal
