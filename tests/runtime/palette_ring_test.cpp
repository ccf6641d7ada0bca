// The runner driver's palette ring (runtime/runner.h) on a device that runs
// nothing until the driver waits: a DeviceApi whose queue is a list of
// deferred operations (a palette upload copies the staging at the time it
// runs, as a DMA engine does; a launch records the palette it reads), run
// only by Wait, Finish and ReadPinned. So every overwrite of a palette or a
// staging buffer that a queued operation still needs shows up in what the
// launches read, deterministically, and the test sees exactly when the
// driver blocks and how many frames stay queued.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "generator/clip_packer.h"
#include "generator/packer.h"
#include "generator/palette_kernel.h"
#include "base/error.h"
#include "model/synthetic.h"
#include "runtime/run_shape.h"
#include "runtime/runner.h"

namespace skintune::internal {
namespace {

class FakeBuffer final : public DeviceBuffer {
 public:
  FakeBuffer(std::size_t bytes, const void* initial) : DeviceBuffer(bytes), device(bytes) {
    if (initial) std::memcpy(device.data(), initial, bytes);
  }
  void* native() const override { return const_cast<std::uint8_t*>(device.data()); }
  std::vector<std::uint8_t> device;   // what the device holds
  std::vector<std::uint8_t> staging;  // the host's page-locked staging (Write)
  std::size_t uploaded_at = 0;        // the queue's length after this buffer's last upload
};

class FakeLaunch final : public DeviceObject {
 public:
  const FakeBuffer* palette = nullptr;
  // A palette kernel (Runner::Animate): the instances it reads, the palette it writes.
  const FakeBuffer* instances = nullptr;
  FakeBuffer* out = nullptr;
};

class FakeMarker final : public DeviceObject {
 public:
  std::size_t position = 0;  // operations queued when marked
};

class DeferredApi final : public DeviceApi {
 public:
  std::string kernel_clock() const override { return "fake"; }
  std::vector<std::function<void()>> queue;  // every operation ever queued, in order
  std::size_t executed = 0;                  // how many of them ran
  std::vector<std::vector<std::uint8_t>> read;  // the palette each launch read, in the order they ran
  std::vector<float> elapsed;  // each launch's scalar `elapsed` (a fused kernel's; else 0)
  std::size_t launches_queued = 0;
  std::size_t prologues_queued = 0;  // palette kernels (FrameRun::prologue)
  int waits = 0, blocking_waits = 0;
  int fenced_stagings = 0, upload_waits = 0;  // Staging told the ring fence covers the last upload; or not, and waited
  // A submit thread (Runner::UseSubmitThread): the calls are serialised by
  // `mutex`, and the threads that made uploads and launches are recorded.
  bool threaded = false;
  int fail_upload = -1;  // the upload (0, 1, ...) that throws
  int uploads = 0;
  std::vector<std::thread::id> submit_threads;
  std::mutex mutex;

  // A device that orders an upload after the launches queued before it (GL);
  // this fake's one queue does, and Mark counts its calls.
  bool ordered = false;
  int marks = 0;

  // Frames the device gathers into one submission (Vulkan's batching).
  std::size_t frames_per_submission = 1;

  bool SubmitsFromAnyThread() const override { return threaded; }
  bool OrdersUploadsAfterLaunches() const override { return ordered; }
  std::size_t FramesPerSubmission() const override { return frames_per_submission; }

  void RunUntil(std::size_t position) {
    for (; executed < position; ++executed) queue[executed]();
  }
  std::size_t LaunchesRun() const { return read.size(); }

  const char* name() const override { return "Fake"; }
  const std::string& device_name() const override { return name_; }
  void Build(const KernelSource&) override {}
  void CheckRun(const PackedMesh&, std::span<const KernelSource>, const RunShape&) const override {}
  std::unique_ptr<PlannedLaunch> Plan(const LaunchSpec& spec) override { return std::make_unique<PlannedLaunch>(spec); }
  std::unique_ptr<DeviceBuffer> Allocate(BufferUse, std::size_t bytes, const void* initial, const std::string&) override {
    return std::make_unique<FakeBuffer>(bytes, initial);
  }
  std::unique_ptr<DeviceObject> PaletteView(const Variant&, DeviceBuffer&, const std::string&) override { return nullptr; }
  std::unique_ptr<DeviceObject> Bind(const PlannedLaunch&, std::span<const ArgumentBinding> arguments, const SetOptions&,
                                     std::size_t&) override {
    auto launch = std::make_unique<FakeLaunch>();
    for (const ArgumentBinding& a : arguments) {
      if (a.role == ArgumentRole::kPalette) launch->palette = static_cast<const FakeBuffer*>(a.buffer);
      if (a.argument->name == "instances") launch->instances = static_cast<const FakeBuffer*>(a.buffer);
      if (a.argument->name == kAnimOutput) launch->out = static_cast<FakeBuffer*>(a.buffer);
    }
    return launch;
  }
  void FinishUploads(const std::string&) override { RunUntil(queue.size()); }
  std::vector<std::vector<double>> RunFrames(const FrameRun& run) override {
    const std::lock_guard<std::mutex> lock(mutex);
    submit_threads.push_back(std::this_thread::get_id());
    EXPECT_EQ(run.use, FrameUse::kLive);
    // The palette kernel, simulated: it copies instance 0's first byte (its
    // clip's low byte) into the palette's first byte, when it runs.
    for (const std::unique_ptr<DeviceObject>& object : run.prologue) {
      const auto& kernel = static_cast<const FakeLaunch&>(*object);
      queue.push_back([&kernel] { kernel.out->device[0] = kernel.instances->device[0]; });
      ++prologues_queued;
    }
    for (const auto& frame : run.frames) {
      const auto& launch = static_cast<const FakeLaunch&>(*frame.front());
      // A fused launch (Runner::Animate of a fused kernel) reads its instances and the run's elapsed.
      const FakeBuffer* read_buffer = launch.palette ? launch.palette : launch.instances;
      float run_elapsed = 0.0f;
      for (const auto& [name, bits] : run.scalars)
        if (name == kAnimElapsed) run_elapsed = std::bit_cast<float>(bits);
      queue.push_back([this, read_buffer, run_elapsed] {
        read.push_back(read_buffer->device);
        elapsed.push_back(run_elapsed);
      });
      ++launches_queued;
    }
    return {};
  }
  // As CUDA and OpenCL: where the driver's fence does not cover the last
  // upload, wait for it; where the driver says it does, it must have run.
  std::span<std::uint8_t> Staging(DeviceBuffer& buffer, const std::string&, bool upload_fenced) override {
    const std::lock_guard<std::mutex> lock(mutex);
    auto& b = static_cast<FakeBuffer&>(buffer);
    if (upload_fenced) {
      ++fenced_stagings;
      EXPECT_GE(executed, b.uploaded_at) << "Staging told the fence covers an upload still queued";
    } else if (executed < b.uploaded_at) {
      ++upload_waits;
      RunUntil(b.uploaded_at);
    }
    b.staging.resize(b.bytes());
    return b.staging;
  }
  void Upload(DeviceBuffer& buffer, std::size_t bytes, const std::string&) override {
    const std::lock_guard<std::mutex> lock(mutex);
    submit_threads.push_back(std::this_thread::get_id());
    if (uploads++ == fail_upload) throw Error("Fake launch: upload " + std::to_string(fail_upload) + " refused");
    auto& b = static_cast<FakeBuffer&>(buffer);
    queue.push_back([&b, bytes] { std::copy(b.staging.begin(), b.staging.begin() + static_cast<std::ptrdiff_t>(bytes), b.device.begin()); });
    b.uploaded_at = queue.size();
  }
  void Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string&, bool) override {
    RunUntil(queue.size());
    std::memcpy(out.data(), static_cast<const FakeBuffer&>(buffer).device.data(), out.size());
  }
  std::span<const std::uint8_t> ReadPinned(const DeviceBuffer& buffer, std::size_t bytes, const std::string&) override {
    const std::lock_guard<std::mutex> lock(mutex);
    RunUntil(queue.size());
    return {static_cast<const FakeBuffer&>(buffer).device.data(), bytes};
  }
  void Mark(std::unique_ptr<DeviceObject>& marker, const std::string&) override {
    const std::lock_guard<std::mutex> lock(mutex);
    if (!marker) marker = std::make_unique<FakeMarker>();
    static_cast<FakeMarker&>(*marker).position = queue.size();
    ++marks;
  }
  void Wait(DeviceObject& marker, const std::string&) override {
    const std::lock_guard<std::mutex> lock(mutex);
    const std::size_t position = static_cast<FakeMarker&>(marker).position;
    ++waits;
    if (executed < position) ++blocking_waits;
    RunUntil(position);
  }
  // Polled (by the submit thread: SubmitThread::Await), the device runs one
  // more operation per query.
  bool Signalled(DeviceObject& marker, const std::string&) override {
    const std::lock_guard<std::mutex> lock(mutex);
    signal_threads.push_back(std::this_thread::get_id());
    if (fail_signal && std::this_thread::get_id() != caller)
      throw Error("Fake launch: the fence query failed");  // on the submit thread
    const std::size_t position = static_cast<FakeMarker&>(marker).position;
    if (executed < position) queue[executed++]();
    return executed >= position;
  }
  std::vector<std::thread::id> signal_threads;  // the thread of each Signalled
  bool fail_signal = false;                     // Signalled throws on any thread but `caller`
  std::thread::id caller = std::this_thread::get_id();
  void Finish() override {
    const std::lock_guard<std::mutex> lock(mutex);
    RunUntil(queue.size());
  }

 private:
  std::string name_ = "deferred fake";
};

// A runner on the fake device with a Skinner's live set of a small mesh.
struct Ring {
  explicit Ring(bool submit_thread = false, bool ordered = false, int slots = kPaletteSlots,
                const std::string& variant = "opencl.b2") {
    mesh = Pack(GenerateDataset(ParseDatasetKey("200-b2")).mesh, ParseVariantKey(variant));
    auto owned = std::make_unique<DeferredApi>();
    api = owned.get();
    api->threaded = submit_thread;
    api->ordered = ordered;
    runner = std::make_unique<Runner>(std::move(owned));
    EXPECT_EQ(runner->UseSubmitThread(), submit_thread);
    const std::vector<KernelSource> kernels = EmitLaunchKernels(mesh);
    prepared = runner->Prepare(mesh, kernels, std::vector<std::vector<std::uint8_t>>{mesh.palette}, 1, slots);
  }
  // Frame f's palette: the mesh's bytes with the frame number in the first.
  std::vector<std::uint8_t> Palette(int f) const {
    std::vector<std::uint8_t> p = mesh.palette;
    p[0] = static_cast<std::uint8_t>(f);
    return p;
  }
  int FrameRead(std::size_t launch) const { return api->read.at(launch).at(0); }

  PackedMesh mesh;
  DeferredApi* api = nullptr;
  std::unique_ptr<Runner> runner;
  Prepared prepared;
};

TEST(PaletteRing, EveryFrameReadsItsOwnPaletteWithSlotsFramesQueued) {
  Ring ring;
  constexpr int kFrames = 4 * kPaletteSlots + 1;
  for (int f = 0; f < kFrames; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    // SetPalette for frame f waited for frame f - slots only: frames
    // f - slots + 1 .. f - 1 are still queued (never for frame f - 1's kernel).
    EXPECT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(std::max(f - kPaletteSlots + 1, 0))) << "frame " << f;
    EXPECT_EQ(ring.runner->PaletteSlot(ring.prepared, 0), f % kPaletteSlots);
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  EXPECT_EQ(ring.api->waits, kFrames - kPaletteSlots) << "a wait per reuse of a slot, none before";
  EXPECT_EQ(ring.api->blocking_waits, kFrames - kPaletteSlots);
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(kFrames));
  for (int f = 0; f < kFrames; ++f) EXPECT_EQ(ring.FrameRead(static_cast<std::size_t>(f)), f) << "launch " << f;
}

// Any depth of ring (SkinnerOptions::palette_buffers), with and without a
// submit thread: SetPalette waits only for the frame `slots` back, and every
// frame reads its own palette; one slot waits for every frame.
class PaletteRingDepth : public ::testing::TestWithParam<std::tuple<int, bool>> {};

TEST_P(PaletteRingDepth, EveryFrameReadsItsOwnPaletteAndWaitsOnlyForTheFrameItsSlotHeld) {
  const auto [slots, threaded] = GetParam();
  Ring ring(threaded, false, slots);
  const int frames = 3 * slots + 2;
  for (int f = 0; f < frames; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    if (!threaded) {
      EXPECT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(std::max(f - slots + 1, 0))) << "frame " << f;
    }
    EXPECT_EQ(ring.runner->PaletteSlot(ring.prepared, 0), f % slots);
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  ring.runner->Finish();
  if (threaded) {
    // The caller queried each fence once; one not yet signalled was polled by
    // the thread: the caller made no wait of its own.
    EXPECT_EQ(ring.api->waits, 0);
    const std::size_t on_caller = static_cast<std::size_t>(
        std::count(ring.api->signal_threads.begin(), ring.api->signal_threads.end(), std::this_thread::get_id()));
    EXPECT_EQ(on_caller, static_cast<std::size_t>(frames - slots));
    EXPECT_GT(ring.api->signal_threads.size(), on_caller) << "no fence polled by the thread";
  } else {
    EXPECT_EQ(ring.api->waits, frames - slots) << "a wait per reuse of a slot, none before";
    EXPECT_TRUE(ring.api->signal_threads.empty());
  }
  ASSERT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(frames));
  for (int f = 0; f < frames; ++f) EXPECT_EQ(ring.FrameRead(static_cast<std::size_t>(f)), f) << "launch " << f;
}

INSTANTIATE_TEST_SUITE_P(Slots, PaletteRingDepth,
                         ::testing::Combine(::testing::Values(1, 2, 3, 6, 16), ::testing::Bool()),
                         [](const ::testing::TestParamInfo<std::tuple<int, bool>>& p) {
                           return std::to_string(std::get<0>(p.param)) + "_slots" +
                                  (std::get<1>(p.param) ? "_submit_thread" : "");
                         });

TEST(PaletteRing, ADeviceThatKeepsUpIsNeverWaitedFor) {
  Ring ring;
  for (int f = 0; f < 3 * kPaletteSlots; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    ring.runner->LaunchSet(ring.prepared, 0);
    ring.api->Finish();  // the device has done everything before the next SetPalette
  }
  EXPECT_EQ(ring.api->blocking_waits, 0);
  for (int f = 0; f < 3 * kPaletteSlots; ++f) EXPECT_EQ(ring.FrameRead(static_cast<std::size_t>(f)), f);
}

TEST(PaletteRing, PalettesReplacedBeforeAnySkinAndSkinsRepeatedReadTheLastPalette) {
  Ring ring;
  std::vector<int> expected;
  for (int f = 0; f < 4 * kPaletteSlots; ++f) {
    if (f % 2 == 0) ring.runner->WritePalette(ring.prepared, 0, ring.Palette(100 + f));  // never skinned
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    ring.runner->LaunchSet(ring.prepared, 0);
    expected.push_back(f);
    if (f % 3 == 0) {
      ring.runner->LaunchSet(ring.prepared, 0);
      expected.push_back(f);
    }
  }
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), expected.size());
  for (std::size_t l = 0; l < expected.size(); ++l) EXPECT_EQ(ring.FrameRead(l), expected[l]) << "launch " << l;
}

// Every frame skinned: each reuse of a slot is covered by the fence of the
// launch that read it (which waited for its upload), so no upload is waited
// for on its own; a slot uploaded and never skinned is, when it comes round.
TEST(PaletteRing, TheRingFenceCoversTheUploadOnlyOfASlotSkinnedSinceItsUpload) {
  Ring ring;
  for (int f = 0; f < 3 * kPaletteSlots; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  EXPECT_EQ(ring.api->fenced_stagings, 2 * kPaletteSlots) << "every staging after the first round";
  EXPECT_EQ(ring.api->upload_waits, 0);
  for (int f = 0; f < kPaletteSlots; ++f) ring.runner->WritePalette(ring.prepared, 0, ring.Palette(50 + f));  // none skinned
  const int fenced = ring.api->fenced_stagings;
  ring.runner->WritePalette(ring.prepared, 0, ring.Palette(60));  // back to a slot uploaded and never skinned
  EXPECT_EQ(ring.api->fenced_stagings, fenced);
  EXPECT_EQ(ring.api->upload_waits, 1) << "its own upload waited for";
  ring.runner->LaunchSet(ring.prepared, 0);
  ring.runner->Finish();
  EXPECT_EQ(ring.FrameRead(ring.api->LaunchesRun() - 1), 60);
}

// On a device that orders uploads after launches (GL), the ring's fence
// follows each upload and no launch: SetPalette for frame f waits for frame
// f - slots's upload only, so one more launch stays queued than elsewhere,
// and every frame still reads its own palette.
TEST(PaletteRing, WhereUploadsFollowLaunchesInOrderTheFenceFollowsTheUploadAndSkinMarksNothing) {
  Ring ring(false, true);
  constexpr int kFrames = 4 * kPaletteSlots + 1;
  for (int f = 0; f < kFrames; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    EXPECT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(std::max(f - kPaletteSlots, 0))) << "frame " << f;
    EXPECT_EQ(ring.api->marks, f + 1) << "one fence per upload";
    ring.runner->LaunchSet(ring.prepared, 0);
    EXPECT_EQ(ring.api->marks, f + 1) << "Skin marked";
  }
  EXPECT_EQ(ring.api->blocking_waits, kFrames - kPaletteSlots);
  EXPECT_EQ(ring.api->upload_waits, 0) << "the fence covers every upload";
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(kFrames));
  for (int f = 0; f < kFrames; ++f) EXPECT_EQ(ring.FrameRead(static_cast<std::size_t>(f)), f) << "launch " << f;
}

// The same with palettes replaced before any Skin and Skins repeated: no
// staging is overwritten while its upload is queued (the fake's Staging
// checks that the fence it was told of covers the upload).
TEST(PaletteRing, WhereUploadsFollowLaunchesInOrderReplacedAndRepeatedFramesReadTheirPalettes) {
  Ring ring(false, true);
  std::vector<int> expected;
  int uploads = 0;
  for (int f = 0; f < 4 * kPaletteSlots; ++f) {
    if (f % 2 == 0) ring.runner->WritePalette(ring.prepared, 0, ring.Palette(100 + f)), ++uploads;  // never skinned
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    ++uploads;
    ring.runner->LaunchSet(ring.prepared, 0);
    expected.push_back(f);
    if (f % 3 == 0) {
      ring.runner->LaunchSet(ring.prepared, 0);
      expected.push_back(f);
    }
  }
  EXPECT_EQ(ring.api->marks, uploads);
  EXPECT_EQ(ring.api->upload_waits, 0);
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), expected.size());
  for (std::size_t l = 0; l < expected.size(); ++l) EXPECT_EQ(ring.FrameRead(l), expected[l]) << "launch " << l;
}

// With a submit thread the uploads and launches are made on it, and every
// frame still reads its own palette with the ring's frames in flight.
TEST(PaletteRing, WithASubmitThreadEveryFrameStillReadsItsOwnPalette) {
  Ring ring(true);
  constexpr int kFrames = 4 * kPaletteSlots + 1;
  for (int f = 0; f < kFrames; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(kFrames));
  for (int f = 0; f < kFrames; ++f) EXPECT_EQ(ring.FrameRead(static_cast<std::size_t>(f)), f) << "launch " << f;
  ASSERT_EQ(ring.api->submit_threads.size(), 2u * kFrames);
  for (const std::thread::id id : ring.api->submit_threads) EXPECT_NE(id, std::this_thread::get_id());
}

// A handed-over upload that fails is thrown by the next call that waits for
// the thread, once; what was queued behind it is dropped, and the next frame
// skins with its own palette.
TEST(PaletteRing, AFailedUploadOnTheSubmitThreadIsThrownOnceByTheNextCall) {
  Ring ring(true);
  ring.api->fail_upload = 2;
  for (int f = 0; f < 3; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));  // frame 2's upload fails on the thread
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  try {
    ring.runner->Finish();
    ADD_FAILURE() << "Finish did not report the failed upload";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "Fake launch: upload 2 refused");
  }
  EXPECT_NO_THROW(ring.runner->Finish());
  EXPECT_EQ(ring.api->LaunchesRun(), 2u) << "frame 2's launch, queued behind the failure, dropped";
  ring.runner->WritePalette(ring.prepared, 0, ring.Palette(10));
  ring.runner->LaunchSet(ring.prepared, 0);
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), 3u);
  EXPECT_EQ(ring.FrameRead(2), 10);
}

// The ring's fence, polled on the submit thread, fails: SetPalette throws
// that error (once) and takes no slot; the frames queued before it still run.
TEST(PaletteRing, AFenceQueryThatFailsOnTheSubmitThreadIsThrownBySetPalette) {
  Ring ring(true);
  for (int f = 0; f < kPaletteSlots; ++f) {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(f));
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  const int slot = ring.runner->PaletteSlot(ring.prepared, 0);
  ring.api->fail_signal = true;  // the next SetPalette reuses a slot: the thread polls its fence
  try {
    ring.runner->WritePalette(ring.prepared, 0, ring.Palette(20));
    ADD_FAILURE() << "SetPalette did not report the failed fence query";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "Fake launch: the fence query failed");
  }
  EXPECT_FALSE(ring.api->signal_threads.empty());
  EXPECT_EQ(ring.runner->PaletteSlot(ring.prepared, 0), slot);
  ring.api->fail_signal = false;
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(kPaletteSlots));
  ring.runner->WritePalette(ring.prepared, 0, ring.Palette(21));
  ring.runner->LaunchSet(ring.prepared, 0);
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(kPaletteSlots) + 1);
  EXPECT_EQ(ring.FrameRead(kPaletteSlots), 21);
}

TEST(PaletteRing, AStagingNeverUploadedTakesNoSlot) {
  // The Skinner's SetPalette of a palette it rejects while packing it.
  Ring ring;
  ring.runner->WritePalette(ring.prepared, 0, ring.Palette(5));
  EXPECT_THROW(ring.runner->UploadPalette(ring.prepared, 0), Error);  // nothing staged since the last upload
  const int slot = ring.runner->PaletteSlot(ring.prepared, 0);
  for (int i = 0; i < kPaletteSlots + 1; ++i) {
    const std::span<std::uint8_t> staging = ring.runner->PaletteStaging(ring.prepared, 0);
    std::fill(staging.begin(), staging.end(), std::uint8_t{0xff});
  }
  EXPECT_EQ(ring.runner->PaletteSlot(ring.prepared, 0), slot);
  ring.runner->LaunchSet(ring.prepared, 0);
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), 1u);
  EXPECT_EQ(ring.FrameRead(0), 5);
}

TEST(PaletteRing, AWrongSizeIsRejectedBeforeTakingASlot) {
  Ring ring;
  ring.runner->WritePalette(ring.prepared, 0, ring.Palette(7));
  const int slot = ring.runner->PaletteSlot(ring.prepared, 0);
  std::vector<std::uint8_t> short_palette = ring.Palette(8);
  short_palette.pop_back();
  EXPECT_THROW(ring.runner->WritePalette(ring.prepared, 0, short_palette), Error);
  EXPECT_EQ(ring.runner->PaletteSlot(ring.prepared, 0), slot);
  ring.runner->LaunchSet(ring.prepared, 0);
  ring.runner->Finish();
  ASSERT_EQ(ring.api->LaunchesRun(), 1u);
  EXPECT_EQ(ring.FrameRead(0), 7);
}

// Animated (Runner::Animate): each frame's palette is its own slot's,
// computed by the palette kernel queued before its launch after the upload of
// its states, and only then: a launch with no upload since reuses it, the
// first launch before any upload computes the rest pose.
TEST(PaletteRing, AnimatedFramesComputeTheirSlotsPaletteOncePerUploadBeforeTheirLaunch) {
  Ring ring;
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("200-b2"));
  const PackedAnimation animation = PackAnimation(asset);
  const std::size_t bytes = ring.prepared.bytes_per_set();
  ring.runner->Animate(ring.prepared, 0, animation.View(), EmitPalette(Lang::kOpenCl, animation.View(), 3));
  // The set's device bytes count the animation, its kept states and each slot's instances.
  EXPECT_GE(ring.prepared.bytes_per_set(), bytes + animation.Bytes() + (kPaletteSlots + 1) * sizeof(AnimInstance));
  ring.runner->LaunchSet(ring.prepared, 0);  // before any states: the rest pose (clip 0xffff)
  constexpr int kFrames = 3 * kPaletteSlots + 1;
  for (int f = 0; f < kFrames; ++f) {
    std::vector<AnimInstance> states(1);
    states[0].clip = static_cast<std::uint16_t>(f);
    ring.runner->WritePalette(ring.prepared, 0, BufferBytes(states));
    ring.runner->LaunchSet(ring.prepared, 0);
    if (f % 2 == 0) ring.runner->LaunchSet(ring.prepared, 0);  // the same states again
  }
  ring.runner->Finish();
  EXPECT_EQ(ring.api->prologues_queued, static_cast<std::size_t>(kFrames + 1)) << "one per upload, and the first";
  ASSERT_EQ(ring.api->LaunchesRun(), static_cast<std::size_t>(1 + kFrames + (kFrames + 1) / 2));
  EXPECT_EQ(ring.FrameRead(0), 0xff) << "the rest pose's clip";
  std::size_t launch = 1;
  for (int f = 0; f < kFrames; ++f) {
    EXPECT_EQ(ring.FrameRead(launch++), f) << "frame " << f;
    if (f % 2 == 0) {
      EXPECT_EQ(ring.FrameRead(launch++), f) << "frame " << f << ", again";
    }
  }
  // A second Animate, or palettes that do not fit the animation, are refused.
  EXPECT_THROW(ring.runner->Animate(ring.prepared, 0, animation.View(), EmitPalette(Lang::kOpenCl, animation.View(), 3)),
               Error);
}

// Fused (the skin launch makes its palette, docs/ANIMATION.md "The palette in
// the skin launch"): no palette kernel runs; each launch reads the instances
// of the last upload and the deltas summed since it, passed with the launch.
// AdvanceAnimation takes no slot and waits only as the ring would (for the
// frame as many frames back as it has slots), until the sum passes
// kFusedRebaseSeconds: then the states advanced on the host go up as an
// upload does, and the sum starts again.
TEST(PaletteRing, FusedFramesReadTheLastUploadAndTheDeltasSinceWithNoPaletteKernel) {
  Ring ring(false, false, kPaletteSlots, "opencl.b2.local");
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("200-b2"));
  const PackedAnimation animation = BakeAnimation(asset, 30.0, BakeSpace::kPalette);
  PaletteKernel fused;
  fused.fused = true;
  ring.runner->Animate(ring.prepared, 0, animation.View(), fused);
  ring.runner->LaunchSet(ring.prepared, 0);  // before any states: the rest pose
  std::vector<AnimInstance> states(1);
  states[0].clip = 0;
  states[0].time = 0.25f;
  ring.runner->WritePalette(ring.prepared, 0, BufferBytes(states));
  const int slot = ring.runner->PaletteSlot(ring.prepared, 0);
  ring.runner->LaunchSet(ring.prepared, 0);
  for (int f = 0; f < 3 * kPaletteSlots; ++f) {
    ring.runner->AdvanceAnimation(ring.prepared, 0, 0.5f);
    // It waits only for the frame as many frames back as the ring has slots.
    EXPECT_LT(ring.api->launches_queued - ring.api->LaunchesRun(), static_cast<std::size_t>(kPaletteSlots)) << "frame " << f;
    if (f >= kPaletteSlots) {
      EXPECT_GE(ring.api->launches_queued - ring.api->LaunchesRun(), static_cast<std::size_t>(kPaletteSlots - 1))
          << "frame " << f << ": it waited for more";
    }
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  EXPECT_EQ(ring.runner->PaletteSlot(ring.prepared, 0), slot) << "AdvanceAnimation took a slot";
  EXPECT_THROW(ring.runner->AdvanceAnimation(ring.prepared, 0, 0.1f, std::vector<std::uint8_t>(8)), Error)
      << "morph weights, which a fused set cannot take";
  // Past the rebase: the states advanced by the sum go up, into the next slot.
  const double before = 0.5 * 3 * kPaletteSlots;
  const auto step = static_cast<float>(Runner::kFusedRebaseSeconds - before + 1.0);
  ring.runner->AdvanceAnimation(ring.prepared, 0, step);
  ring.runner->LaunchSet(ring.prepared, 0);
  EXPECT_NE(ring.runner->PaletteSlot(ring.prepared, 0), slot);
  ring.runner->AdvanceAnimation(ring.prepared, 0, 0.5f);
  ring.runner->LaunchSet(ring.prepared, 0);
  ring.runner->Finish();
  EXPECT_EQ(ring.api->prologues_queued, 0u);
  const std::size_t frames = 2 + 3 * kPaletteSlots + 2;
  ASSERT_EQ(ring.api->LaunchesRun(), frames);
  const auto instance = [&](std::size_t launch) {
    AnimInstance in;
    std::memcpy(&in, ring.api->read.at(launch).data(), sizeof in);
    return in;
  };
  EXPECT_EQ(instance(0).clip, kAnimRestPose);
  EXPECT_EQ(instance(1).clip, 0);
  for (std::size_t f = 1; f < 2 + 3 * kPaletteSlots; ++f) {
    EXPECT_FLOAT_EQ(instance(f).time, 0.25f) << "launch " << f;
    EXPECT_FLOAT_EQ(ring.api->elapsed.at(f), 0.5f * static_cast<float>(f - 1)) << "launch " << f;
  }
  std::vector<AnimInstance> rebased = states;
  AdvanceAnimInstances(animation.View(), rebased, static_cast<float>(before + step));
  EXPECT_FLOAT_EQ(instance(frames - 2).time, rebased[0].time);
  EXPECT_FLOAT_EQ(ring.api->elapsed.at(frames - 2), 0.0f);
  EXPECT_FLOAT_EQ(instance(frames - 1).time, rebased[0].time);
  EXPECT_FLOAT_EQ(ring.api->elapsed.at(frames - 1), 0.5f);
}

// A fused frame holds no buffer: where the API gathers frames into shared
// submissions, AdvanceAnimation waits for the frame twice that many back, or
// as many as the ring has slots where that is more, so that one submission
// fills while the device runs the one before.
class FusedPace : public ::testing::TestWithParam<std::tuple<int, std::size_t>> {};

TEST_P(FusedPace, AdvanceAnimationWaitsForTheFrameTwoSubmissionsOrTheRingBack) {
  const auto [slots, per_submission] = GetParam();
  const std::size_t depth = std::max(static_cast<std::size_t>(slots), 2 * per_submission);
  Ring ring(false, false, slots, "opencl.b2.local");
  ring.api->frames_per_submission = per_submission;
  const PackedAnimation animation = BakeAnimation(GenerateDataset(ParseDatasetKey("200-b2")), 30.0, BakeSpace::kPalette);
  PaletteKernel fused;
  fused.fused = true;
  ring.runner->Animate(ring.prepared, 0, animation.View(), fused);
  for (std::size_t f = 0; f < 3 * depth; ++f) {
    ring.runner->AdvanceAnimation(ring.prepared, 0, 0.01f);
    const std::size_t queued = ring.api->launches_queued - ring.api->LaunchesRun();
    EXPECT_LT(queued, depth) << "frame " << f << ": it did not wait for the frame " << depth << " back";
    if (f >= depth) {
      EXPECT_EQ(queued, depth - 1) << "frame " << f << ": it waited for a later frame";
    }
    ring.runner->LaunchSet(ring.prepared, 0);
  }
  ring.runner->Finish();
  EXPECT_EQ(ring.api->LaunchesRun(), 3 * depth);
}

INSTANTIATE_TEST_SUITE_P(SlotsAndSubmissions, FusedPace,
                         ::testing::Values(std::tuple{3, std::size_t{1}}, std::tuple{3, std::size_t{8}},
                                           std::tuple{16, std::size_t{2}}, std::tuple{2, std::size_t{4}}),
                         [](const ::testing::TestParamInfo<std::tuple<int, std::size_t>>& p) {
                           return std::to_string(std::get<0>(p.param)) + "_slots_" +
                                  std::to_string(std::get<1>(p.param)) + "_frames_a_submission";
                         });

TEST(PaletteRing, AnAnimationWhosePaletteDoesNotFillTheSetsIsRefused) {
  Ring ring;
  const PackedAnimation animation = PackAnimation(GenerateDataset(ParseDatasetKey("200-b2")));
  try {
    ring.runner->Animate(ring.prepared, 0, animation.View(), EmitPalette(Lang::kOpenCl, animation.View(), 4));
    FAIL() << "a mat4 palette kernel over mat3x4 palettes was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the palettes of"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skintune::internal
