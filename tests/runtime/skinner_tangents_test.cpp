// Tangents through the public API on every backend found here (OpenCL on
// PoCL, GL on llvmpipe, Vulkan on lavapipe, the cpu device; CUDA and the
// NVIDIA APIs on a GPU machine): SkinnerOptions::tangents picks a tangent
// variant, ReadTangents gives each tangent turned by the blended matrix with
// its handedness, as the float64 gold does, and the misuses are errors.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "model/synthetic.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::ExpectSkinsLikeTheGold;
using testing::Floats;
using testing::TempDir;
using testing::View;

// A synthetic mesh with tangents of both handednesses on scaling joints.
const SkinnedAsset& Tangents() {
  static const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("3001-b4-tangents-seed5"));
  return asset;
}

struct TangentCase {
  Backend backend;
  std::string variant;  // forced, its normals axis set by SkinnerOptions::tangents
};
void PrintTo(const TangentCase& c, std::ostream* out) { *out << c.variant; }

class SkinnerTangents : public testing::BackendFixture<TangentCase> {
 protected:
  View view_{Tangents().mesh};
};

TEST_P(SkinnerTangents, ReadTangentsIsTheGoldWithItsHandedness) {
  SkinnerOptions options;
  options.tangents = true;
  options.variant = GetParam().variant;
  Result<Skinner> skinner = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, options);
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  EXPECT_EQ(ParseVariantKey(skinner->selection().variant).normals, Normals::kTangents) << skinner->selection().variant;
  const AnimationClip& clip = Tangents().animations.front();
  for (double at : {0.25, 0.75}) {
    SCOPED_TRACE("t = " + std::to_string(at));
    ExpectSkinsLikeTheGold(*skinner, Tangents().mesh, Tangents().PaletteAt(0, clip.start + at * clip.duration()));
  }
}

TEST_P(SkinnerTangents, TangentsWithoutTheirArraysOrReadWithoutThemAreErrors) {
  SkinnerOptions options;
  options.tangents = true;
  options.variant = GetParam().variant;
  MeshView no_tangents = view_.mesh;
  no_tangents.tangents = nullptr;
  Result<Skinner> refused = Skinner::Create(device_, WinnersDb::Empty(), no_tangents, options);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("MeshView::tangents is null"), std::string::npos)
      << refused.status().message();
  MeshView no_normals = view_.mesh;
  no_normals.normals = nullptr;
  refused = Skinner::Create(device_, WinnersDb::Empty(), no_normals, options);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("tangents are skinned with normals"), std::string::npos)
      << refused.status().message();

  options.tangents = false;
  options.normals = true;
  Result<Skinner> normals_only = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, options);
  ASSERT_TRUE(normals_only.ok()) << normals_only.status().message();
  const std::vector<float> palette = Floats(Tangents().PaletteAt(-1, 0.0));
  ASSERT_TRUE(normals_only->SetPalette(palette.data(), palette.size()).ok());
  ASSERT_TRUE(normals_only->Skin().ok());
  std::vector<float> out(normals_only->vertex_count() * 4);
  const Status read = normals_only->ReadTangents(out.data(), out.size());
  EXPECT_EQ(read.code(), ErrorCode::kInvalidState);
  EXPECT_NE(read.message().find("skins no tangents"), std::string::npos) << read.message();
}

std::vector<TangentCase> Cases() {
  return {{Backend::kOpenCl, "opencl.b4.soa"},        {Backend::kOpenCl, "opencl.b4.aos.point"},
          {Backend::kCuda, "cuda.b4.soa-split"},      {Backend::kGl, "glsl-compute.b4.aos"},
          {Backend::kGl, "glsl-vertex.b4.soa"},       {Backend::kVulkan, "vulkan.b4.soa-split.local"},
          {Backend::kCpu, "cpu.b4.soa"},              {Backend::kCpu, "cpu.b4.aos.point"}};
}
std::string CaseName(const ::testing::TestParamInfo<TangentCase>& info) { return testing::ParameterName(info.param.variant); }
INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinnerTangents, ::testing::ValuesIn(Cases()), CaseName);

}  // namespace
}  // namespace skintune::internal
