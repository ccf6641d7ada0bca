// skintune (internal to tuner/): the tuner's one TunedDevice, over the
// runtime's runner driver (runtime/runner.h) on any device its discovery
// finds (runtime/backend_table.h), whatever the API.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "generator/variant.h"
#include "runtime/backend_table.h"
#include "runtime/device_identity.h"
#include "runtime/program_cache.h"
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

// The quickest of several runners on contexts of their own
// (FoundDevice::open_own): `count` opened with `open` and kept open together,
// each one's launch start sampled by `probe` (ms), `rounds` times each, the
// runners taken in turn; the one of the lowest TrimmedMean (a tenth off each
// end) kept, the first on a tie, the others closed. The device's start of a
// launch after the command before it is the context's: on an H200 one CUDA
// context's kernel read 4.06-4.10 us and another's 4.19-4.26, steady within
// each (docs/TUNING.md "Kernel time"). A runner that fails to open or to be
// probed is left out; the last Error is thrown when none is left.
struct QuickestRunner {
  std::unique_ptr<skintune::internal::Runner> runner;
  std::vector<double> starts_ms;  // each runner's trimmed mean in opening order; NaN where it failed
  std::size_t chosen = 0;         // runner's index in starts_ms
  // Where the choice's time went (the timing log): each runner's opening and
  // its probe's preparing (kernels built, buffers made), then the rounds.
  std::vector<double> open_ms, prepare_ms;
  double probing_ms = 0.0;
};
// A runner's launch-start probe, prepared once and sampled each round (ms).
using LaunchStartRound = std::function<std::vector<double>()>;
QuickestRunner OpenQuickest(int count, int rounds, const std::function<std::unique_ptr<skintune::internal::Runner>()>& open,
                            const std::function<LaunchStartRound(skintune::internal::Runner&)>& probe_of);

// The runner a tuning run measures `device` on (`lang` its probe's kernel
// language, `cache` the program cache its builds use, or null): on a GPU
// whose API makes contexts of a runner's own, the quickest of six by their
// launch start (LaunchStartProbe); elsewhere, or where none opens, `open`'s.
// SKINTUNE_TIMING_LOG records each context's launch start and the choice.
// `context`, when given, says how the context was chosen ("" where it was
// not) and its launch start (ms): the chosen one's, or on any other GPU the
// opened runner's, probed in two rounds as the choice probes (0 on the
// host's CPU, whose kernel time has no launch to start). Each measurement
// records both (timing.context, timing.launch_start_ms). ChoosesContext:
// whether it chooses; ProbesLaunchStart: whether it probes (the probes take
// the chip's lock: open it before taking any).
struct MeasuringContext {
  std::string choice;
  double launch_start_ms = 0.0;
};
bool ProbesLaunchStart(const FoundDevice& device);
bool ChoosesContext(const FoundDevice& device);
std::unique_ptr<skintune::internal::Runner> OpenMeasuringRunner(const FoundDevice& device, Lang lang,
                                                                ProgramCache* cache,
                                                                MeasuringContext* context = nullptr);
// The launch-start probe on `runner`: a 4 KiB copy's kernel time, the flush
// and then the copy, as every kernel time is taken: the device's start of a
// launch after the command before it, and little else. Its buffers and the
// flush's are made once (on the chip, under its lock), and each Samples() is
// one round of them (ms). No clock is read around them: nothing records it.
// Outlived by `runner`.
class LaunchStartProbe {
 public:
  LaunchStartProbe(skintune::internal::Runner& runner, const DeviceIdentity& device, Lang lang, ProgramCache* cache);
  std::vector<double> Samples();

 private:
  const DeviceIdentity& device_;
  RunnerExecutor executor_;
  std::unique_ptr<Executor::Timed> copy_;
};

// A device's last-level cache as a tune worker's parent resolved it across
// every API's view of the chip (tuner/worker.h WorkerArguments).
struct GivenCache {
  std::string device_id;  // DeviceIdentity::Id() of the device it is given to
  std::uint64_t bytes = 0;
  std::string source;
};

// Every device found (DiscoverTunedDevices), each measuring through
// `decorate` when given; with `only`, that API's devices alone
// (DiscoverDevices: their caches matched among themselves), and the device
// `given` names takes its figure instead.
Discovery DiscoverTunedDevices(const ExecutorDecorator& decorate, const char* only = nullptr,
                               const GivenCache* given = nullptr);

// The bytes of input sets a device's runner keeps across the measurements of
// one data set (Runner::ShareTimedInputs): an eighth of the device's memory,
// at most 1 GiB (8 sets of a 6400k-vertex mesh's inputs: 8 x ~100 MB);
// 256 MiB where the device does not say.
std::size_t SharedInputBytes(const DeviceIdentity& d);

}  // namespace skintune::internal::tuner_internal
