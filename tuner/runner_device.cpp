// skintune: the tuner's TunedDevice on any device of any API
// (tuner/runner_device.h): identity, limits and languages from the runtime's
// discovery (runtime/backend_table.h), the jobs (tuner/measure_job.h) and the
// copy bandwidth through the runner driver (runtime/runner.h), programs
// through the on-disk program cache (runtime/program_cache.h) on GPUs, which
// CompileAhead fills from several threads.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <list>
#include <mutex>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <thread>
#include <utility>

#include "tuner/runner_device.h"

#include "base/error.h"
#include "generator/packer.h"  // PackPalette
#include "runtime/program_cache.h"
#include "tuner/datasets.h"
#include "tuner/host_lock.h"
#include "tuner/measure_job.h"
#include "tuner/schedule.h"  // IsHostCpu

namespace skintune::internal::tuner_internal {

namespace {

// The APIs whose kernels CompileAhead builds on several threads:
// - opencl, cuda: into the measuring runner itself (Runner::ConcurrentBuilds:
//   clBuildProgram of distinct programs in one context is thread-safe, OpenCL
//   1.2 appendix A.2, and so are NVRTC and the CUDA driver API), so Measure
//   finds each kernel built in its own context. (With a runner per thread,
//   NVIDIA's OpenCL built each kernel twice: once ahead, then again from the
//   cached PTX in the measuring context, 42 ms per measurement on the H100.)
//   PoCL compiles one kernel at a time in a process, whatever the threads,
//   and once more per work-group size at the kernel's first launch (~250 ms
//   a variant on the H200 machine's host, 2026-11-28), so its kernels are
//   compiled ahead by running them once, in several processes of their own
//   (CompileAheadInProcesses; tuner/device_tuning.cpp starts them). NVIDIA's
//   OpenCL builds one program at a time in a process too, so its kernels are
//   built (not run) in processes of their own, into the program cache, where
//   the measuring process loads each in 3-4 ms instead of ~100 ms of
//   compiling (H200 machine, 2026-12-02: a cold turn 14.0-15.7 s against
//   16.1-17.4 in process; tuner/device_tuning.cpp has them build one task ahead);
// Each of the others with a runner (and program cache object) of its own,
// so that no API object is shared between threads:
// - vulkan: each thread's runner has a VkDevice of its own, and its Build
//   creates the pipeline (the driver's compile): the SPIR-V lands in the
//   program cache, the driver's compile in the driver's own disk cache
//   (NVIDIA keeps one), and the measuring runner finds both;
// - gl: each thread's runner has an EGL context of its own, current on that
//   thread only; program binaries land in the program cache.
// On the H100 a cold default run spent 100-130 ms per GL and Vulkan variant
// between timings, most of it compiling one kernel at a time (H100 machine, 2026-11-24).
constexpr std::string_view kCompileAheadApis[] = {"opencl", "cuda", "vulkan", "gl"};
constexpr std::string_view kNvidiaOpenClPlatform = "NVIDIA CUDA";  // its OpenCL platform's name

// At most this many compile threads (each holds a context of the device).
constexpr unsigned kMaxCompileThreads = 8;

// The contexts a GPU's measuring runner is chosen from (OpenQuickest), and
// how each one's launch start is probed. On an H200 (2026-12-01) a CUDA
// context's 4 KiB copy after the flush read 2.05-2.08 us or 2.18-2.21, and
// the 100k-b4 kernel 4.06-4.13 or 4.19-4.26 us on the same contexts. About
// half the contexts were of the quicker kind there, so six would leave all
// slow one time in 64; on another H200 one worker's six all read 2.26-2.37:
// the share differs from machine to machine. On a third (2026-12-02) 4 of 18
// CUDA contexts were quick (2.08-2.13 us, the rest 2.18-2.42) and one cold
// run's six were all slow: its six CUDA winners read 3.3-4% slower than the
// other two runs'. CUDA chooses from ten, which leave all slow about one
// time in twelve there, for 0.4 s a context (opened and probed ahead, while
// the API before it measures); NVIDIA's OpenCL, whose chosen contexts read
// within 1.2% across those runs, from six.
int ContextsToChoose(const DeviceIdentity& device) { return device.backend == "cuda" ? 10 : 6; }

// A runner opened as untimed work on the chip (tuner/host_lock.h ChipQuiet):
// its context's allocations wait for a race there, and a race for them.
std::unique_ptr<skintune::internal::Runner> OpenQuietly(
    const std::function<std::unique_ptr<skintune::internal::Runner>()>& open) {
  const ChipQuiet landing(ChipQuiet::Mode::kLanding);
  return open();
}

constexpr std::size_t kLaunchStartProbeBytes = 4096;
constexpr int kLaunchStartProbeRounds = 2;
constexpr int kLaunchStartProbeUntimed = 3;
constexpr int kLaunchStartProbeSamples = 50;

// CPU devices (PoCL) keep compiled kernels in a cache of their own (PoCL's
// kernel cache), which a build from source finds; skintune's program cache
// is not used for them: reading a PoCL program back (CL_PROGRAM_BINARIES) for
// it made a cold tune of 48 kernels on 100k-b2 38 s instead of 17 s on the
// 2-core development machine (docs/PERFORMANCE.md). Compiling ahead fills
// PoCL's cache, and pays only with enough cores to compile on: on 2 cores it
// measured no gain (the compiles cost the same, two at a time), and on the
// 2-core machine (2026-12-02, two cold default runs of each, alternated)
// SKINTUNE_COMPILE_AHEAD=always took 89.9-92.0 s against 76.8-84.7 without:
// PoCL's measuring worker built for 10 s instead of 43-46, but its turn took
// 73-74 s instead of 61-68. So a CPU device compiles ahead only on a host
// with at least this many logical CPUs.
constexpr unsigned kMinCpusToCompileAheadForACpuDevice = 8;

// Compile threads that outlive one CompileAhead call, each with a runner of
// its own, opened on its thread at its first kernel (GL's EGL context is
// current on that thread only; Vulkan's VkDevice): opened once per device
// instead of once per data set, which cost Vulkan ~1.1 s and GL ~0.6 s per
// data set on the H100 (2026-11-24).
class CompileThreads {
 public:
  using Open = std::function<std::unique_ptr<skintune::internal::Runner>()>;
  using Job = std::function<void(skintune::internal::Runner&, std::size_t)>;
  CompileThreads(unsigned count, Open open) : open_(std::move(open)) {
    for (unsigned t = 0; t < count; ++t) threads_.emplace_back([this] { Loop(); });
  }
  ~CompileThreads() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : threads_) t.join();
  }
  std::size_t size() const { return threads_.size(); }
  // Runs job(runner, i) for every i < count on the threads (a thread whose
  // runner did not open takes none); returns when every thread is done.
  void Run(std::size_t count, const Job& job) {
    std::unique_lock<std::mutex> lock(mutex_);
    job_ = &job;
    count_ = count;
    next_ = 0;
    busy_ = threads_.size();
    ++generation_;
    wake_.notify_all();
    done_.wait(lock, [&] { return busy_ == 0; });
    job_ = nullptr;
  }

 private:
  void Loop() {
    std::unique_ptr<skintune::internal::Runner> runner;
    bool opened = false;
    std::uint64_t seen = 0;
    for (;;) {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) {
        lock.unlock();
        const ChipQuiet landing(ChipQuiet::Mode::kLanding);  // its context's closing
        runner.reset();
        return;
      }
      seen = generation_;
      lock.unlock();
      std::size_t i = next_++;
      if (i < count_ && !opened) {  // a thread with nothing to build opens nothing
        opened = true;
        try {
          runner = open_();
        } catch (const Error&) {
          // No context of its own: the others build the rest, Measure this one.
        }
      }
      for (; runner && i < count_; i = next_++) (*job_)(*runner, i);
      lock.lock();
      if (--busy_ == 0) done_.notify_all();
    }
  }

  Open open_;
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  bool stop_ = false;
  std::uint64_t generation_ = 0;
  const Job* job_ = nullptr;
  std::size_t count_ = 0;
  std::atomic<std::size_t> next_{0};
  std::size_t busy_ = 0;
};

class RunnerDevice final : public TunedDevice {
 public:
  RunnerDevice(FoundDevice device, std::vector<Lang> languages, int index, ExecutorDecorator decorate)
      : device_(std::move(device)), languages_(std::move(languages)), decorate_(std::move(decorate)) {
    device_.identity.index = index;
  }

  ~RunnerDevice() override {
    compile_threads_.reset();  // each thread closes its own context under a hold of its own
    const ChipQuiet landing(ChipQuiet::Mode::kLanding);  // the contexts' closing
    executor_.reset();
    runner_.reset();
    builder_executor_.reset();
    builder_.reset();
  }

  const DeviceIdentity& identity() const override { return device_.identity; }
  DeviceLimits limits() const override { return device_.limits; }
  std::vector<Lang> languages() const override { return languages_; }

  Measurement Measure(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options) override {
    return MeasurementOf(
        {&MeasuringExecutor(), &datasets_, &device_.identity, limits(), languages(), variant, dataset, options});
  }

  std::vector<std::vector<double>> Race(const std::vector<Variant>& variants, const TuningDataset& dataset,
                                        const TimingOptions& options) override {
    std::vector<std::vector<double>> samples;
    const RaceJob job{&MeasuringExecutor(), &datasets_, &device_.identity, variants, dataset, options, &samples};
    if (!job.Run()) throw Error("race on " + dataset.key + ": no variant, or a stop rule that cannot work");
    return samples;
  }

  double CopyBandwidthGBps(std::size_t bytes) override {
    const std::size_t size = CopyBytesCapped(bytes, device_.max_allocation_bytes);
    // One set (a copy this large is far beyond any cache), its kernel time
    // by the same method as every variant's (the flush, then each copy
    // alone). Its buffers (several times the last-level cache: seconds of
    // allocation and first touch on a CPU device) are made before a CPU
    // device takes the host's cores for the samples alone (tuner/host_lock.h),
    // so the GPU workers beside it wait only for the samples.
    Executor& executor = MeasuringExecutor();  // before the chip's lock: a context's choice takes it
    const ChipLock chip;  // its buffers and its samples (tuner/host_lock.h)
    const std::unique_ptr<Executor::Timed> copy = executor.Copy(languages_.front(), 2 * size, 1);
    const HostLock timed(TimedMode(IsHostCpu(device_.identity)));
    return ProbeCopyGBps(*copy, size);
  }

  std::size_t CompileAhead(const std::vector<Variant>& variants, const TuningDataset& dataset,
                           CompileFor compile_for) override {
    if (!CompilesAhead(device_.identity)) return 0;
    // Compiles are host work. Each kernel's build holds the host lock on its
    // own, not the whole batch: a CPU device asking to time waits for the
    // builds under way, not for a batch of 48 (3.5 s with NVIDIA's OpenCL,
    // which made PoCL's first data set take 36 s instead of 16 on the H200
    // machine, and the GPU's other APIs waited behind PoCL, 2026-11-29).
    const HostLock::Mode host_work = HostWorkMode(IsHostCpu(device_.identity));
    if (CompilesAheadByRunning(device_.identity)) {
      const HostLock held(host_work);
      return RunOnce(variants, dataset, compile_for);
    }
    std::vector<KernelSource> kernels;
    {
      const HostLock held(host_work);
      kernels = KernelsOf(variants, dataset);
    }
    if (kernels.empty()) return 0;
    std::atomic<std::size_t> built{0};
    const auto build = [&](skintune::internal::Runner& runner, std::size_t i) {
      const ChipQuiet landing(ChipQuiet::Mode::kLanding);  // the program lands on the chip
      const HostLock held(host_work);
      try {
        runner.Build(kernels[i]);
        ++built;
      } catch (const Error&) {
        // A compile failure is Measure's to record (compile_failed).
      }
    };
    try {
      skintune::internal::Runner& into = BuildingRunner(compile_for, host_work);
      if (into.ConcurrentBuilds()) {
        BuildOnShortLivedThreads(into, kernels.size(), build);
        return built;
      }
    } catch (const Error&) {
      return 0;  // the device does not open: Measure records why
    }
    CompileThreadsOfTheirOwn().Run(kernels.size(), build);
    return built;
  }

 private:
  // The executor the jobs run on (opening runner_ on first use): the
  // RunnerExecutor over it, wrapped in decorate_ when given. The first call
  // holds no lock where ProbesLaunchStart: the probe takes the chip's lock,
  // which must not nest in a caller's (one flock per process: the inner
  // release would end the outer hold) nor follow the host's.
  Executor& MeasuringExecutor() {
    if (!runner_) {
      MeasuringContext context;
      runner_ = OpenMeasuringRunner(device_, languages_.front(), &cache_, &context);
      if (cache_.enabled()) runner_->UseProgramCache(&cache_, device_.identity.Id());
      runner_->ShareTimedInputs(SharedInputBytes(device_.identity));
      auto executor = std::make_unique<RunnerExecutor>(*runner_, device_.identity);
      executor->SetContext(std::move(context.choice), context.launch_start_ms);
      executor_ = std::move(executor);
      if (decorate_) executor_ = decorate_(std::move(executor_), device_.identity);
    }
    return *executor_;
  }

  // The kernels of `variants`, each once, emitted here (one thread) as
  // Measure emits them; a variant that cannot be packed or emitted is left
  // for Measure to record (invalid).
  std::vector<KernelSource> KernelsOf(const std::vector<Variant>& variants, const TuningDataset& dataset) {
    DatasetCache::Entry& data = datasets_.Get(dataset.key);
    std::vector<KernelSource> kernels;
    std::set<std::string> hashes;
    for (const Variant& v : variants) {
      try {
        std::vector<KernelSource> emitted;
        (void)PackScene(datasets_, data, v, emitted);
        for (KernelSource& k : emitted)
          if (hashes.insert(k.source_hash).second) kernels.push_back(std::move(k));
      } catch (const Error&) {
      }
    }
    return kernels;
  }

  // The runner CompileAhead builds into (opened on first use). For this
  // process: the measuring runner, so that Measure finds each kernel built
  // in its own context; opened under the host lock (host work), but for a
  // context's choice or launch-start probe, which times on the chip and
  // comes first (the chip's lock is never taken after the host's:
  // tuner/host_lock.h). For the cache only: the measuring runner where one
  // is open, else builder_, on the shared context: a process that times
  // nothing chooses or probes no context (the probes would run on the chip
  // beside another API's timing).
  skintune::internal::Runner& BuildingRunner(CompileFor compile_for, HostLock::Mode host_work) {
    if (runner_ || compile_for == CompileFor::kThisProcess) {
      if (!runner_ && ProbesLaunchStart(device_)) MeasuringExecutor();
      const HostLock held(host_work);
      MeasuringExecutor();
      return *runner_;
    }
    if (!builder_) {
      const ChipQuiet landing(ChipQuiet::Mode::kLanding);  // a context's opening, before the host lock (host_lock.h)
      const HostLock held(host_work);
      std::unique_ptr<skintune::internal::Runner> opened = device_.open();
      if (cache_.enabled()) opened->UseProgramCache(&cache_, device_.identity.Id());
      builder_executor_ = std::make_unique<RunnerExecutor>(*opened, device_.identity, nullptr);
      builder_ = std::move(opened);
    }
    return *builder_;
  }
  Executor& BuildingExecutor(CompileFor compile_for) {
    skintune::internal::Runner& runner = BuildingRunner(compile_for, HostLock::Mode::kNone);
    return &runner == runner_.get() ? MeasuringExecutor() : *builder_executor_;
  }

  // Each variant run once as its verification runs it (a build, then a
  // launch of its geometry), its output unread: the compile ahead of a device
  // that compiles again at a kernel's first launch. One at a time: such a
  // driver compiles one kernel at a time in a process (the tuner runs several
  // processes: CompileAheadInProcesses). Returns the variants run; one that
  // fails is left for Measure to record.
  std::size_t RunOnce(const std::vector<Variant>& variants, const TuningDataset& dataset, CompileFor compile_for) {
    DatasetCache::Entry& data = datasets_.Get(dataset.key);
    std::size_t ran = 0;
    for (const Variant& v : variants) {
      try {
        std::vector<KernelSource> kernels;
        const PackedMesh& packed = PackScene(datasets_, data, v, kernels);
        (void)BuildingExecutor(compile_for).Run(packed, kernels, PackPalette(data.verification_palette, v),
                                                data.instances());
        ++ran;
      } catch (const Error&) {
        // Measure records it.
      }
    }
    return ran;
  }

  static unsigned CompileThreadCount() {
    return std::clamp<unsigned>(std::thread::hardware_concurrency(), 1u, kMaxCompileThreads);
  }

  // Into `runner` itself, from threads that end with the call.
  void BuildOnShortLivedThreads(skintune::internal::Runner& runner, std::size_t count,
                                const CompileThreads::Job& build) {
    std::atomic<std::size_t> next{0};
    const auto work = [&] {
      for (std::size_t i = next++; i < count; i = next++) build(runner, i);
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < std::min<std::size_t>(CompileThreadCount(), count); ++t) pool.emplace_back(work);
    work();
    for (std::thread& t : pool) t.join();
  }

  // The compile threads with runners of their own, started on first use.
  CompileThreads& CompileThreadsOfTheirOwn() {
    if (!compile_threads_)
      compile_threads_ = std::make_unique<CompileThreads>(CompileThreadCount(), [this] {
        std::unique_ptr<skintune::internal::Runner> runner = OpenQuietly(device_.open);
        if (cache_.enabled()) {
          const std::lock_guard<std::mutex> lock(thread_caches_mutex_);
          runner->UseProgramCache(&thread_caches_.emplace_back(cache_.dir()), device_.identity.Id());
        }
        return runner;
      });
    return *compile_threads_;
  }

  FoundDevice device_;
  std::vector<Lang> languages_;
  ExecutorDecorator decorate_;  // empty: the RunnerExecutor as it is
  // ProgramCache::DefaultDir() ($SKINTUNE_CACHE_DIR, ...); none for a CPU device.
  ProgramCache cache_{IsHostCpu(device_.identity) ? "-" : ""};
  std::unique_ptr<skintune::internal::Runner> runner_;  // made on first use
  std::unique_ptr<Executor> executor_;  // over runner_: remembers the copies it timed
  // CompileAhead's for the cache alone, where runner_ is not open (BuildingRunner).
  std::unique_ptr<skintune::internal::Runner> builder_;
  std::unique_ptr<Executor> builder_executor_;  // over builder_ (declared after it: ended first)
  DatasetCache datasets_;
  // The compile threads' program cache objects (one per thread: its counters
  // are its own), then the threads, joined (and their runners closed) first.
  std::list<ProgramCache> thread_caches_;
  std::mutex thread_caches_mutex_;
  std::unique_ptr<CompileThreads> compile_threads_;
};

}  // namespace

namespace {

// "the quickest of 6 contexts by launch start (a 4 KiB copy after the flush):
// 2.088 us; the others 2.102-2.258 us" (1 ns steps; failed ones counted apart).
std::string ContextChoiceText(const QuickestRunner& quickest) {
  const auto us = [](double ms) {
    char text[32];
    std::snprintf(text, sizeof text, "%.3f", ms * 1e3);
    return std::string(text);
  };
  double low = 0.0, high = 0.0;
  int others = 0, failed = 0;
  for (std::size_t c = 0; c < quickest.starts_ms.size(); ++c) {
    const double ms = quickest.starts_ms[c];
    if (std::isnan(ms)) {
      ++failed;
    } else if (c != quickest.chosen) {
      low = others == 0 ? ms : std::min(low, ms);
      high = others == 0 ? ms : std::max(high, ms);
      ++others;
    }
  }
  std::string text = "the quickest of " + std::to_string(quickest.starts_ms.size()) +
                     " contexts by launch start (a " + std::to_string(kLaunchStartProbeBytes / 1024) +
                     " KiB copy after the flush): " + us(quickest.starts_ms[quickest.chosen]) + " us";
  if (others > 0) text += "; the others " + us(low) + "-" + us(high) + " us";
  if (failed > 0) text += "; " + std::to_string(failed) + " failed to open or to be timed";
  return text;
}

}  // namespace

bool ProbesLaunchStart(const FoundDevice& device) { return !IsHostCpu(device.identity); }
bool ChoosesContext(const FoundDevice& device) { return device.open_own && ProbesLaunchStart(device); }

LaunchStartProbe::LaunchStartProbe(skintune::internal::Runner& runner, const DeviceIdentity& device, Lang lang,
                                   ProgramCache* cache)
    : device_(device), executor_(runner, device, nullptr) {
  if (cache && cache->enabled()) runner.UseProgramCache(cache, device.Id());
  const ChipLock chip;  // as every timing on the chip, from its first upload
  copy_ = executor_.Copy(lang, kLaunchStartProbeBytes, 1);
}

std::vector<double> LaunchStartProbe::Samples() {
  const ChipLock chip;
  const HostLock timed(TimedMode(IsHostCpu(device_)));
  return copy_->Cold(kLaunchStartProbeUntimed, kLaunchStartProbeSamples);
}

std::unique_ptr<skintune::internal::Runner> OpenMeasuringRunner(const FoundDevice& device, Lang lang,
                                                                ProgramCache* cache, MeasuringContext* context) {
  if (context) *context = {};
  const auto probe_of = [&](skintune::internal::Runner& runner) -> LaunchStartRound {
    auto probe = std::make_shared<LaunchStartProbe>(runner, device.identity, lang, cache);
    return [probe] { return probe->Samples(); };
  };
  // The one runner the device opens, and its launch start (left 0 where the
  // probe fails: the measurements say why, if the device cannot time).
  const auto opened = [&](const std::string& why) {
    std::unique_ptr<skintune::internal::Runner> runner = OpenQuietly(device.open);
    std::vector<double> samples;
    try {
      const LaunchStartRound round = probe_of(*runner);
      for (int r = 0; r < kLaunchStartProbeRounds; ++r) {
        const std::vector<double> more = round();
        samples.insert(samples.end(), more.begin(), more.end());
      }
    } catch (const Error& e) {
      TimingLog([&] { return device.identity.Id() + " launch start not probed: " + e.what(); });
      return runner;
    }
    const double ms = samples.empty() ? 0.0 : TrimmedMean(samples, 0.1);
    TimingLog([&] { return device.identity.Id() + " launch start (us): " + std::to_string(ms * 1e3) + why; });
    if (context) context->launch_start_ms = ms;
    return runner;
  };
  if (!ProbesLaunchStart(device)) return OpenQuietly(device.open);
  if (!ChoosesContext(device)) return opened("");
  QuickestRunner quickest;
  try {
    quickest = OpenQuickest(ContextsToChoose(device.identity), kLaunchStartProbeRounds, device.open_own, probe_of);
  } catch (const Error& e) {
    return opened(std::string("; no context of its own (") + e.what() + "): the shared one");
  }
  TimingLog([&] {
    std::string line = device.identity.Id() + " launch start of " + std::to_string(quickest.starts_ms.size()) +
                       " contexts (us):";
    for (const double ms : quickest.starts_ms) line += " " + std::to_string(ms * 1e3);
    const auto whole_ms = [](const std::vector<double>& all) {
      std::string text;
      for (const double ms : all) text += " " + std::to_string(std::lround(ms));
      return text;
    };
    return line + "; measuring on context " + std::to_string(quickest.chosen) + "; opened in (ms)" +
           whole_ms(quickest.open_ms) + ", probes prepared in (ms)" + whole_ms(quickest.prepare_ms) + ", probed in " +
           std::to_string(std::lround(quickest.probing_ms)) + " ms";
  });
  if (context) *context = {ContextChoiceText(quickest), quickest.starts_ms[quickest.chosen]};
  return std::move(quickest.runner);
}

QuickestRunner OpenQuickest(int count, int rounds, const std::function<std::unique_ptr<skintune::internal::Runner>()>& open,
                            const std::function<LaunchStartRound(skintune::internal::Runner&)>& probe_of) {
  std::vector<std::unique_ptr<skintune::internal::Runner>> runners;
  std::vector<LaunchStartRound> probes;  // each runner's, ended before any runner
  std::vector<std::vector<double>> samples;
  std::optional<Error> last;
  const auto drop = [&](std::size_t c, const Error& e) {
    last = e;
    probes[c] = nullptr;
    runners[c].reset();
  };
  using Clock = std::chrono::steady_clock;
  const auto ms_since = [](Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  };
  QuickestRunner quickest;
  for (int c = 0; c < count; ++c) {
    runners.emplace_back();
    probes.emplace_back();
    samples.emplace_back();
    try {
      Clock::time_point t = Clock::now();
      runners.back() = OpenQuietly(open);  // not its probe, which times on the chip
      quickest.open_ms.push_back(ms_since(t));
      t = Clock::now();
      probes.back() = probe_of(*runners.back());
      quickest.prepare_ms.push_back(ms_since(t));
    } catch (const Error& e) {
      drop(runners.size() - 1, e);
    }
  }
  const Clock::time_point opened = Clock::now();
  for (int r = 0; r < rounds; ++r)
    for (std::size_t c = 0; c < runners.size(); ++c) {
      if (!runners[c]) continue;
      try {
        const std::vector<double> more = probes[c]();
        samples[c].insert(samples[c].end(), more.begin(), more.end());
      } catch (const Error& e) {
        drop(c, e);
      }
    }
  probes.clear();
  quickest.probing_ms = ms_since(opened);
  for (std::size_t c = 0; c < runners.size(); ++c) {
    const bool probed = runners[c] && !samples[c].empty();
    quickest.starts_ms.push_back(probed ? TrimmedMean(samples[c], 0.1) : std::nan(""));
    if (probed && (!quickest.runner || quickest.starts_ms[c] < quickest.starts_ms[quickest.chosen])) {
      quickest.runner = std::move(runners[c]);
      quickest.chosen = c;
    }
  }
  if (!quickest.runner) throw last ? *last : Error("OpenQuickest: no runner to open");
  const ChipQuiet landing(ChipQuiet::Mode::kLanding);  // the others' closing
  runners.clear();
  return quickest;
}

std::unique_ptr<TunedDevice> MakeRunnerDevice(FoundDevice device, std::vector<Lang> languages, int index,
                                              ExecutorDecorator decorate) {
  return std::make_unique<RunnerDevice>(std::move(device), std::move(languages), index, std::move(decorate));
}

Discovery DiscoverTunedDevices(const ExecutorDecorator& decorate, const char* only, const GivenCache* given) {
  Discovered found = DiscoverDevices(only);
  Discovery discovery;
  discovery.skipped = std::move(found.skipped);
  int index = 0;
  for (FoundDevice& device : found.devices) {
    if (given && device.identity.Id() == given->device_id) {
      device.identity.last_level_cache_bytes = given->bytes;
      device.identity.last_level_cache_source = given->source;
    }
    const BackendEntry* entry = FindBackend(device.identity.backend);
    discovery.devices.push_back(MakeRunnerDevice(std::move(device), entry->languages, index++, decorate));
  }
  return discovery;
}

std::size_t SharedInputBytes(const DeviceIdentity& d) {
  constexpr std::size_t kMax = std::size_t{1} << 30;
  return d.global_memory_bytes > 0 ? std::min<std::size_t>(kMax, d.global_memory_bytes / 8) : kMax / 4;
}

}  // namespace skintune::internal::tuner_internal

namespace skintune::internal {

Discovery DiscoverTunedDevices() { return tuner_internal::DiscoverTunedDevices(tuner_internal::ExecutorDecorator{}); }

bool CompilesAheadInProcesses(const DeviceIdentity& device) {
  // NVIDIA's OpenCL builds one program at a time in a process, whatever the
  // threads (5 kernels in 420-560 ms), and loads a program another process
  // built, from the program cache, in 3-4 ms (H200, 2026-12-02): the helpers
  // need that cache on disk.
  return CompilesAheadByRunning(device) ||
         (device.backend == "opencl" && device.platform == tuner_internal::kNvidiaOpenClPlatform &&
          CompilesAhead(device) && !ProgramCache::DefaultDir().empty());
}

bool CompilesAheadByRunning(const DeviceIdentity& device) {
  return device.backend == "opencl" && IsHostCpu(device) && CompilesAhead(device);
}

bool CompilesAhead(const DeviceIdentity& device) {
  const auto& list = tuner_internal::kCompileAheadApis;
  if (std::find(std::begin(list), std::end(list), device.backend) == std::end(list)) return false;
  // SKINTUNE_COMPILE_AHEAD=always|never (docs/TUNING.md): the tests run both
  // paths on CPU devices with "always".
  if (const char* forced = std::getenv("SKINTUNE_COMPILE_AHEAD")) {
    if (std::string_view(forced) == "always") return true;
    if (std::string_view(forced) == "never") return false;
  }
  return !IsHostCpu(device) ||
         std::thread::hardware_concurrency() >= tuner_internal::kMinCpusToCompileAheadForACpuDevice;
}

}  // namespace skintune::internal
