// Dual-quaternion skinning through the public API on every backend found here
// (OpenCL on PoCL, GL on llvmpipe, Vulkan on lavapipe, the cpu device; CUDA
// and the NVIDIA APIs on a GPU machine): SkinnerOptions::dual_quaternions
// picks a dq variant (the database's, else the built-in default's dq twin),
// whose positions, normals and tangents are the float64 dual-quaternion
// gold's; a palette matrix that is not rigid is refused naming it, and a
// linear variant never serves the option nor dq the linear Skinner.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "templates/embedded_support.h"  // DualQuaternionOf

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

// A synthetic mesh with normals and tangents on a rigid animation (rotations
// and translations only) with random bone indices, so joints far apart in
// the rig, whose quaternions are far apart too, blend.
const SkinnedAsset& Rigid() {
  static const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("3001-b4-random-rigid-tangents-seed9"));
  return asset;
}

struct DqCase {
  Backend backend;
  std::string variant;  // forced ("" : the database's choice, here the built-in default's dq twin)
};
void PrintTo(const DqCase& c, std::ostream* out) { *out << c.variant; }

class SkinnerDualQuaternions : public testing::BackendFixture<DqCase> {
 protected:
  SkinnerOptions Options() const {
    SkinnerOptions options;
    options.tangents = true;
    options.dual_quaternions = true;
    options.variant = GetParam().variant;
    return options;
  }
  View view_{Rigid().mesh};
};

TEST_P(SkinnerDualQuaternions, SkinsLikeTheDualQuaternionGold) {
  Result<Skinner> skinner = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, Options());
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  const Variant chosen = ParseVariantKey(skinner->selection().variant);
  EXPECT_EQ(chosen.blend, Blend::kDualQuaternion) << skinner->selection().variant;
  EXPECT_EQ(chosen.palette, PaletteFormat::kDualQuaternion) << skinner->selection().variant;
  const AnimationClip& clip = Rigid().animations.front();
  for (double at : {0.2, 0.7}) {
    SCOPED_TRACE("t = " + std::to_string(at));
    ExpectSkinsLikeTheGold(*skinner, Rigid().mesh, Rigid().PaletteAt(0, clip.start + at * clip.duration()));
  }
  // A frame whose joints twist 110 degrees one way and the other in turn (a
  // candy wrapper): influences' quaternions then point apart (q and -q are
  // one rotation, so the kernel flips them onto the first's side), and the
  // dual-quaternion result is far from the linear one, so a linear kernel or
  // one without the flip fails here.
  std::vector<glm::mat4> palette = Rigid().PaletteAt(0, clip.start + 0.7 * clip.duration());
  for (std::size_t j = 0; j < palette.size(); ++j)
    palette[j] = palette[j] * glm::rotate(glm::mat4(1.0f), glm::radians(j % 2 ? 110.0f : -110.0f), glm::vec3(0, 1, 0));
  ExpectSkinsLikeTheGold(*skinner, Rigid().mesh, palette);
  std::vector<glm::vec4> real(palette.size());
  for (std::size_t j = 0; j < palette.size(); ++j) {
    float dq[8];
    ASSERT_TRUE(skintune_kernels::DualQuaternionOf(&palette[j][0][0], dq));
    real[j] = glm::vec4(dq[0], dq[1], dq[2], dq[3]);
  }
  const SkinnedMesh& mesh = Rigid().mesh;
  std::size_t flipped = 0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v)
    for (int i = 1; i < mesh.influences; ++i)
      flipped += glm::dot(real[mesh.joints[v * 4]], real[mesh.joints[v * 4 + i]]) < 0.0f ? 1 : 0;
  EXPECT_GT(flipped, 0u);
  const GoldResult linear = SkinGold(mesh, palette);
  const GoldResult dq = SkinGoldDualQuaternion(mesh, palette);
  std::vector<glm::vec3> linear_positions(linear.positions.begin(), linear.positions.end());
  EXPECT_GT(CompareToGold(dq.positions, linear_positions).max_relative, 1e-4);
}

TEST_P(SkinnerDualQuaternions, APaletteMatrixThatScalesIsRefusedNamingIt) {
  Result<Skinner> skinner = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, Options());
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  std::vector<glm::mat4> palette = Rigid().PaletteAt(-1, 0.0);
  palette[5] = glm::scale(palette[5], glm::vec3(1.0f, 1.2f, 1.0f));
  const std::vector<float> matrices = Floats(palette);
  const Status set = skinner->SetPalette(matrices.data(), matrices.size());
  EXPECT_EQ(set.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(set.message().find("matrix 5 (instance 0, joint 5)"), std::string::npos) << set.message();
  EXPECT_NE(set.message().find("not a rigid transform"), std::string::npos) << set.message();
}

std::vector<DqCase> Cases() {
  return {{Backend::kOpenCl, ""},
          {Backend::kOpenCl, "opencl.b4.soa-split.dualquat.dq.local"},
          {Backend::kCuda, "cuda.b4.soa.dualquat.dq.constant"},
          {Backend::kGl, "glsl-compute.b4.aos.dualquat.dq"},
          {Backend::kGl, "glsl-vertex.b4.soa.dualquat.dq.image"},
          {Backend::kVulkan, "vulkan.b4.soa-split.dualquat.dq.local"},
          {Backend::kVulkan, ""},
          {Backend::kCpu, "cpu.b4.soa.dualquat.dq"}};
}
std::string CaseName(const ::testing::TestParamInfo<DqCase>& info) {
  return info.param.variant.empty() ? std::string(BackendName(info.param.backend)) + "_default"
                                    : testing::ParameterName(info.param.variant);
}
INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinnerDualQuaternions, ::testing::ValuesIn(Cases()), CaseName);

// The option and the variant must agree; animation on the device writes matrices.
TEST(SkinnerDualQuaternionsMisuse, ALinearVariantForTheOptionOrDqWithoutItOrWithAnimationIsAnError) {
  TempDir dir;
  const Backend backend = Backend::kCpu;
  Result<Device> device = Device::Open("", &backend, CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  View view{Rigid().mesh};
  SkinnerOptions options;
  options.dual_quaternions = true;
  options.variant = "cpu.b4.soa.mat3x4.matrix";
  Result<Skinner> refused = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("asks for blend dq"), std::string::npos) << refused.status().message();
  options.dual_quaternions = false;
  options.variant = "cpu.b4.soa.dualquat.dq";
  refused = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("set SkinnerOptions::dual_quaternions"), std::string::npos)
      << refused.status().message();
  options.variant.clear();
  Result<Skinner> linear = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
  ASSERT_TRUE(linear.ok()) << linear.status().message();
  EXPECT_NE(ParseVariantKey(linear->selection().variant).blend, Blend::kDualQuaternion);

  Result<Model> model = Model::Load(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf");
  ASSERT_TRUE(model.ok()) << model.status().message();
  options.dual_quaternions = true;
  Result<Skinner> animated = Skinner::CreateAnimated(*device, WinnersDb::Empty(), *model, options);
  ASSERT_FALSE(animated.ok());
  EXPECT_EQ(animated.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(animated.status().message().find("linear blending only"), std::string::npos)
      << animated.status().message();
}

}  // namespace
}  // namespace skintune::internal
