// Morph targets through the public API on every backend found here (OpenCL
// on PoCL, GL on llvmpipe, Vulkan on lavapipe, the cpu device; CUDA and the
// NVIDIA APIs on a GPU machine): a MeshView with morph targets takes a morph
// variant, SetMorphWeights gives each instance its own weights, uploaded
// with the next SetPalette, and every instance's positions, normals and
// tangents are the float64 gold of the mesh morphed at its weights, then
// skinned. The misuses are errors that change nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "model/gltf_import.h"
#include "model/synthetic.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::Floats;
using testing::MorphView;
using testing::TempDir;
using testing::Vec3s;

constexpr int kInstances = 3;

// A synthetic mesh with normals, tangents and five morph targets (target 0
// over every vertex, the others over patches, the last at weight 0).
const SkinnedAsset& Morphing() {
  static const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("3001-b4-morph5-tangents-seed7"));
  return asset;
}

// Instance k's weights in frame `frame`: every target moves, each instance
// and frame its own mix, one weight negative and one above 1 (glTF allows both).
std::vector<float> FrameWeights(int frame, int targets) {
  std::vector<float> out;
  for (int k = 0; k < kInstances; ++k)
    for (int t = 0; t < targets; ++t)
      out.push_back(static_cast<float>(std::sin(1.3 * frame + 0.7 * k + 0.9 * t) * 0.8 + (t == 1 ? 0.6 : 0.0)));
  return out;
}

// Instance k's palette in frame `frame`: its own time of the clip.
std::vector<glm::mat4> FramePalettes(const SkinnedAsset& asset, int frame) {
  const AnimationClip& clip = asset.animations.front();
  std::vector<glm::mat4> out;
  for (int k = 0; k < kInstances; ++k) {
    const double phase = std::fmod((k + 0.5) / kInstances + 0.29 * frame, 1.0);
    const std::vector<glm::mat4> pose = asset.PaletteAt(0, clip.start + phase * clip.duration());
    out.insert(out.end(), pose.begin(), pose.end());
  }
  return out;
}

// Every instance's outputs against the gold of the mesh at its weights (as
// the chosen variant stores offsets and weights), skinned with its palette.
void ExpectInstancesMorphedLikeTheGold(Skinner& skinner, const SkinnedMesh& mesh, const std::vector<float>& weights,
                                       const std::vector<glm::mat4>& palettes) {
  const Variant variant = ParseVariantKey(skinner.selection().variant);
  const std::size_t n = mesh.vertex_count(), targets = mesh.morph.count();
  std::vector<float> positions(kInstances * n * 3), normals(kInstances * n * 3), tangents(kInstances * n * 4);
  ASSERT_TRUE(skinner.ReadPositions(positions.data(), positions.size()).ok());
  ASSERT_TRUE(skinner.ReadNormals(normals.data(), normals.size()).ok());
  ASSERT_TRUE(skinner.ReadTangents(tangents.data(), tangents.size()).ok());
  for (int k = 0; k < kInstances; ++k) {
    SCOPED_TRACE("instance " + std::to_string(k));
    SkinnedMesh weighted = mesh;
    weighted.morph.weights.assign(weights.begin() + k * targets, weights.begin() + (k + 1) * targets);
    const GoldResult gold = SkinGold(QuantisedMesh(weighted, variant),
                                     std::span(palettes).subspan(k * mesh.joint_count, mesh.joint_count), true, true);
    const auto part = [&](const std::vector<float>& all, std::size_t floats) {
      return std::vector<float>(all.begin() + k * n * floats, all.begin() + (k + 1) * n * floats);
    };
    const GoldComparison p = CompareToGold(gold.positions, Vec3s(part(positions, 3)));
    EXPECT_LT(p.max_relative, 1e-5) << variant.Key() << ": positions, worst vertex " << p.worst_vertex;
    const GoldComparison q = CompareToGold(gold.normals, Vec3s(part(normals, 3)));
    EXPECT_LT(q.max_relative, 1e-5) << variant.Key() << ": normals, worst vertex " << q.worst_vertex;
    const std::vector<float> t = part(tangents, 4);
    std::vector<glm::vec4> t4(n);
    std::memcpy(t4.data(), t.data(), t.size() * sizeof(float));
    const GoldComparison c = CompareTangentsToGold(gold.tangents, t4);
    EXPECT_EQ(c.wrong_handedness, 0u) << variant.Key();
    EXPECT_LT(c.max_relative, 1e-5) << variant.Key() << ": tangents, worst vertex " << c.worst_vertex;
    // Not vacuous: the weights move this instance away from the unmorphed mesh's skin.
    SkinnedMesh unmorphed = mesh;
    unmorphed.morph = MorphTargets{};
    const GoldResult plain =
        SkinGold(unmorphed, std::span(palettes).subspan(k * mesh.joint_count, mesh.joint_count), false, false);
    EXPECT_GT(MaxDistance(plain.positions, gold.positions), 1e-3 * BoundingBoxDiagonal(mesh.positions));
  }
}

struct MorphCase {
  Backend backend;
  std::string variant;  // forced; its normals axis set by SkinnerOptions::tangents
};
void PrintTo(const MorphCase& c, std::ostream* out) { *out << c.variant; }

class SkinnerMorph : public testing::BackendFixture<MorphCase> {
 protected:
  Result<Skinner> Create(const MeshView& mesh) {
    SkinnerOptions options;
    options.tangents = true;
    options.instances = kInstances;
    options.variant = GetParam().variant;
    return Skinner::Create(device_, WinnersDb::Empty(), mesh, options);
  }
  MorphView view_{Morphing().mesh};
};

TEST_P(SkinnerMorph, EveryInstanceIsMorphedAtItsOwnWeightsEveryFrame) {
  Result<Skinner> skinner = Create(view_.view.mesh);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  const int targets = skinner->morph_target_count();
  ASSERT_EQ(targets, 5);
  for (int frame = 0; frame < 4; ++frame) {  // more frames than palette buffers: the ring turns
    SCOPED_TRACE("frame " + std::to_string(frame));
    const std::vector<float> weights = FrameWeights(frame, targets);
    const std::vector<glm::mat4> palettes = FramePalettes(Morphing(), frame);
    const std::vector<float> matrices = Floats(palettes);
    ASSERT_TRUE(skinner->SetMorphWeights(weights.data(), weights.size()).ok());
    ASSERT_TRUE(skinner->SetPalette(matrices.data(), matrices.size()).ok());
    ASSERT_TRUE(skinner->Skin().ok());
    ExpectInstancesMorphedLikeTheGold(*skinner, Morphing().mesh, weights, palettes);
    if (HasFailure()) return;
  }
}

// Weights go up with the next SetPalette, in its palette buffer: a Skin
// between keeps the frame's; a rejected call changes nothing.
TEST_P(SkinnerMorph, WeightsTakeEffectWithTheNextPaletteAndMisusesChangeNothing) {
  Result<Skinner> skinner = Create(view_.view.mesh);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  const int targets = skinner->morph_target_count();
  const std::vector<float> first = FrameWeights(0, targets), second = FrameWeights(1, targets);
  const std::vector<glm::mat4> palettes = FramePalettes(Morphing(), 0);
  const std::vector<float> matrices = Floats(palettes);
  ASSERT_TRUE(skinner->SetMorphWeights(first.data(), first.size()).ok());
  ASSERT_TRUE(skinner->SetPalette(matrices.data(), matrices.size()).ok());
  ASSERT_TRUE(skinner->SetMorphWeights(second.data(), second.size()).ok());
  ASSERT_TRUE(skinner->Skin().ok());
  ExpectInstancesMorphedLikeTheGold(*skinner, Morphing().mesh, first, palettes);

  const auto refused = [&](const Status& s, ErrorCode code, const std::string& part) {
    EXPECT_EQ(s.code(), code) << s.message();
    EXPECT_NE(s.message().find(part), std::string::npos) << s.message();
  };
  refused(skinner->SetMorphWeights(second.data(), second.size() - 1), ErrorCode::kInvalidArgument,
          std::to_string(kInstances) + " instances x 5 morph targets");
  refused(skinner->SetMorphWeights(nullptr, second.size()), ErrorCode::kInvalidArgument, "weights is null");
  std::vector<float> bad = second;
  bad[1 * targets + 2] = std::numeric_limits<float>::quiet_NaN();
  refused(skinner->SetMorphWeights(bad.data(), bad.size()), ErrorCode::kInvalidArgument,
          "weight " + std::to_string(targets + 2) + " (instance 1, target 2)");
  // The last accepted weights (second) go up with this palette.
  ASSERT_TRUE(skinner->SetPalette(matrices.data(), matrices.size()).ok());
  ASSERT_TRUE(skinner->Skin().ok());
  ExpectInstancesMorphedLikeTheGold(*skinner, Morphing().mesh, second, palettes);

  // A mesh without morph targets has no weights to set.
  testing::View plain(Morphing().mesh);
  SkinnerOptions options;
  options.variant = ParseVariantKey(GetParam().variant).lang == Lang::kCpu ? "cpu.b4" : "";
  Result<Skinner> unmorphed = Skinner::Create(device_, WinnersDb::Empty(), plain.mesh, options);
  ASSERT_TRUE(unmorphed.ok()) << unmorphed.status().message();
  EXPECT_EQ(unmorphed->morph_target_count(), 0);
  EXPECT_FALSE(SkinsMorph(ParseVariantKey(unmorphed->selection().variant))) << unmorphed->selection().variant;
  refused(unmorphed->SetMorphWeights(first.data(), 5), ErrorCode::kInvalidState, "the mesh has no morph targets");
}

// A crowd animated on the device (CreateAnimated) keeps its model's morph
// targets: each instance's weights, set from the host, go up with its frame,
// from SetAnimation and from AdvanceAnimation alike, and every instance is
// its reference at its own time and weights (Model::SkinReference).
TEST_P(SkinnerMorph, AnAnimatedCrowdMorphsAtTheWeightsSetFromTheHostEveryFrame) {
  Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple-morph.gltf");
  ASSERT_TRUE(model.ok()) << model.status().message();
  SkinnerOptions options;
  options.instances = kInstances;
  options.variant = GetParam().variant;
  Result<Skinner> skinner = Skinner::CreateAnimated(device_, WinnersDb::Empty(), *model, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  ASSERT_EQ(skinner->morph_target_count(), 2);
  const int targets = 2;
  const std::size_t n = model->vertex_count();
  std::vector<float> times(kInstances);
  for (int k = 0; k < kInstances; ++k) times[k] = static_cast<float>(model->animation_start(0) + 0.1 + 0.25 * k);
  const auto expect_frame = [&](int frame, const std::vector<float>& weights) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    ASSERT_TRUE(skinner->Skin().ok());
    std::vector<float> positions(kInstances * n * 3);
    ASSERT_TRUE(skinner->ReadPositions(positions.data(), positions.size()).ok());
    for (int k = 0; k < kInstances; ++k) {
      std::vector<float> matrices, reference;
      ASSERT_TRUE(model->Palette(0, times[k], &matrices).ok());
      ASSERT_TRUE(model->SkinReference(matrices.data(), matrices.size(), weights.data() + k * targets, targets,
                                       &reference).ok());
      double worst = 0.0, extent = 0.0;
      for (std::size_t i = 0; i < n * 3; ++i) {
        worst = std::max(worst, std::abs(double(positions[k * n * 3 + i]) - double(reference[i])));
        extent = std::max(extent, std::abs(double(reference[i])));
      }
      EXPECT_LT(worst, 2e-5 * extent) << "instance " << k;  // the palette kernel's float32 adds to the skin's
    }
  };
  // Each instance and frame its own weights, one above 1 and one negative (glTF allows both).
  const auto weights_of = [&](int frame) {
    std::vector<float> w;
    for (int k = 0; k < kInstances; ++k)
      for (int t = 0; t < targets; ++t)
        w.push_back(static_cast<float>(std::sin(0.9 * frame + 1.7 * k + 0.6 * t) * 1.2 + (t == 0 ? 0.3 : 0.0)));
    return w;
  };
  for (int frame = 0; frame < 4; ++frame) {
    const std::vector<float> weights = weights_of(frame);
    ASSERT_TRUE(skinner->SetMorphWeights(weights.data(), weights.size()).ok());
    if (frame < 2) {
      std::vector<AnimationState> states(kInstances);
      for (int k = 0; k < kInstances; ++k) states[k] = {0, times[k], -1, 0.0f, 0.0f};
      ASSERT_TRUE(skinner->SetAnimation(states.data(), states.size()).ok());
    } else {  // nothing uploaded but the weights: the clocks advance on the device
      const float delta = 0.05f;
      ASSERT_TRUE(skinner->AdvanceAnimation(delta).ok());
      for (float& t : times) t += delta;
    }
    expect_frame(frame, weights);
    if (HasFailure()) return;
  }
}

std::vector<MorphCase> Cases() {
  return {{Backend::kOpenCl, "opencl.b4.soa.morph-dense"},
          {Backend::kOpenCl, "opencl.b4.aos.point.morph-sparse-half"},
          {Backend::kCuda, "cuda.b4.soa-split.morph-sparse"},
          {Backend::kCuda, "cuda.b4.aos.constant.morph-dense-half"},
          {Backend::kGl, "glsl-compute.b4.aos.morph-dense-half"},
          {Backend::kGl, "glsl-vertex.b4.soa.morph-sparse"},
          {Backend::kVulkan, "vulkan.b4.soa-split.local.morph-dense"},
          {Backend::kVulkan, "vulkan.b4.soa.image.morph-sparse-half"},
          {Backend::kCpu, "cpu.b4.soa.morph-sparse"},
          {Backend::kCpu, "cpu.b4.aos.point.morph-dense-half"}};
}
std::string CaseName(const ::testing::TestParamInfo<MorphCase>& info) {
  return testing::ParameterName(info.param.variant);
}
INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinnerMorph, ::testing::ValuesIn(Cases()), CaseName);

// With no variant forced, a mesh with morph targets takes a morph variant
// (the built-in default: dense float32 offsets, exact).
TEST(SkinnerMorphDefault, AMeshWithMorphTargetsTakesAMorphVariant) {
  TempDir dir;
  const Backend backend = Backend::kCpu;
  Result<Device> device = Device::Open("", &backend, CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  MorphView view(Morphing().mesh);
  Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.view.mesh, SkinnerOptions{});
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  EXPECT_EQ(ParseVariantKey(skinner->selection().variant).morph, Morph::kDense) << skinner->selection().variant;

  MeshView broken = view.view.mesh;
  broken.morph_positions = nullptr;
  Result<Skinner> refused = Skinner::Create(*device, WinnersDb::Empty(), broken, SkinnerOptions{});
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("morph_target_count is 5 but morph_positions is null"), std::string::npos)
      << refused.status().message();
  std::vector<float> offsets = view.positions;
  offsets[7] = std::numeric_limits<float>::infinity();
  broken.morph_positions = offsets.data();
  refused = Skinner::Create(*device, WinnersDb::Empty(), broken, SkinnerOptions{});
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("target 0 vertex 2: position offset is not finite"), std::string::npos)
      << refused.status().message();
}

// A glTF file's morph targets through Model: the weights of its animation
// at a time (Model::MorphWeights) with its palette, against
// Model::SkinReference at the same weights; CreateAnimated keeps its morph
// targets (their weights set from the host).
TEST(SkinnerMorphModel, AGltfsAnimatedWeightsSkinLikeItsReference) {
  TempDir dir;
  const Backend backend = Backend::kCpu;
  Result<Device> device = Device::Open("", &backend, CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple-morph.gltf");
  ASSERT_TRUE(model.ok()) << model.status().message();
  ASSERT_EQ(model->morph_target_count(), 2);
  Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), model->mesh(), SkinnerOptions{});
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  for (const double t : {0.1, 0.45, 0.9}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    std::vector<float> weights, matrices, reference;
    ASSERT_TRUE(model->MorphWeights(0, t, &weights).ok());
    ASSERT_TRUE(model->Palette(0, t, &matrices).ok());
    ASSERT_TRUE(model->SkinReference(matrices.data(), matrices.size(), weights.data(), weights.size(), &reference).ok());
    ASSERT_TRUE(skinner->SetMorphWeights(weights.data(), weights.size()).ok());
    ASSERT_TRUE(skinner->SetPalette(matrices.data(), matrices.size()).ok());
    ASSERT_TRUE(skinner->Skin().ok());
    std::vector<float> positions(model->vertex_count() * 3);
    ASSERT_TRUE(skinner->ReadPositions(positions.data(), positions.size()).ok());
    double worst = 0.0, extent = 0.0;
    for (std::size_t i = 0; i < positions.size(); ++i) {
      worst = std::max(worst, std::abs(double(positions[i]) - double(reference[i])));
      extent = std::max(extent, std::abs(double(reference[i])));
    }
    EXPECT_LT(worst, 1e-5 * extent);
  }
  std::vector<float> wrong(3, 0.0f), matrices, out;
  ASSERT_TRUE(model->Palette(-1, 0.0, &matrices).ok());
  const Status mismatch = model->SkinReference(matrices.data(), matrices.size(), wrong.data(), wrong.size(), &out);
  EXPECT_NE(mismatch.message().find("3 morph weights given, the model has 2 morph targets"), std::string::npos)
      << mismatch.message();
  Result<Skinner> animated = Skinner::CreateAnimated(*device, WinnersDb::Empty(), *model, SkinnerOptions{});
  ASSERT_TRUE(animated.ok()) << animated.status().message();
  EXPECT_EQ(animated->morph_target_count(), 2) << "an animated Skinner keeps the model's morph targets";
}

}  // namespace
}  // namespace skintune::internal
