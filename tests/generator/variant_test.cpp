#include <gtest/gtest.h>

#include <unordered_set>

#include <nlohmann/json.hpp>

#include "generator/space.h"
#include "generator/variant.h"
#include "base/error.h"

namespace skintune::internal {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(VariantKey, DefaultKeyListsEveryAxisInCanonicalOrder) {
  EXPECT_EQ(Variant{}.Key(), "opencl.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.nonormals");
}

TEST(VariantKey, EveryPointOfTheFullSpaceRoundTripsThroughItsKeyAndJson) {
  std::size_t checked = 0;
  TuningSpace space = TuningSpace::Full();
  space.influences = {1, 8};  // keep the test fast; every other axis complete
  space.wg_sizes = {32, 1024};
  space.animations = {Animation::kHost};  // the others: below
  const auto round_trip = [&](const Variant& v) {
    ASSERT_EQ(ParseVariantKey(v.Key()), v) << v.Key();
    const nlohmann::json j = v;
    ASSERT_EQ(j.get<Variant>(), v) << j.dump();
    ++checked;
  };
  space.ForEach(round_trip);
  EXPECT_EQ(checked, space.Size());
  checked = 0;
  // Every other animation value beside every language, normals, morph and normal format.
  for (const Animation a : TuningSpace::Full().animations) {
    if (a == Animation::kHost) continue;
    TuningSpace one = space;
    one.animations = {a};
    one.influences = {4};
    one.wg_sizes = {128};
    one.layouts = {Layout::kSoa};
    one.positions = {PositionFormat::kFloat4};
    one.indices = {IndexFormat::kU16};
    one.weights = {WeightFormat::kF32};
    one.storages = {PaletteStorage::kGlobal};
    one.vertices_per_item = {1};
    one.ForEach(round_trip);
  }
}

TEST(VariantKey, TokensMayComeInAnyOrderAndOmittedAxesTakeDefaults) {
  const Variant v = ParseVariantKey("wg256.cuda.b2.u8.soa-split");
  EXPECT_EQ(v.lang, Lang::kCuda);
  EXPECT_EQ(v.influences, 2);
  EXPECT_EQ(v.index, IndexFormat::kU8);
  EXPECT_EQ(v.layout, Layout::kSoaSplit);
  EXPECT_EQ(v.wg_size, 256);
  EXPECT_EQ(v.weight, Variant{}.weight);
}

TEST(VariantKey, GlslVertexDefaultsToNoWorkGroups) {
  EXPECT_EQ(ParseVariantKey("glsl-vertex.b1").wg_size, 0);
}

TEST(VariantKey, MalformedKeysNameTheBadToken) {
  EXPECT_EQ(ErrorOf([] { ParseVariantKey("opencl.b4.fast"); }).rfind("variant 'opencl.b4.fast': unknown token 'fast' (expected <lang>", 0), 0u);
  EXPECT_NE(ErrorOf([] { ParseVariantKey("opencl..b4"); }).find("unknown token ''"), std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseVariantKey(""); }).find("empty key"), std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseVariantKey("opencl.cuda"); }).find("axis 'lang' given twice"), std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseVariantKey("b4.bx"); }).find("unknown token 'bx'"), std::string::npos);
  EXPECT_NE(ErrorOf([] { ParseVariantKey("v2x"); }).find("unknown token 'v2x'"), std::string::npos);
}

TEST(VariantJson, RejectsUnknownValuesAndMismatchedKeys) {
  EXPECT_NE(ErrorOf([] { nlohmann::json{{"layout", "zigzag"}}.get<Variant>(); }).find("'layout' has unknown value 'zigzag'"), std::string::npos);
  EXPECT_NE(ErrorOf([] { nlohmann::json{{"influences", "four"}}.get<Variant>(); }).find("'influences' must be an integer"), std::string::npos);
  EXPECT_NE(ErrorOf([] { nlohmann::json{{"key", "cuda.b1"}, {"lang", "opencl"}}.get<Variant>(); }).find("does not match"), std::string::npos);
}

// The normals axis was a flag before tangents: files written then say
// false / true, which read as none / normals; its names read as themselves,
// and the key keeps its old tokens.
TEST(VariantJson, TheNormalsAxisReadsOldFlagsAndItsNames) {
  const auto read = [](const nlohmann::json& value) { return nlohmann::json{{"normals", value}}.get<Variant>().normals; };
  EXPECT_EQ(read(false), Normals::kNone);
  EXPECT_EQ(read(true), Normals::kNormals);
  EXPECT_EQ(read("tangents"), Normals::kTangents);
  EXPECT_EQ(read("none"), Normals::kNone);
  EXPECT_NE(ErrorOf([] { nlohmann::json{{"normals", "yes"}}.get<Variant>(); }).find("'normals' has unknown value 'yes'"),
            std::string::npos);
  Variant v;
  v.normals = Normals::kTangents;
  EXPECT_EQ(nlohmann::json(v)["normals"], "tangents");
  EXPECT_TRUE(v.Key().ends_with(".tangents")) << v.Key();
  EXPECT_EQ(ParseVariantKey("opencl.b4.nonormals").normals, Normals::kNone);
  EXPECT_EQ(ParseVariantKey("opencl.b4.normals").normals, Normals::kNormals);
}

TEST(VariantHash, IsStableAndDistinguishesVariants) {
  EXPECT_EQ(Variant{}.Hash(), ParseVariantKey(Variant{}.Key()).Hash());
  std::unordered_set<std::size_t> hashes;
  TuningSpace space = TuningSpace::Full();
  space.langs = {Lang::kOpenCl};
  space.influences = {4};
  // Two values of the largest axes keep the test's time; every axis still varies.
  space.wg_sizes = {32, 1024};
  space.morphs = {Morph::kNone, Morph::kSparseHalf};
  std::size_t n = 0;
  space.ForEach([&](const Variant& v) { hashes.insert(v.Hash()); ++n; });
  EXPECT_EQ(hashes.size(), n);
}

}  // namespace
}  // namespace skintune::internal
