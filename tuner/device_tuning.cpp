// skintune: one device's part of a tuning run (tuner/device_tuning.h).
#include "tuner/device_tuning.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <set>
#include <thread>
#include <utility>

#include "generator/emit.h"  // kGeneratorVersion
#include "runtime/runner.h"  // TimingLog

#include "tuner/executor.h"  // ProbeCopyBytes
#include "tuner/race.h"
#include "tuner/strategy.h"
#include "tuner/tuned_device.h"

namespace skintune::internal {

TuningLedger::TuningLedger(MeasurementCache& cache, std::size_t total, Progress progress)
    : cache_(cache), total_(total), progress_(std::move(progress)) {}

std::optional<Measurement> TuningLedger::Trusted(const std::string& cache_key, double tolerance) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const Measurement* found = cache_.Find(cache_key);
  if (found && MeasuredAgainOnResume(*found, tolerance).empty()) return *found;
  return std::nullopt;
}

bool TuningLedger::Cached(const std::string& cache_key) {
  const std::lock_guard<std::mutex> lock(mutex_);
  return cache_.Find(cache_key) != nullptr;
}

void TuningLedger::Append(const Measurement& m) {
  const std::lock_guard<std::mutex> lock(mutex_);
  cache_.Append(m);
}

std::optional<RaceRecord> TuningLedger::FindRace(const std::string& race_key) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const RaceRecord* found = cache_.FindRace(race_key);
  return found ? std::optional<RaceRecord>(*found) : std::nullopt;
}

void TuningLedger::AppendRace(const std::string& race_key, const RaceRecord& race) {
  const std::lock_guard<std::mutex> lock(mutex_);
  cache_.AppendRace(race_key, race);
}

void TuningLedger::Advance(DeviceResult& device, std::size_t device_done, const std::string& what) {
  const std::lock_guard<std::mutex> lock(mutex_);
  device_done = std::min(device_done, device.planned);
  if (device_done > device.done) {
    done_ += device_done - device.done;
    device.done = device_done;
  }
  if (!what.empty() && progress_) progress_(done_, total_, what);
}

bool HeadStarts::Begin(std::size_t d, const std::function<bool()>& overtaken) {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (overtaken()) return false;
  under_way_.insert(d);
  return true;
}

void HeadStarts::Leave(std::size_t d, std::unique_ptr<IsolatedDevice> worker) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    under_way_.erase(d);
    if (worker) workers_[d] = std::move(worker);
  }
  left_.notify_all();
}

std::unique_ptr<IsolatedDevice> HeadStarts::Take(std::size_t d) {
  std::unique_lock<std::mutex> lock(mutex_);
  left_.wait(lock, [&] { return under_way_.count(d) == 0; });
  const auto found = workers_.find(d);
  if (found == workers_.end()) return nullptr;
  std::unique_ptr<IsolatedDevice> worker = std::move(found->second);
  workers_.erase(found);
  return worker;
}

OneTaskAhead::OneTaskAhead(std::size_t tasks, std::function<void(std::size_t)> compile)
    : tasks_(tasks),
      thread_([this, compile = std::move(compile)] {
        for (std::size_t i = 0; i < tasks_; ++i) {
          {
            std::unique_lock<std::mutex> lock(mutex_);
            changed_.wait(lock, [&] { return stop_ || begun_ >= i; });  // the task before has begun
            if (stop_) return;
          }
          compile(i);
          {
            const std::lock_guard<std::mutex> lock(mutex_);
            compiled_ = i + 1;
          }
          changed_.notify_all();
        }
      }) {}

OneTaskAhead::~OneTaskAhead() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void OneTaskAhead::Begin(std::size_t i) {
  if (i >= tasks_) return;  // nothing compiled for it: nothing to wait for
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return compiled_ > i; });
  begun_ = std::max(begun_, i + 1);
  lock.unlock();
  changed_.notify_all();
}

CompileHelpers::CompileHelpers(const WorkerSetup& workers, const DeviceIdentity& device)
    : workers_(workers), device_(device) {}

CompileHelpers::~CompileHelpers() { EndInputs(); }

void CompileHelpers::EndInputs() {
  for (const auto& helper : helpers_) helper->EndInput();
}

std::size_t CompileHelpers::Count() { return std::clamp<std::size_t>(std::thread::hardware_concurrency() / 2, 1, 8); }

void CompileHelpers::CompileAhead(const std::vector<Variant>& variants, const TuningDataset& dataset) {
  if (!threads_) threads_ = std::make_unique<ThreadPool>(static_cast<unsigned>(Count()));
  const std::size_t count = std::min(Count(), variants.size());
  while (helpers_.size() < count) {
    helpers_.push_back(std::make_unique<IsolatedDevice>(workers_.executable, device_, workers_.variant_timeout_s));
    if (!workers_.host_lock.empty()) helpers_.back()->UseHostLock(workers_.host_lock);
  }
  std::vector<std::vector<Variant>> shares(count);
  for (std::size_t i = 0; i < variants.size(); ++i) shares[i % count].push_back(variants[i]);
  threads_->ParallelFor(count, 1, [&](std::size_t begin, std::size_t end) {
    for (std::size_t h = begin; h < end; ++h)
      (void)helpers_[h]->CompileAhead(shares[h], dataset, CompileFor::kTheCache);
  });
}

int CompileHelpers::starts() const {
  int total = 0;
  for (const auto& h : helpers_) total += h->starts();
  return total;
}

namespace {

// "ok 0.123 ms, error 1.2e-07 of the diagonal (f32)", or the status and the
// first line of its detail.
std::string ShortStatus(const Measurement& m) {
  std::string text = Name(m.status);
  if (IsTimed(m.status)) {
    char ms[96];
    std::snprintf(ms, sizeof ms, " %.3f ms, error %.1e of the diagonal (%s)", m.timing.median_ms,
                  m.source_error.position_rel, Name(m.variant.weight));
    text += ms;
  } else if (!m.detail.empty()) {
    std::string detail = m.detail.substr(0, m.detail.find('\n'));
    if (detail.size() > 120) detail = detail.substr(0, 120) + "...";
    text += " (" + detail + ")";
  }
  return text;
}

// The measurement cache's key of `variant` on a device and data set, by this generator.
std::string CacheKeyOf(const std::string& device_id, const std::string& dataset, const Variant& variant) {
  Measurement probe;
  probe.device_id = device_id;
  probe.dataset = dataset;
  probe.variant = variant;
  probe.generator_version = kGeneratorVersion;
  return probe.CacheKey();
}

// SKINTUNE_TIMING_LOG: how long one step of a device's tuning took, as
// "<device> <step>: <ms> ms" when the span ends (nothing when the log is off).
// With the measurements' phases it tells where a run's time goes.
class LoggedSpan {
 public:
  LoggedSpan(const std::string& who, std::string what) : who_(who), what_(std::move(what)) {}
  ~LoggedSpan() {
    TimingLog([&] {
      const std::chrono::duration<double, std::milli> ms = std::chrono::steady_clock::now() - start_;
      char text[32];
      std::snprintf(text, sizeof text, "%.1f ms", ms.count());
      return who_ + " " + what_ + ": " + text;
    });
  }
  LoggedSpan(const LoggedSpan&) = delete;
  LoggedSpan& operator=(const LoggedSpan&) = delete;

 private:
  const std::string& who_;
  std::string what_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

class DeviceTuning {
 public:
  DeviceTuning(const TuningPlan& plan, std::size_t d, const TuneConfig& config, const WorkerSetup& workers,
               TuningLedger& ledger, DeviceResult& result)
      : plan_(plan),
        d_(d),
        device_(plan.devices[d].identity),
        config_(config),
        ledger_(ledger),
        result_(result),
        worker_(StartedAheadOr(workers, d)),
        helpers_(workers, device_),
        chip_start_(workers.chip_start),
        id_(device_.Id()),
        name_(device_.backend + " " + device_.name) {
    // This device's timing: its tie margin and stop rule (a CPU's are wider: TimingOptions::ForDevice).
    timing_ = config.timing.ForDevice(device_);
    if (!workers.host_lock.empty()) worker_->UseHostLock(workers.host_lock);
    if (!workers.chip_lock.empty()) worker_->UseChipLock(workers.chip_lock);
  }

  // The turn's processes are ended together, then reaped (the members'
  // destructors): NVIDIA's OpenCL worker with six contexts and its eight
  // helpers, stopped one after another, held the chip's next turn about 1 s
  // (H200 machine, 2026-12-02). Its compiles ahead end first: they use them.
  ~DeviceTuning() {
    one_task_ahead_.reset();
    helpers_.EndInputs();
    worker_->EndInput();
  }
  DeviceTuning(const DeviceTuning&) = delete;
  DeviceTuning& operator=(const DeviceTuning&) = delete;

  void Run() {
    const LoggedSpan span(name_, "device");
    try {
      CompileEachTaskAhead();
      MeasureCopyBandwidth();
      if (chip_start_) chip_start_->Open();
      for (const Task& task : plan_.tasks) {
        if (!IsTurnTask(task)) continue;
        RunTask(task);
        task_start_ += task.planned;
        Advance(0, "");
      }
    } catch (const WorkerError& e) {
      // This device cannot be used: the run goes on with the others.
      if (chip_start_) chip_start_->Open();
      result_.given_up = e.what();
      ledger_.Advance(result_, result_.planned, name_ + ": given up: " + e.what());
    }
    ledger_.Advance(result_, result_.planned, "");
  }

 private:
  // The device's progress at `task_done` evaluations into the current task.
  void Advance(std::size_t task_done, const std::string& what) { ledger_.Advance(result_, task_start_ + task_done, what); }

  void MeasureCopyBandwidth() {
    Advance(0, name_ + ": copy bandwidth");
    const LoggedSpan span(name_, "start and copy bandwidth");
    std::string why_not;
    const std::size_t bytes = tuner_internal::ProbeCopyBytes(device_);
    if (const std::optional<double> gbps = worker_->CopyBandwidthGBps(bytes, &why_not))
      result_.copy_gbps = *gbps;
    else
      Advance(0, name_ + ": copy bandwidth not measured: " + why_not);
  }

  // `m` made invalid if its kernel time is impossible against the device's
  // copy bandwidth, measured again first (RejectOverCeilingMeasuringAgain).
  void RejectOverTheCeiling(Measurement& m) {
    if (!result_.copy_gbps) return;
    const double copy_traffic = IsHostCpu(device_) ? kHostCopyTraffic : 1.0;
    RejectOverCeilingMeasuringAgain(m, *result_.copy_gbps, copy_traffic, copy_remeasures_left_, [this] {
      const LoggedSpan span(name_, "copy bandwidth measured again");
      return worker_->CopyBandwidthGBps(tuner_internal::ProbeCopyBytes(device_));
    });
  }

  // A GPU whose kernels are compiled in helper processes (CompileAheadInProcesses:
  // NVIDIA's OpenCL) has each task's kernels compiled there one task ahead:
  // the first task's beside the device's start, each next one's while the
  // task before it is measured. Each task waits for its own (RunTask), and
  // the search's compiles ahead are left out. A step's batch on the helpers
  // took 100-360 ms, a move alone built in process 60-100 ms, and the
  // helpers' start ~1 s, all on the turn's path; every task's kernels
  // compiled at once from the start (288 kernels) took the host's cores
  // from the turn's own start (5.3-6.7 s instead of 3.0-3.8) and from the
  // next API's precompile (3.9-4.3 s a data set instead of 1.4-1.8; H200
  // machine, 2026-12-02). Not for a CPU device: its helpers' compiles would
  // take the cores it times on.
  void CompileEachTaskAhead() {
    if (IsHostCpu(device_) || !CompilesAheadInProcesses(device_)) return;
    std::vector<std::pair<std::string, std::vector<Variant>>> work;  // data set, kernels
    for (const Task& task : plan_.tasks) {
      if (!IsTurnTask(task)) continue;
      const std::string& key = plan_.datasets[task.dataset].info.key;
      std::vector<Variant> all = task.baselines;
      all.insert(all.end(), task.candidates.begin(), task.candidates.end());
      task_ahead_[&task] = work.size();
      work.emplace_back(key, NotTrusted(all, key));
    }
    // The count first: the lambda's capture may be made (and `work` moved
    // from) before another argument is evaluated.
    const std::size_t tasks = work.size();
    one_task_ahead_ = std::make_unique<OneTaskAhead>(tasks, [this, work = std::move(work)](std::size_t i) {
      try {
        const LoggedSpan span(name_, "compile ahead of " + std::to_string(work[i].second.size()) + " kernels for " +
                                         work[i].first + " in helpers, a task ahead");
        if (!work[i].second.empty()) helpers_.CompileAhead(work[i].second, TuningDataset{work[i].first});
      } catch (...) {
        // Only a head start lost: the measurement builds its own kernel and records any failure.
      }
    });
  }

  // Whether this turn runs `task`: this device's, with something to measure.
  bool IsTurnTask(const Task& task) const {
    return task.device == d_ && !(task.candidates.empty() && task.baselines.empty());
  }

  // Those of `variants` that the cache has no trusted record of on data set `key`.
  std::vector<Variant> NotTrusted(const std::vector<Variant>& variants, const std::string& key) {
    std::vector<Variant> left;
    for (const Variant& v : variants)
      if (!ledger_.Trusted(CacheKeyOf(id_, key, v), config_.timing.tolerance)) left.push_back(v);
    return left;
  }

  // One task: the baselines, the search, then the race that settles it.
  void RunTask(const Task& task) {
    task_ = &task;
    key_ = plan_.datasets[task.dataset].info.key;
    const LoggedSpan span(name_, "task " + key_);
    if (const auto ahead = task_ahead_.find(&task); ahead != task_ahead_.end()) one_task_ahead_->Begin(ahead->second);
    task_done_ = 0;
    seen_.clear();
    announced_.clear();
    const Evaluator evaluate = [this](const Variant& v) { return Evaluate(v); };
    const LookAhead ahead = [this](const std::vector<Variant>& next) { CompileAhead(next); };
    ahead(task.baselines);
    const std::size_t first_of_task = result_.measurements.size();
    for (const Variant& b : task.baselines) evaluate(b);
    StrategyOptions strategy = config_.strategy;
    strategy.margin = timing_.tie_margin;  // moves beyond noise only (strategy.h)
    if (!task.candidates.empty()) Search(task.candidates, evaluate, strategy, ahead);
    const auto measured = [this, first_of_task] {
      return std::vector<Measurement>(result_.measurements.begin() + static_cast<std::ptrdiff_t>(first_of_task),
                                      result_.measurements.end());
    };
    if (!measured().empty()) Settle(evaluate, ahead, measured);
  }

  // Compile ahead: the variants the task will measure next and the cache
  // has not (the baselines, then what the strategy announces), built in
  // parallel by the worker before any of them is timed.
  void CompileAhead(const std::vector<Variant>& next) {
    if (one_task_ahead_) return;  // compiled a task ahead (CompileEachTaskAhead)
    std::vector<Variant> ahead;   // the kernels not measured, nor announced before in this task
    for (Variant& v : NotTrusted(next, key_))
      if (announced_.insert(v.Key()).second) ahead.push_back(std::move(v));
    if (ahead.size() < 2 || !CompilesAhead(device_)) return;  // one kernel: built by its measurement
    Advance(task_done_, name_ + ": compiling " + std::to_string(ahead.size()) + " kernels for " + key_);
    const LoggedSpan span(name_, "compile ahead of " + std::to_string(ahead.size()) + " kernels for " + key_);
    if (CompilesAheadInProcesses(device_))
      helpers_.CompileAhead(ahead, TuningDataset{key_});
    else
      worker_->CompileAhead(ahead, TuningDataset{key_});
  }

  // One evaluation of the search: the cache's record, or a measurement in
  // the worker appended to the cache; the kernel time of an ok one.
  std::optional<double> Evaluate(const Variant& v) {
    const std::string cache_key = CacheKeyOf(id_, key_, v);
    const std::optional<Measurement> found = ledger_.Trusted(cache_key, config_.timing.tolerance);
    Measurement m = found ? *found : worker_->Measure(v, TuningDataset{key_}, timing_);
    ApplyBudget(m, config_.max_error);  // this run's budget, whatever the record's was
    if (!found) {
      RejectOverTheCeiling(m);
      ledger_.Append(m);
    }
    if (seen_.insert(cache_key).second) {
      result_.measurements.push_back(m);
      task_done_ = std::min(task_done_ + 1, task_->planned);
      // The variant and its result first: a progress bar cuts the end of long lines.
      Advance(task_done_, v.Key() + ": " + ShortStatus(m) + " [" + name_ + ", " + key_ + "]" + (found ? " (cached)" : ""));
    }
    if (m.status != MeasureStatus::kOk) return std::nullopt;
    return m.timing.median_ms;
  }

  // The search settled by races of its leader's neighbourhood, in this device's worker (race.h).
  void Settle(const Evaluator& evaluate, const LookAhead& ahead, const std::function<std::vector<Measurement>()>& measured) {
    Advance(task_done_, name_ + ": racing the leaders of " + key_);
    RaceMemo memo;
    memo.find = [this](const std::string& race_key) { return ledger_.FindRace(race_key); };
    memo.keep = [this](const std::string& race_key, const RaceRecord& race) { ledger_.AppendRace(race_key, race); };
    // The walk may spend the search's budget once more (docs/TUNING.md "Races and ties").
    const SearchToSettle search{task_->candidates, evaluate, measured, ahead,
                                config_.strategy.budget > 0 ? config_.strategy.budget : kSettleWalkDefault};
    const Racer racer = [this](const std::vector<Variant>& variants, std::string* why) {
      std::vector<RaceSamples> legs;
      for (int leg = 0; leg < RaceLegsFor(device_); ++leg) {
        if (leg > 0) worker_->Restart();  // the next leg in a fresh process
        const LoggedSpan span(name_, "race of " + std::to_string(variants.size()) + " for " + key_);
        std::optional<RaceSamples> samples = worker_->Race(variants, TuningDataset{key_}, timing_, why);
        if (!samples) return std::optional<std::vector<RaceSamples>>();
        legs.push_back(std::move(*samples));
      }
      return std::optional<std::vector<RaceSamples>>(std::move(legs));
    };
    bool cached_race = false;
    result_.races.push_back(SettleSearch(racer, search, id_, task_->lang, key_, timing_, memo, &cached_race));
    if (cached_race) Advance(task_done_, name_ + ": the race of " + key_ + " (cached)");
  }

  // The worker its precompile left (HeadStarts), else a fresh one.
  std::unique_ptr<IsolatedDevice> StartedAheadOr(const WorkerSetup& workers, std::size_t d) {
    std::unique_ptr<IsolatedDevice> worker;
    if (workers.head_starts) worker = workers.head_starts->Take(d);
    // (name_ is not made yet: it comes after worker_.)
    if (worker)
      TimingLog([&] { return device_.backend + " " + device_.name + " measures in the worker that compiled ahead"; });
    return worker ? std::move(worker)
                  : std::make_unique<IsolatedDevice>(workers.executable, device_, workers.variant_timeout_s);
  }

  const TuningPlan& plan_;
  const std::size_t d_;
  const DeviceIdentity& device_;
  const TuneConfig& config_;
  TuningLedger& ledger_;
  DeviceResult& result_;
  std::unique_ptr<IsolatedDevice> worker_;
  CompileHelpers helpers_;  // CompileAheadInProcesses only
  ChipStart* chip_start_;   // opened once this turn has started (null: no chip lock shared)
  TimingOptions timing_ = config_.timing;
  const std::string id_, name_;
  std::size_t task_start_ = 0;  // evaluations planned before the current task
  int copy_remeasures_left_ = kCopyRemeasures;  // RejectOverTheCeiling
  // The current task.
  const Task* task_ = nullptr;
  std::string key_;             // its dataset
  std::size_t task_done_ = 0;   // its evaluations done
  std::set<std::string> seen_;  // its cache keys recorded
  std::set<std::string> announced_;  // its variants compiled ahead (CompileAhead), by key
  // CompileEachTaskAhead's: each task's place in its order, and the
  // compiles, declared last: they use the members above, so they end first.
  std::map<const Task*, std::size_t> task_ahead_;
  std::unique_ptr<OneTaskAhead> one_task_ahead_;
};

}  // namespace

void TuneDevice(const TuningPlan& plan, std::size_t d, const TuneConfig& config, const WorkerSetup& workers,
                TuningLedger& ledger, DeviceResult& result) {
  DeviceTuning(plan, d, config, workers, ledger, result).Run();
}

void PrecompileDevice(const TuningPlan& plan, std::size_t d, const WorkerSetup& workers, TuningLedger& ledger,
                      const std::function<bool()>& overtaken) {
  const DeviceIdentity& device = plan.devices[d].identity;
  if (!CompilesAhead(device)) return;
  if (workers.head_starts && !workers.head_starts->Begin(d, overtaken)) return;
  std::unique_ptr<IsolatedDevice> worker;
  try {
    worker = std::make_unique<IsolatedDevice>(workers.executable, device, workers.variant_timeout_s);
    if (!workers.host_lock.empty()) worker->UseHostLock(workers.host_lock);
    if (!workers.chip_lock.empty()) worker->UseChipLock(workers.chip_lock);
    // A worker that may be left to the turn measures there: it builds into
    // its measuring runner, choosing its context first, where the chip's
    // lock keeps the choice's probes out of the measuring API's jobs. Not
    // before the chip's first turn has started (ChipStart): until then it
    // builds for the program cache, which its measuring runner then loads from.
    const bool may_measure = workers.head_starts && !workers.chip_lock.empty();
    for (const Task& task : plan.tasks) {
      if (task.device != d || overtaken()) continue;  // the turn came: it takes the worker as it is
      const CompileFor compile_for = may_measure && (!workers.chip_start || workers.chip_start->IsOpen())
                                         ? CompileFor::kThisProcess
                                         : CompileFor::kTheCache;
      const std::string& key = plan.datasets[task.dataset].info.key;
      std::vector<Variant> ahead;
      for (const std::vector<Variant>* list : {&task.baselines, &task.candidates})
        for (const Variant& v : *list)
          if (!ledger.Cached(CacheKeyOf(device.Id(), key, v))) ahead.push_back(v);
      if (ahead.size() < 2) continue;  // one kernel: built by its measurement
      const std::string who = device.backend + " " + device.name;
      const LoggedSpan span(who, "precompile of " + std::to_string(ahead.size()) + " kernels for " + key);
      worker->CompileAhead(ahead, TuningDataset{key}, compile_for);
    }
  } catch (...) {
    // Only a head start lost: the device's own worker compiles and records any failure.
    worker.reset();
  }
  if (workers.head_starts) workers.head_starts->Leave(d, worker && worker->starts() > 0 ? std::move(worker) : nullptr);
}

}  // namespace skintune::internal
