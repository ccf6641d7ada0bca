// skintune: a tuning run (tuner/tune.h), in three steps:
//   1. the plan (tuner/plan.h): the config and options checked, the datasets
//      loaded, the devices discovered (only for their identities, limits and
//      languages), one task per device x language x dataset: anything wrong
//      with the input fails here, before any device measures;
//   2. the schedule (tuner/schedule.h): devices that share hardware one after
//      another, so that no two measurements share a chip, and devices that
//      share none (a CPU device and a GPU) at the same time;
//   3. each device's tasks through its own child process
//      (tuner/device_tuning.h, tuner/worker.h), whose TunedDevice runs the
//      measurement job (tuner/measure_job.h).
// The devices' results are then joined, in device order, into the report.
#include "tuner/tune.h"

#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <memory>
#include <thread>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "runtime/device_clock.h"
#include "runtime/runner.h"  // TimingLog
#include "tuner/device_tuning.h"
#include "tuner/host_lock.h"
#include "tuner/plan.h"
#include "tuner/schedule.h"

namespace skintune::internal {

namespace {

std::string ReadFirstMatch(const std::string& path, const std::string& prefix) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) != 0) continue;
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::size_t start = line.find_first_not_of(" \t", colon + 1);
    return start == std::string::npos ? std::string() : line.substr(start);
  }
  return {};
}

nlohmann::json MachineInfo() {
  nlohmann::json m = nlohmann::json::object();
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) == 0) m["hostname"] = host;
  struct utsname u {};
  if (::uname(&u) == 0) {
    m["os"] = std::string(u.sysname) + " " + u.release + " " + u.version + " " + u.machine;
  }
  m["cpu_model"] = ReadFirstMatch("/proc/cpuinfo", "model name");
  m["logical_cpus"] = ::sysconf(_SC_NPROCESSORS_ONLN);
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGE_SIZE);
  m["memory_bytes"] = pages > 0 && page_size > 0 ? static_cast<std::uint64_t>(pages) * page_size : 0;
  return m;
}

// The report's header: what the run is, before anything is measured.
TuningReport ReportHeader(const TuneConfig& config) {
  TuningReport report;
  report.created = UtcTimestamp();
  report.config = config.name;
  report.strategy = config.strategy.name;
  report.max_error = config.max_error;
  report.tie_margin = config.timing.tie_margin;
  report.host_tie_margin = config.timing.host_tie_margin;
  report.process_spread = config.timing.process_spread;
  report.host_process_spread = config.timing.host_process_spread;
  report.choose_in_tie_set = config.timing.choose_in_tie_set;
  report.host_choose_in_tie_set = config.timing.host_choose_in_tie_set;
  report.choose_unseparated = config.timing.choose_unseparated;
  report.host_choose_unseparated = config.timing.host_choose_unseparated;
  report.machine = MachineInfo();
  return report;
}

// A group of GPU devices (the APIs of one GPU: they share it) is tuned one
// device after another. While one is measured, workers of their own
// compile the later devices' kernels into the program cache (host work:
// the shared host lock), so each device starts with its compiles done, as
// in a warm run (on the H100 a cold `skintune run` spent about 20 s more
// than a warm one, most of it compiling one API after another). Every
// candidate not yet measured is compiled: the search's choices are not
// known ahead. Not for CPU devices (their compiles would take the cores
// they and their neighbours time on), nor on hosts of fewer than 8 threads.
// A worker done before its device's turn is left to it (HeadStarts): the
// thread stays until the group is done, since a worker dies with the thread
// that started it (PR_SET_PDEATHSIG, tuner/worker.h).
GroupAhead PrecompileLaterDevices(const TuningPlan& plan, const std::vector<std::size_t>& scheduled,
                                  const std::vector<WorkerSetup>& workers_of, TuningLedger& ledger) {
  return [&plan, &scheduled, &workers_of, &ledger](const std::vector<std::size_t>& group,
                                                    const std::atomic<std::size_t>& reached) {
    const auto cpu = [&](std::size_t k) { return IsHostCpu(plan.devices[scheduled[k]].identity); };
    if (std::thread::hardware_concurrency() < 8 || std::any_of(group.begin(), group.end(), cpu)) return;
    for (std::size_t k = 1; k < group.size(); ++k) {
      const auto overtaken = [&reached, k] { return reached.load() >= k; };  // its turn came: it compiles its own
      if (!overtaken()) PrecompileDevice(plan, scheduled[group[k]], workers_of[group[k]], ledger, overtaken);
    }
    while (reached.load() < group.size()) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  };
}

// The devices' results into the report, in device order: a device's
// invalid points, then its measurements and races; the devices given up
// are skipped with the reason. Throws Error when every device with work
// was given up.
void JoinResults(const TuningPlan& plan, const std::vector<DeviceResult>& results, std::size_t with_work,
                 TuningReport& report) {
  std::size_t devices_failed = 0;
  for (std::size_t d = 0; d < plan.devices.size(); ++d) {
    if (!plan.HasTasks(d)) continue;
    const DeviceResult& result = results[d];
    for (const Task& t : plan.tasks)
      if (t.device == d) report.measurements.insert(report.measurements.end(), t.invalid.begin(), t.invalid.end());
    report.measurements.insert(report.measurements.end(), result.measurements.begin(), result.measurements.end());
    report.races.insert(report.races.end(), result.races.begin(), result.races.end());
    if (result.copy_gbps) report.copy_bandwidth_gbps[plan.devices[d].identity.Id()] = *result.copy_gbps;
    if (result.given_up) {
      ++devices_failed;
      report.skipped.push_back(plan.devices[d].identity.Id() + ": " + *result.given_up);
    }
  }
  if (with_work > 0 && devices_failed == with_work) {
    std::string why;
    for (const std::string& s : report.skipped) why += (why.empty() ? "" : "; ") + s;
    throw Error("no device could be tuned: " + why);
  }
}

// Tunes every device of the plan with evaluations to run, as the schedule
// says; returns each device's result (in plan order). `report` gets the
// devices with a task (a device with only invalid points is reported,
// with nothing measured).
std::vector<DeviceResult> TuneDevices(const TuningPlan& plan, const TuneConfig& config, const TuneOptions& options,
                                      TuningLedger& ledger, TuningReport& report, std::size_t* with_work_count) {
  std::vector<DeviceResult> results(plan.devices.size());
  std::vector<std::size_t> with_work;
  std::vector<DeviceIdentity> identities;
  for (std::size_t d = 0; d < plan.devices.size(); ++d) {
    if (!plan.HasTasks(d)) continue;  // none of the space's languages: not measured, not reported
    report.devices.push_back(plan.devices[d].identity);
    results[d].planned = plan.PlannedOn(d);
    if (results[d].planned == 0) continue;  // only invalid points: recorded, nothing to measure
    with_work.push_back(d);
    identities.push_back(plan.devices[d].identity);
  }
  *with_work_count = with_work.size();
  // Every NVIDIA GPU tuned is held at a compute context's clocks while the
  // devices are tuned (runtime/device_clock.h ClockHold): its GL and Vulkan
  // kernels are then timed at the clock its CUDA and OpenCL kernels are.
  std::string unheld;
  const std::unique_ptr<ClockHold> clocks = ClockHold::ForDevices(identities, &unheld);
  TimingLog([&] {
    return clocks ? "compute clocks held on " + std::to_string(clocks->held()) + " GPU(s)" : "compute clocks not held: " + unheld;
  });
  Schedule schedule = ScheduleDevices(identities, options.parallel_devices);
  std::unique_ptr<tuner_internal::HostLockFile> host_lock;
  if (schedule.shares_host) host_lock = std::make_unique<tuner_internal::HostLockFile>();
  HeadStarts head_starts;  // outlives every worker's thread (RunSchedule joins them)
  const WorkerSetup workers{options.worker_executable, config.variant_timeout_s, host_lock ? host_lock->path() : "", "",
                            &head_starts};
  // A lock file per group of a chip's APIs, named to each of its devices'
  // workers: those tuned at once (shares_chip) each hold the chip for its
  // work on it; those tuned one after another, so that a later API's worker
  // started ahead chooses its context between the measuring API's jobs,
  // never during one (PrecompileDevice).
  std::vector<std::unique_ptr<tuner_internal::HostLockFile>> chip_locks;
  std::vector<std::unique_ptr<ChipStart>> chip_starts;  // one per chip lock: its first turn's start
  std::vector<WorkerSetup> workers_of(with_work.size(), workers);
  for (std::size_t g = 0; g < schedule.groups.size(); ++g) {
    const auto cpu = [&](std::size_t k) { return IsHostCpu(identities[k]); };
    const std::vector<std::size_t>& group = schedule.groups[g];
    if (group.size() < 2 || std::any_of(group.begin(), group.end(), cpu)) continue;
    chip_locks.push_back(std::make_unique<tuner_internal::HostLockFile>("chip"));
    if (chip_locks.back()->path().empty()) {  // no lock to share: the chip's APIs one after another
      schedule.shares_chip[g] = false;
      continue;
    }
    chip_starts.push_back(std::make_unique<ChipStart>());
    for (const std::size_t k : group) {
      workers_of[k].chip_lock = chip_locks.back()->path();
      workers_of[k].chip_start = chip_starts.back().get();
    }
  }
  RunSchedule(
      schedule, [&](std::size_t k) { TuneDevice(plan, with_work[k], config, workers_of[k], ledger, results[with_work[k]]); },
      PrecompileLaterDevices(plan, with_work, workers_of, ledger));
  return results;
}

}  // namespace

TuningReport RunTuning(const TuneConfig& config, const TuneOptions& options) {
  ValidateRun(config, options);
  MeasurementCache cache(options.cache_path);
  const auto progress = [&](std::size_t done, std::size_t total, const std::string& what) {
    if (options.progress) options.progress(done, total, what);
  };
  TuningReport report = ReportHeader(config);
  const TuningPlan plan =
      PlanTuning(config, options, report.created, [&](const std::string& what) { progress(0, 0, what); });
  for (const PlannedDataset& d : plan.datasets) report.datasets.push_back(d.info);
  report.skipped = plan.skipped;
  TuningLedger ledger(cache, plan.total, progress);
  std::size_t with_work = 0;
  const std::vector<DeviceResult> results = TuneDevices(plan, config, options, ledger, report, &with_work);
  JoinResults(plan, results, with_work, report);
  report.created = UtcTimestamp();  // when the run finished
  progress(plan.total, plan.total, "done");
  return report;
}

}  // namespace skintune::internal
