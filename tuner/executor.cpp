// skintune: the executor over the runner driver and the sampling of kernel
// and frame times (tuner/executor.h).
#include "tuner/executor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "generator/languages.h"
#include "base/error.h"
#include "base/thread_pool.h"

namespace skintune::internal::tuner_internal {

KernelTime SampleKernelTime(Executor::Timed& timed, const TimingOptions& options) {
  using Clock = std::chrono::steady_clock;
  const StopRule& rule = options.stop;
  // The warm-up frames first, outside the time cap: they also prepare the
  // flush (its buffer is made on first use) and warm the device.
  (void)timed.Cold(std::max(options.warmup, 1), 0);
  const auto start = Clock::now();
  KernelTime t;
  for (;;) {
    const std::size_t want = std::min(rule.batch, rule.max_samples - std::min(rule.max_samples, t.samples.size()));
    const std::vector<double> batch =
        ColdSamples(timed, static_cast<int>(std::max<std::size_t>(want, 1)), options.frames_per_sample);
    if (batch.empty()) throw Error("timing: the device gave no kernel time");
    t.samples.insert(t.samples.end(), batch.begin(), batch.end());
    t.clock_mhz = timed.ClockMhz();
    for (const double s : batch)
      if (!(s > 0.0) || !std::isfinite(s))
        throw Error("timing: the device gave a kernel time of " + std::to_string(s) + " ms");
    t.interval = MedianInterval(t.samples);
    const double elapsed = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    if (ShouldStop(rule, t.interval, elapsed, &t.tight)) return t;
  }
}

std::vector<double> ColdSamples(Executor::Timed& timed, int samples, int frames) {
  frames = std::max(frames, 1);
  std::vector<double> raw = timed.Cold(0, samples * frames);
  if (frames == 1 || raw.empty()) return raw;
  // Sample j is the quickest of frames j, j + n, j + 2n, ...: frames apart
  // in time, so that one burst of a neighbour's load covers few samples whole.
  const std::size_t n = std::max<std::size_t>(raw.size() / static_cast<std::size_t>(frames), 1);
  std::vector<double> out(n, 0.0);
  for (std::size_t j = 0; j < n; ++j) {
    out[j] = raw[j];
    for (std::size_t f = j + n; f < raw.size(); f += n) out[j] = std::min(out[j], raw[f]);
  }
  return out;
}

double SampleFrameTime(Executor::Timed& timed, const TimingOptions& options, int* frames) {
  const double one = timed.FrameMs(std::max(options.warmup, 1), 1);
  const double wanted = one > 0.0 ? options.burst_ms / one : 1.0;
  // A power of two on a log scale, as the kernel's old bursts were, 1..kMaxBurstFrames.
  int n = 1;
  while (n < kMaxBurstFrames && n * std::sqrt(2.0) < wanted) n *= 2;
  std::vector<double> ms;
  for (int r = 0; r < std::max(options.repetitions, 1); ++r) ms.push_back(timed.FrameMs(0, n));
  if (frames) *frames = n;
  return Median(ms);
}

namespace {

// A verification run's outputs as the executor hands them to a job.
Executor::Output OutputOf(RunResult&& result) {
  return {std::move(result.positions), std::move(result.normals), std::move(result.tangents), result.poisoned_vertices};
}

}  // namespace

Executor::Output RunnerExecutor::Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                     std::span<const std::uint8_t> palette, int instances) {
  RunResult result = runner_.Run(mesh, kernels, palette, instances);
  return OutputOf(std::move(result));
}

Executor::Output Executor::RunAnimated(const PackedMesh& mesh, std::span<const KernelSource>, std::span<const std::uint8_t>,
                                       int, const AnimatedInputs&) {
  throw Error(std::string(Name(mesh.variant.lang)) + " launch: this executor makes no palettes on the device");
}

std::unique_ptr<Executor::Timed> Executor::PrepareAnimated(const PackedMesh& mesh, std::span<const KernelSource>,
                                                           std::span<const std::vector<std::uint8_t>>, int,
                                                           const AnimatedInputs&) {
  throw Error(std::string(Name(mesh.variant.lang)) + " launch: this executor makes no palettes on the device");
}

Executor::Output RunnerExecutor::RunAnimated(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                             std::span<const std::uint8_t> palette, int instances,
                                             const AnimatedInputs& animated) {
  if (animated.states.size() != 1) throw Error("RunAnimated: " + std::to_string(animated.states.size()) + " sets of states, not one");
  const AnimationView view = animated.clips->View();
  RunResult result = runner_.Run(mesh, kernels, palette, instances, Runner::Animated{&view, &animated.kernel, animated.states.front()});
  return OutputOf(std::move(result));
}

namespace {

class RunnerTimed final : public Executor::Timed {
 public:
  RunnerTimed(Runner& runner, RunnerExecutor& executor, Prepared prepared, Lang lang, std::string what, bool animated = false)
      : runner_(runner), executor_(executor), prepared_(std::move(prepared)), lang_(lang), what_(std::move(what)),
        animated_(animated) {}
  std::vector<double> Cold(int untimed, int samples) override {
    const Prepared& flush = executor_.Flush(lang_);
    const std::function<void()> before = executor_.BeforeEachSample();
    std::vector<double> palette;  // the palette kernel's times of the batch taken last (the one kept)
    const auto take = [&] {
      std::vector<std::vector<double>> launches;
      std::vector<double> ms = runner_.TimeCold(prepared_, flush, untimed, samples, animated_ ? &launches : nullptr, before);
      palette.clear();
      for (const std::vector<double>& frame : launches)
        if (!frame.empty()) palette.push_back(frame.front());  // the palette kernel: the frame's first launch
      return ms;
    };
    const auto keep = [&](std::vector<double> ms) {
      palette_ms_.insert(palette_ms_.end(), palette.begin(), palette.end());
      return ms;
    };
    if (samples == 0 || !executor_.clock().active()) return keep(take());
    const auto warm = [&] { (void)runner_.TimeCold(prepared_, flush, kClockWarmFrames, 0, nullptr, before); };
    ClockGuard::Batch batch = executor_.clock().Take(take, warm, what_);
    if (batch.mhz > 0) clock_mhz_ = clock_mhz_ == 0 ? batch.mhz : std::min(clock_mhz_, batch.mhz);
    return keep(std::move(batch.samples));
  }
  unsigned ClockMhz() const override { return clock_mhz_; }
  std::vector<double> PaletteKernelMs() const override { return palette_ms_; }
  double FrameMs(int untimed, int frames) override { return runner_.FrameMs(prepared_, untimed, frames); }
  std::size_t bytes_per_set() const override { return prepared_.bytes_per_set(); }

 private:
  Runner& runner_;
  RunnerExecutor& executor_;
  Prepared prepared_;
  Lang lang_;
  std::string what_;  // the variant or copy, for the timing log
  unsigned clock_mhz_ = 0;
  bool animated_ = false;
  std::vector<double> palette_ms_;
};

}  // namespace

HostFlush::HostFlush(std::size_t bytes)
    : words_(std::max<std::size_t>(bytes / sizeof(std::uint64_t), 1)), threads_(std::make_unique<ThreadPool>()) {
  // Distinct values, written once: no page is shared or left unbacked.
  for (std::size_t i = 0; i < words_.size(); ++i) words_[i] = i * 0x9e3779b97f4a7c15ull;
}

HostFlush::~HostFlush() = default;

void HostFlush::operator()() {
  const std::size_t threads = threads_->size();
  const std::size_t share = (words_.size() + threads - 1) / threads;
  std::vector<std::uint64_t> sums(threads, 0);
  threads_->ParallelFor(threads, 1, [&](std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      const std::size_t from = std::min(words_.size(), t * share), to = std::min(words_.size(), from + share);
      std::uint64_t sum = 0;
      for (std::size_t i = from; i < to; ++i) sum ^= words_[i];
      sums[t] = sum;
    }
  });
  std::uint64_t all = 0;
  for (const std::uint64_t s : sums) all ^= s;
  // The reads must happen: their result goes where the compiler cannot see through.
  asm volatile("" : : "r"(all) : "memory");
}

bool HostFlushes(const DeviceIdentity& device) { return IsSoftwareRasterizer(device); }

namespace {

// The GPU's clock reader (runtime/device_clock.h), null for a device on the
// host's CPU or one whose clock is not told; the reason goes to the timing log.
std::unique_ptr<DeviceClock> ClockOf(const DeviceIdentity& device) {
  if (IsHostCpu(device)) return nullptr;
  std::string why;
  std::unique_ptr<DeviceClock> clock = DeviceClock::Open(device, &why);
  TimingLog([&] { return device.Id() + (clock ? " SM clock read through NVML" : " SM clock not read: " + why); });
  return clock;
}

}  // namespace

RunnerExecutor::RunnerExecutor(Runner& runner, const DeviceIdentity& device)
    : RunnerExecutor(runner, device, ClockOf(device)) {}

RunnerExecutor::RunnerExecutor(Runner& runner, const DeviceIdentity& device, std::unique_ptr<DeviceClock> clock)
    : runner_(runner),
      flush_bytes_(runner.api().evicts_own_buffers() ? 0 : FlushBytes(device.last_level_cache_bytes, IsHostCpu(device))),
      clock_(std::move(clock)) {
  if (HostFlushes(device)) host_flush_ = std::make_unique<HostFlush>(flush_bytes_);
}

RunnerExecutor::~RunnerExecutor() = default;

const Prepared& RunnerExecutor::Flush(Lang lang) {
  if (const auto found = flushes_.find(lang); found != flushes_.end()) return found->second;
  return flushes_.emplace(lang, runner_.PrepareFlush(lang, host_flush_ || EvictsOwnBuffers() ? kAnchorBytes : flush_bytes_)).first->second;
}

std::function<void()> RunnerExecutor::BeforeEachSample() {
  if (!host_flush_) return {};
  return [flush = host_flush_.get()] { (*flush)(); };
}

std::unique_ptr<Executor::Timed> RunnerExecutor::Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                                         std::span<const std::vector<std::uint8_t>> palettes,
                                                         int instances) {
  const Lang lang = kernels.empty() ? mesh.variant.lang : kernels.front().lang;
  return std::make_unique<RunnerTimed>(runner_, *this, runner_.Prepare(mesh, kernels, palettes, instances), lang,
                                       mesh.variant.Key());
}

std::unique_ptr<Executor::Timed> RunnerExecutor::PrepareAnimated(const PackedMesh& mesh,
                                                                 std::span<const KernelSource> kernels,
                                                                 std::span<const std::vector<std::uint8_t>> palettes,
                                                                 int instances, const AnimatedInputs& animated) {
  if (animated.states.size() != palettes.size())
    throw Error("PrepareAnimated: " + std::to_string(animated.states.size()) + " sets of states for " +
                std::to_string(palettes.size()) + " input sets");
  const Lang lang = kernels.empty() ? mesh.variant.lang : kernels.front().lang;
  // A Skinner's ring, so that FrameMs advances the clocks as a crowd's frames do (AdvanceAnimation).
  Prepared prepared = runner_.Prepare(mesh, kernels, palettes, instances, kPaletteSlots);
  const AnimationView view = animated.clips->View();
  for (std::size_t s = 0; s < palettes.size(); ++s) {
    runner_.Animate(prepared, static_cast<int>(s), view, animated.kernel);
    for (int slot = 0; slot < kPaletteSlots; ++slot)  // every slot's instances: the set's states
      runner_.WritePalette(prepared, static_cast<int>(s), animated.states[s]);
  }
  runner_.Finish();
  // The palette kernel's own time is its frame's first launch's; a fused frame has none.
  return std::make_unique<RunnerTimed>(runner_, *this, std::move(prepared), lang, mesh.variant.Key(), !animated.kernel.fused);
}

std::unique_ptr<Executor::Timed> RunnerExecutor::Copy(Lang lang, std::size_t bytes, int input_sets) {
  return std::make_unique<RunnerTimed>(runner_, *this, runner_.PrepareCopy(lang, bytes, input_sets),
                                       LanguageOf(lang).copy_lang, "copy of " + std::to_string(bytes) + " bytes");
}

const KernelTime& Executor::CopyTime(Lang lang, std::size_t bytes, int input_sets, const TimingOptions& options) {
  const std::string key = std::string(Name(lang)) + "|" + std::to_string(bytes / 32) + "|" + std::to_string(input_sets);
  if (const auto found = copy_times_.find(key); found != copy_times_.end()) return *found->second;
  const std::unique_ptr<Timed> copy = Copy(lang, bytes, input_sets);
  auto time = std::make_unique<KernelTime>(SampleKernelTime(*copy, options));
  return *copy_times_.emplace(key, std::move(time)).first->second;
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double CopyGBps(std::size_t bytes, const std::vector<double>& ms) {
  const double median = Median(ms);
  if (!(median > 0.0)) throw Error("copy kernel: no positive time measured");
  return 2.0 * static_cast<double>(bytes) / median / 1e6;
}

std::size_t CopyBytesCapped(std::size_t bytes, std::uint64_t max_allocation_bytes) {
  constexpr std::size_t kGranule = 4096;
  std::uint64_t capped = bytes;
  if (max_allocation_bytes > 0) capped = std::min<std::uint64_t>(capped, max_allocation_bytes / 4);
  capped -= capped % kGranule;
  return static_cast<std::size_t>(std::max<std::uint64_t>(capped, kGranule));
}

std::size_t ProbeCopyBytes(const DeviceIdentity& d) {
  std::uint64_t bytes = std::max<std::uint64_t>(64ull << 20, 2 * d.last_level_cache_bytes);
  if (d.global_memory_bytes > 0) bytes = std::min<std::uint64_t>(bytes, d.global_memory_bytes / 4);
  return static_cast<std::size_t>(bytes);
}

double ProbeCopyGBps(Executor::Timed& copy, std::size_t bytes) {
  TimingOptions options;
  options.warmup = 2;
  options.stop.min_samples = 5;
  options.stop.max_samples = 20;
  options.stop.batch = 5;
  return CopyGBps(bytes, {SampleKernelTime(copy, options).interval.median});
}

}  // namespace skintune::internal::tuner_internal
