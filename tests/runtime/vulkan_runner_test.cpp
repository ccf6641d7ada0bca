// The language vulkan (templates/skin.comp compiled to SPIR-V) through the
// runner driver on the machine's Vulkan devices (lavapipe in CI), with the
// validation layer on: every test also fails on any validation warning or
// error. The generated covering set against the float64 gold on fresh random
// meshes (the seed is printed; SKINTUNE_TEST_SEED=<n> reproduces a run),
// the staging paths of a discrete GPU (forced on lavapipe), instances,
// poison and guard, build logs, timing, the copy kernel, the program cache
// and the device identity. Every test skips, with the reason, only when no
// Vulkan device can be opened; GPU-only expectations skip without a GPU.
#include <gtest/gtest.h>

#include <cstdlib>
#include <iostream>
#include <regex>
#include <set>

#include "generator/clip_packer.h"
#include "generator/constraints.h"
#include "generator/copy_kernel.h"
#include "generator/covering.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "generator/palette_kernel.h"
#include "base/error.h"
#include "runner_test_support.h"
#include "runtime/backends/vulkan/vulkan_devices.h"
#include "runtime/backends/vulkan/vulkan_loader.h"
#include "runtime/backends/vulkan/vulkan_runner.h"
#include "runtime/program_cache.h"
#include "runtime/run_shape.h"
#include "tests/common/scratch_dir.h"
#include "tests/generator/palette_gold.h"

namespace skintune::internal {
namespace {

using namespace skintune::internal::testing;  // the runner tests' helpers (runner_test_support.h)

// Whether the validation layer is installed (this machine: vulkan-validationlayers).
bool ValidationLayerMissing(const std::string& error) {
  return error.find("no VK_LAYER_KHRONOS_validation") != std::string::npos;
}

// One runner for the whole program (device 0), with validation where the
// layer is installed (a GPU machine may have the driver but not the layer),
// or null with the reason.
VulkanRunner* Runner(std::string& why) {
  static std::string reason;
  static std::unique_ptr<VulkanRunner> runner = []() -> std::unique_ptr<VulkanRunner> {
    try {
      std::unique_ptr<VulkanRunner> r;
      try {
        r = std::make_unique<VulkanRunner>(0, true);
      } catch (const Error& e) {
        if (!ValidationLayerMissing(e.what())) throw;
        std::cout << "[ Vulkan   ] " << e.what() << ": running without validation\n";
        r = std::make_unique<VulkanRunner>(0, false);
      }
      const vk::VulkanDeviceInfo& i = r->info();
      std::cout << "[ Vulkan   ] " << i.name << " (" << i.vendor << ", " << i.type << "), " << i.driver_version
                << ", Vulkan " << i.api_version << ", UUID " << i.uuid << "\n";
      return r;
    } catch (const Error& e) {
      reason = e.what();
      return nullptr;
    }
  }();
  why = reason;
  return runner.get();
}

// Whether this machine's runners validate (the layer is installed).
bool ValidationOn() {
  static const bool on = [] {
    try {
      VulkanRunner probe(0, true);
      return true;
    } catch (const Error&) {
      return false;
    }
  }();
  return on;
}

// Fails the test on any validation message that appeared during it.
class Validated : public ::testing::Test {
 protected:
  void SetUp() override {
    runner_ = Runner(why_);
    if (!runner_) GTEST_SKIP() << why_;
    before_ = runner_->validation_messages().size();
  }
  void TearDown() override {
    if (!runner_) return;
    const std::vector<std::string> messages = runner_->validation_messages();
    for (std::size_t m = before_; m < messages.size(); ++m) ADD_FAILURE() << "validation: " << messages[m];
  }
  // CesiumMan prepared for a B=4 variant and a 4 KiB flush: what the cold-frame tests time.
  struct ColdFrames {
    Prepared mesh;
    Prepared flush;
  };
  ColdFrames PrepareColdFrames() {
    const Variant variant =
        ParseVariantKey("vulkan.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.nonormals");
    const SkinnedAsset& asset = SmallAsset("cesium");
    const PackedMesh packed = Pack(asset.mesh, variant);
    const std::vector<KernelSource> kernels = EmitLaunchKernels(packed, 1);
    const std::vector<std::vector<std::uint8_t>> palettes = {PackPalette(asset.PaletteAt(-1, 0.0), variant)};
    return {runner_->Prepare(packed, kernels, palettes), runner_->PrepareFlush(Lang::kVulkan, 4096)};
  }
  VulkanRunner* runner_ = nullptr;
  std::string why_;
  std::size_t before_ = 0;
};

// The generated covering set for this device's limits: every value of every
// axis and every pair of layout x index x weight x palette x storage x blend
// that fits, each variant on a fresh mesh with its own influence count.
// A lost device is stage "lost" whatever the caller's stage (the tune worker
// then exits); every other result keeps the caller's.
// NVIDIA's families (graphics + compute, transfer, compute alone, video) and
// lavapipe's one: skintune submits to the compute family without graphics
// where it has timestamps, else to the first compute family with them.
TEST(VulkanQueueFamily, AComputeFamilyWithoutGraphicsIsTakenWhereItHasTimestamps) {
  const auto family = [](VkQueueFlags flags, std::uint32_t timestamp_bits, std::uint32_t queues = 1) {
    VkQueueFamilyProperties p{};
    p.queueFlags = flags;
    p.timestampValidBits = timestamp_bits;
    p.queueCount = queues;
    return p;
  };
  constexpr VkQueueFlags kGraphics = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT | VK_QUEUE_TRANSFER_BIT;
  constexpr VkQueueFlags kCompute = VK_QUEUE_COMPUTE_BIT | VK_QUEUE_TRANSFER_BIT;
  const std::vector<VkQueueFamilyProperties> nvidia = {family(kGraphics, 64, 16), family(VK_QUEUE_TRANSFER_BIT, 64, 2),
                                                       family(kCompute, 64, 8), family(0, 0, 1)};
  EXPECT_EQ(vk::ComputeFamily(nvidia), 2u);
  std::vector<VkQueueFamilyProperties> untimed = nvidia;
  untimed[2].timestampValidBits = 0;
  EXPECT_EQ(vk::ComputeFamily(untimed), 0u) << "a compute family without timestamps cannot time kernels";
  std::vector<VkQueueFamilyProperties> empty = nvidia;
  empty[2].queueCount = 0;
  EXPECT_EQ(vk::ComputeFamily(empty), 0u);
  EXPECT_EQ(vk::ComputeFamily(std::vector{family(kGraphics, 64)}), 0u);           // lavapipe
  EXPECT_EQ(vk::ComputeFamily(std::vector{family(kGraphics, 0), family(kCompute, 0)}), 0u);  // none timed: the first
  EXPECT_EQ(vk::ComputeFamily(std::vector{family(VK_QUEUE_TRANSFER_BIT, 64)}), UINT32_MAX);
}

TEST(VulkanCheck, ADeviceLostIsStageLost) {
  const auto message = [](VkResult r) {
    try {
      vk::Check(r, "launch", "vkQueueSubmit");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(VK_ERROR_DEVICE_LOST), "Vulkan lost: vkQueueSubmit: VK_ERROR_DEVICE_LOST");
  EXPECT_EQ(message(VK_ERROR_OUT_OF_DEVICE_MEMORY), "Vulkan launch: vkQueueSubmit: VK_ERROR_OUT_OF_DEVICE_MEMORY");
  EXPECT_EQ(message(VK_SUCCESS), "no error");
}

TEST_F(Validated, CoveringSetMatchesTheGold) {
  const CoveringSet set = BuildCoveringSet(Lang::kVulkan, vk::LimitsOf(runner_->info()), testing::CoveringShape());
  for (const std::string& pair : set.uncoverable)
    EXPECT_NE(pair.find("storage=local"), std::string::npos) << "only local storage may be uncoverable: " << pair;
  ExpectCoveringSetMatchesGold(*runner_, set, LaunchTimes::kNonNegative);
  std::cout << "[ covering ] " << set.variants.size() << " vulkan variants verified on " << runner_->device_name()
            << "\n";
}

// Each palette storage, bucketed launches (first > 0) and normals, with
// kernel buffers in unmapped memory: uploads and read-backs through staging
// buffers, as on a discrete GPU. (A runner of its own, made with
// $SKINTUNE_VULKAN_STAGING set.)
TEST_F(Validated, StagedBuffersMatchTheGold) {
  setenv("SKINTUNE_VULKAN_STAGING", "1", 1);
  VulkanRunner staged(0, ValidationOn());
  unsetenv("SKINTUNE_VULKAN_STAGING");
  const Case cases[] = {
      {"vulkan.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.normals", "cesium"},
      {"vulkan.b2.padded.aos.float3.u16.f32.mat4.image.matrix.v2c.wg64.nonormals", "b2"},
      {"vulkan.b3.padded.soa-split.float4.u8.unorm8.mat3x4.constant.point.v4s.wg32.normals", "b3"},
      {"vulkan.b4.bucketed.aos.float3.u8.unorm8.mat4.local.point.v2s.wg64.normals", "cesium"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + ", seed " + std::to_string(Seed()));
    ExpectCaseMatchesGold(staged, c, ParseVariantKey(c.key), LaunchTimes::kNonNegative);
  }
  for (const std::string& m : staged.validation_messages()) ADD_FAILURE() << "validation: " << m;
}

// The Skinner's frame loop (runtime/runner.h "the palette ring") with
// unmapped kernel buffers, as on a discrete GPU: palettes through each slot's
// staging, copied by the frame's own command buffer, frames queued without a
// wait, read-backs through the kept read-back buffer; each read is the gold
// of its frame's palettes, and the validation layer says nothing.
TEST_F(Validated, TheFrameLoopThroughStagingIsEachFramesGold) {
  setenv("SKINTUNE_VULKAN_STAGING", "1", 1);
  VulkanRunner staged(0, ValidationOn());
  unsetenv("SKINTUNE_VULKAN_STAGING");
  constexpr int kInstances = 2;
  for (const char* key : {"vulkan.b4.padded.soa.float4.u16.f32.mat3x4.constant.matrix.v1c.wg64.nonormals",
                          "vulkan.b4.bucketed.aos.float3.u16.f32.mat4.image.matrix.v2c.wg64.normals"}) {
    SCOPED_TRACE(key);
    const Variant variant = ParseVariantKey(key);
    const SkinnedAsset& asset = SmallAsset("cesium");
    const PackedMesh packed = Pack(asset.mesh, variant);
    const SkinnedMesh quantised = QuantisedMesh(asset.mesh, variant);
    const std::vector<KernelSource> kernels = EmitLaunchKernels(packed, kInstances);
    std::vector<std::uint8_t> rest;
    for (int k = 0; k < kInstances; ++k) rest.insert(rest.end(), packed.palette.begin(), packed.palette.end());
    Prepared live = staged.Prepare(packed, kernels, std::vector<std::vector<std::uint8_t>>{rest}, kInstances, kPaletteSlots);
    const auto frame_palette = [&](int f, int k) { return InstancePalette(asset, f * kInstances + k); };
    for (int f = 0; f < 3 * kPaletteSlots + 1; ++f) {
      std::vector<std::uint8_t> bytes;
      for (int k = 0; k < kInstances; ++k) {
        const std::vector<std::uint8_t> p = PackPalette(frame_palette(f, k), variant);
        bytes.insert(bytes.end(), p.begin(), p.end());
      }
      staged.WritePalette(live, 0, bytes);
      staged.LaunchSet(live, 0);
      if (f % 4 != 3 && f != 3 * kPaletteSlots) continue;
      const std::span<const std::uint8_t> positions = staged.ReadOutput(live, 0, Output::kPositions);
      for (int k = 0; k < kInstances; ++k) {
        const GoldResult gold = SkinGold(quantised, frame_palette(f, k), false);
        const GoldComparison c = CompareToGold(gold.positions, UnpackInstance(packed, positions, k));
        EXPECT_EQ(c.non_finite, 0u) << "frame " << f << ", instance " << k;
        EXPECT_LT(c.max_relative, kTolerance) << "frame " << f << ", instance " << k << ", worst vertex " << c.worst_vertex;
      }
    }
  }
  for (const std::string& m : staged.validation_messages()) ADD_FAILURE() << "validation: " << m;
}

// Cold frames (the kernel time) are each submitted alone and waited for, so
// that every one starts on an idle device: sixteen to a submission, NVIDIA's
// last four of every sixteen took 5.1 us where the others took 5.9 (an H200,
// December 2026). Two untimed frames and five samples: seven submissions.
TEST_F(Validated, ColdFramesAreSubmittedOneAtATime) {
  const ColdFrames cold = PrepareColdFrames();
  (void)runner_->TimeCold(cold.mesh, cold.flush, 1, 1);  // uploads and builds done
  const std::uint64_t before = runner_->submissions();
  const std::vector<double> ms = runner_->TimeCold(cold.mesh, cold.flush, 2, 5);
  EXPECT_EQ(ms.size(), 5u);
  EXPECT_EQ(runner_->submissions() - before, 7u);
}

// Cold frames are recorded into sixteen command buffers taken in turn, not
// the one retired last: on NVIDIA's driver a launch's stamped time depends
// steadily on its command buffer (4.13-4.42 us by command buffer for one
// 100k-vertex kernel on an H200, December 2026), so a kernel time taken on
// one carried that command buffer's level from one process to the next.
TEST_F(Validated, ColdFramesTakeSixteenCommandBuffersInTurn) {
  ColdFrames cold = PrepareColdFrames();
  (void)runner_->TimeCold(cold.mesh, cold.flush, 1, 1);
  (void)runner_->FrameMs(cold.mesh, 2, 8);  // frames of the loop retire their command buffers in between
  const std::vector<double> ms = runner_->TimeCold(cold.mesh, cold.flush, 2, 38);
  EXPECT_EQ(ms.size(), 38u);
  const std::vector<std::uintptr_t> order = runner_->cold_command_buffers();
  ASSERT_EQ(order.size(), 40u);
  const std::set<std::uintptr_t> distinct(order.begin(), order.end());
  ASSERT_GE(distinct.size(), 16u);
  EXPECT_EQ(std::set<std::uintptr_t>(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(distinct.size())).size(),
            distinct.size())
      << "a command buffer came round again before every other had";
  for (std::size_t i = distinct.size(); i < order.size(); ++i)
    EXPECT_EQ(order[i], order[i - distinct.size()]) << "frame " << i << " is out of turn";
}

// Frames queued faster than the device runs them share submissions (the
// open command buffer of VulkanApi::OpenFrames, at most 8 frames each): 32
// frames of a 128-instance crowd (419k vertices, milliseconds a frame on a
// CPU device, tens of microseconds on a GPU) queued back to back take a
// handful of vkQueueSubmit calls, not 32, and the read after them is the
// gold of the palette they skinned with.
TEST_F(Validated, FramesQueuedFasterThanTheDeviceRunsThemShareSubmissions) {
  constexpr int kInstances = 128, kFrames = 32;
  const char* key = "vulkan.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.nonormals";
  const Variant variant = ParseVariantKey(key);
  const SkinnedAsset& asset = SmallAsset("cesium");
  const PackedMesh packed = Pack(asset.mesh, variant);
  const std::vector<KernelSource> kernels = EmitLaunchKernels(packed, kInstances);
  std::vector<std::uint8_t> palettes;
  for (int k = 0; k < kInstances; ++k) {
    const std::vector<std::uint8_t> p = PackPalette(InstancePalette(asset, k), variant);
    palettes.insert(palettes.end(), p.begin(), p.end());
  }
  Prepared live = runner_->Prepare(packed, kernels, std::vector<std::vector<std::uint8_t>>{palettes}, kInstances,
                                   kPaletteSlots);
  runner_->WritePalette(live, 0, palettes);
  runner_->LaunchSet(live, 0);
  (void)runner_->ReadOutput(live, 0, Output::kPositions);  // built, uploaded, run once, idle
  const std::uint64_t before = runner_->submissions();
  for (int f = 0; f < kFrames; ++f) runner_->LaunchSet(live, 0);
  const std::uint64_t submissions = runner_->submissions() - before;
  EXPECT_GE(submissions, static_cast<std::uint64_t>(kFrames / 8)) << "at most 8 frames a submission";
  EXPECT_LE(submissions, static_cast<std::uint64_t>(kFrames / 2)) << "frames queued back to back were submitted one by one";
  const std::span<const std::uint8_t> positions = runner_->ReadOutput(live, 0, Output::kPositions);
  const SkinnedMesh quantised = QuantisedMesh(asset.mesh, variant);
  for (int k : {0, kInstances / 2, kInstances - 1}) {
    const GoldResult gold = SkinGold(quantised, InstancePalette(asset, k), false);
    const GoldComparison c = CompareToGold(gold.positions, UnpackInstance(packed, positions, k));
    EXPECT_EQ(c.non_finite, 0u) << "instance " << k;
    EXPECT_LT(c.max_relative, kTolerance) << "instance " << k << ", worst vertex " << c.worst_vertex;
  }
}

// Frames that make their palettes in the skin launch (fused) hold no palette
// slot, so AdvanceAnimation waits only for the frame twice Vulkan's frames a
// submission back (16), not the ring's (3): 48 fused frames of 512k vertices
// (about a second of them on a CPU device, 10 us each on a GPU) queued back to
// back take a handful of submissions, where waiting 3 back submitted one or
// two frames at a time (31 of 48 on lavapipe, 2026-12-01).
TEST_F(Validated, FusedFramesQueuedFasterThanTheDeviceRunsThemShareSubmissions) {
  constexpr int kInstances = 64, kFrames = 48;
  const char* key = "vulkan.b4.padded.soa.float4.u16.f32.mat3x4.local.matrix.v8s.wg256.nonormals";
  const Variant variant = ParseVariantKey(key);
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("8k-b4"));
  const PackedAnimation records = BakeAnimation(asset, 30.0, BakeSpace::kPalette);
  const PackedMesh packed = Pack(asset.mesh, variant);
  const std::vector<KernelSource> kernels = EmitLaunchKernels(packed, kInstances);
  std::vector<std::uint8_t> rest;
  for (int k = 0; k < kInstances; ++k) rest.insert(rest.end(), packed.palette.begin(), packed.palette.end());
  Prepared live = runner_->Prepare(packed, kernels, std::vector<std::vector<std::uint8_t>>{rest}, kInstances,
                                   kPaletteSlots);
  PaletteKernel fused;
  fused.fused = true;
  runner_->Animate(live, 0, records.View(), fused);
  std::vector<AnimInstance> states(kInstances);
  for (int k = 0; k < kInstances; ++k) {
    states[static_cast<std::size_t>(k)].clip = 0;
    states[static_cast<std::size_t>(k)].time = 0.01f * static_cast<float>(k);
  }
  runner_->WritePalette(live, 0, {reinterpret_cast<const std::uint8_t*>(states.data()), states.size() * sizeof(AnimInstance)});
  runner_->LaunchSet(live, 0);
  (void)runner_->ReadOutput(live, 0, Output::kPositions);  // built, uploaded, run once, idle
  const std::uint64_t before = runner_->submissions();
  for (int f = 0; f < kFrames; ++f) {
    runner_->AdvanceAnimation(live, 0, 1.0f / 60.0f);
    runner_->LaunchSet(live, 0);
  }
  const std::uint64_t submissions = runner_->submissions() - before;
  EXPECT_GE(submissions, static_cast<std::uint64_t>(kFrames / 8)) << "at most 8 frames a submission";
  EXPECT_LE(submissions, static_cast<std::uint64_t>(kFrames / 2)) << "fused frames waited for the frame 3 back";
  // The last frame: each instance's clip advanced by the frames' seconds, from its baked records.
  std::vector<AnimInstance> advanced = states;
  AdvanceAnimInstances(records.View(), advanced, static_cast<float>(kFrames) / 60.0f);
  const std::span<const std::uint8_t> positions = runner_->ReadOutput(live, 0, Output::kPositions);
  for (int k : {0, kInstances - 1}) {
    std::vector<glm::mat4> palette;
    for (const glm::dmat4& m : BakedGoldPalette(records, advanced[static_cast<std::size_t>(k)])) palette.emplace_back(m);
    const GoldResult gold = SkinGold(QuantisedMesh(asset.mesh, variant), palette, false);
    const GoldComparison c = CompareToGold(gold.positions, UnpackInstance(packed, positions, k));
    EXPECT_EQ(c.non_finite, 0u) << "instance " << k;
    EXPECT_LT(c.max_relative, 1e-4) << "instance " << k << ", worst vertex " << c.worst_vertex;
  }
}

// Animated frames (a palette kernel before each frame's skin launch) queued
// back to back share a command buffer, where a frame's palette kernel may go
// beside the frame before it (no barrier between them) where the ring has
// another slot for that frame to read. The validation layer's
// synchronization checks, on for this runner, find no hazard within those
// command buffers with a ring of one slot (each palette kernel waits, and
// each frame for the one before) or of several, and the last frame read is
// its own clips' pose.
TEST(VulkanAnimatedFrames, FramesSharingACommandBufferHaveNoHazardWhateverTheRing) {
  if (!ValidationOn()) GTEST_SKIP() << "no validation layer to check synchronization with";
  setenv("VK_LAYER_ENABLES", "VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT", 1);
  VulkanRunner runner(0, true);
  unsetenv("VK_LAYER_ENABLES");
  constexpr int kInstances = 64;  // 128k vertices: frames queued faster than a CPU device runs them
  const char* key = "vulkan.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.nonormals";
  const Variant variant = ParseVariantKey(key);
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("2k-b4"));
  const PackedAnimation animation = PackAnimation(asset);
  const PackedMesh packed = Pack(asset.mesh, variant);
  const std::vector<KernelSource> kernels = EmitLaunchKernels(packed, kInstances);
  std::vector<std::uint8_t> rest;
  for (int k = 0; k < kInstances; ++k) rest.insert(rest.end(), packed.palette.begin(), packed.palette.end());
  for (int slots : {1, 2, 3}) {
    SCOPED_TRACE(std::to_string(slots) + " palette slots");
    const std::size_t messages = runner.validation_messages().size();
    Prepared live = runner.Prepare(packed, kernels, std::vector<std::vector<std::uint8_t>>{rest}, kInstances, slots);
    runner.Animate(live, 0, animation.View(), EmitPalette(Lang::kVulkan, animation.View(), 3));
    std::vector<AnimInstance> states(kInstances);
    for (int k = 0; k < kInstances; ++k) {
      states[static_cast<std::size_t>(k)].clip = 0;
      states[static_cast<std::size_t>(k)].time = 0.005f * static_cast<float>(k);  // within the clip after the frames
    }
    runner.WritePalette(live, 0, {reinterpret_cast<const std::uint8_t*>(states.data()), states.size() * sizeof(AnimInstance)});
    runner.LaunchSet(live, 0);
    (void)runner.ReadOutput(live, 0, Output::kPositions);  // built, uploaded, run once, idle
    const std::uint64_t before = runner.submissions();
    constexpr int kFrames = 12;
    for (int f = 0; f < kFrames; ++f) {
      runner.AdvanceAnimation(live, 0, 1.0f / 60.0f);
      runner.LaunchSet(live, 0);
    }
    if (slots > 1) {  // with one, each frame waits for the one before
      EXPECT_LT(runner.submissions() - before, static_cast<std::uint64_t>(kFrames)) << "no frames shared a command buffer";
    }
    const std::span<const std::uint8_t> positions = runner.ReadOutput(live, 0, Output::kPositions);
    for (int k : {0, kInstances - 1}) {
      AnimInstance advanced = states[static_cast<std::size_t>(k)];
      advanced.time += static_cast<float>(kFrames) / 60.0f;
      const GoldResult gold = SkinGold(QuantisedMesh(asset.mesh, variant), asset.skeleton.Palette(GoldPose(asset, animation, advanced)), false);
      const GoldComparison c = CompareToGold(gold.positions, UnpackInstance(packed, positions, k));
      EXPECT_EQ(c.non_finite, 0u) << "instance " << k;
      EXPECT_LT(c.max_relative, 1e-4) << "instance " << k << ", worst vertex " << c.worst_vertex;
    }
    const std::vector<std::string> all = runner.validation_messages();
    for (std::size_t m = messages; m < all.size(); ++m) ADD_FAILURE() << "validation: " << all[m];
  }
}

// K instances per launch, each against the gold of its own palette.
TEST_F(Validated, InstancesMatchTheGoldOfTheirPalettes) {
  const testing::Case cases[] = {
      {"vulkan.b2.padded.soa.float4.u16.f32.mat3x4.constant.matrix.v1c.wg64.normals", "b2"},
      {"vulkan.b4.bucketed.soa-split.float3.u8.unorm16.mat3x4.image.point.v2s.wg32.nonormals", "cesium"},
      {"vulkan.b3.padded.aos.float4.i32.f32.mat4.local.matrix.v4c.wg128.normals", "b3-random"},
  };
  for (const testing::InstanceCase& c : testing::WithInstanceCounts(cases)) {
    SCOPED_TRACE(std::string(c.key) + " x" + std::to_string(c.instances) + ", seed " + std::to_string(Seed()));
    testing::ExpectInstanceCaseMatchesGold(*runner_, c, vk::LimitsOf(runner_->info()));
  }
}

constexpr const char* kKey = "vulkan.b2.soa.float4.u16.f32.wg64";

TEST_F(Validated, PoisonedOutputCatchesAKernelThatSkipsVertices) {
  Faulty f = WithFault(kKey, "if (v >= n) break;", "if (v >= n / 2u) break;");
  ExpectHalfPoisoned(f, runner_->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant)));
}

TEST_F(Validated, GuardCatchesAKernelThatWritesPastTheEnd) {
  ExpectRunFails(*runner_,
                 WithFault(kKey, "STORE_POSITION(out_first + v, skinned_position);",
                           "STORE_POSITION(out_first + v + 64u, skinned_position);"),
                 "writing 64 vertices past the output was not caught",
                 {"Vulkan guard", "out_positions", "wrote past the end"});
}

TEST_F(Validated, BuildFailureCarriesTheLog) {
  Faulty f = WithFault(kKey, "float weight_of(uint raw) {", "float weight_of(uint raw) {\n  undeclared_name_xyz = 1;");
  ExpectRunFails(*runner_, f, "a kernel with an undeclared name built", {"Vulkan build", "undeclared_name_xyz"});
}

// The same text is a GL shader and a Vulkan one: VULKAN (predefined by
// glslang for Vulkan targets) selects the push-constant block.
TEST_F(Validated, TheComputeTemplateCompilesAloneAndInstanced) {
  for (const bool instanced : {false, true}) {
    KernelSource s;
    s.lang = Lang::kVulkan;
    s.entry_point = "main";
    s.text = ExpandedTemplate("skin.comp");
    if (instanced) s.text.insert(s.text.find('\n') + 1, "#define INSTANCED 1\n");
    s.source_hash = SourceHash(s.text);
    EXPECT_NO_THROW(runner_->Build(s)) << (instanced ? "instanced" : "plain");
  }
}

TEST_F(Validated, RejectsAGlslVertexKernelAndAConstantPaletteAboveTheLimit) {
  EXPECT_NE(testing::ErrorOf([&] { runner_->Build(Emit(ParseVariantKey("glsl-vertex.b2.v1c.wg0"), 0, 20)); })
                .find("Vulkan build"),
            std::string::npos);
  const std::uint32_t limit = runner_->info().limits.maxUniformBufferRange;
  const std::size_t instances = limit / (12 * 48) + 1;  // b2's 12 joints of mat3x4 (48 bytes)
  if (instances > runner_->info().limits.maxComputeWorkGroupCount[1] || instances > 100000)
    GTEST_SKIP() << "maxUniformBufferRange " << limit << " needs too many instances to exceed";
  const testing::InstancedRun run = testing::InstancedInputs(ParseVariantKey("vulkan.b2.soa.constant.wg64"), "b2",
                                                             static_cast<int>(instances));
  const std::string error = testing::ErrorOf([&] {
    runner_->RunInstanced(run.packed, static_cast<int>(instances), run.palette_bytes);
  });
  EXPECT_NE(error.find("maxUniformBufferRange"), std::string::npos) << error;
}

// Timestamps: per launch in Run, per burst in Time (instanced frames over two
// sets, so later frames reuse a set: barriers); the same-size copy, a correct
// copy, timed the same way.
TEST_F(Validated, TimesBurstsAndTheCopyKernel) {
  const InstancedRun run = InstancedInputs(ParseVariantKey("vulkan.b4.bucketed.soa.global.wg64"), "cesium", 3);
  const std::vector<KernelSource> kernels = EmitLaunchKernels(run.packed, 3);
  const std::vector<std::vector<std::uint8_t>> sets = {run.palette_bytes, run.palette_bytes};
  const Prepared prepared = runner_->Prepare(run.packed, kernels, sets, 3);
  EXPECT_EQ(prepared.input_sets(), 2);
  for (const int frames : {1, 4}) {
    const std::vector<double> ms = runner_->Time(prepared, 2, 5, frames);
    ASSERT_EQ(ms.size(), 5u) << frames << " frames per burst";
    for (const double t : ms) EXPECT_GT(t, 0.0);
  }
  const CopyKernel copy = EmitCopy(Lang::kVulkan, 1 << 20);
  EXPECT_EQ(copy.kernel.lang, Lang::kVulkan);
  const RunResult copied = runner_->Run(copy.mesh, std::span<const KernelSource>(&copy.kernel, 1));
  EXPECT_EQ(copied.poisoned_vertices, 0u);
  EXPECT_EQ(copied.positions, copy.mesh.launches[0].inputs[0].bytes);
  const Prepared copies = runner_->PrepareCopy(Lang::kVulkan, 1 << 20, 3);
  const std::vector<double> ms = runner_->Time(copies, 1, 3, 4);
  ASSERT_EQ(ms.size(), 3u);
  for (const double t : ms) EXPECT_GT(t, 0.0);
}

TEST_F(Validated, ProgramCacheStoresSpirvAndASecondRunnerLoadsIt) {
  const std::string dir = testing::ScratchDir("vulkan-cache").string();
  const KernelSource source = Emit(ParseVariantKey(kKey), 0, 20);
  ProgramCache first(dir);
  {
    VulkanRunner a(0, ValidationOn());
    a.UseProgramCache(&first, "vulkan:test");
    a.Build(source);
    a.Build(source);
  }
  EXPECT_EQ(first.counters().builds, 1);
  EXPECT_EQ(first.counters().memory_hits, 1);
  ProgramCache second(dir);
  VulkanRunner b(0, ValidationOn());
  b.UseProgramCache(&second, "vulkan:test");
  b.Build(source);
  EXPECT_EQ(second.counters().builds, 0);
  EXPECT_EQ(second.counters().disk_hits, 1);
}

TEST_F(Validated, IdentityNamesTheChipByUuid) {
  const DeviceIdentity id = vk::IdentityOf(runner_->info());
  EXPECT_EQ(id.backend, "vulkan");
  EXPECT_TRUE(id.uuid.empty() || std::regex_match(id.uuid, std::regex("[0-9a-f]{32}"))) << id.uuid;
  EXPECT_TRUE(id.pci_bus_id.empty() || std::regex_match(id.pci_bus_id, std::regex("[0-9a-f]{4}:[0-9a-f]{2}:[0-9a-f]{2}\\.[0-9a-f]")))
      << id.pci_bus_id;
  const DeviceLimits limits = vk::LimitsOf(runner_->info());
  EXPECT_GE(limits.max_wg_size, 128u);
  EXPECT_GE(limits.uniform_block_bytes, 16384u);
  EXPECT_GT(runner_->info().timestamp_valid_bits, 0u);
  if (id.type != "gpu") GTEST_SKIP() << "GPU-only: a GPU's Vulkan device has a UUID (here " << id.name << ", a " << id.type << ")";
  EXPECT_FALSE(id.uuid.empty());
}

// CI (lavapipe, a CPU device) must run under the validation layer; a GPU
// machine without the layer runs the same tests without it.
TEST_F(Validated, ValidationIsOnOnTheCpuDevice) {
  std::string error;
  try {
    VulkanRunner probe(0, true);
  } catch (const Error& e) {
    error = e.what();
  }
  if (runner_->info().type != "cpu" && ValidationLayerMissing(error))
    GTEST_SKIP() << "no validation layer on this GPU machine: " << error;
  EXPECT_EQ(error, "") << "the validation layer (vulkan-validationlayers) must be installed where CI runs";
}

TEST(VulkanRunnerSetup, AMissingDeviceIsAClearError) {
  const std::string error = testing::ErrorOf([] { VulkanRunner r(1000); });
  EXPECT_TRUE(error.rfind("Vulkan setup: ", 0) == 0) << error;
}

}  // namespace
}  // namespace skintune::internal
