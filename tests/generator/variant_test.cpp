#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <tuple>
#include <unordered_map>
#include <utility>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
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

void ExpectRoundTrip(const Variant& v) {
  ASSERT_EQ(ParseVariantKey(v.Key()), v) << v.Key();
  const nlohmann::json j = v;
  ASSERT_EQ(j.get<Variant>(), v) << j.dump();
}

// `full` with every axis `keep` refuses cut to the value `pick` says (the
// axis's index in SpaceLists order -> the value's position, modulo the
// list's length).
template <typename Keep, typename Pick>
TuningSpace CutTo(const TuningSpace& full, Keep keep, Pick pick) {
  TuningSpace s = full;
  std::size_t axis = 0;
  std::apply(
      [&](auto&... lists) {
        const auto cut = [&](auto& list) {
          if (!keep(axis)) list = {list[pick(axis) % list.size()]};
          ++axis;
        };
        (cut(lists), ...);
      },
      SpaceLists(s));
  return s;
}

constexpr std::size_t kAxes = std::tuple_size_v<decltype(SpaceLists(std::declval<TuningSpace&>()))>;

// Every value of every axis beside every value of every other axis (the
// others at one value, a different one for each pair), so any two tokens
// that could interfere in a key meet; the whole product (about 10^9 points)
// took 243 s of CI on one core with only its B and work-group axes cut.
TEST(VariantKey, EveryPairOfAxisValuesRoundTripsThroughItsKeyAndJson) {
  const TuningSpace full = TuningSpace::Full();
  std::uint64_t checked = 0;
  for (std::size_t a = 0; a < kAxes; ++a)
    for (std::size_t b = a + 1; b < kAxes; ++b) {
      const TuningSpace pair = CutTo(
          full, [&](std::size_t axis) { return axis == a || axis == b; },
          [&](std::size_t axis) { return a * kAxes + b + axis; });
      pair.ForEach(ExpectRoundTrip);
      checked += pair.Size();
    }
  EXPECT_GT(checked, 1000u);
}

// And 20,000 points of the whole space drawn at random (fixed seed): keys
// whose every token is chosen at once.
TEST(VariantKey, RandomPointsOfTheFullSpaceRoundTripThroughTheirKeyAndJson) {
  const TuningSpace full = TuningSpace::Full();
  std::mt19937_64 rng(20261202);
  for (int n = 0; n < 20000; ++n) {
    const TuningSpace point =
        CutTo(full, [](std::size_t) { return false; }, [&](std::size_t) { return static_cast<std::size_t>(rng()); });
    ASSERT_EQ(point.Size(), 1u);
    point.ForEach(ExpectRoundTrip);
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

// Distinct variants hash apart, and a variant's hash is its key's: every
// pair of axis values (as the key test above), 100,000 points of the full
// space drawn at random, and the whole product of the axes that say how a
// kernel reads and stores its data (layout to normal format) at one point of
// the others, where a hash that combined its axes weakly would collide first.
// The whole product of every axis but language, B, work-group size and morph
// took 111 s of one core.
TEST(VariantHash, IsStableAndDistinguishesVariants) {
  EXPECT_EQ(Variant{}.Hash(), ParseVariantKey(Variant{}.Key()).Hash());
  std::unordered_map<std::size_t, std::string> seen;  // hash -> key
  std::size_t shared = 0, unstable = 0;
  std::string example;
  const auto distinct = [&](const Variant& v) {
    const std::string key = v.Key();
    const auto [at, fresh] = seen.emplace(v.Hash(), key);
    if (!fresh && at->second != key && shared++ == 0) example = at->second + " and " + key;
    if (v.Hash() != ParseVariantKey(key).Hash() && unstable++ == 0) example += " (unstable: " + key + ")";
  };
  const TuningSpace full = TuningSpace::Full();
  for (std::size_t a = 0; a < kAxes; ++a)
    for (std::size_t b = a + 1; b < kAxes; ++b)
      CutTo(
          full, [&](std::size_t axis) { return axis == a || axis == b; },
          [&](std::size_t axis) { return a * kAxes + b + axis; })
          .ForEach(distinct);
  std::mt19937_64 rng(1202);
  for (int n = 0; n < 100000; ++n)
    CutTo(full, [](std::size_t) { return false; }, [&](std::size_t) { return static_cast<std::size_t>(rng()); })
        .ForEach(distinct);
  const std::size_t first = AxisIndex<&Variant::layout>(), last = AxisIndex<&Variant::normal_format>();
  const auto format_axis = [&](std::size_t axis) {
    return axis >= first && axis <= last && axis != AxisIndex<&Variant::wg_size>() && axis != AxisIndex<&Variant::morph>();
  };
  const TuningSpace formats = CutTo(full, format_axis, [](std::size_t) { return 0; });
  EXPECT_GT(formats.Size(), 10000u);
  formats.ForEach(distinct);
  EXPECT_GT(seen.size(), 50000u);
  EXPECT_EQ(shared, 0u) << "variants that share a hash, e.g. " << example;
  EXPECT_EQ(unstable, 0u) << example;
}

}  // namespace
}  // namespace skintune::internal
