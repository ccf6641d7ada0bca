#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "generator/space.h"
#include "base/error.h"

namespace skintune::internal {
namespace {

TEST(TuningSpace, SizeMatchesTheNumberOfPointsVisited) {
  TuningSpace s = TuningSpace::Full();
  s.influences = {2};
  std::uint64_t visited = 0;
  s.ForEach([&](const Variant&) { ++visited; });
  EXPECT_EQ(visited, s.Size());
}

TEST(TuningSpace, GlslVertexCollapsesWorkGroupAxes) {
  TuningSpace s = TuningSpace::Full();
  s.langs = {Lang::kGlslVertex};
  s.ForEach([](const Variant& v) {
    ASSERT_EQ(v.wg_size, 0);
    ASSERT_EQ(v.vertices_per_item, 1);
  });
  // palettes and blends: 3 each; normals: 3; morph: 5; normal formats: 3; animation: 26
  EXPECT_EQ(s.Size(), 8u * 2 * 3 * 2 * 3 * 3 * 3 * 4 * 3 * 3 * 5 * 3 * 26);
}

TEST(TuningSpace, FromJsonRestrictsNamedAxesAndKeepsTheRestFull) {
  const TuningSpace s = SpaceFromJson(nlohmann::json::parse(R"({"lang": ["opencl"], "wg_size": [64, 256]})"), "c.json");
  EXPECT_EQ(s.langs, std::vector<Lang>{Lang::kOpenCl});
  EXPECT_EQ(s.wg_sizes, (std::vector<int>{64, 256}));
  EXPECT_EQ(s.layouts.size(), 3u);
  EXPECT_EQ(nlohmann::json(s)["wg_size"], nlohmann::json::parse("[64, 256]"));
}

TEST(TuningSpace, FromJsonReadsTheNormalsAxisByNameAndAsOldConfigsWroteIt) {
  const TuningSpace named = SpaceFromJson(nlohmann::json::parse(R"({"normals": ["none", "tangents"]})"), "c.json");
  EXPECT_EQ(named.normals, (std::vector<Normals>{Normals::kNone, Normals::kTangents}));
  const TuningSpace old = SpaceFromJson(nlohmann::json::parse(R"({"normals": [false, true]})"), "c.json");
  EXPECT_EQ(old.normals, (std::vector<Normals>{Normals::kNone, Normals::kNormals}));
}

// Dual quaternions compute something else than linear blending: chosen, never
// raced against it, and never the default.
TEST(TuningSpace, FromJsonTakesDualQuaternionsOnlyWhenAskedAndAlone) {
  const TuningSpace linear = SpaceFromJson(nlohmann::json::parse(R"({"lang": ["cuda"]})"), "c.json");
  EXPECT_EQ(linear.blends, (std::vector<Blend>{Blend::kMatrix, Blend::kPoint}));
  EXPECT_EQ(linear.palettes, (std::vector<PaletteFormat>{PaletteFormat::kMat4, PaletteFormat::kMat3x4}));
  const TuningSpace dq = SpaceFromJson(nlohmann::json::parse(R"({"blend": ["dq"]})"), "c.json");
  EXPECT_EQ(dq.blends, std::vector<Blend>{Blend::kDualQuaternion});
  EXPECT_EQ(dq.palettes, std::vector<PaletteFormat>{PaletteFormat::kDualQuaternion});
  try {
    SpaceFromJson(nlohmann::json::parse(R"({"blend": ["matrix", "dq"]})"), "c.json");
    FAIL() << "dq raced against matrix";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("c.json: space.blend: \"dq\""), std::string::npos) << e.what();
  }
}

TEST(TuningSpace, FromJsonNamesTheBadAxisOrValue) {
  auto error = [](const char* text) {
    try {
      SpaceFromJson(nlohmann::json::parse(text), "c.json");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(error(R"({"storage": ["constant", "texture"]})"),
            "c.json: space.storage[1]: unknown value 'texture' (expected one of constant, local, global, image)");
  EXPECT_EQ(error(R"({"colour": ["red"]})").rfind("c.json: space.colour: unknown axis", 0), 0u);
  EXPECT_EQ(error(R"({"layout": []})"), "c.json: space.layout is empty");
  EXPECT_EQ(error(R"({"wg_size": [64, "big"]})"), "c.json: space.wg_size[1]: expected an integer");
  EXPECT_EQ(error(R"({"normals": "yes"})"), "c.json: space.normals: expected a list of values");
  EXPECT_EQ(error(R"([1, 2])"), "c.json: space must be an object of axis -> list of values");
}

// The morph axis follows the data set: none alone without morph targets,
// the four morph values (no none) with them; the space's own list is kept
// where it names fewer.
TEST(TuningSpace, ForDataSetKeepsTheMorphValuesOfTheDataSet) {
  TuningSpace s = TuningSpace::Full();
  EXPECT_EQ(ForDataSet(s, {77, 4, true}).morphs, std::vector<Morph>{Morph::kNone});
  ProblemShape morph{77, 4, true};
  morph.morph_targets = 3;
  morph.morph_moves = true;
  EXPECT_EQ(ForDataSet(s, morph).morphs,
            (std::vector<Morph>{Morph::kDense, Morph::kSparse, Morph::kDenseHalf, Morph::kSparseHalf}));
  s.morphs = {Morph::kNone, Morph::kSparseHalf};
  EXPECT_EQ(ForDataSet(s, morph).morphs, std::vector<Morph>{Morph::kSparseHalf});
  s.morphs = {Morph::kDense};
  EXPECT_TRUE(ForDataSet(s, {77, 4, true}).morphs.empty());
  // Animation: host on a scene the host animates, the device's 25 forms on one animated on the device.
  EXPECT_EQ(ForDataSet(s, {77, 4, true}).animations, std::vector<Animation>{Animation::kHost});
  ProblemShape animated{77, 4, true};
  animated.animated = true;
  EXPECT_EQ(ForDataSet(s, animated).animations, (std::vector<Animation>{Animation::kSampled, Animation::kBaked30,
                                                                       Animation::kBaked60, Animation::kBaked120,
                                                                       Animation::kBaked240, Animation::kLocal30,
                                                                       Animation::kLocal60, Animation::kLocal120,
                                                                       Animation::kLocal240, Animation::kHybrid30,
                                                                       Animation::kHybrid60, Animation::kHybrid120,
                                                                       Animation::kHybrid240, Animation::kFused30, Animation::kFused60,
                                                                       Animation::kFused120, Animation::kFused240,
                                                                       Animation::kFusedLocal30, Animation::kFusedLocal60,
                                                                       Animation::kFusedLocal120, Animation::kFusedLocal240,
                                                                       Animation::kFusedHybrid30, Animation::kFusedHybrid60,
                                                                       Animation::kFusedHybrid120, Animation::kFusedHybrid240}));
  s.animations = {Animation::kHost};
  EXPECT_TRUE(ForDataSet(s, animated).animations.empty());
}

// The normals' format is the user's: a config that leaves it out tunes
// float32 only; listed formats stay, except on a data set without normals.
TEST(TuningSpace, NormalFormatIsFloat32UnlessListedAndOnlyWhereTheDataSetHasNormals) {
  EXPECT_EQ(SpaceFromJson(nlohmann::json::object(), "test").normal_formats,
            std::vector<NormalFormat>{NormalFormat::kF32});
  const TuningSpace listed = SpaceFromJson({{"normal_format", {"f32", "oct16", "snorm8"}}}, "test");
  EXPECT_EQ(listed.normal_formats.size(), 3u);
  EXPECT_EQ(ForDataSet(listed, {77, 4, true}).normal_formats.size(), 3u);
  EXPECT_EQ(ForDataSet(listed, {77, 4, false}).normal_formats, std::vector<NormalFormat>{NormalFormat::kF32});
  EXPECT_THROW(SpaceFromJson({{"normal_format", {"half"}}}, "test"), Error);
}

TEST(Enumerate, CountsValidAndInvalidByConstraint) {
  TuningSpace s = TuningSpace::Full();
  s.langs = {Lang::kOpenCl};
  s.influences = {4};
  DeviceLimits device;
  device.max_wg_size = 256;
  std::uint64_t seen = 0;
  const SpaceCount c = Enumerate(s, device, {77, 4, true}, [&](const Variant& v) {
    ++seen;
    EXPECT_TRUE(CheckVariant(v, device, {77, 4, true}).empty());
  });
  EXPECT_EQ(c.total, ForDataSet(s, {77, 4, true}).Size());  // no morph targets: morph none alone; animation host alone
  EXPECT_EQ(c.total * 5 * 26, s.Size());
  EXPECT_EQ(c.valid, seen);
  std::uint64_t invalid = 0;
  for (const auto& [constraint, n] : c.invalid_by) invalid += n;
  EXPECT_EQ(c.valid + invalid, c.total);
  EXPECT_GT(c.invalid_by.at(Constraint::kWgSizeDevice), 0u);
  EXPECT_GT(c.invalid_by.at(Constraint::kAssignmentRedundant), 0u);
}

}  // namespace
}  // namespace skintune::internal
