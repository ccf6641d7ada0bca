// The measurement job (tuner/measure_job.h MeasureJob) over a fake
// executor: the residency rule, the burst and the same-size copy it asks the
// runner for, and what it records. No device: the fake answers the
// verification run with the gold itself and times with numbers it is given.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "generator/variant.h"
#include "runtime/backend_table.h"
#include "runtime/device_clock.h"
#include "runtime/physical_device.h"
#include "runtime/runner.h"
#include "tuner/datasets.h"
#include "tuner/executor.h"
#include "tuner/fault_injection.h"
#include "tuner/host_lock.h"
#include "tuner/measure_job.h"
#include "tuner/measurement.h"
#include "tests/tuner/lock_holder.h"

namespace skintune::internal {
namespace {

using tuner_internal::DatasetCache;
using tuner_internal::Executor;
using tuner_internal::MeasureJob;
using tuner_internal::MeasurementOf;

// Answers Run with the variant's gold (so verification passes) and Time /
// TimeCopy with fixed per-frame times, recording what it was asked.
class FakeExecutor final : public Executor {
 public:
  FakeExecutor(DatasetCache& datasets, std::string dataset) : datasets_(datasets), dataset_(std::move(dataset)) {}

  // Instance after instance, each in packed order; vertex `wrong_vertex` of
  // the scene's output (when set) is moved by 1.
  Output Run(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::span<const std::uint8_t>,
             int instances) override {
    for (const KernelSource& k : kernels) run_texts.push_back(k.text);
    DatasetCache::Entry& entry = datasets_.Get(dataset_);
    const GoldResult& gold = datasets_.Gold(entry, mesh.variant);
    run_instances = instances;
    Output out;
    out.positions.resize(static_cast<std::size_t>(instances) * mesh.vertex_count * mesh.output_stride_bytes);
    for (std::size_t k = 0; k < static_cast<std::size_t>(instances); ++k) {
      for (std::size_t p = 0; p < mesh.vertex_count; ++p) {
        const std::size_t v = k * mesh.vertex_count + mesh.order[p];
        const glm::dvec3& g = gold.positions[v];
        const float xyz[4] = {static_cast<float>(g.x) + (wrong_vertex == v ? 1.0f : 0.0f), static_cast<float>(g.y),
                              static_cast<float>(g.z), 1.0f};
        std::memcpy(out.positions.data() + (k * mesh.vertex_count + p) * mesh.output_stride_bytes, xyz,
                    std::min<std::size_t>(16, mesh.output_stride_bytes));
      }
    }
    return out;
  }
  // Samples of `ms` with a spread of `spread` (alternating above and below), and a fixed frame time.
  class FakeTimed final : public Timed {
   public:
    FakeTimed(FakeExecutor& owner, double ms, double spread) : owner_(owner), ms_(ms), spread_(spread) {}
    std::vector<double> Cold(int untimed, int samples) override {
      owner_.calls.push_back("cold");
      owner_.cold_untimed += untimed;
      std::vector<double> out;
      for (int i = 0; i < samples; ++i, ++n_) out.push_back(ms_ * (1.0 + (n_ % 2 ? spread_ : -spread_) * (n_ % 7) / 7.0));
      owner_.samples_taken += samples;
      return out;
    }
    double FrameMs(int, int frames) override {
      owner_.calls.push_back("frame");
      owner_.frame_frames = frames;
      return owner_.frame_ms;
    }
    std::size_t bytes_per_set() const override { return owner_.bytes_per_set; }

   private:
    FakeExecutor& owner_;
    double ms_, spread_;
    int n_ = 0;
  };
  std::unique_ptr<Timed> Prepare(const PackedMesh&, std::span<const KernelSource>,
                                 std::span<const std::vector<std::uint8_t>> palettes, int instances) override {
    time_instances = instances;
    time_sets = static_cast<int>(palettes.size());
    if (prepared < per_prepare.size()) {
      const auto [ms, its_spread] = per_prepare[prepared++];
      return std::make_unique<FakeTimed>(*this, ms, its_spread);
    }
    return std::make_unique<FakeTimed>(*this, kernel_ms, spread);
  }
  std::unique_ptr<Timed> Copy(Lang lang, std::size_t bytes, int input_sets) override {
    copy_lang = lang;
    copy_bytes = bytes;
    copy_sets = input_sets;
    if (copy_fails) throw Error("OpenCL launch: the copy could not run");
    return std::make_unique<FakeTimed>(*this, copy_ms, 0.0);
  }
  std::string KernelClock() const override { return "fake clock"; }
  std::string ContextChoice() const override { return context_choice; }
  double LaunchStartMs() const override { return launch_start_ms; }
  std::size_t FlushReadBytes() const override { return flush_bytes; }

  double kernel_ms = 0.030, copy_ms = 0.025, frame_ms = 0.040, spread = 0.0;
  // The times (ms, spread) of the first Prepares, in order; then kernel_ms and spread.
  std::vector<std::pair<double, double>> per_prepare;
  std::size_t prepared = 0;
  std::size_t wrong_vertex = static_cast<std::size_t>(-1);
  int run_instances = 0, time_instances = 0;
  std::size_t bytes_per_set = 0, flush_bytes = 100u << 20;
  bool copy_fails = false;
  std::string context_choice;    // ContextChoice
  double launch_start_ms = 0.0;  // LaunchStartMs
  int time_sets = 0, frame_frames = 0;
  int cold_untimed = 0, samples_taken = 0;
  std::optional<Lang> copy_lang;
  std::size_t copy_bytes = 0;
  int copy_sets = 0;
  std::vector<std::string> run_texts;  // the kernels of every Run, in order
  std::vector<std::string> calls;      // "cold" and "frame", each Timed's calls in order (the copy's too)

 private:
  DatasetCache& datasets_;
  std::string dataset_;
};

DeviceIdentity Gpu(std::uint64_t llc) {
  DeviceIdentity d;
  d.backend = "opencl";
  d.platform = "NVIDIA CUDA";
  d.name = "NVIDIA H100 80GB HBM3";
  d.driver_version = "580";
  d.type = "gpu";
  d.last_level_cache_bytes = llc;
  return d;
}

DeviceLimits Limits() {
  DeviceLimits l;
  l.max_wg_size = 1024;
  l.local_memory_bytes = 48 << 10;
  l.constant_memory_bytes = 64 << 10;
  return l;
}

Measurement MeasureOn(FakeExecutor& executor, DatasetCache& datasets, const DeviceIdentity& device,
                      const std::string& key, const TimingOptions& options) {
  return MeasurementOf({&executor, &datasets, &device, Limits(), {Lang::kOpenCl}, ParseVariantKey(key), {"5000-b4"}, options});
}

constexpr const char* kVariant = "opencl.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.nonormals";

// The residency rule: the sets rotated while timing cover at least twice the
// PHYSICAL chip's cache, whatever one API reports. NVIDIA's OpenCL reports
// 4.3 MB on an H100; matched by UUID with CUDA's 50 MB, the OpenCL device's
// timing footprint covers 2 x 50 MB.
TEST(Measure, InputSetsCoverTwiceThePhysicalCacheWhateverTheApiReports) {
  CacheReport opencl{"opencl", "gpu", "NVIDIA H100 80GB HBM3", "00112233445566778899aabbccddeeff", "", 4325376, 80ull << 30};
  CacheReport cuda{"cuda", "gpu", "NVIDIA H100 80GB HBM3", "00112233445566778899aabbccddeeff", "", 50ull << 20, 80ull << 30};
  opencl.name = cuda.name = "GPU of its own";  // no datasheet match: the figure must come from CUDA through the UUID
  const std::vector<CacheFigure> figures = ResolveLastLevelCaches({opencl, cuda}, 0);
  ASSERT_EQ(figures[0].bytes, 50ull << 20) << figures[0].source;

  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  executor.bytes_per_set = 200000;
  TimingOptions options;
  options.max_input_sets = 1000;
  const Measurement m = MeasureOn(executor, datasets, Gpu(figures[0].bytes), kVariant, options);
  ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  EXPECT_EQ(executor.time_sets, m.timing.input_sets);
  EXPECT_GE(static_cast<double>(m.timing.input_sets) * m.bytes_per_frame, 2.0 * (50ull << 20));
  EXPECT_EQ(m.timing.footprint_bytes, static_cast<double>(m.timing.input_sets) * 200000.0);
  // What the API alone says would have given far fewer sets.
  EXPECT_LT(tuner_internal::InputSetsFor(4325376, static_cast<std::uint64_t>(m.bytes_per_frame), 1000),
            m.timing.input_sets / 5);
}

// A GPU measurement's packing, gold checks and timing wait for no CPU
// device's timed bursts (tuner/host_lock.h): its worker holds the chip's lock
// meanwhile, and a wait there idles the chip.
TEST(Measure, AGpuMeasurementRunsWhileACpuDeviceHoldsTheHostsCores) {
  const tuner_internal::HostLockFile file;
  ASSERT_FALSE(file.path().empty());
  skintune::internal::testing::LockHolder cpu_device([&] {  // for 300 ms from here
    tuner_internal::UseHostLock(file.path());
    new tuner_internal::HostLock(tuner_internal::TimedMode(/*cpu_device=*/true));
  });
  tuner_internal::UseHostLock(file.path());
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  const auto start = std::chrono::steady_clock::now();
  const Measurement m = MeasureOn(executor, datasets, Gpu(50ull << 20), kVariant, TimingOptions{});
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  EXPECT_LT(ms, 200.0) << "the GPU measurement waited for the CPU device's hold";
  cpu_device.Join();
}

// Every measurement carries the same-size copy: the bytes its frame moves,
// the same input sets, the same method, and x_copy = time / copy time.
TEST(Measure, TimesTheSameSizeCopyBySameMethod) {
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  TimingOptions options;
  const Measurement m = MeasureOn(executor, datasets, Gpu(50ull << 20), kVariant, options);
  ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  ASSERT_TRUE(executor.copy_lang.has_value());
  EXPECT_EQ(*executor.copy_lang, Lang::kOpenCl);
  EXPECT_EQ(static_cast<double>(executor.copy_bytes), m.bytes_per_frame);
  EXPECT_EQ(executor.copy_sets, m.timing.input_sets);
  EXPECT_DOUBLE_EQ(m.timing.copy_ms, 0.025);
  EXPECT_DOUBLE_EQ(m.x_copy, 0.030 / 0.025);
  EXPECT_EQ(m.timing.version, kTimingVersion);
  EXPECT_EQ(ImpossibleFigures(m), "");
}

// The frame time is taken before any of the kernel time's samples, so that
// every variant's kernel time, the first one's of a worker included, follows
// a Skinner's frames (after them NVIDIA's OpenCL started later kernels 0.15
// us later, an H200 in December 2026); the copy's samples come last.
TEST(Measure, TheFrameTimeComesBeforeTheKernelTimesSamples) {
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  const Measurement m = MeasureOn(executor, datasets, Gpu(50ull << 20), kVariant, TimingOptions{});
  ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  const auto first = [&](const std::string& call) {
    return std::find(executor.calls.begin(), executor.calls.end(), call) - executor.calls.begin();
  };
  ASSERT_LT(first("frame"), static_cast<std::ptrdiff_t>(executor.calls.size())) << "no frame time";
  EXPECT_LT(first("frame"), first("cold"));
  EXPECT_GT(m.timing.frame_ms, 0.0);
  EXPECT_GT(m.timing.repetitions, 0);
}

// Every measurement records its context: how it was chosen and its launch
// start, which the kernel time less it compares across APIs.
TEST(Measure, EachMeasurementRecordsItsContextsChoiceAndLaunchStart) {
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  executor.context_choice = "the quickest of 6 contexts by launch start (a 4 KiB copy after the flush): 2.088 us";
  executor.launch_start_ms = 2.088e-3;
  const Measurement m = MeasureOn(executor, datasets, Gpu(50ull << 20), kVariant, TimingOptions{});
  ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  EXPECT_EQ(m.timing.context, executor.context_choice);
  EXPECT_EQ(m.timing.launch_start_ms, 2.088e-3);
}

// A copy that cannot run leaves the kernel's own time standing, with no
// x_copy and the reason in the detail.
TEST(Measure, AFailedCopyKeepsTheKernelTimeAndSaysWhy) {
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  executor.copy_fails = true;
  const Measurement m = MeasureOn(executor, datasets, Gpu(50ull << 20), kVariant, TimingOptions{});
  ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  EXPECT_EQ(m.x_copy, 0.0);
  EXPECT_EQ(m.timing.copy_ms, 0.0);
  EXPECT_NE(m.detail.find("same-size copy failed"), std::string::npos) << m.detail;
  EXPECT_EQ(ImpossibleFigures(m), "");
}

// Scenes (model/scene.h): K instances run the instanced kernels with K
// palettes, a batch one concatenated mesh; both are judged against the copy
// of the whole scene's bytes, and verified part by part: a wrong vertex is
// named by its instance or batch mesh.
TEST(Measure, InstancesAndBatchesAreVerifiedPartByPartAndTimedAsAWhole) {
  const DeviceIdentity gpu = Gpu(50ull << 20);
  const Variant variant = ParseVariantKey("opencl.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64");
  TimingOptions options;
  {
    DatasetCache datasets;
    FakeExecutor executor(datasets, "1000-b2-x5");
    const Measurement single = [&] {
      DatasetCache d;
      FakeExecutor e(d, "1000-b2");
      return MeasurementOf({&e, &d, &gpu, Limits(), {Lang::kOpenCl}, variant, {"1000-b2"}, options});
    }();
    const Measurement m = MeasurementOf({&executor, &datasets, &gpu, Limits(), {Lang::kOpenCl}, variant, {"1000-b2-x5"}, options});
    ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
    EXPECT_EQ(executor.run_instances, 5);
    EXPECT_EQ(executor.time_instances, 5);
    EXPECT_EQ(m.bytes_per_frame, 5 * single.bytes_per_frame);  // the copy of five meshes' bytes
    EXPECT_EQ(static_cast<double>(executor.copy_bytes), m.bytes_per_frame);
    // The least the crowd's frame moves: its one mesh's inputs once, each
    // instance's outputs (soa float4 positions) and palette (77 joints x 48 bytes).
    const double outputs_and_palette = 1000.0 * 16 + 77 * 48;
    EXPECT_EQ(single.least_bytes_per_frame, single.bytes_per_frame);
    EXPECT_EQ(m.least_bytes_per_frame, single.bytes_per_frame + 4 * outputs_and_palette);
    executor.wrong_vertex = 3 * 1000 + 17;
    const Measurement wrong =
        MeasurementOf({&executor, &datasets, &gpu, Limits(), {Lang::kOpenCl}, variant, {"1000-b2-x5"}, options});
    EXPECT_EQ(wrong.status, MeasureStatus::kVerifyFailed);
    EXPECT_NE(wrong.detail.find("instance 3: positions: max relative error"), std::string::npos) << wrong.detail;
    EXPECT_NE(wrong.detail.find("at vertex 17"), std::string::npos) << wrong.detail;
  }
  {
    const std::string key = "800-b1-bones5+1200-b2-bones30-seed4+600-b2";
    DatasetCache datasets;
    FakeExecutor executor(datasets, key);
    const Measurement m = MeasurementOf({&executor, &datasets, &gpu, Limits(), {Lang::kOpenCl}, variant, {key}, options});
    ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
    EXPECT_EQ(executor.run_instances, 1);
    EXPECT_EQ(datasets.Get(key).parts.size(), 3u);
    EXPECT_EQ(datasets.Get(key).mesh().joint_count, 5 + 30 + 77);
    executor.wrong_vertex = 800 + 1200 + 5;
    const Measurement wrong = MeasurementOf({&executor, &datasets, &gpu, Limits(), {Lang::kOpenCl}, variant, {key}, options});
    EXPECT_EQ(wrong.status, MeasureStatus::kVerifyFailed);
    EXPECT_NE(wrong.detail.find("meshes[2] (600-b2): positions"), std::string::npos) << wrong.detail;
    EXPECT_NE(wrong.detail.find("at vertex 5 "), std::string::npos) << wrong.detail;
    // The constraints hold for the whole batch: u8 indices address 256 joints, not 4 x 77.
    const Variant u8 = ParseVariantKey("opencl.b2.padded.soa.float4.u8.f32.mat3x4.global.matrix.v1c.wg64");
    const std::string big = "500-b2+500-b2-seed2+500-b2-seed3+500-b2-seed4";  // 4 x 77 joints
    DatasetCache more;
    FakeExecutor e(more, big);
    const Measurement invalid = MeasurementOf({&e, &more, &gpu, Limits(), {Lang::kOpenCl}, u8, {big}, options});
    EXPECT_EQ(invalid.status, MeasureStatus::kInvalid);
    EXPECT_NE(invalid.detail.find("308"), std::string::npos) << invalid.detail;
  }
}

// Every ok measurement records both figures: the kernel time with its
// interval, the samples and the clock, and the frame time.
TEST(Measure, RecordsTheKernelTimeWithItsIntervalAndTheFrameTime) {
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  executor.spread = 0.001;
  TimingOptions options;
  options.burst_ms = 1.0;
  const Measurement m = MeasureOn(executor, datasets, Gpu(50ull << 20), kVariant, options);
  ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  EXPECT_NEAR(m.timing.median_ms, 0.030, 0.0001);
  EXPECT_LE(m.timing.low_ms, m.timing.median_ms);
  EXPECT_GE(m.timing.high_ms, m.timing.median_ms);
  EXPECT_GE(m.timing.repetitions, static_cast<int>(options.stop.min_samples));
  EXPECT_TRUE(m.timing.tight);
  EXPECT_EQ(m.timing.clock, "fake clock");
  EXPECT_DOUBLE_EQ(m.timing.frame_ms, 0.040);
  EXPECT_EQ(m.timing.burst_frames, executor.frame_frames);
  EXPECT_GE(executor.cold_untimed, options.warmup) << "warm-up frames before the samples";
  EXPECT_EQ(m.timing.version, kTimingVersion);
  EXPECT_EQ(ImpossibleFigures(m), "");
}

// Timing whose samples come in batches of ten, at least ten and at most
// `cap`, with no cap on their time.
TimingOptions TenAtATime(std::size_t cap) {
  TimingOptions options;
  options.stop.min_samples = 10;
  options.stop.batch = 10;
  options.stop.max_samples = cap;
  options.stop.max_ms = 1e6;
  return options;
}

// The stop rule as the job applies it: a steady kernel stops at
// min_samples; a noisy one samples up to the cap and says it was capped.
TEST(Measure, SamplesUntilTheIntervalIsTightOrTheCap) {
  TimingOptions options = TenAtATime(60);
  DatasetCache datasets;
  FakeExecutor steady(datasets, "5000-b4");
  const Measurement a = MeasureOn(steady, datasets, Gpu(50ull << 20), kVariant, options);
  EXPECT_EQ(a.timing.repetitions, 10);
  EXPECT_TRUE(a.timing.tight);
  FakeExecutor noisy(datasets, "5000-b4");
  noisy.spread = 0.3;
  const Measurement b = MeasureOn(noisy, datasets, Gpu(50ull << 20), kVariant, options);
  EXPECT_EQ(b.timing.repetitions, 60);
  EXPECT_FALSE(b.timing.tight);
}

// Cold frames of given times in turn, recording how many each call asked for.
class ScriptedFrames final : public Executor::Timed {
 public:
  explicit ScriptedFrames(std::function<double(int)> frame_ms) : frame_ms_(std::move(frame_ms)) {}
  std::vector<double> Cold(int untimed, int samples) override {
    asked.push_back(samples);
    n_ += untimed;
    std::vector<double> out;
    for (int i = 0; i < samples; ++i) out.push_back(frame_ms_(n_++));
    return out;
  }
  double FrameMs(int, int) override { return 1.0; }
  std::size_t bytes_per_set() const override { return 1; }
  std::vector<int> asked;

 private:
  std::function<double(int)> frame_ms_;
  int n_ = 0;
};

// A sample of several frames is the quickest of frames spread over the
// batch (j, j + n, j + 2n of n samples), not of frames in a row.
TEST(KernelTimeSamples, ASampleIsTheQuickestOfItsFramesSpreadOverTheBatch) {
  const std::vector<double> frames = {2, 2, 2, 1, 1, 2, 2, 2, 2, 2, 1, 2};
  ScriptedFrames timed([&](int i) { return frames[static_cast<std::size_t>(i)]; });
  EXPECT_EQ(tuner_internal::ColdSamples(timed, 4, 3), (std::vector<double>{1, 2, 1, 1}));
  EXPECT_EQ(timed.asked, (std::vector<int>{12}));
  ScriptedFrames single([&](int i) { return frames[static_cast<std::size_t>(i)]; });
  EXPECT_EQ(tuner_internal::ColdSamples(single, 4, 1), (std::vector<double>{2, 2, 2, 1}));
}

// Frames of which seven in ten are hit (twice as long, as a neighbour's thread
// preempting one of the frame's doubles it on the host's CPU): the median of
// single frames is the hit frames' time, the median of the quickest of three
// the kernel's, and that one is tight at the first batch. The host's CPU
// devices sample so by default; a GPU's frames one by one.
TEST(KernelTimeSamples, OnTheHostsCpuTheQuickestOfThreeFramesIsTheKernelsTimeWhereMostFramesWereHit) {
  std::vector<double> frames;
  std::uint32_t state = 12345;
  for (int i = 0; i < 2000; ++i) {
    state = state * 1664525u + 1013904223u;
    frames.push_back((state >> 16) % 10 < 7 ? 2.0 : 1.0);
  }
  TimingOptions options = TenAtATime(60);
  DeviceIdentity host;
  host.type = "cpu";
  const TimingOptions on_host = options.ForDevice(host);
  EXPECT_EQ(on_host.frames_per_sample, 3);
  EXPECT_EQ(options.ForDevice(Gpu(50ull << 20)).frames_per_sample, 1);
  ScriptedFrames singles([&](int i) { return frames[static_cast<std::size_t>(i)]; });
  EXPECT_DOUBLE_EQ(tuner_internal::SampleKernelTime(singles, options).interval.median, 2.0);
  options.frames_per_sample = 3;
  ScriptedFrames triples([&](int i) { return frames[static_cast<std::size_t>(i)]; });
  const tuner_internal::KernelTime t = tuner_internal::SampleKernelTime(triples, options);
  EXPECT_DOUBLE_EQ(t.interval.median, 1.0);
  EXPECT_TRUE(t.tight);
  EXPECT_EQ(t.samples.size(), 10u);
}

// Cold residency: a footprint inside the cache (one input set of a small
// mesh) is never timed without the flush, which reads at least twice the
// last-level cache before every sample.
TEST(Measure, AFootprintInsideTheCacheIsTimedAfterAFlush) {
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  executor.bytes_per_set = 100000;
  TimingOptions options;
  options.max_input_sets = 1;
  const std::uint64_t llc = 50ull << 20;
  executor.flush_bytes = FlushBytes(llc);
  const Measurement m = MeasureOn(executor, datasets, Gpu(llc), kVariant, options);
  ASSERT_EQ(m.status, MeasureStatus::kOk) << m.detail;
  EXPECT_LT(m.timing.footprint_bytes, 2.0 * static_cast<double>(llc));
  EXPECT_GE(m.timing.flush_bytes, 2.0 * static_cast<double>(llc));
  EXPECT_GE(FlushBytes(0), 2 * kUnknownCacheBytes) << "an unknown cache is flushed as a 64 MiB one";
  EXPECT_EQ(FlushBytes(300ull << 20, /*cpu=*/true), kCpuFlushCapBytes) << "a CPU's socket-wide L3 is not read whole";
  EXPECT_EQ(FlushBytes(300ull << 20, /*cpu=*/false), 600ull << 20);
}

// ---------------------------------------------------------------- the job's inputs

MeasureJob CompleteJob(FakeExecutor& executor, DatasetCache& datasets, const DeviceIdentity& device, Measurement& m) {
  return {&executor, &datasets, &device, Limits(), {Lang::kOpenCl}, ParseVariantKey(kVariant), {"5000-b4"}, {}, &m};
}

// A job checks its inputs before it runs: a missing one, or timing options
// that cannot work, fail Validate() and Run() writes nothing.
TEST(MeasureJob, RunsOnlyWithEveryInputAndTimingThatCanWork) {
  DatasetCache datasets;
  FakeExecutor executor(datasets, "5000-b4");
  const DeviceIdentity gpu = Gpu(50ull << 20);
  Measurement m;
  EXPECT_TRUE(CompleteJob(executor, datasets, gpu, m).Validate());
  const std::vector<std::pair<const char*, std::function<void(MeasureJob&)>>> breaks = {
      {"no executor", [](MeasureJob& j) { j.executor = nullptr; }},
      {"no data sets", [](MeasureJob& j) { j.datasets = nullptr; }},
      {"no device", [](MeasureJob& j) { j.device = nullptr; }},
      {"no output", [](MeasureJob& j) { j.measurement = nullptr; }},
      {"no data set key", [](MeasureJob& j) { j.dataset.key.clear(); }},
      {"no language", [](MeasureJob& j) { j.languages.clear(); }},
      {"a tolerance of 0", [](MeasureJob& j) { j.options.tolerance = 0.0; }},
      {"a tolerance over kMaxTolerance", [](MeasureJob& j) { j.options.tolerance = 2 * kMaxTolerance; }},
      {"a batch of no samples", [](MeasureJob& j) { j.options.stop.batch = 0; }},
      {"bursts of no time", [](MeasureJob& j) { j.options.burst_ms = 0.0; }}};
  for (const auto& [what, broken] : breaks) {
    SCOPED_TRACE(what);
    m.detail = "untouched";
    MeasureJob job = CompleteJob(executor, datasets, gpu, m);
    broken(job);
    EXPECT_FALSE(job.Validate());
    EXPECT_FALSE(job.Run());
    EXPECT_EQ(m.detail, "untouched");
  }
  EXPECT_EQ(executor.run_texts.size(), 0u) << "nothing ran";
  EXPECT_TRUE(CompleteJob(executor, datasets, gpu, m).Run());
  EXPECT_EQ(m.status, MeasureStatus::kOk) << m.detail;
}

// ---------------------------------------------------------------- injected faults (tuner/fault_injection.h)

// The fault-injecting executor around a fake, and a job on it.
struct FaultyFake {
  DatasetCache datasets;
  FakeExecutor* fake = nullptr;  // owned by `executor`
  std::unique_ptr<Executor> executor;
  DeviceIdentity gpu = Gpu(50ull << 20);

  explicit FaultyFake(const std::string& kind) {
    auto inner = std::make_unique<FakeExecutor>(datasets, "5000-b4");
    fake = inner.get();
    executor = tuner_internal::InjectingFault({ParseVariantKey(kVariant).Key(), kind})(std::move(inner), gpu);
  }
  Measurement Measure(const std::string& key) {
    return MeasurementOf({executor.get(), &datasets, &gpu, Limits(), {Lang::kOpenCl}, ParseVariantKey(key), {"5000-b4"}, {}});
  }
};

constexpr const char* kOtherVariant = "opencl.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.nonormals";

// A GPU API on the host's CPU (llvmpipe, lavapipe) is flushed by the host
// before each sample (HostFlush: the same bytes its flush kernel read,
// recorded the same); a GPU and PoCL flush with their kernel; skintune's cpu
// device evicts each frame's own buffers and reads no flush.
TEST(Executor, AGpuApiOnTheHostIsFlushedByTheHostAndEveryOtherDeviceByItsKernel) {
  Discovered found = DiscoverDevices("cpu");
  ASSERT_FALSE(found.devices.empty()) << "skintune's cpu device is always there";
  const std::unique_ptr<Runner> runner = found.devices.front().open();
  const DeviceIdentity cpu = found.devices.front().identity;
  ASSERT_EQ(cpu.type, "cpu");
  {
    tuner_internal::RunnerExecutor own(*runner, cpu);
    EXPECT_TRUE(own.EvictsOwnBuffers());
    EXPECT_EQ(own.FlushReadBytes(), 0u);
    EXPECT_FALSE(static_cast<bool>(own.BeforeEachSample()));
  }
  // The choice by identity, on a runner that flushes (the executor reads
  // only its identity's type and backend, and whether the runner evicts):
  // any GPU API's (llvmpipe's or lavapipe's here).
  std::unique_ptr<Runner> flushing;
  for (const char* api : {"vulkan", "gl", "cuda", "opencl"}) {
    for (const auto& device : DiscoverDevices(api).devices) {
      std::unique_ptr<Runner> r = device.open();
      if (!r->api().evicts_own_buffers()) {
        flushing = std::move(r);
        break;
      }
    }
    if (flushing) break;
  }
  if (!flushing) GTEST_SKIP() << "no device here flushes with a kernel (only the host's own devices, which evict)";
  const auto as = [&](const char* backend, const char* type) {
    DeviceIdentity d = cpu;
    d.backend = backend;
    d.type = type;
    return d;
  };
  for (const DeviceIdentity& d : {as("gl", "cpu"), as("vulkan", "cpu"), as("cpu", "cpu"), as("opencl", "cpu"),
                                  as("vulkan", "gpu"), as("cuda", "gpu")}) {
    SCOPED_TRACE(d.backend + " on a " + d.type);
    const bool host = d.type == "cpu" && (d.backend == "gl" || d.backend == "vulkan");
    EXPECT_EQ(tuner_internal::HostFlushes(d), host);
    tuner_internal::RunnerExecutor executor(*flushing, d);
    EXPECT_FALSE(executor.EvictsOwnBuffers());
    EXPECT_EQ(static_cast<bool>(executor.BeforeEachSample()), host);
    EXPECT_EQ(executor.FlushReadBytes(), FlushBytes(cpu.last_level_cache_bytes, d.type == "cpu"));
  }
  tuner_internal::HostFlush flush(1u << 20);
  EXPECT_EQ(flush.bytes(), 1u << 20);
  flush();  // reads every word on every core, and returns
}

// A clock that reads `low` MHz for its first `low_reads` readings, then
// `high`; its boost is 1980. It counts its readings.
class ScriptedClock final : public DeviceClock {
 public:
  ScriptedClock(unsigned low, int low_reads, unsigned high, int* reads)
      : low_(low), low_reads_(low_reads), high_(high), reads_(reads) {}
  std::optional<unsigned> SmMhz() override { return (*reads_)++ < low_reads_ ? low_ : high_; }
  std::optional<unsigned> MaxSmMhz() override { return 1980u; }

 private:
  unsigned low_;
  int low_reads_;
  unsigned high_;
  int* reads_;
};

// Every batch of samples a device's executor takes goes through the clock
// guard where the device's clock is read (tuner/clock_guard.h): an idle
// clock is warmed back first and the clock around the batches kept is the
// kernel time's. Here on the cpu device with a stand-in clock (a real one is
// only opened for an NVIDIA GPU).
TEST(Executor, EveryBatchOfSamplesIsTakenAtTheClockUnderLoadAndRecordsIt) {
  Discovered found = DiscoverDevices("cpu");
  ASSERT_FALSE(found.devices.empty()) << "skintune's cpu device is always there";
  const std::unique_ptr<Runner> runner = found.devices.front().open();
  TimingOptions options;
  options.warmup = 1;
  options.stop.batch = 4;
  options.stop.min_samples = 4;
  options.stop.max_samples = 8;
  {
    int reads = 0;  // idle at 900 MHz for two readings: before the batch and the warm-up's first
    tuner_internal::RunnerExecutor executor(*runner, found.devices.front().identity,
                                            std::make_unique<ScriptedClock>(900, 2, 1980, &reads));
    const std::unique_ptr<Executor::Timed> copy = executor.Copy(Lang::kCpu, 1u << 20, 2);
    const tuner_internal::KernelTime t = tuner_internal::SampleKernelTime(*copy, options);
    EXPECT_EQ(t.clock_mhz, 1980u) << "the batches ran after the clock was warmed back";
    EXPECT_GE(reads, 4) << "read before and after each batch, and in the warm-up";
    EXPECT_EQ(executor.clock().reference_mhz(), 1980u);
  }
  {
    int reads = 0;  // a GPU that never gets above 1500 MHz under load: its clock becomes the reference
    tuner_internal::RunnerExecutor executor(*runner, found.devices.front().identity,
                                            std::make_unique<ScriptedClock>(1500, 1 << 30, 1500, &reads));
    const std::unique_ptr<Executor::Timed> copy = executor.Copy(Lang::kCpu, 1u << 20, 2);
    const tuner_internal::KernelTime t = tuner_internal::SampleKernelTime(*copy, options);
    EXPECT_EQ(t.clock_mhz, 1500u);
    EXPECT_EQ(executor.clock().reference_mhz(), 1500u) << "after a second of warming";
    EXPECT_FALSE(t.samples.empty());
  }
  tuner_internal::RunnerExecutor without(*runner, found.devices.front().identity);
  EXPECT_FALSE(without.clock().active()) << "the cpu device's clock is not read";
  const std::unique_ptr<Executor::Timed> copy = without.Copy(Lang::kCpu, 1u << 20, 2);
  EXPECT_EQ(tuner_internal::SampleKernelTime(*copy, options).clock_mhz, 0u);
}

// The race stops once no undecided candidate can be the winner: a noisy
// candidate near the margin's edge that moves more bytes than one proven
// equal to the fastest cannot be picked, so its verdict decides nothing and
// the race ends at min_samples; one moving as few bytes as any contender
// could be picked, and the race samples on to its cap.
TEST(RaceJob, StopsOnceNoUndecidedCandidateCanWin) {
  const std::string lean = "opencl.b4.padded.soa.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals";
  for (const bool noisy_moves_more : {true, false}) {
    SCOPED_TRACE(noisy_moves_more ? "the noisy candidate moves more bytes" : "the noisy candidate moves as few");
    DatasetCache datasets;
    FakeExecutor executor(datasets, "5000-b4");
    executor.per_prepare = {{1.0, 0.0}, {1.002, 0.0}, {1.05, 0.3}};
    const DeviceIdentity gpu = Gpu(50u << 20);
    tuner_internal::RaceJob job;
    job.executor = &executor;
    job.datasets = &datasets;
    job.device = &gpu;
    job.variants = {ParseVariantKey(kVariant), ParseVariantKey(lean),
                    ParseVariantKey(noisy_moves_more ? std::string(kVariant).replace(std::string(kVariant).find("wg64"), 4, "wg256")
                                                     : std::string(lean).replace(lean.find("wg64"), 4, "wg256"))};
    job.dataset = {"5000-b4"};
    job.options.stop.min_samples = 10;
    job.options.stop.batch = 10;
    job.options.stop.max_samples = 60;
    job.options.stop.max_ms = 3.6e6;
    std::vector<std::vector<double>> samples;
    job.samples = &samples;
    ASSERT_TRUE(job.Run());
    ASSERT_EQ(samples.size(), 3u);
    EXPECT_EQ(samples[2].size(), noisy_moves_more ? 10u : 60u);
  }
}

// A race on the host's CPU takes each sample as the quickest of its frames,
// as the search's measurements do: three frames a sample by default.
TEST(RaceJob, OnTheHostsCpuEachSampleIsTheQuickestOfThreeFrames) {
  for (const int frames : {1, 3}) {
    SCOPED_TRACE(std::to_string(frames) + " frames a sample");
    DatasetCache datasets;
    FakeExecutor executor(datasets, "5000-b4");
    executor.spread = 0.3;  // samples 0.7-1.3x the kernel's time: the quickest of three is below the median of one
    DeviceIdentity host;
    host.type = "cpu";
    host.backend = "opencl";
    tuner_internal::RaceJob job;
    job.executor = &executor;
    job.datasets = &datasets;
    job.device = &host;
    job.variants = {ParseVariantKey(kVariant), ParseVariantKey(kOtherVariant)};
    job.dataset = {"5000-b4"};
    TimingOptions options = TenAtATime(20);
    options.host_frames_per_sample = frames;
    job.options = options.ForDevice(host);
    std::vector<std::vector<double>> samples;
    job.samples = &samples;
    ASSERT_TRUE(job.Run());
    ASSERT_EQ(samples.size(), 2u);
    const std::size_t taken = samples[0].size() + samples[1].size();
    EXPECT_EQ(static_cast<std::size_t>(executor.samples_taken), taken * static_cast<std::size_t>(frames))
        << "each sample's frames were asked of the device in its batch";
    const double median = tuner_internal::Median(samples[0]);
    if (frames == 3) {
      EXPECT_LT(median, executor.kernel_ms * 0.95) << "the quickest of three frames a sample";
    }
    if (frames == 1) {
      EXPECT_NEAR(median, executor.kernel_ms, executor.kernel_ms * 0.05);
    }
  }
}

TEST(FaultInjection, TheDeviceGetsTheFaultyVariantsKernelsEditedAndEveryOtherAsEmitted) {
  for (const char* kind : {"compile", "wrong", "hang"}) {
    SCOPED_TRACE(kind);
    FaultyFake f(kind);
    (void)f.Measure(kOtherVariant);
    ASSERT_FALSE(f.fake->run_texts.empty());
    for (const std::string& text : f.fake->run_texts) EXPECT_EQ(text.find("skintune injected"), std::string::npos);
    f.fake->run_texts.clear();
    (void)f.Measure(kVariant);
    ASSERT_FALSE(f.fake->run_texts.empty());
    for (const std::string& text : f.fake->run_texts) EXPECT_NE(text.find("skintune injected"), std::string::npos);
  }
}

TEST(FaultInjection, ALostDeviceFailsItsVariantAndEveryLaterRunAsTheRunnerSaysLost) {
  FaultyFake f("lost");
  EXPECT_EQ(f.Measure(kOtherVariant).status, MeasureStatus::kOk);
  for (const char* key : {kVariant, kOtherVariant}) {
    SCOPED_TRACE(key);
    const Measurement m = f.Measure(key);
    EXPECT_EQ(m.status, MeasureStatus::kLaunchFailed);
    EXPECT_EQ(m.detail, "opencl lost: the device was lost in this process (injected fault 'lost')");
    EXPECT_TRUE(tuner_internal::DeviceLostIn(m.detail));
  }
  EXPECT_THROW((void)f.executor->Copy(Lang::kOpenCl, 4096, 1), Error);
}

TEST(FaultInjection, ACrashEndsTheProcessWhenTheVariantRuns) {
  EXPECT_DEATH(
      {
        FaultyFake f("crash");
        (void)f.Measure(kOtherVariant);
        (void)f.Measure(kVariant);
      },
      "");
}

TEST(FaultInjection, NoFaultInTheEnvironmentIsNoDecorator) {
  ::unsetenv("SKINTUNE_INJECT_FAULT");
  EXPECT_FALSE(tuner_internal::FaultsFromEnvironment());
  ::setenv("SKINTUNE_INJECT_FAULT", "opencl.b2=hang", 1);
  EXPECT_TRUE(tuner_internal::FaultsFromEnvironment());
  ::unsetenv("SKINTUNE_INJECT_FAULT");
}

}  // namespace
}  // namespace skintune::internal
