// The meshes engines skin, through the public API on every backend found
// here (OpenCL on PoCL, GL on llvmpipe, Vulkan on lavapipe, the cpu device;
// CUDA and the NVIDIA APIs on a GPU machine), in every normal format:
// CesiumMan, Fox (positions: it has no normals), a glTF with morph targets (RiggedSimple-morph.gltf, its
// weights animated) and synthetic meshes with tangents of B = 1 to 8, each
// mid-animation. Positions within 1e-5 of the bounding-box diagonal of the
// float64 gold; normals and tangents within 1e-5 in float32 and within the
// format's stated bound packed (docs/VARIANTS.md "Packed normals and
// tangents"); every tangent keeps its handedness.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "generator/packer.h"
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

struct EngineMesh {
  std::string name;
  SkinnedAsset asset;
};

const std::vector<EngineMesh>& Meshes() {
  static const std::vector<EngineMesh> meshes = [] {
    std::vector<EngineMesh> out;
    GltfImportOptions options;
    options.tangents_when_present = true;
    for (const char* file : {"CesiumMan.gltf", "Fox.gltf", "RiggedSimple-morph.gltf"})
      out.push_back({file, ImportGltf((std::filesystem::path(SKINTUNE_TEST_DATA_DIR) / file).string(), options).asset});
    for (int b = 1; b <= 8; ++b) {
      const std::string key = "1500-b" + std::to_string(b) + "-seed" + std::to_string(b) + "-tangents";
      out.push_back({key, GenerateDataset(ParseDatasetKey(key))});
    }
    return out;
  }();
  return meshes;
}

struct BackendCase {
  Backend backend;
};
void PrintTo(const BackendCase& c, std::ostream* out) { *out << BackendName(c.backend); }

class SkinnerEngineMeshes : public testing::BackendFixture<BackendCase> {};

TEST_P(SkinnerEngineMeshes, PositionsNormalsAndTangentsAreTheGoldInEveryNormalFormat) {
  int with_normals = 0, with_tangents = 0, with_morph = 0;
  for (const EngineMesh& m : Meshes()) {
    const SkinnedAsset& asset = m.asset;
    const SkinnedMesh& mesh = asset.mesh;
    const bool normals = mesh.has_normals(), tangents = mesh.has_tangents();  // Fox.gltf has neither
    with_normals += normals;
    with_tangents += tangents;
    with_morph += mesh.has_morph();
    const AnimationClip& clip = asset.animations.front();
    const double t = clip.start + 0.55 * clip.duration();
    const std::vector<glm::mat4> palette = asset.PaletteAt(0, t);
    const SkinnedMesh weighted = mesh.has_morph() ? asset.MeshWithMorphWeightsAt(0, t) : mesh;
    MorphView view(mesh);
    for (const skintune::NormalFormat asked :
         {skintune::NormalFormat::kF32, skintune::NormalFormat::kOct16, skintune::NormalFormat::kSnorm8}) {
      if (!normals && asked != skintune::NormalFormat::kF32) continue;
      SkinnerOptions options;
      options.normals = normals;
      options.tangents = tangents;
      options.normal_format = asked;
      Result<Skinner> skinner = Skinner::Create(device_, WinnersDb::Empty(), view.view.mesh, options);
      ASSERT_TRUE(skinner.ok()) << m.name << ": " << skinner.status().message();
      const Variant variant = ParseVariantKey(skinner->selection().variant);
      SCOPED_TRACE(m.name + " " + variant.Key());
      if (mesh.has_morph()) {
        const std::vector<float> weights(weighted.morph.weights.begin(), weighted.morph.weights.end());
        ASSERT_TRUE(skinner->SetMorphWeights(weights.data(), weights.size()).ok());
      }
      const std::vector<float> matrices = Floats(palette);
      ASSERT_TRUE(skinner->SetPalette(matrices.data(), matrices.size()).ok());
      ASSERT_TRUE(skinner->Skin().ok());
      const std::size_t n = mesh.vertex_count();
      std::vector<float> positions(3 * n), tangent_floats(4 * n);
      ASSERT_TRUE(skinner->ReadPositions(positions.data(), positions.size()).ok());
      const GoldResult gold = SkinGold(QuantisedMesh(weighted, variant), palette, normals, tangents);
      const double diagonal = BoundingBoxDiagonal(mesh.positions);
      EXPECT_LE(CompareToGold(gold.positions, Vec3s(positions)).max_absolute, 1e-5 * diagonal);
      const NormalFormat format = variant.normal_format;
      EXPECT_EQ(static_cast<int>(format), static_cast<int>(asked));
      if (!normals) continue;
      std::vector<float> normal_floats(3 * n);
      ASSERT_TRUE(skinner->ReadNormals(normal_floats.data(), normal_floats.size()).ok());
      EXPECT_LE(CompareToGold(gold.normals, Vec3s(normal_floats)).max_absolute, 1e-5 + NormalFormatBound(format));
      if (!tangents) continue;
      ASSERT_TRUE(skinner->ReadTangents(tangent_floats.data(), tangent_floats.size()).ok());
      std::vector<glm::vec4> t4(n);
      std::memcpy(t4.data(), tangent_floats.data(), tangent_floats.size() * sizeof(float));
      const GoldComparison c = CompareTangentsToGold(gold.tangents, t4);
      EXPECT_EQ(c.wrong_handedness, 0u);
      EXPECT_LE(c.max_absolute, 1e-5 + TangentFormatBound(format));
    }
  }
  EXPECT_GE(with_normals, 10) << "all but Fox.gltf";
  EXPECT_GE(with_tangents, 8) << "the synthetic meshes carry tangents";
  EXPECT_EQ(with_morph, 1) << "RiggedSimple-morph.gltf";
}

INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinnerEngineMeshes,
                         ::testing::Values(BackendCase{Backend::kOpenCl}, BackendCase{Backend::kCuda},
                                           BackendCase{Backend::kGl}, BackendCase{Backend::kVulkan},
                                           BackendCase{Backend::kCpu}),
                         [](const ::testing::TestParamInfo<BackendCase>& param) {
                           return testing::ParameterName(BackendName(param.param.backend));
                         });

}  // namespace
}  // namespace skintune::internal
