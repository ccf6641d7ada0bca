// Animation on the device through the public API, on every backend found
// here (OpenCL on PoCL, GL on llvmpipe, Vulkan on lavapipe, the cpu device;
// CUDA and the NVIDIA APIs on a GPU machine): Skinner::CreateAnimated packs a
// glTF model's animations once, SetAnimation uploads each instance's clips,
// times and blend weight, and Skin runs the palette kernel before the skin
// kernel. Each instance's output is checked against the float64 gold skinned
// with the float64 reference palette of its (blended) pose, in palette
// storages and formats of every kind; the misuses are errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "generator/variant.h"
#include "runtime/selection.h"
#include "skintune/skintune.h"
#include "tests/common/test_asset.h"
#include "tests/generator/palette_gold.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::GoldPose;
using testing::TempDir;
using testing::TestAsset;

// Positions within this of the gold, relative to the bounding-box diagonal:
// the skin kernels' 1e-5 plus the float32 palette kernel's own error (its
// bound: 1e-5 of each joint's scale, docs/ANIMATION.md).
constexpr double kTolerance = 2e-5;

struct AnimatedCase {
  Backend backend;
  std::string variant;  // forced
  std::string model;    // a glTF of tests/data
  double bake_rate = 0.0;  // SkinnerOptions::bake_rate: 0 sampled clips
  skintune::BakeSpace bake_space = skintune::BakeSpace::kPalette;  // SkinnerOptions::bake_space
  bool fused = false;  // SkinnerOptions::fuse_palette: the palettes made in the skin launch
};
bool BakedLocally(const AnimatedCase& c) { return c.bake_rate > 0.0 && c.bake_space == skintune::BakeSpace::kLocal; }
bool BakedHybrid(const AnimatedCase& c) { return c.bake_rate > 0.0 && c.bake_space == skintune::BakeSpace::kHybrid; }
void PrintTo(const AnimatedCase& c, std::ostream* out) {
  *out << c.variant << " " << c.model
       << (BakedHybrid(c) ? " baked hybrid" : BakedLocally(c) ? " baked locally" : c.bake_rate > 0.0 ? " baked" : "")
       << (c.fused ? ", fused" : "");
}

class SkinnerAnimated : public testing::BackendFixture<AnimatedCase> {
 protected:
  void SetUp() override {
    BackendFixture::SetUp();
    if (IsSkipped()) return;
    Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/" + GetParam().model);
    ASSERT_TRUE(model.ok()) << model.status().message();
    model_ = std::move(*model);
  }
  const SkinnedAsset& Asset() const { return TestAsset(GetParam().model); }
  static SkinnerOptions Options() {
    SkinnerOptions options;
    options.variant = GetParam().variant;
    options.bake_rate = GetParam().bake_rate;
    options.bake_space = GetParam().bake_space;
    options.fuse_palette = GetParam().fused;
    return options;
  }

  // Instance k: clip k % clips at its own phase; every third a blend of two
  // clips; the last the rest pose.
  std::vector<AnimationState> Crowd(int instances, double phase) const {
    std::vector<AnimationState> states(static_cast<std::size_t>(instances));
    const int clips = model_.animation_count();
    for (int k = 0; k < instances; ++k) {
      AnimationState& s = states[static_cast<std::size_t>(k)];
      if (k + 1 == instances) break;  // the rest pose
      const int a = k % clips, b = (k + 1) % clips;
      const double u = std::fmod(phase + 0.37 * k, 1.0);
      s.animation = a;
      s.time = static_cast<float>(model_.animation_start(a) + u * model_.animation_duration(a));
      if (k % 3 == 2) {
        s.animation2 = b;
        s.time2 = static_cast<float>(model_.animation_start(b) + (1.0 - u) * model_.animation_duration(b));
        s.weight = 0.35f;
      }
    }
    return states;
  }

  // The AnimInstance the device makes of a state (SetAnimation's mapping).
  static AnimInstance InstanceOf(const AnimationState& s) {
    return {s.animation < 0 ? kAnimRestPose : static_cast<std::uint16_t>(s.animation),
            s.animation2 < 0 || s.weight == 0.0f ? kAnimRestPose : static_cast<std::uint16_t>(s.animation2), s.time,
            s.time2, s.weight};
  }

  // Five instances and a ring of two: frames queued behind the last fill it.
  static SkinnerOptions AdvancingOptions() {
    SkinnerOptions options = Options();
    options.instances = 5;
    options.palette_buffers = 2;
    return options;
  }
  static std::vector<AnimInstance> InstancesOf(const std::vector<AnimationState>& states) {
    std::vector<AnimInstance> instances;
    for (const AnimationState& s : states) instances.push_back(InstanceOf(s));
    return instances;
  }
  // `expected` after a frame's AdvanceAnimation(delta), `total` the deltas
  // since `start` was set: a palette kernel advances each clock by each delta
  // (in float32, as AdvanceAnimInstances does); a fused Skinner's launches add
  // the deltas' sum to the clocks set (docs/ANIMATION.md "The palette in the
  // skin launch").
  static void Advance(const PackedAnimation& packed, std::vector<AnimInstance>& expected,
                      const std::vector<AnimationState>& start, float delta, double& total) {
    total += delta;
    if (!GetParam().fused) {
      AdvanceAnimInstances(packed.View(), expected, delta);
      return;
    }
    expected = InstancesOf(start);
    AdvanceAnimInstances(packed.View(), expected, static_cast<float>(total));
  }
  double LongestClip() const {
    double longest = 0.0;
    for (int a = 0; a < model_.animation_count(); ++a) longest = std::max(longest, model_.animation_duration(a));
    return longest;
  }

  // Skins `states` and expects instance k to be the gold of its pose.
  void ExpectLikeTheGold(Skinner& skinner, const std::vector<AnimationState>& states) {
    const Status set = skinner.SetAnimation(states.data(), states.size());
    ASSERT_TRUE(set.ok()) << set.message();
    const Status skinned = skinner.Skin();
    ASSERT_TRUE(skinned.ok()) << skinned.message();
    std::vector<AnimInstance> expected;
    for (const AnimationState& s : states) expected.push_back(InstanceOf(s));
    ExpectSkinnedAs(skinner, expected);
  }

  // Expects the last Skin's instance k to be the gold of `expected[k]`'s pose.
  void ExpectSkinnedAs(Skinner& skinner, const std::vector<AnimInstance>& expected) {
    const Variant variant = ParseVariantKey(skinner.selection().variant);
    const SkinnedMesh& mesh = Asset().mesh;
    const std::size_t n = mesh.vertex_count();
    std::vector<float> positions(expected.size() * n * 3);
    const Status read = skinner.ReadPositions(positions.data(), positions.size());
    ASSERT_TRUE(read.ok()) << read.message();
    const PackedAnimation packed = PackAnimation(Asset());
    const double rate = GetParam().bake_rate;
    const internal::BakeSpace space = BakedHybrid(GetParam())    ? internal::BakeSpace::kHybrid
                                      : BakedLocally(GetParam()) ? internal::BakeSpace::kLocal
                                                                 : internal::BakeSpace::kPalette;
    const PackedAnimation baked = rate > 0.0 ? BakeAnimation(Asset(), rate, space) : PackedAnimation{};
    const SkinnedMesh quantised = QuantisedMesh(mesh, variant);
    for (std::size_t k = 0; k < expected.size(); ++k) {
      const AnimInstance& in = expected[k];
      // Baked clips: the float64 evaluation of their frames (how far that is
      // from the sampled gold is BakedClipInfo's, tested with the kernels).
      std::vector<glm::mat4> palette;
      if (rate > 0.0) {
        for (const glm::dmat4& m : testing::BakedGoldPaletteOf(Asset(), baked, in)) palette.emplace_back(m);
      } else {
        palette = Asset().skeleton.Palette(GoldPose(Asset(), packed, in));
      }
      const GoldResult gold = SkinGold(quantised, palette, false);
      const std::vector<float> part(positions.begin() + static_cast<std::ptrdiff_t>(k * n * 3),
                                    positions.begin() + static_cast<std::ptrdiff_t>((k + 1) * n * 3));
      const GoldComparison p = CompareToGold(gold.positions, testing::Vec3s(part));
      EXPECT_EQ(p.non_finite, 0u) << variant.Key() << " instance " << k;
      EXPECT_LT(p.max_relative, kTolerance)
          << variant.Key() << " instance " << k << " (clip " << in.clip << " t=" << in.time << ", clip2 " << in.clip2
          << " t2=" << in.time2 << " w=" << in.weight << "): worst vertex " << p.worst_vertex;
    }
  }

  Model model_;
};

TEST_P(SkinnerAnimated, EveryInstanceIsTheGoldOfItsOwnClipsTimesAndBlend) {
  SkinnerOptions options = Options();
  options.instances = 7;
  Result<Skinner> skinner = Skinner::CreateAnimated(device_, WinnersDb::Empty(), model_, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  EXPECT_TRUE(skinner->animated());
  const std::vector<BakedClip> clips = skinner->baked_clips();
  if (GetParam().bake_rate > 0.0) {
    ASSERT_EQ(clips.size(), static_cast<std::size_t>(model_.animation_count()));
    std::size_t bytes = 0;
    for (std::size_t c = 0; c < clips.size(); ++c) {
      EXPECT_EQ(clips[c].name, model_.animation_name(static_cast<int>(c)));
      EXPECT_GE(clips[c].frames, 2);
      EXPECT_GT(clips[c].max_error, 0.0);
      bytes += clips[c].bytes;
    }
    EXPECT_GT(skinner->animation_bytes(), bytes);  // and the rest pose's frame, and the clips' ranges
  } else {
    EXPECT_TRUE(clips.empty());
    EXPECT_GT(skinner->animation_bytes(), 0u);
  }
  for (double phase : {0.1, 0.6}) {
    SCOPED_TRACE("phase " + std::to_string(phase));
    ExpectLikeTheGold(*skinner, Crowd(options.instances, phase));
  }
  // One character alone: the kernel that is not instanced reads its one state.
  options.instances = 1;
  Result<Skinner> alone = Skinner::CreateAnimated(device_, WinnersDb::Empty(), model_, options);
  ASSERT_TRUE(alone.ok()) << alone.status().message();
  std::vector<AnimationState> one = Crowd(2, 0.3);
  one.resize(1);
  SCOPED_TRACE("one instance");
  ExpectLikeTheGold(*alone, one);
}

TEST_P(SkinnerAnimated, FramesInFlightEachKeepTheirOwnStates) {
  // More frames than palette buffers queued before one read: the ring's slots
  // each carry their own instances, and the last frame's are read.
  SkinnerOptions options;
  options.instances = 3;
  options.palette_buffers = 2;
  options.variant = GetParam().variant;
  options.bake_rate = GetParam().bake_rate;
  options.bake_space = GetParam().bake_space;
  Result<Skinner> skinner = Skinner::CreateAnimated(device_, WinnersDb::Empty(), model_, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  for (int frame = 0; frame < 5; ++frame) {
    const std::vector<AnimationState> states = Crowd(options.instances, 0.2 * frame);
    ASSERT_TRUE(skinner->SetAnimation(states.data(), states.size()).ok());
    ASSERT_TRUE(skinner->Skin().ok());
  }
  ExpectLikeTheGold(*skinner, Crowd(options.instances, 0.9));
}

// AdvanceAnimation: the clocks move on the device, nothing uploaded, each
// looping in its clip's range, frame after frame with the ring full; as
// AdvanceAnimInstances computes it on the host.
TEST_P(SkinnerAnimated, AdvanceAnimationMovesEveryClockOnTheDeviceAndLoopsEachClip) {
  SkinnerOptions options = AdvancingOptions();
  Result<Skinner> skinner = Skinner::CreateAnimated(device_, WinnersDb::Empty(), model_, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  const std::vector<AnimationState> start = Crowd(options.instances, 0.8);
  ExpectLikeTheGold(*skinner, start);
  std::vector<AnimInstance> expected = InstancesOf(start);
  const PackedAnimation packed = PackAnimation(Asset());
  const double longest = LongestClip();
  // Steps of a third of the longest clip: every clip wraps within the five frames, and one step goes back.
  double total = 0.0;
  for (const double step : {1.0 / 3, 1.0 / 3, -0.25, 1.0 / 3, 1.0 / 3}) {
    const auto delta = static_cast<float>(step * longest);
    const Status advanced = skinner->AdvanceAnimation(delta);
    ASSERT_TRUE(advanced.ok()) << advanced.message();
    ASSERT_TRUE(skinner->Skin().ok());
    Advance(packed, expected, start, delta, total);
  }
  SCOPED_TRACE("after five steps");
  ExpectSkinnedAs(*skinner, expected);
  for (std::size_t k = 0; k + 1 < expected.size(); ++k) {  // every clock stayed in its clip's range
    const AnimInstance& in = expected[k];
    EXPECT_GE(in.time, model_.animation_start(in.clip)) << "instance " << k;
    EXPECT_LE(in.time, model_.animation_start(in.clip) + model_.animation_duration(in.clip) + 1e-4) << "instance " << k;
  }
  // A Skin with no new frame repeats the last one; a state set again starts from it.
  ASSERT_TRUE(skinner->Skin().ok());
  ExpectSkinnedAs(*skinner, expected);
  ExpectLikeTheGold(*skinner, start);

  EXPECT_EQ(skinner->AdvanceAnimation(std::numeric_limits<float>::infinity()).code(), ErrorCode::kInvalidArgument);
  options.bake_rate = 0.0;  // a Skinner of SetPalette bakes nothing (BadStates... checks the refusal)
  options.bake_space = skintune::BakeSpace::kPalette;
  options.fuse_palette = false;
  Result<Skinner> plain = Skinner::Create(device_, WinnersDb::Empty(), model_.mesh(), options);
  ASSERT_TRUE(plain.ok()) << plain.status().message();
  EXPECT_EQ(plain->AdvanceAnimation(0.1f).code(), ErrorCode::kInvalidState);
}

// Frames advanced on the device, some waited for and some queued behind the
// last: where an API runs the palette kernel beside the frame before (OpenCL's
// second queue while the device is busy) or on the frame's own queue (when it
// is idle), every frame's kernel still starts from the states the one before
// left. Without the second queue's wait for a palette kernel queued on the
// first, this test failed on PoCL in 9 of 20 runs (2026-11-30).
TEST_P(SkinnerAnimated, FramesWaitedForAndQueuedInTurnEachAdvanceFromTheLast) {
  const SkinnerOptions options = AdvancingOptions();
  Result<Skinner> skinner = Skinner::CreateAnimated(device_, WinnersDb::Empty(), model_, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  const std::vector<AnimationState> start = Crowd(options.instances, 0.3);
  ExpectLikeTheGold(*skinner, start);
  std::vector<AnimInstance> expected = InstancesOf(start);
  const PackedAnimation packed = PackAnimation(Asset());
  const auto delta = static_cast<float>(LongestClip() / 7.0);
  double total = 0.0;
  for (int round = 0; round < 12; ++round) {  // each round: one frame on an idle device, two behind a busy one
    ASSERT_TRUE(skinner->Finish().ok());
    for (int frame = 0; frame < 3; ++frame) {
      ASSERT_TRUE(skinner->AdvanceAnimation(delta).ok());
      ASSERT_TRUE(skinner->Skin().ok());
      Advance(packed, expected, start, delta, total);
    }
    SCOPED_TRACE("round " + std::to_string(round));
    ExpectSkinnedAs(*skinner, expected);
  }
}

TEST_P(SkinnerAnimated, TheRestPoseUntilTheFirstSetAnimation) {
  SkinnerOptions options;
  options.instances = 2;
  options.variant = GetParam().variant;
  options.bake_rate = GetParam().bake_rate;
  options.bake_space = GetParam().bake_space;
  Result<Skinner> skinner = Skinner::CreateAnimated(device_, WinnersDb::Empty(), model_, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  ASSERT_TRUE(skinner->Skin().ok());
  const std::size_t n = model_.vertex_count();
  std::vector<float> positions(2 * n * 3);
  ASSERT_TRUE(skinner->ReadPositions(positions.data(), positions.size()).ok());
  std::vector<float> rest;
  ASSERT_TRUE(model_.Palette(-1, 0.0, &rest).ok());
  std::vector<float> gold;
  ASSERT_TRUE(model_.SkinReference(rest.data(), rest.size(), &gold).ok());
  double diagonal = 0.0, worst = 0.0;
  for (std::size_t i = 0; i < gold.size(); ++i) diagonal = std::max(diagonal, std::abs(static_cast<double>(gold[i])));
  for (std::size_t i = 0; i < positions.size(); ++i)
    worst = std::max(worst, std::abs(static_cast<double>(positions[i]) - gold[i % gold.size()]));
  EXPECT_LT(worst, kTolerance * 4.0 * diagonal) << "the rest pose, largest |coordinate| " << diagonal;
}

TEST_P(SkinnerAnimated, BadStatesAreRejectedNamingTheFieldAndChangeNothing) {
  SkinnerOptions options;
  options.instances = 2;
  options.variant = GetParam().variant;
  options.bake_rate = GetParam().bake_rate;
  options.bake_space = GetParam().bake_space;
  Result<Skinner> skinner = Skinner::CreateAnimated(device_, WinnersDb::Empty(), model_, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  const std::vector<AnimationState> good = Crowd(2, 0.3);
  const auto expect_bad = [&](std::vector<AnimationState> states, std::size_t count, const std::string& says) {
    const Status s = skinner->SetAnimation(states.data(), count);
    EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument) << says;
    EXPECT_NE(s.message().find(says), std::string::npos) << s.message();
  };
  std::vector<AnimationState> bad = good;
  bad[1].animation = model_.animation_count();
  expect_bad(bad, 2, "states[1].animation is " + std::to_string(model_.animation_count()));
  bad = good;
  bad[0].weight = 0.5f;
  bad[0].animation2 = -2;
  expect_bad(bad, 2, "states[0].animation2 is -2");
  bad = good;
  bad[0].time = std::numeric_limits<float>::quiet_NaN();
  expect_bad(bad, 2, "states[0].time is not finite");
  bad = good;
  bad[1].weight = 1.5f;
  expect_bad(bad, 2, "states[1].weight");
  expect_bad(good, 1, "SetAnimation");
  EXPECT_EQ(skinner->SetAnimation(nullptr, 2).code(), ErrorCode::kInvalidArgument);
  // The rejected frames took no slot and changed nothing: the good one is skinned.
  ExpectLikeTheGold(*skinner, good);

  const std::vector<float> palette(static_cast<std::size_t>(2 * model_.joint_count() * 16), 0.0f);
  const Status set_palette = skinner->SetPalette(palette.data(), palette.size());
  EXPECT_EQ(set_palette.code(), ErrorCode::kInvalidState);
  EXPECT_NE(set_palette.message().find("SetAnimation"), std::string::npos) << set_palette.message();

  if (options.bake_rate > 0.0) {  // a Skinner of SetPalette bakes nothing: the option is refused, not ignored
    const Result<Skinner> refused = Skinner::Create(device_, WinnersDb::Empty(), model_.mesh(), options);
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.status().message().find("SkinnerOptions::bake_rate"), std::string::npos)
        << refused.status().message();
    options.bake_rate = 0.0;
  }
  if (options.bake_space != skintune::BakeSpace::kPalette) {  // nor a space
    const Result<Skinner> refused = Skinner::Create(device_, WinnersDb::Empty(), model_.mesh(), options);
    ASSERT_FALSE(refused.ok());
    EXPECT_NE(refused.status().message().find("SkinnerOptions::bake_space"), std::string::npos)
        << refused.status().message();
    options.bake_space = skintune::BakeSpace::kPalette;
  }
  {  // nor whether a crowd cross-fades
    SkinnerOptions fades = options;
    fades.cross_fades = false;
    const Result<Skinner> refused = Skinner::Create(device_, WinnersDb::Empty(), model_.mesh(), fades);
    ASSERT_FALSE(refused.ok());
    EXPECT_NE(refused.status().message().find("SkinnerOptions::cross_fades"), std::string::npos)
        << refused.status().message();
  }
  Result<Skinner> plain = Skinner::Create(device_, WinnersDb::Empty(), model_.mesh(), options);
  ASSERT_TRUE(plain.ok()) << plain.status().message();
  EXPECT_FALSE(plain->animated());
  EXPECT_EQ(plain->SetAnimation(good.data(), good.size()).code(), ErrorCode::kInvalidState);
}

TEST(SkinnerAnimatedModel, ABakeRateOutsideItsRangeIsRefusedNamingIt) {
  Result<Device> device = Device::Open("", nullptr);
  if (!device.ok()) GTEST_SKIP() << "no device: " << device.status().message();
  Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/Fox.gltf");
  ASSERT_TRUE(model.ok()) << model.status().message();
  for (const double rate : {-0.5, -2.0, 1001.0, std::numeric_limits<double>::quiet_NaN()}) {
    SkinnerOptions options;
    options.bake_rate = rate;
    const Result<Skinner> skinner = Skinner::CreateAnimated(*device, WinnersDb::Empty(), *model, options);
    ASSERT_FALSE(skinner.ok()) << rate;
    EXPECT_EQ(skinner.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(skinner.status().message().find("SkinnerOptions::bake_rate is"), std::string::npos)
        << skinner.status().message();
  }
  // A space is what a rate bakes: with nothing baked, or the tuned entry deciding, it is refused, not ignored.
  for (const double rate : {0.0, kBakeRateTuned}) {
    for (const auto& [space, name] : {std::pair{skintune::BakeSpace::kLocal, "kLocal"},
                                      std::pair{skintune::BakeSpace::kHybrid, "kHybrid"}}) {
      SkinnerOptions options;
      options.bake_rate = rate;
      options.bake_space = space;
      const Result<Skinner> skinner = Skinner::CreateAnimated(*device, WinnersDb::Empty(), *model, options);
      ASSERT_FALSE(skinner.ok()) << rate;
      EXPECT_EQ(skinner.status().code(), ErrorCode::kInvalidArgument);
      EXPECT_NE(skinner.status().message().find(std::string("SkinnerOptions::bake_space ") + name +
                                                " bakes clips at SkinnerOptions::bake_rate"),
                std::string::npos)
          << skinner.status().message();
    }
  }
  SkinnerOptions bad_space;
  bad_space.bake_rate = 30.0;
  bad_space.bake_space = static_cast<skintune::BakeSpace>(7);
  EXPECT_NE(Skinner::CreateAnimated(*device, WinnersDb::Empty(), *model, bad_space)
                .status().message().find("SkinnerOptions::bake_space is 7, not a BakeSpace"),
            std::string::npos);
}

// fuse_palette makes the palettes from baked records in the skin launch:
// with sampled clips or a form the tuned entry decides, or where no launch has a local copy to
// make them in, it is refused, naming why; nothing is made.
TEST(SkinnerAnimatedModel, FusingThePaletteIsRefusedWhereItCannotBeDone) {
  Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/Fox.gltf");
  ASSERT_TRUE(model.ok()) << model.status().message();
  const auto refused = [&](Device& device, SkinnerOptions options, const std::string& expected) {
    options.fuse_palette = true;
    const Result<Skinner> skinner = Skinner::CreateAnimated(device, WinnersDb::Empty(), *model, options);
    ASSERT_FALSE(skinner.ok()) << expected;
    EXPECT_EQ(skinner.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(skinner.status().message().find(expected), std::string::npos) << skinner.status().message();
  };
  const Backend cpu_backend = Backend::kCpu, opencl_backend = Backend::kOpenCl;
  Result<Device> cpu = Device::Open("", &cpu_backend);
  ASSERT_TRUE(cpu.ok()) << cpu.status().message();
  SkinnerOptions options;
  refused(*cpu, options, "bake_rate is 0.000000 (sampled)");
  options.bake_rate = kBakeRateTuned;
  refused(*cpu, options, "bake_rate is kBakeRateTuned (the tuned entry's form decides)");
  options.bake_rate = 60.0;
  for (const skintune::BakeSpace space :
       {skintune::BakeSpace::kPalette, skintune::BakeSpace::kLocal, skintune::BakeSpace::kHybrid}) {
    options.bake_space = space;  // every bake space's records can be fused, but not on the cpu device
    refused(*cpu, options, "the cpu device runs its palette kernel as a call");
  }
  SkinnerOptions host;
  host.fuse_palette = true;
  Result<Skinner> plain = Skinner::Create(*cpu, WinnersDb::Empty(), model->mesh(), host);
  ASSERT_FALSE(plain.ok());
  EXPECT_NE(plain.status().message().find("Skinner::Create: SkinnerOptions::fuse_palette"), std::string::npos)
      << plain.status().message();
  Result<Device> opencl = Device::Open("", &opencl_backend);
  if (!opencl.ok()) GTEST_SKIP() << "no OpenCL device: " << opencl.status().message();
  // Where nothing was tuned fused, the group makes its palette for many vertices (storage local, 8 an item,
  // strided), as 3x4 rows where the built-in default's palette is a mat4.
  SkinnerOptions untuned;
  untuned.bake_rate = 60.0;
  untuned.fuse_palette = true;
  const Result<Skinner> made = Skinner::CreateAnimated(*opencl, WinnersDb::Empty(), *model, untuned);
  ASSERT_TRUE(made.ok()) << made.status().message();
  const Variant fused = ParseVariantKey(made->selection().variant);
  EXPECT_EQ(fused.storage, PaletteStorage::kLocal);
  EXPECT_EQ(fused.wg_size * fused.vertices_per_item, 2048) << made->selection().variant;
  EXPECT_EQ(fused.assignment, Assignment::kStrided) << made->selection().variant;
  EXPECT_EQ(fused.palette, PaletteFormat::kMat3x4) << made->selection().variant;
  EXPECT_NE(made->selection().reason.find("each group makes its palette once"), std::string::npos)
      << made->selection().reason;
  options.variant = "opencl.b4.soa.dualquat.dq";
  options.dual_quaternions = true;
  refused(*opencl, options, "SkinnerOptions::dual_quaternions");
}

// kBakeRateTuned: the palette kernel's form is the chosen entry's, tuned on a
// scene animated on the device (docs/TUNING.md "Animated scenes"): baked at
// its rate, or sampled; sampled from an entry tuned with the host's palettes.
// Palette records tuned on a crowd that does not cross-fade serve only a
// Skinner whose crowd does not (SkinnerOptions::cross_fades false), which
// then refuses a blend.
TEST(SkinnerAnimatedModel, TheWinnersDatabaseDecidesThePaletteKernelsFormWhenAsked) {
  Result<Device> device = Device::Open("", nullptr);
  if (!device.ok()) GTEST_SKIP() << "no device: " << device.status().message();
  Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/Fox.gltf");
  ASSERT_TRUE(model.ok()) << model.status().message();
  const DeviceInfo& info = device->info();
  const std::string lang = std::string(Name(LanguagesOf(info.backend).front()));
  const auto database = [&](const std::string& form, bool cross_fades = false, const std::string& storage = "global") {
    const std::string key = lang + ".b4.padded.soa.float4.u16.f32.mat3x4." + storage + ".matrix.v1c." +
                            (lang == "cpu" || lang == "glsl-vertex" ? "wg0" : "wg64") + form;
    nlohmann::json entry = {{"device_id", info.id}, {"backend", BackendName(info.backend)}, {"platform", info.platform},
                            {"vendor", info.vendor}, {"device_name", info.name}, {"driver_version", info.driver_version},
                            {"device_type", info.type}, {"lang", lang}, {"influences", 4}, {"vertices", 10368},
                            {"vertex_bucket", "25k"}, {"shape", "instances"}, {"instances", 6}, {"meshes", 1},
                            {"dataset", "Fox.gltf-x6-anim"}, {"median_ms", 0.05}, {"gbps", 10.0}, {"copy_fraction", 0.5},
                            {"created", "2026-11-30T08:00:00Z"}, {"source", "animated-crowds (coordinate)"},
                            {"source_error", {{"diagonal", 1.0}, {"position_abs", 5e-5}, {"position_rel", 5e-5},  // baking's loss
                                              {"normal_abs", 0.0}, {"quantisation_rel", 5e-5}}},
                            {"max_relative_error", 3e-7}, {"variant", ParseVariantKey(key)},
                            {"cross_fades", cross_fades}};
    const nlohmann::json db = {{"schema_version", "1.10.0"}, {"kind", "skintune-winners-db"}, {"entries", {entry}}};
    Result<WinnersDb> parsed = WinnersDb::Parse(db.dump(), "test database");
    EXPECT_TRUE(parsed.ok()) << parsed.status().message();
    return parsed.ok() ? std::move(*parsed) : WinnersDb::Empty();
  };
  SkinnerOptions options;
  options.instances = 6;
  options.bake_rate = kBakeRateTuned;
  {  // a crowd that cross-fades (the default) is not given palette records tuned without blends
    const Result<Skinner> skinner = Skinner::CreateAnimated(*device, database(".anim-baked60"), *model, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_EQ(skinner->selection().level, MatchLevel::kGenericDefault) << skinner->selection().reason;
    EXPECT_TRUE(skinner->baked_clips().empty());
    EXPECT_NE(skinner->selection().reason.find("palette records baked for a crowd that does not cross-fade clips"),
              std::string::npos)
        << skinner->selection().reason;
    // Tuned on a crowd that cross-fades, its recorded error holds the blends: taken.
    const Result<Skinner> blended = Skinner::CreateAnimated(*device, database(".anim-baked60", true), *model, options);
    ASSERT_TRUE(blended.ok()) << blended.status().message();
    EXPECT_EQ(blended->selection().level, MatchLevel::kExactDevice) << blended->selection().reason;
  }
  options.cross_fades = false;
  {
    Result<Skinner> skinner = Skinner::CreateAnimated(*device, database(".anim-baked60"), *model, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_EQ(skinner->selection().level, MatchLevel::kExactDevice) << skinner->selection().reason;
    ASSERT_EQ(skinner->baked_clips().size(), static_cast<std::size_t>(model->animation_count()));
    for (int c = 0; c < model->animation_count(); ++c)  // F = ceil(duration x 60) + 1
      EXPECT_NEAR(skinner->baked_clips()[static_cast<std::size_t>(c)].frames,
                  std::ceil(model->animation_duration(c) * 60.0) + 1, 1.0) << c;
    EXPECT_NE(skinner->selection().reason.find("made as tuned: baked60"), std::string::npos) << skinner->selection().reason;
    // The crowd was declared without blends: a blend is refused, not mixed in the model's space unrecorded.
    std::vector<AnimationState> states(6);
    EXPECT_TRUE(skinner->SetAnimation(states.data(), states.size()).ok());
    states[2] = {0, 0.5f, 1, 0.25f, 0.5f};
    const Status refused = skinner->SetAnimation(states.data(), states.size());
    EXPECT_EQ(refused.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.message().find("states[2].weight is 0.5"), std::string::npos) << refused.message();
    EXPECT_NE(refused.message().find("SkinnerOptions::cross_fades is false"), std::string::npos) << refused.message();
  }
  options.cross_fades = true;  // local records and sampled clips blend as the source does: every crowd takes them
  {  // baked in local space: its records are nodes', and the reason names the form
    const Result<Skinner> skinner = Skinner::CreateAnimated(*device, database(".anim-local60"), *model, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    ASSERT_EQ(skinner->baked_clips().size(), static_cast<std::size_t>(model->animation_count()));
    const PackedAnimation local = BakeAnimation(TestAsset("Fox.gltf"), 60.0, internal::BakeSpace::kLocal);
    EXPECT_EQ(skinner->baked_clips()[0].bytes, local.baked[0].bytes);
    EXPECT_EQ(skinner->animation_bytes(), local.Bytes());
    EXPECT_NE(skinner->selection().reason.find("made as tuned: local60"), std::string::npos) << skinner->selection().reason;
    SkinnerOptions palette_space = options;  // the same rate in the other space is the caller's own choice
    palette_space.bake_rate = 60.0;
    const Result<Skinner> own = Skinner::CreateAnimated(*device, database(".anim-local60"), *model, palette_space);
    ASSERT_TRUE(own.ok()) << own.status().message();
    EXPECT_NE(own->selection().reason.find("not as tuned (local60)"), std::string::npos) << own->selection().reason;
  }
  {  // hybrid records: both, their bytes together; the same rate as local records only is not the tuned form
    const Result<Skinner> skinner = Skinner::CreateAnimated(*device, database(".anim-hybrid60"), *model, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    const PackedAnimation hybrid = BakeAnimation(TestAsset("Fox.gltf"), 60.0, internal::BakeSpace::kHybrid);
    ASSERT_EQ(skinner->baked_clips().size(), hybrid.baked.size());
    EXPECT_EQ(skinner->baked_clips()[0].bytes, hybrid.baked[0].bytes);
    EXPECT_EQ(skinner->animation_bytes(), hybrid.Bytes());
    EXPECT_NE(skinner->selection().reason.find("made as tuned: hybrid60"), std::string::npos)
        << skinner->selection().reason;
    SkinnerOptions local_space = options;
    local_space.bake_rate = 60.0;
    local_space.bake_space = skintune::BakeSpace::kLocal;
    const Result<Skinner> own = Skinner::CreateAnimated(*device, database(".anim-hybrid60"), *model, local_space);
    ASSERT_TRUE(own.ok()) << own.status().message();
    EXPECT_NE(own->selection().reason.find("not as tuned (hybrid60)"), std::string::npos) << own->selection().reason;
  }
  if (lang != "cpu" && lang != "glsl-vertex") {  // palette records made in the skin launch, as tuned
    Result<Skinner> skinner = Skinner::CreateAnimated(*device, database(".anim-fused60", true, "local"), *model, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_NE(skinner->selection().reason.find("made as tuned: fused60"), std::string::npos) << skinner->selection().reason;
    EXPECT_NE(skinner->selection().variant.find(".local."), std::string::npos) << skinner->selection().variant;
    const PackedAnimation records = BakeAnimation(TestAsset("Fox.gltf"), 60.0);
    EXPECT_EQ(skinner->animation_bytes(), records.Bytes());
    std::vector<AnimationState> states(6);
    states[1] = {1, 0.5f};
    EXPECT_TRUE(skinner->SetAnimation(states.data(), states.size()).ok());
    EXPECT_TRUE(skinner->AdvanceAnimation(0.25f).ok());
    EXPECT_TRUE(skinner->Skin().ok());
    EXPECT_TRUE(skinner->Finish().ok());
    SkinnerOptions fused = options;  // the tuned entry decides: fuse_palette beside kBakeRateTuned is refused
    fused.fuse_palette = true;
    EXPECT_EQ(Skinner::CreateAnimated(*device, database(".anim-fused60", true, "local"), *model, fused).status().code(),
              ErrorCode::kInvalidArgument);
  }
  if (lang != "cpu" && lang != "glsl-vertex") {  // hybrid records made in the skin launch, as tuned: both records go up
    Result<Skinner> skinner =
        Skinner::CreateAnimated(*device, database(".anim-fusedhybrid60", true, "local"), *model, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_NE(skinner->selection().reason.find("made as tuned: fusedhybrid60"), std::string::npos)
        << skinner->selection().reason;
    const PackedAnimation hybrid = BakeAnimation(TestAsset("Fox.gltf"), 60.0, internal::BakeSpace::kHybrid);
    EXPECT_EQ(skinner->animation_bytes(), hybrid.Bytes());
    std::vector<AnimationState> states(6);
    states[1] = {1, 0.5f};
    states[2] = {0, 0.25f, 1, 0.75f, 0.5f};  // a cross-fade: its groups walk the hierarchy
    EXPECT_TRUE(skinner->SetAnimation(states.data(), states.size()).ok());
    EXPECT_TRUE(skinner->AdvanceAnimation(0.25f).ok());
    EXPECT_TRUE(skinner->Skin().ok());
    EXPECT_TRUE(skinner->Finish().ok());
  }
  {  // a rate of the caller's own: the entry's form is not taken, and the reason says so
    SkinnerOptions sampled = options;
    sampled.bake_rate = 0.0;
    const Result<Skinner> skinner = Skinner::CreateAnimated(*device, database(".anim-baked60"), *model, sampled);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_TRUE(skinner->baked_clips().empty());
    EXPECT_NE(skinner->selection().reason.find("not as tuned (baked60)"), std::string::npos) << skinner->selection().reason;
  }
  for (const char* form : {".anim-sampled", ""}) {
    SCOPED_TRACE(form);
    const Result<Skinner> skinner = Skinner::CreateAnimated(*device, database(form), *model, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_TRUE(skinner->baked_clips().empty()) << "sampled";
  }
  // A Skinner of SetPalette takes no animated entry, and refuses the option.
  SkinnerOptions plain;
  plain.instances = 6;
  const Result<Skinner> host = Skinner::Create(*device, database(".anim-baked60"), model->mesh(), plain);
  ASSERT_TRUE(host.ok()) << host.status().message();
  EXPECT_EQ(host->selection().level, MatchLevel::kGenericDefault) << host->selection().reason;
  plain.bake_rate = kBakeRateTuned;
  EXPECT_EQ(Skinner::Create(*device, database(""), model->mesh(), plain).status().code(), ErrorCode::kInvalidArgument);
}

TEST(SkinnerAnimatedModel, AnEmptyModelIsRefused) {
  Result<Device> device = Device::Open("", nullptr);
  if (!device.ok()) GTEST_SKIP() << "no device: " << device.status().message();
  const Result<Skinner> skinner = Skinner::CreateAnimated(*device, WinnersDb::Empty(), Model());
  ASSERT_FALSE(skinner.ok());
  EXPECT_EQ(skinner.status().code(), ErrorCode::kInvalidState);
  EXPECT_NE(skinner.status().message().find("Model is empty"), std::string::npos) << skinner.status().message();
}

std::vector<AnimatedCase> Cases() {
  // Every palette storage and both palette formats (the kernel writes mat4's fourth row too).
  return {{Backend::kOpenCl, "opencl.b4.soa", "Fox.gltf"},
          {Backend::kOpenCl, "opencl.b4.aos.mat4.image", "CesiumMan.gltf"},
          {Backend::kCuda, "cuda.b4.soa-split.constant", "Fox.gltf"},
          {Backend::kCuda, "cuda.b4.soa.image.mat4", "CesiumMan.gltf"},
          {Backend::kGl, "glsl-compute.b4.aos.constant", "Fox.gltf"},
          {Backend::kGl, "glsl-vertex.b4.soa", "CesiumMan.gltf"},
          {Backend::kVulkan, "vulkan.b4.soa-split.local", "Fox.gltf"},
          {Backend::kVulkan, "vulkan.b4.soa.image.mat4", "CesiumMan.gltf"},
          {Backend::kCpu, "cpu.b4.soa", "Fox.gltf"},
          {Backend::kCpu, "cpu.b4.aos.mat4", "CesiumMan.gltf"},
          // Baked clips (docs/ANIMATION.md "Baked clips") in every API, both palette formats.
          {Backend::kOpenCl, "opencl.b4.soa", "CesiumMan.gltf", 30.0},
          {Backend::kCuda, "cuda.b4.soa.image.mat4", "Fox.gltf", 30.0},
          {Backend::kGl, "glsl-compute.b4.aos.constant", "CesiumMan.gltf", 30.0},
          {Backend::kGl, "glsl-vertex.b4.soa", "Fox.gltf", 30.0},
          {Backend::kVulkan, "vulkan.b4.soa.image.mat4", "Fox.gltf", 30.0},
          {Backend::kCpu, "cpu.b4.soa", "CesiumMan.gltf", 60.0},
          // Baked in local space (docs/ANIMATION.md "Baked in local space"), likewise.
          {Backend::kOpenCl, "opencl.b4.soa", "Fox.gltf", 30.0, skintune::BakeSpace::kLocal},
          {Backend::kCuda, "cuda.b4.soa.image.mat4", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kLocal},
          {Backend::kGl, "glsl-compute.b4.aos.constant", "Fox.gltf", 30.0, skintune::BakeSpace::kLocal},
          {Backend::kGl, "glsl-vertex.b4.soa", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kLocal},
          {Backend::kVulkan, "vulkan.b4.soa-split.local", "Fox.gltf", 30.0, skintune::BakeSpace::kLocal},
          {Backend::kCpu, "cpu.b4.aos.mat4", "Fox.gltf", 60.0, skintune::BakeSpace::kLocal},
          // Hybrid records (docs/ANIMATION.md "Hybrid records"), likewise.
          {Backend::kOpenCl, "opencl.b4.soa", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kHybrid},
          {Backend::kCuda, "cuda.b4.soa.image.mat4", "Fox.gltf", 30.0, skintune::BakeSpace::kHybrid},
          {Backend::kGl, "glsl-compute.b4.aos.constant", "Fox.gltf", 30.0, skintune::BakeSpace::kHybrid},
          {Backend::kGl, "glsl-vertex.b4.soa", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kHybrid},
          {Backend::kVulkan, "vulkan.b4.soa.image.mat4", "Fox.gltf", 30.0, skintune::BakeSpace::kHybrid},
          {Backend::kCpu, "cpu.b4.soa", "Fox.gltf", 60.0, skintune::BakeSpace::kHybrid},
          // Palette records made in the skin launch (docs/ANIMATION.md "The palette in the skin
          // launch"): every compute language, both palette formats, storage made local or local.
          {Backend::kOpenCl, "opencl.b4.soa", "Fox.gltf", 30.0, skintune::BakeSpace::kPalette, true},
          {Backend::kOpenCl, "opencl.b4.aos.mat4", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kPalette, true},
          {Backend::kCuda, "cuda.b4.soa.mat4", "Fox.gltf", 30.0, skintune::BakeSpace::kPalette, true},
          {Backend::kCuda, "cuda.b4.soa-split.local", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kPalette, true},
          {Backend::kGl, "glsl-compute.b4.aos", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kPalette, true},
          {Backend::kVulkan, "vulkan.b4.soa-split.local", "Fox.gltf", 30.0, skintune::BakeSpace::kPalette, true},
          {Backend::kVulkan, "vulkan.b4.soa.mat4", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kPalette, true},
          // Local and hybrid records made in the skin launch, each work-group walking the
          // hierarchy (fusedlocal*, fusedhybrid*), in groups of 128 and of 32.
          {Backend::kOpenCl, "opencl.b4.soa", "Fox.gltf", 30.0, skintune::BakeSpace::kLocal, true},
          {Backend::kOpenCl, "opencl.b4.aos.mat4.wg32", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kHybrid, true},
          {Backend::kCuda, "cuda.b4.soa.mat4", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kLocal, true},
          {Backend::kCuda, "cuda.b4.soa-split.local.wg32", "Fox.gltf", 30.0, skintune::BakeSpace::kHybrid, true},
          {Backend::kGl, "glsl-compute.b4.aos.wg32", "Fox.gltf", 30.0, skintune::BakeSpace::kLocal, true},
          {Backend::kGl, "glsl-compute.b4.soa.mat4", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kHybrid, true},
          {Backend::kVulkan, "vulkan.b4.soa-split.local.wg32", "CesiumMan.gltf", 30.0, skintune::BakeSpace::kLocal, true},
          {Backend::kVulkan, "vulkan.b4.soa.mat4", "Fox.gltf", 30.0, skintune::BakeSpace::kHybrid, true}};
}
std::string CaseName(const ::testing::TestParamInfo<AnimatedCase>& info) {
  return testing::ParameterName(info.param.variant + "_" + info.param.model.substr(0, info.param.model.find('.')) +
                                (BakedHybrid(info.param)    ? "_baked_hybrid"
                                 : BakedLocally(info.param) ? "_baked_locally"
                                 : info.param.bake_rate > 0.0 ? "_baked"
                                                              : "") +
                                (info.param.fused ? "_fused" : ""));
}
INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinnerAnimated, ::testing::ValuesIn(Cases()), CaseName);

}  // namespace
}  // namespace skintune::internal
