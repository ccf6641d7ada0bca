// The driver's warm-up (runtime/runner.cpp WarmUntilStable) against a fake
// device whose clock behaves like NVIDIA's on the H100: it rises only under
// sustained load (a submission that keeps it busy for a while) and falls when
// left idle. Frames really sleep for their modelled time, so the warm-up's
// wall-clock rules act on them; the times the fake reports are the model's,
// so what Time returns says exactly which clock the frames ran at.
//
// Timing version 2's warm-up failed both tests: its 16-frame bursts never
// loaded the device enough to raise the clock, and a steady burst time at
// the low clock ended the warm-up (docs/PERFORMANCE.md "Lessons that still hold").
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "generator/copy_kernel.h"
#include "base/error.h"
#include "runtime/device_api.h"
#include "runtime/runner.h"

namespace skintune::internal {
namespace {

// Device bandwidth at each clock, bytes per ms; a submission that keeps the
// device busy at least kLoadMs counts towards kRaiseMs of load, after which
// the clock is high; kCoolMs of wall time without a submission drops it
// (the driver lowers an idle clock; the runner's kStillBusyMs is shorter).
constexpr double kColdBytesPerMs = 20e6;  // 20 GB/s
constexpr double kHotBytesPerMs = 40e6;   // 40 GB/s
constexpr double kLoadMs = 3.0;
constexpr double kRaiseMs = 60.0;
constexpr double kCoolMs = 150.0;  // far above the tests' 15 ms pauses: a loaded 2-core CI machine delays a thread by tens of ms

struct Clock {
  double load_ms = 0.0;
  double slowdown = 1.0;  // > 1: the device slower than it was, at every clock, from now on
  std::size_t frames = 0;  // frames run so far
  std::vector<BufferUse> allocations;  // each buffer the runner allocated
  std::optional<std::chrono::steady_clock::time_point> idle_since;
  bool hot() const { return load_ms >= kRaiseMs; }
  double BytesPerMs() const { return (hot() ? kHotBytesPerMs : kColdBytesPerMs) / slowdown; }
  // At the start of a submission: a device idle for kCoolMs is cold.
  void Wake() {
    if (idle_since && std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - *idle_since).count() >= kCoolMs)
      load_ms = 0.0;
  }
};

// The device idles long enough for its clock to fall (a compile, a verification).
void Idle() { std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(2 * kCoolMs)); }

class FakeBuffer final : public DeviceBuffer {
 public:
  explicit FakeBuffer(std::size_t bytes) : DeviceBuffer(bytes) {}
  void* native() const override { return const_cast<FakeBuffer*>(this); }
};

class FakeBound final : public DeviceObject {
 public:
  std::size_t bytes = 0;  // read and written by one launch
};

class FakeApi final : public DeviceApi {
 public:
  std::string kernel_clock() const override { return "fake"; }
  explicit FakeApi(Clock& clock) : clock_(clock) {}
  const char* name() const override { return "Fake"; }
  const std::string& device_name() const override { return name_; }
  void Build(const KernelSource&) override {}
  void CheckRun(const PackedMesh&, std::span<const KernelSource>, const RunShape&) const override {}
  std::unique_ptr<PlannedLaunch> Plan(const LaunchSpec& spec) override { return std::make_unique<PlannedLaunch>(spec); }
  std::unique_ptr<DeviceBuffer> Allocate(BufferUse use, std::size_t bytes, const void*, const std::string&) override {
    clock_.allocations.push_back(use);
    return std::make_unique<FakeBuffer>(bytes);
  }
  std::unique_ptr<DeviceObject> PaletteView(const Variant&, DeviceBuffer&, const std::string&) override { return nullptr; }
  std::unique_ptr<DeviceObject> Bind(const PlannedLaunch&, std::span<const ArgumentBinding> arguments, const SetOptions&,
                                     std::size_t&) override {
    auto bound = std::make_unique<FakeBound>();
    for (const ArgumentBinding& a : arguments)
      if ((a.role == ArgumentRole::kInput || a.role == ArgumentRole::kOutput) && a.buffer) bound->bytes += a.buffer->bytes();
    return bound;
  }
  void FinishUploads(const std::string&) override {}
  TimingPolicy timing_policy() const override { return {true}; }

  // Every frame sleeps its modelled time; the clock counts this submission's
  // load once it is done. Bursts report the model's time.
  std::vector<std::vector<double>> RunFrames(const FrameRun& run) override {
    clock_.Wake();
    clock_.frames += run.frames.size();
    const double per_ms = clock_.BytesPerMs();
    const auto frame_ms = [&](std::size_t f) {
      double bytes = 0.0;
      for (const std::unique_ptr<DeviceObject>& launch : run.frames[f]) bytes += static_cast<double>(static_cast<const FakeBound&>(*launch).bytes);
      return bytes / per_ms;
    };
    double busy = 0.0;
    for (std::size_t f = 0; f < run.frames.size(); ++f) busy += frame_ms(f);
    std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(busy));
    if (busy >= kLoadMs) clock_.load_ms += busy;
    clock_.idle_since = std::chrono::steady_clock::now();
    std::vector<std::vector<double>> bursts;
    const std::size_t untimed = static_cast<std::size_t>(run.untimed);
    for (std::size_t b = 0; b < run.TimedBursts(); ++b) {
      double ms = 0.0;
      for (std::size_t f = untimed + b * run.burst; f < untimed + (b + 1) * run.burst; ++f) ms += frame_ms(f);
      bursts.push_back({ms});
    }
    return bursts;
  }
  std::span<std::uint8_t> Staging(DeviceBuffer& buffer, const std::string&, bool) override {
    staging_.resize(buffer.bytes());
    return staging_;
  }
  void Upload(DeviceBuffer&, std::size_t, const std::string&) override {}
  void Read(const DeviceBuffer&, std::span<std::uint8_t> out, const std::string&, bool) override {
    std::memset(out.data(), 0, out.size());
  }
  std::span<const std::uint8_t> ReadPinned(const DeviceBuffer&, std::size_t bytes, const std::string&) override {
    staging_.assign(bytes, 0);
    return staging_;
  }
  void Mark(std::unique_ptr<DeviceObject>&, const std::string&) override {}
  void Wait(DeviceObject&, const std::string&) override {}
  void Finish() override {}

 private:
  Clock& clock_;
  std::string name_ = "fake device";
  std::vector<std::uint8_t> staging_;
};

// The copy every test times: 1 MB, 0.05 ms a frame cold, 0.025 hot.
constexpr std::size_t kCopyBytes = 1'000'000;

// A frame of that copy at the high clock, by the fake's model.
double HotFrameMs() { return static_cast<double>(CopyBytes(EmitCopy(Lang::kOpenCl, kCopyBytes))) / kHotBytesPerMs; }

// Per-frame times of `prepared`: 2 untimed frames, then 5 bursts of 10.
std::vector<double> TimeIt(Runner& runner, const Prepared& prepared) {
  return runner.Time(prepared, 2, 5, 10);
}

// A runner on the fake device and the copy every test times.
class WarmUp : public ::testing::Test {
 protected:
  Clock clock;
  Runner runner{std::make_unique<FakeApi>(clock)};
  const Prepared small = runner.PrepareCopy(Lang::kOpenCl, kCopyBytes, 2);
};

// A 16-frame burst of the copy is 0.8 ms of load, too little to raise the clock.
TEST_F(WarmUp, RaisesAClockThatOnlySustainedLoadRaises) {
  const std::vector<double> ms = TimeIt(runner, small);
  ASSERT_FALSE(ms.empty());
  EXPECT_TRUE(clock.hot()) << "load seen by the device: " << clock.load_ms << " ms";
  const double hot_ms = HotFrameMs();
  for (double t : ms) EXPECT_NEAR(t, hot_ms, 1e-12) << "a frame timed at the low clock (" << 2 * hot_ms << " ms)";
}

TEST_F(WarmUp, AFullWarmUpEndsOnlyWhenTheClockProbeIsBackUp) {
  const std::vector<double> first = TimeIt(runner, small);
  ASSERT_TRUE(clock.hot());
  // The device idles (a compile, a verification): the clock drops. The probe
  // sees it, and the warm-up must not stop at a steady low clock.
  Idle();
  const std::vector<double> second = TimeIt(runner, small);
  ASSERT_EQ(second.size(), first.size());
  EXPECT_TRUE(clock.hot());
  const double hot_ms = HotFrameMs();
  for (std::size_t i = 0; i < second.size(); ++i) {
    EXPECT_NEAR(first[i], hot_ms, 1e-12) << "burst " << i;
    EXPECT_NEAR(second[i], hot_ms, 1e-12) << "burst " << i << " after the device idled";
  }
}

// A device just timed: its clock is up (the two tests below start here).
class WarmDevice : public WarmUp {
 protected:
  void SetUp() override {
    ASSERT_FALSE(TimeIt(runner, small).empty());
    ASSERT_TRUE(clock.hot());
  }
};

// Timings back to back (the tuner times a variant's burst length, the
// variant and its copy in a row): the device was busy a moment ago, so the
// second runs exactly its own frames, no probe and no warm-up, and still at
// the high clock.
TEST_F(WarmDevice, BackToBackTimingsNeedNoWarmUp) {
  const std::size_t before = clock.frames;
  const std::vector<double> second = TimeIt(runner, small);
  EXPECT_EQ(clock.frames - before, 2u + 5u * 10u) << "frames beyond the timed call's own: a probe or a warm-up ran";
  for (double t : second) EXPECT_NEAR(t, HotFrameMs(), 1e-12);
}

// A device still warm after a short pause (the probe within 15% of the best)
// gets one burst long enough to keep it busy, not the 200 ms floor of a full
// warm-up nor its steadiness check.
TEST_F(WarmDevice, AStillWarmDeviceGetsOneBusyBurst) {
  std::this_thread::sleep_for(std::chrono::milliseconds(15));  // past the runner's 10 ms, well short of the clock's kCoolMs
  const std::size_t before = clock.frames;
  const std::vector<double> second = TimeIt(runner, small);
  for (double t : second) EXPECT_NEAR(t, HotFrameMs(), 1e-12);
  // Bursts of 16, 32, ... frames until one lasts 4 ms of the host's clock
  // (256 frames of 0.025 ms): 496 frames, plus the probe's 6 and the call's
  // own 52; fewer when a loaded machine stretches a burst past 4 ms sooner
  // (112 seen under a parallel ctest). A steadiness check would add at
  // least one more burst of 256, a full warm-up bursts to its 1 s cap.
  const std::size_t warm_up = clock.frames - before - (2u + 5u * 10u) - 6u;
  EXPECT_GE(warm_up, 16u);
  EXPECT_LE(warm_up, 16u + 32u + 64u + 128u + 256u);
}

// The device got slower for good (the fastest probe seen can no longer be
// reached): one full warm-up runs to its one-second cap, and its last probe
// becomes the reference, so the next variant after a pause is still warm
// (one busy burst) instead of paying another second (NVIDIA's Vulkan on the
// H100 late in a `skintune run`: seven variants in a row, 1 s each).
TEST_F(WarmDevice, AWarmUpCappedAtASecondResetsTheReference) {
  clock.slowdown = 1.3;  // beyond the probe's 15%
  Idle();
  auto start = std::chrono::steady_clock::now();
  ASSERT_FALSE(TimeIt(runner, small).empty());
  const double first_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(first_ms, 1000.0) << "the first warm-up after the slowdown should run to the cap";
  std::this_thread::sleep_for(std::chrono::milliseconds(15));  // past the runner's 10 ms, well short of the clock's kCoolMs
  const std::size_t before = clock.frames;
  start = std::chrono::steady_clock::now();
  const std::vector<double> second = TimeIt(runner, small);
  const double second_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(second_ms, 200.0) << "a second full warm-up ran";
  const std::size_t warm_up = clock.frames - before - (2u + 5u * 10u) - 6u;
  EXPECT_LE(warm_up, 16u + 32u + 64u + 128u + 256u) << "more than one busy burst";
  for (double t : second) EXPECT_NEAR(t, HotFrameMs() * clock.slowdown, 1e-12);
}

// Runner::ShareTimedInputs (the tuner's runners): a second Prepare of the
// same inputs and palettes binds the first one's buffers, set by set, and
// allocates none (inputs, outputs, palettes); other palettes get palettes of
// their own and nothing else; a verification Run never shares; and without
// the call every Prepare allocates its own.
TEST(SharedInputs, ASecondPrepareOfTheSameInputsAllocatesNone) {
  const CopyKernel copy = EmitCopy(Lang::kOpenCl, kCopyBytes);
  const std::vector<std::vector<std::uint8_t>> palettes(3, copy.mesh.palette);
  std::vector<std::vector<std::uint8_t>> other_palettes = palettes;
  for (std::vector<std::uint8_t>& p : other_palettes) p.front() ^= 1;
  const auto allocated = [&](const Clock& clock, BufferUse use) {
    return std::count(clock.allocations.begin(), clock.allocations.end(), use);
  };
  for (const bool share : {false, true}) {
    SCOPED_TRACE(share ? "shared" : "not shared");
    Clock clock;
    Runner runner(std::make_unique<FakeApi>(clock));
    if (share) runner.ShareTimedInputs(std::size_t{1} << 30);
    const std::span<const KernelSource> kernel(&copy.kernel, 1);
    { const Prepared first = runner.Prepare(copy.mesh, kernel, palettes); }
    EXPECT_EQ(allocated(clock, BufferUse::kInput), 3);
    EXPECT_EQ(allocated(clock, BufferUse::kOutput), 3);
    EXPECT_EQ(allocated(clock, BufferUse::kPalette), 3);
    const Prepared second = runner.Prepare(copy.mesh, kernel, palettes);
    EXPECT_EQ(second.input_sets(), 3);
    EXPECT_EQ(allocated(clock, BufferUse::kInput), share ? 3 : 6);
    EXPECT_EQ(allocated(clock, BufferUse::kOutput), share ? 3 : 6);
    EXPECT_EQ(allocated(clock, BufferUse::kPalette), share ? 3 : 6);
    // Both alive: set k of each binds the same buffers, and no two sets of one Prepared do.
    for (int set = 0; set < 3; ++set) {
      EXPECT_EQ(runner.OutputBuffer(second, set, Output::kPositions) != nullptr, true);
      for (int other = 0; other < 3; ++other)
        if (other != set) {
          EXPECT_NE(runner.OutputBuffer(second, set, Output::kPositions), runner.OutputBuffer(second, other, Output::kPositions));
        }
    }
    const Prepared third = runner.Prepare(copy.mesh, kernel, other_palettes);
    EXPECT_EQ(allocated(clock, BufferUse::kInput), share ? 3 : 9);
    EXPECT_EQ(allocated(clock, BufferUse::kOutput), share ? 3 : 9);
    EXPECT_EQ(allocated(clock, BufferUse::kPalette), share ? 6 : 9);
    for (int set = 0; set < 3; ++set)
      EXPECT_EQ(runner.OutputBuffer(third, set, Output::kPositions) == runner.OutputBuffer(second, set, Output::kPositions), share);
    // A verification allocates its own (the fake reads back zeros, so its
    // guard check fails after the allocations this counts).
    EXPECT_THROW((void)runner.Run(copy.mesh, kernel), Error);
    EXPECT_EQ(allocated(clock, BufferUse::kInput), share ? 4 : 10);
    EXPECT_EQ(allocated(clock, BufferUse::kOutput), share ? 4 : 10);
  }
}

// Kept buffers past the budget are dropped oldest first (here all but the
// newest), and a Prepared still holding one keeps it alive.
TEST(SharedInputs, TheBudgetDropsTheOldestBuffers) {
  const CopyKernel copy = EmitCopy(Lang::kOpenCl, kCopyBytes);
  const std::vector<std::vector<std::uint8_t>> palettes(2, copy.mesh.palette);
  Clock clock;
  Runner runner(std::make_unique<FakeApi>(clock));
  runner.ShareTimedInputs(1);  // less than one buffer: only the newest is kept
  const std::span<const KernelSource> kernel(&copy.kernel, 1);
  const Prepared first = runner.Prepare(copy.mesh, kernel, palettes);
  const std::size_t after_first = clock.allocations.size();
  const Prepared second = runner.Prepare(copy.mesh, kernel, palettes);
  EXPECT_EQ(clock.allocations.size(), 2 * after_first);  // the one kept buffer is never the one looked up
  EXPECT_NE(runner.OutputBuffer(first, 0, Output::kPositions), nullptr);
  EXPECT_NE(runner.OutputBuffer(first, 0, Output::kPositions), runner.OutputBuffer(second, 0, Output::kPositions));
}

}  // namespace
}  // namespace skintune::internal
