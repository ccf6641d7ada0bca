// The Skinner's frame loop (runtime/runner.h "the palette ring") through the
// public API on every backend found here (OpenCL on PoCL, GL on llvmpipe,
// Vulkan on lavapipe; CUDA where a GPU is, skipped with the reason
// elsewhere): frames queued without Finish, each with its own palettes, read
// back at the end or every few frames, the caller's array reused at once,
// more frames than palette slots in flight, and rejected palettes that must
// not take a slot. Every read-back is compared with the float64 gold of the
// palettes of its frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <ostream>
#include <string>
#include <vector>

#include "model/gltf_import.h"
#include "runtime/runner.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::Floats;
using testing::TempDir;
using testing::Vec3s;
using testing::View;

constexpr int kInstances = 3;  // every frame skins K instances, each with its own pose

const SkinnedAsset& Cesium() {
  static const SkinnedAsset asset = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
  return asset;
}

// The K palettes of frame `frame`: instance k at its own phase of the clip,
// each frame a step further, so no two frames (nor instances) share a pose.
std::vector<std::vector<glm::mat4>> FramePoses(int frame) {
  const AnimationClip& clip = Cesium().animations.front();
  std::vector<std::vector<glm::mat4>> poses;
  for (int k = 0; k < kInstances; ++k) {
    const double phase = std::fmod((k + 0.5) / kInstances + 0.137 * frame, 1.0);
    poses.push_back(Cesium().PaletteAt(0, clip.start + (clip.end - clip.start) * phase));
  }
  return poses;
}

std::vector<float> Matrices(const std::vector<std::vector<glm::mat4>>& poses) {
  std::vector<float> out;
  for (const std::vector<glm::mat4>& p : poses) {
    const std::vector<float> f = Floats(p);
    out.insert(out.end(), f.begin(), f.end());
  }
  return out;
}

// What a run covers: a backend and a forced variant ("" = the built-in default).
struct FrameCase {
  Backend backend;
  std::string variant;
  bool submit_thread = false;  // DeviceOptions::submit_thread (CUDA and OpenCL)
  int palette_buffers = kDefaultPaletteBuffers;  // SkinnerOptions::palette_buffers
};

void PrintTo(const FrameCase& c, std::ostream* out) {
  *out << BackendName(c.backend) << " " << (c.variant.empty() ? "built-in default" : c.variant)
       << (c.submit_thread ? " with a submit thread" : "")
       << (c.palette_buffers != kDefaultPaletteBuffers ? ", " + std::to_string(c.palette_buffers) + " palette buffers" : "");
}

std::string CaseName(const ::testing::TestParamInfo<FrameCase>& info) {
  std::string name = std::string(BackendName(info.param.backend)) + "_" +
                     (info.param.variant.empty() ? "default" : info.param.variant) +
                     (info.param.submit_thread ? "_submit_thread" : "") +
                     (info.param.palette_buffers != kDefaultPaletteBuffers
                          ? "_" + std::to_string(info.param.palette_buffers) + "_buffers"
                          : "");
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
}

// Every backend with its languages' palette storages that hold K palettes:
// each storage binds the ring's slots its own way (CUDA's constant symbol is
// shared by every slot; GL and Vulkan pad the uniform block; images view
// each slot).
std::vector<FrameCase> Cases() {
  const struct {
    Backend backend;
    std::vector<std::string> langs;
  } kBackends[] = {{Backend::kOpenCl, {"opencl"}},
                   {Backend::kCuda, {"cuda"}},
                   {Backend::kGl, {"glsl-compute", "glsl-vertex"}},
                   {Backend::kVulkan, {"vulkan"}}};
  std::vector<FrameCase> cases;
  for (const auto& b : kBackends) {
    cases.push_back({b.backend, ""});
    // The shallowest ring (two palette buffers) and a deep one.
    for (int buffers : {2, 6}) cases.push_back({b.backend, "", false, buffers});
    for (const std::string& lang : b.langs)
      for (const char* storage : {"constant", "global", "image"}) cases.push_back({b.backend, lang + ".b4.soa." + storage});
  }
  // The frame's driver calls on the device's submit thread, where the API allows it.
  for (const auto& b : kBackends) {
    if (b.backend != Backend::kOpenCl && b.backend != Backend::kCuda) continue;
    cases.push_back({b.backend, "", true});
    cases.push_back({b.backend, "", true, 6});
    cases.push_back({b.backend, b.langs.front() + ".b4.soa.image", true});
  }
  return cases;
}

class SkinnerFrames : public ::testing::TestWithParam<FrameCase> {
 protected:
  void SetUp() override {
    const Backend backend = GetParam().backend;
    DeviceOptions device_options = CacheIn(dir_);
    device_options.submit_thread = GetParam().submit_thread;
    Result<Device> device = Device::Open("", &backend, device_options);
    if (!device.ok()) GTEST_SKIP() << "no " << BackendName(backend) << " device: " << device.status().message();
    device_ = std::move(*device);
    EXPECT_EQ(device_.info().submit_thread, GetParam().submit_thread);
    SkinnerOptions options;
    options.instances = kInstances;
    options.variant = GetParam().variant;
    options.palette_buffers = GetParam().palette_buffers;
    Result<Skinner> skinner = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    skinner_ = std::move(*skinner);
    variant_ = ParseVariantKey(skinner_.selection().variant);
    quantised_ = QuantisedMesh(Cesium().mesh, variant_);
  }

  void Set(const std::vector<float>& matrices) {
    const Status set = skinner_.SetPalette(matrices.data(), matrices.size());
    ASSERT_TRUE(set.ok()) << set.message();
  }
  void Skin() {
    const Status skinned = skinner_.Skin();
    ASSERT_TRUE(skinned.ok()) << skinned.message();
  }

  // Reads the positions back and expects instance k to be the gold of poses[k].
  void ExpectReadIsTheGoldOf(const std::vector<std::vector<glm::mat4>>& poses, const std::string& what) {
    SCOPED_TRACE(what + ", " + variant_.Key());
    const std::size_t n = Cesium().mesh.vertex_count();
    std::vector<float> positions(kInstances * n * 3);
    const Status read = skinner_.ReadPositions(positions.data(), positions.size());
    ASSERT_TRUE(read.ok()) << read.message();
    for (std::size_t k = 0; k < poses.size(); ++k) {
      const GoldResult gold = SkinGold(quantised_, poses[k], false);
      const std::vector<float> part(positions.begin() + static_cast<std::ptrdiff_t>(k * n * 3),
                                    positions.begin() + static_cast<std::ptrdiff_t>((k + 1) * n * 3));
      const GoldComparison c = CompareToGold(gold.positions, Vec3s(part));
      EXPECT_EQ(c.non_finite, 0u) << "instance " << k;
      EXPECT_LT(c.max_relative, 1e-5) << "instance " << k << ", worst vertex " << c.worst_vertex;
    }
  }

  // The ring's depth the frame counts below go round: this case's palette
  // buffers, never fewer than the default ring's.
  static int Slots() { return std::max(kPaletteSlots, GetParam().palette_buffers); }

  TempDir dir_;
  View view_{Cesium().mesh};
  Device device_;
  Skinner skinner_;
  Variant variant_;
  SkinnedMesh quantised_;
};

TEST_P(SkinnerFrames, FramesQueuedWithoutFinishEndWithTheLastFramesGold) {
  const int kFrames = 4 * Slots() + 2;
  for (int f = 0; f < kFrames; ++f) {
    Set(Matrices(FramePoses(f)));
    Skin();
  }
  ExpectReadIsTheGoldOf(FramePoses(kFrames - 1), "after " + std::to_string(kFrames) + " frames");
}

TEST_P(SkinnerFrames, AReadEveryFewFramesIsThatFramesGold) {
  // Every fourth frame: the reads land on every slot of the ring in turn.
  const int kEvery = Slots() + 1;
  for (int f = 0; f < 4 * kEvery; ++f) {
    Set(Matrices(FramePoses(f)));
    Skin();
    if (f % kEvery == kEvery - 1) ExpectReadIsTheGoldOf(FramePoses(f), "frame " + std::to_string(f));
  }
}

TEST_P(SkinnerFrames, TheCallersArrayIsFreeRightAfterSetPalette) {
  // One array for every frame, as an animation system keeps it: overwritten
  // with the next frame's palettes before this frame's Skin, and with a
  // pose no frame has after the last.
  std::vector<float> matrices = Matrices(FramePoses(0));
  const int kFrames = 2 * Slots() + 1;
  for (int f = 0; f < kFrames; ++f) {
    Set(matrices);
    matrices = Matrices(FramePoses(f + 1));
    Skin();
  }
  std::fill(matrices.begin(), matrices.end(), 0.0f);
  ExpectReadIsTheGoldOf(FramePoses(kFrames - 1), "the array zeroed after the last SetPalette");
}

TEST_P(SkinnerFrames, MoreFramesInFlightThanPaletteSlotsIncludingRepeatedCalls) {
  // Frames that call Skin twice, and palettes replaced before any Skin read
  // them: each Skin uses the last palettes set.
  std::vector<std::vector<glm::mat4>> last;
  for (int f = 0; f < 5 * Slots(); ++f) {
    if (f % 4 == 1) Set(Matrices(FramePoses(f + 100)));  // replaced at once, never skinned
    last = FramePoses(f);
    Set(Matrices(last));
    Skin();
    if (f % 3 == 2) Skin();
  }
  ExpectReadIsTheGoldOf(last, "after 5 x slots frames");
  ASSERT_TRUE(skinner_.Finish().ok());
  ExpectReadIsTheGoldOf(last, "after Finish, read again");
}

TEST_P(SkinnerFrames, ARejectedPaletteTakesNoSlot) {
  const std::vector<std::vector<glm::mat4>> good = FramePoses(3);
  Set(Matrices(good));
  Skin();
  std::vector<float> bad = Matrices(FramePoses(4));
  bad[5] = std::numeric_limits<float>::quiet_NaN();
  for (int i = 0; i < Slots() + 1; ++i) {
    const Status nan = skinner_.SetPalette(bad.data(), bad.size());
    EXPECT_EQ(nan.code(), ErrorCode::kInvalidArgument) << nan.message();
    const Status short_array = skinner_.SetPalette(bad.data(), bad.size() - 16);
    EXPECT_EQ(short_array.code(), ErrorCode::kInvalidArgument) << short_array.message();
    Skin();  // still the good palettes
  }
  ExpectReadIsTheGoldOf(good, "after rejected palettes");
}

TEST_P(SkinnerFrames, TwoSkinnersOnOneDeviceInterleaveTheirFrames) {
  // The second Skinner's frames are queued between the first's SetPalette and
  // Skin: each skins with its own palettes (a palette staged for one is never
  // uploaded by, nor lost in, the other's frame).
  SkinnerOptions options;
  options.instances = kInstances;
  options.variant = GetParam().variant;
  options.palette_buffers = GetParam().palette_buffers;
  Result<Skinner> second = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, options);
  ASSERT_TRUE(second.ok()) << second.status().message();
  for (int f = 0; f < 2 * Slots() + 1; ++f) {
    Set(Matrices(FramePoses(f)));
    const std::vector<float> other = Matrices(FramePoses(f + 50));
    ASSERT_TRUE(second->SetPalette(other.data(), other.size()).ok());
    ASSERT_TRUE(second->Skin().ok());
    Skin();
  }
  ExpectReadIsTheGoldOf(FramePoses(2 * Slots()), "the first Skinner");
  std::swap(skinner_, *second);
  ExpectReadIsTheGoldOf(FramePoses(2 * Slots() + 50), "the second Skinner");
}

INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinnerFrames, ::testing::ValuesIn(Cases()), CaseName);

}  // namespace
}  // namespace skintune::internal
