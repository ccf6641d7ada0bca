// Packed normals and tangents through the public API on every backend found
// here (OpenCL on PoCL, GL on llvmpipe, Vulkan on lavapipe, the cpu device;
// CUDA and the NVIDIA APIs on a GPU machine): SkinnerOptions::normal_format
// picks the format, ReadNormals / ReadTangents decode it within its stated
// bound of the float64 gold, handedness kept, ReadPackedNormals /
// ReadPackedTangents give the words the decoding read, and misuses are errors.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "generator/packer.h"
#include "model/synthetic.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::Floats;
using testing::TempDir;
using testing::Vec3s;

constexpr int kInstances = 2;

// A mesh with normals and tangents whose joints scale non-uniformly (the
// synthetic rigs do), so normals and tangents turn differently.
const SkinnedAsset& Asset() {
  static const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("2501-b4-seed11-tangents"));
  return asset;
}

struct FormatCase {
  Backend backend;
  std::string variant;  // forced ("" for the database's choice); its normals by SkinnerOptions
  skintune::NormalFormat format;
};
void PrintTo(const FormatCase& c, std::ostream* out) { *out << c.variant; }

class SkinnerNormalFormat : public testing::BackendFixture<FormatCase> {
 protected:
  Result<Skinner> Create() {
    SkinnerOptions options;
    options.tangents = true;
    options.instances = kInstances;
    options.variant = GetParam().variant;
    options.normal_format = GetParam().format;
    return Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, options);
  }
  testing::View view_{Asset().mesh};
};

TEST_P(SkinnerNormalFormat, DecodedOutputsAreTheGoldWithinTheFormatsBoundAndTheWordsAreThoseDecoded) {
  Result<Skinner> skinner = Create();
  ASSERT_TRUE(skinner.ok()) << skinner.status().message();
  const Variant variant = ParseVariantKey(skinner->selection().variant);
  const NormalFormat format = variant.normal_format;
  ASSERT_EQ(static_cast<int>(format), static_cast<int>(GetParam().format)) << variant.Key();
  const SkinnedAsset& asset = Asset();
  const SkinnedMesh& mesh = asset.mesh;
  const std::size_t n = mesh.vertex_count();
  std::vector<glm::mat4> palettes;
  for (int k = 0; k < kInstances; ++k) {
    const AnimationClip& clip = asset.animations.front();
    const std::vector<glm::mat4> pose = asset.PaletteAt(0, clip.start + (0.3 + 0.4 * k) * clip.duration());
    palettes.insert(palettes.end(), pose.begin(), pose.end());
  }
  const std::vector<float> matrices = Floats(palettes);
  ASSERT_TRUE(skinner->SetPalette(matrices.data(), matrices.size()).ok());
  ASSERT_TRUE(skinner->Skin().ok());
  std::vector<float> normals(kInstances * n * 3), tangents(kInstances * n * 4);
  std::vector<std::uint32_t> normal_words(kInstances * n), tangent_words(kInstances * n);
  ASSERT_TRUE(skinner->ReadNormals(normals.data(), normals.size()).ok());
  ASSERT_TRUE(skinner->ReadTangents(tangents.data(), tangents.size()).ok());
  ASSERT_TRUE(skinner->ReadPackedNormals(normal_words.data(), normal_words.size()).ok());
  ASSERT_TRUE(skinner->ReadPackedTangents(tangent_words.data(), tangent_words.size()).ok());
  for (int k = 0; k < kInstances; ++k) {
    SCOPED_TRACE("instance " + std::to_string(k));
    const GoldResult gold =
        SkinGold(QuantisedMesh(mesh, variant), std::span(palettes).subspan(k * mesh.joint_count, mesh.joint_count),
                 true, true);
    const std::size_t first = k * n;
    const GoldComparison q =
        CompareToGold(gold.normals, Vec3s({normals.begin() + 3 * first, normals.begin() + 3 * (first + n)}));
    EXPECT_LT(q.max_relative, 1e-5 + NormalFormatBound(format)) << variant.Key() << ", worst vertex " << q.worst_vertex;
    // Not vacuous: a packed format is off by more than float32 rounding somewhere.
    EXPECT_GT(q.max_relative, 0.05 * NormalFormatBound(format)) << variant.Key();
    std::vector<glm::vec4> t4(n);
    std::memcpy(t4.data(), tangents.data() + 4 * first, n * sizeof(glm::vec4));
    const GoldComparison c = CompareTangentsToGold(gold.tangents, t4);
    EXPECT_EQ(c.wrong_handedness, 0u) << variant.Key();
    EXPECT_LT(c.max_relative, 1e-5 + TangentFormatBound(format)) << variant.Key() << ", worst vertex " << c.worst_vertex;
    for (std::size_t v = 0; v < n; v += 97) {  // the words are what ReadNormals / ReadTangents decoded
      const glm::vec3 decoded = UnpackedNormal(format, normal_words[first + v]);
      EXPECT_EQ(decoded, glm::vec3(normals[3 * (first + v)], normals[3 * (first + v) + 1], normals[3 * (first + v) + 2]));
      EXPECT_EQ(UnpackedTangent(format, tangent_words[first + v]), t4[v]);
    }
  }

  // The kernel runs the documented rule: the same variant writing float32,
  // packed by PackedNormalWord (the emitted header's PackNormal), gives the
  // kernel's words, but where the two compilations round a step apart (fused
  // multiply-adds): then one unit in one component, at few vertices.
  SkinnerOptions f32_options;
  f32_options.tangents = true;
  f32_options.instances = kInstances;
  f32_options.variant = GetParam().variant;
  Result<Skinner> f32 = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, f32_options);
  ASSERT_TRUE(f32.ok()) << f32.status().message();
  ASSERT_TRUE(f32->SetPalette(matrices.data(), matrices.size()).ok());
  ASSERT_TRUE(f32->Skin().ok());
  std::vector<float> f32_normals(normals.size()), f32_tangents(tangents.size());
  ASSERT_TRUE(f32->ReadNormals(f32_normals.data(), f32_normals.size()).ok());
  ASSERT_TRUE(f32->ReadTangents(f32_tangents.data(), f32_tangents.size()).ok());
  const int fields = format == NormalFormat::kOct16 ? 2 : 4, bits = 32 / fields;
  const auto units_apart = [&](std::uint32_t a, std::uint32_t b) {
    int most = 0;
    for (int f = 0; f < fields; ++f) {
      const std::uint32_t mask = (1u << bits) - 1u;
      int x = static_cast<int>((a >> (f * bits)) & mask), y = static_cast<int>((b >> (f * bits)) & mask);
      if (bits == 8) x = static_cast<std::int8_t>(x), y = static_cast<std::int8_t>(y);
      most = std::max(most, std::abs(x - y));
    }
    return most;
  };
  std::size_t differing = 0;
  for (std::size_t v = 0; v < normal_words.size(); ++v) {
    const std::uint32_t normal = PackedNormalWord(format, {f32_normals[3 * v], f32_normals[3 * v + 1], f32_normals[3 * v + 2]});
    const std::uint32_t t = PackedTangentWord(
        format, {f32_tangents[4 * v], f32_tangents[4 * v + 1], f32_tangents[4 * v + 2], f32_tangents[4 * v + 3]});
    const int apart = std::max(units_apart(normal, normal_words[v]), units_apart(t, tangent_words[v]));
    ASSERT_LE(apart, 1) << variant.Key() << ": vertex " << v << " words " << std::hex << normal_words[v] << " "
                        << tangent_words[v] << ", the rule's " << normal << " " << t;
    differing += apart > 0;
  }
  EXPECT_LE(differing, normal_words.size() / 100) << variant.Key() << ": words other than the rule's";
}

std::vector<FormatCase> Cases() {
  using F = skintune::NormalFormat;
  return {{Backend::kOpenCl, "opencl.b4.soa", F::kOct16},
          {Backend::kOpenCl, "opencl.b4.aos.point.v2c", F::kSnorm8},
          {Backend::kCuda, "cuda.b4.soa-split", F::kOct16},
          {Backend::kCuda, "cuda.b4.aos.constant", F::kSnorm8},
          {Backend::kGl, "glsl-compute.b4.aos", F::kSnorm8},
          {Backend::kGl, "glsl-vertex.b4.soa", F::kOct16},
          {Backend::kVulkan, "vulkan.b4.soa-split.local", F::kOct16},
          {Backend::kVulkan, "vulkan.b4.soa.image", F::kSnorm8},
          {Backend::kCpu, "cpu.b4.soa", F::kOct16},
          {Backend::kCpu, "cpu.b4.aos.point", F::kSnorm8},
          {Backend::kCpu, "", F::kOct16}};  // the built-in default takes the format
}
std::string CaseName(const ::testing::TestParamInfo<FormatCase>& info) {
  return testing::ParameterName((info.param.variant.empty() ? std::string("default") : info.param.variant) +
                                (info.param.format == skintune::NormalFormat::kOct16 ? ".oct16" : ".snorm8"));
}
INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinnerNormalFormat, ::testing::ValuesIn(Cases()), CaseName);

TEST(SkinnerNormalFormatMisuse, EachMisuseIsOneClearError) {
  TempDir dir;
  const Backend backend = Backend::kCpu;
  Result<Device> device = Device::Open("", &backend, CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  testing::View view(Asset().mesh);
  const auto refused = [](const Status& s, ErrorCode code, const std::string& part) {
    EXPECT_EQ(s.code(), code) << s.message();
    EXPECT_NE(s.message().find(part), std::string::npos) << s.message();
  };
  SkinnerOptions options;
  options.normal_format = skintune::NormalFormat::kOct16;
  Result<Skinner> no_normals = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
  ASSERT_FALSE(no_normals.ok());
  refused(no_normals.status(), ErrorCode::kInvalidArgument, "normal_format oct16 packs normals, and the Skinner skins none");
  options.normals = true;
  options.variant = "cpu.b4.soa.normals.normals-snorm8";
  Result<Skinner> disagreeing = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
  ASSERT_FALSE(disagreeing.ok());
  refused(disagreeing.status(), ErrorCode::kInvalidArgument,
          "it writes snorm8 normals, and SkinnerOptions::normal_format asks for oct16");
  options.normal_format = static_cast<skintune::NormalFormat>(7);
  Result<Skinner> bad = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
  ASSERT_FALSE(bad.ok());
  refused(bad.status(), ErrorCode::kInvalidArgument, "SkinnerOptions::normal_format is 7");

  SkinnerOptions plain;
  plain.normals = true;
  Result<Skinner> f32 = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, plain);
  ASSERT_TRUE(f32.ok()) << f32.status().message();
  const std::vector<float> matrices = Floats(Asset().PaletteAt(0, 0.0));
  ASSERT_TRUE(f32->SetPalette(matrices.data(), matrices.size()).ok());
  ASSERT_TRUE(f32->Skin().ok());
  std::vector<std::uint32_t> words(view.mesh.vertex_count);
  refused(f32->ReadPackedNormals(words.data(), words.size()), ErrorCode::kInvalidState, "writes no packed normals");
  refused(f32->ReadPackedTangents(words.data(), words.size()), ErrorCode::kInvalidState, "writes no packed tangents");
}

}  // namespace
}  // namespace skintune::internal
