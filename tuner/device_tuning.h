// skintune: one device's part of a tuning run, measured through a worker
// process of its own (tuner/worker.h): for each of its tasks (tuner/plan.h)
// the baselines, the search (tuner/strategy.h: each evaluation takes the
// cache's record when there is one, else measures in the worker and appends
// the result to the cache before going on) and the race that settles it
// (tuner/race.h). tuner/schedule.h decides which devices run at once; what
// they share is a TuningLedger.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "base/thread_pool.h"
#include "tuner/config.h"
#include "tuner/measurement.h"
#include "tuner/plan.h"
#include "tuner/race_record.h"
#include "tuner/worker.h"

namespace skintune::internal {

// One device's results, kept apart from the others' until the run joins
// them in device order, so that the report does not depend on the timing of
// the threads.
struct DeviceResult {
  std::size_t planned = 0;  // evaluations expected on the device
  std::size_t done = 0;     // of them, done
  std::vector<Measurement> measurements;
  std::vector<RaceRecord> races;
  std::optional<double> copy_gbps;
  std::optional<std::string> given_up;  // why the device could not be used
};

// What the devices tuned at the same time share, behind one lock: the
// measurement cache and the run's progress.
class TuningLedger {
 public:
  using Progress = std::function<void(std::size_t done, std::size_t total, const std::string& what)>;
  TuningLedger(MeasurementCache& cache, std::size_t total, Progress progress);

  // The cache's record of `cache_key` when this run can trust it (the cache
  // is input: MeasuredAgainOnResume names why a record is measured again).
  std::optional<Measurement> Trusted(const std::string& cache_key, double tolerance);
  // Whether the cache has any record of `cache_key`.
  bool Cached(const std::string& cache_key);
  void Append(const Measurement& m);  // on disk before the next variant
  std::optional<RaceRecord> FindRace(const std::string& race_key);
  void AppendRace(const std::string& race_key, const RaceRecord& race);
  // Moves `device`'s progress to `device_done` (never back, at most its
  // planned) and reports `what` (nothing when empty).
  void Advance(DeviceResult& device, std::size_t device_done, const std::string& what);

 private:
  std::mutex mutex_;
  MeasurementCache& cache_;
  std::size_t total_;
  std::size_t done_ = 0;
  Progress progress_;
};

// The workers that compiled a later device's kernels ahead of its turn
// (PrecompileDevice), each left for that turn (TuneDevice): the turn then
// measures in a process already started, its program cache read and its
// compile threads' contexts open. A device's own compiles ahead (Vulkan's
// opened a VkDevice per compile thread at the turn's first batch) cost its
// turn 1.9-5.4 s on the H200 machine before (three cold default runs,
// 2026-12-01). A turn that comes while its device's precompile is under way
// waits for the data set being compiled, then takes the worker: a fresh one
// would open and choose its contexts again (2.5-3.5 s for CUDA, H200
// machine, 2026-12-02), then compile what is left all the same.
class HeadStarts {
 public:
  // A precompile for device `d` begins, unless `overtaken()` (asked under
  // the lock that Take holds too): a turn that came first has a worker of its own.
  bool Begin(std::size_t d, const std::function<bool()>& overtaken);
  // The precompile Begun for `d` has ended, leaving `worker` (null: none).
  void Leave(std::size_t d, std::unique_ptr<IsolatedDevice> worker);
  // The worker left for device `d`, or null; waits while its precompile is under way.
  std::unique_ptr<IsolatedDevice> Take(std::size_t d);

 private:
  std::mutex mutex_;
  std::condition_variable left_;
  std::set<std::size_t> under_way_;
  std::map<std::size_t, std::unique_ptr<IsolatedDevice>> workers_;
};

// Opened once the first turn on a chip has its context chosen and its copy
// measured (or has ended). Until then a later API's worker started ahead
// (PrecompileDevice) compiles for the program cache only and chooses no
// context: that choice's probes take the chip's lock, and the first turn's
// start waited for them (NVIDIA's OpenCL's 4.4-5.5 s beside them, 3.0-3.8 s
// alone, H200 machine, 2026-12-02).
class ChipStart {
 public:
  void Open() { opened_ = true; }
  bool IsOpen() const { return opened_; }

 private:
  std::atomic<bool> opened_{false};
};

// Compiles a turn's tasks' kernels one task ahead (DeviceTuning, where
// helper processes compile them): task 0's at once, task i's once task
// i - 1 has begun, on a thread of its own. Each task begins (Begin) once its
// own are compiled.
class OneTaskAhead {
 public:
  // compile(i) for i in 0..tasks-1, in order; it must not throw.
  OneTaskAhead(std::size_t tasks, std::function<void(std::size_t)> compile);
  // Stops: waits for the compile under way; the tasks after it are not compiled.
  ~OneTaskAhead();
  OneTaskAhead(const OneTaskAhead&) = delete;
  OneTaskAhead& operator=(const OneTaskAhead&) = delete;

  // Task i begins (in order, 0 first): returns once its kernels are
  // compiled, and lets task i + 1's compile start. A task past the last
  // one compiled for begins at once.
  void Begin(std::size_t i);

 private:
  const std::size_t tasks_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::size_t compiled_ = 0;  // tasks whose compile has ended
  std::size_t begun_ = 0;     // tasks begun
  bool stop_ = false;
  std::thread thread_;  // last: started once the members above are made
};

// How a device's worker processes are started.
struct WorkerSetup {
  std::string executable;         // the skintune binary
  double variant_timeout_s = 60;  // per variant
  std::string host_lock;          // shared by every worker (tuner/host_lock.h); "" = none
  std::string chip_lock;          // shared by the workers of one chip's APIs (host_lock.h ChipLock); "" = none
  HeadStarts* head_starts = nullptr;  // where a device's turn finds a worker started ahead; null = none
  ChipStart* chip_start = nullptr;    // the chip's first turn's start (with chip_lock); null = none
};

// Worker processes that compile a device's kernels ahead side by side, each a
// share of them (CompileAheadInProcesses, tuner/tuned_device.h: a driver that
// compiles one kernel at a time in a process). Started at their first share,
// they live as long as the object; a helper that fails costs only its
// share's head start (IsolatedDevice::CompileAhead). They are driven from
// threads that live as long as they do: a worker is killed when the thread
// that started it ends (PR_SET_PDEATHSIG, tuner/worker.h).
class CompileHelpers {
 public:
  CompileHelpers(const WorkerSetup& workers, const DeviceIdentity& device);
  ~CompileHelpers();
  CompileHelpers(const CompileHelpers&) = delete;
  CompileHelpers& operator=(const CompileHelpers&) = delete;

  // Half the host's logical CPUs (the others are the GPU workers' beside it), 1 to 8.
  static std::size_t Count();

  // Each helper (up to Count(), at most one per variant) compiles its share
  // of `variants`; returns when every one has answered.
  void CompileAhead(const std::vector<Variant>& variants, const TuningDataset& dataset);

  int starts() const;  // helper processes started so far
  // Ends every helper's input: they exit side by side (IsolatedDevice::EndInput).
  void EndInputs();

 private:
  const WorkerSetup& workers_;
  const DeviceIdentity& device_;
  std::unique_ptr<ThreadPool> threads_;                   // outlives the helpers (declared before them)
  std::vector<std::unique_ptr<IsolatedDevice>> helpers_;  // each driven by one thread at a time
};

// Tunes device `d` of `plan` into `result`: its copy bandwidth, then each of
// its tasks. A device that cannot be used (WorkerError) is given up with the
// reason, never the run.
void TuneDevice(const TuningPlan& plan, std::size_t d, const TuneConfig& config, const WorkerSetup& workers,
                TuningLedger& ledger, DeviceResult& result);

// Compiles the kernels of device `d`'s tasks that the cache has no record
// of, in a worker of its own, ahead of the device's turn: stops at the task
// when `overtaken()` (the device's own turn came: it compiles its own). Only
// a head start: any failure is left to the device's own worker to record.
// Done first, it leaves its worker to the turn (workers.head_starts). Under
// the chip's lock (workers.chip_lock) that worker compiles for itself, its
// context chosen ahead of the turn; without one, for the program cache only.
void PrecompileDevice(const TuningPlan& plan, std::size_t d, const WorkerSetup& workers, TuningLedger& ledger,
                      const std::function<bool()>& overtaken);

}  // namespace skintune::internal
