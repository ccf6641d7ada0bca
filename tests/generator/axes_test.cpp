// The axes table against everything that spells axes: keys, JSON, configs,
// kernels' #defines, and the JSON schemas (data files the compiler cannot
// check). Every case is generated from the table, so a new axis or value is
// tested without touching this file.
#include "generator/axes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/emit.h"
#include "generator/space.h"
#include "generator/variant.h"

namespace skintune::internal {
namespace {

// Variant{} (OpenCL: every axis has work-groups) with axis i set to `code`.
Variant With(std::size_t i, int code) {
  Variant v;
  kAxes[i].Set(v, code);
  return v;
}

// Every listed value of every axis, as (axis, code).
std::vector<std::pair<std::size_t, int>> EveryValue() {
  std::vector<std::pair<std::size_t, int>> all;
  for (std::size_t i = 0; i < kAxisCount; ++i)
    for (const AxisValueSpec& value : kAxes[i].values) all.emplace_back(i, value.code);
  return all;
}

TEST(Axes, EveryValueRoundTripsThroughKeyAndJson) {
  for (const auto& [i, code] : EveryValue()) {
    const Variant v = With(i, code);
    EXPECT_EQ(kAxes[i].Get(v), code) << kAxes[i].name;
    EXPECT_EQ(ParseVariantKey(v.Key()), v) << v.Key();
    const nlohmann::json j = v;
    EXPECT_EQ(j.at(kAxes[i].name), ValueJson(kAxes[i], code)) << j.dump();
    EXPECT_EQ(j.get<Variant>(), v) << j.dump();
  }
}

TEST(Axes, EveryTokenAloneSetsItsAxisOnly) {
  for (const auto& [i, code] : EveryValue()) {
    if (kAxes[i].joins_previous) continue;  // its token is part of the previous axis's
    Variant expected = With(i, code);
    std::string token = KeyToken(kAxes[i], code);
    if (JoinsNext(i)) token += KeyToken(kAxes[i + 1], kAxes[i + 1].Get(expected));
    if (!HasWorkGroups(expected.lang)) expected = CollapseWorkGroups(expected);
    EXPECT_EQ(ParseVariantKey(token), expected) << token;
  }
}

TEST(Axes, EveryValueRoundTripsThroughASpaceConfig) {
  // One value per axis (the default's), then each value of each axis in turn.
  nlohmann::json base = nlohmann::json::object();
  for (const Axis& a : kAxes) base[a.name] = nlohmann::json::array({ValueJson(a, a.Get(Variant{}))});
  for (const auto& [i, code] : EveryValue()) {
    nlohmann::json config = base;
    config[kAxes[i].name] = nlohmann::json::array({ValueJson(kAxes[i], code)});
    const TuningSpace space = SpaceFromJson(config, "c.json");
    EXPECT_EQ(nlohmann::json(space), config);
    std::vector<Variant> visited;
    space.ForEach([&](const Variant& v) { visited.push_back(v); });
    EXPECT_EQ(visited, std::vector<Variant>{CollapseWorkGroups(With(i, code))}) << config.dump();
    EXPECT_EQ(space.Size(), 1u);
  }
}

TEST(Axes, FullSpaceListsEveryValueOfTheTable) {
  const nlohmann::json full = TuningSpace::Full();
  ASSERT_EQ(full.size(), kAxisCount);
  for (const Axis& a : kAxes) {
    nlohmann::json expected = nlohmann::json::array();
    for (const AxisValueSpec& value : a.values) expected.push_back(ValueJson(a, value.code));
    EXPECT_EQ(full.at(a.name), expected) << a.name;
  }
}

TEST(Axes, KeyFormatIsTheGrammarErrorsHaveAlwaysQuoted) {
  EXPECT_EQ(KeyFormat(),
            "<lang>.b<B>.<padded|bucketed>.<aos|soa|soa-split>.<float4|float3>.<i32|u16|u8>.<f32|unorm16|unorm8>"
            ".<mat4|mat3x4|dualquat>.<constant|local|global|image>.<matrix|point|dq>.v<1|2|4|8><c|s>.wg<N>"
            ".<nonormals|normals|tangents>[.<morph-dense|morph-sparse|morph-dense-half|morph-sparse-half>]"
            "[.<normals-oct16|normals-snorm8>]"
            "[.anim-<sampled|<baked|local|hybrid|fused|fusedlocal|fusedhybrid><30|60|120|240>>]");
}

TEST(Axes, CodesDifferExactlyOnTheAxisThatDiffers) {
  for (const auto& [i, code] : EveryValue()) {
    for (const AxisValueSpec& other : kAxes[i].values) {
      if (other.code == code) continue;
      const std::array<int, kAxisCount> a = AxisCodes(With(i, code)), b = AxisCodes(With(i, other.code));
      for (std::size_t k = 0; k < kAxisCount; ++k) EXPECT_EQ(a[k] != b[k], k == i) << kAxes[i].name << " " << k;
    }
  }
}

TEST(Axes, EachDefineCarriesItsAxisValueIntoTheKernel) {
  for (const auto& [i, code] : EveryValue()) {
    const Axis& a = kAxes[i];
    if (*a.define == '\0') continue;
    const KernelSource source = Emit(With(i, code), 0, 77, EmitOptions{.morph_targets = 3});
    const auto it = std::find_if(source.defines.begin(), source.defines.end(),
                                 [&](const auto& d) { return d.first == a.define; });
    ASSERT_NE(it, source.defines.end()) << a.define;
    EXPECT_EQ(it->second, DefineValue(a, code)) << a.define;
  }
}

// configs/*.schema.json are data: they must list the table's axes and values.
nlohmann::json ReadSchema(const std::filesystem::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

const nlohmann::json& Resolve(const nlohmann::json& schema, const nlohmann::json& node) {
  if (!node.contains("$ref")) return node;
  const std::string ref = node["$ref"].get<std::string>();
  return schema.at(nlohmann::json::json_pointer(ref.substr(1)));  // "#/$defs/lang"
}

void ExpectPropertyMatches(const nlohmann::json& schema, const nlohmann::json& property, const Axis& a,
                           const std::string& where) {
  const nlohmann::json& p = Resolve(schema, property);
  std::vector<int> codes;
  for (const AxisValueSpec& value : a.values) codes.push_back(value.code);
  switch (a.field.kind) {
    case AxisKind::kFlag: EXPECT_EQ(p.value("type", ""), "boolean") << where; return;
    case AxisKind::kEnum: {
      nlohmann::json names = nlohmann::json::array();
      for (int code : codes) names.push_back(ValueJson(a, code));
      if (a.reads_flags) names.insert(names.end(), {false, true});  // what older files wrote
      EXPECT_EQ(p.value("enum", nlohmann::json()), names) << where;
      return;
    }
    case AxisKind::kNumber: break;
  }
  if (p.contains("enum")) {
    EXPECT_EQ(p["enum"], nlohmann::json(codes)) << where;
    return;
  }
  if (a.without_work_groups) codes.push_back(*a.without_work_groups);  // wg0
  EXPECT_EQ(p.value("minimum", -1), *std::min_element(codes.begin(), codes.end())) << where;
  EXPECT_EQ(p.value("maximum", -1), *std::max_element(codes.begin(), codes.end())) << where;
  for (int code : codes) EXPECT_EQ(code % p.value("multipleOf", 1), 0) << where << " " << code;
}

// Checks every object whose properties hold a whole variant, and every
// "lang" property; returns how many variant objects it found.
int CheckSchemaNode(const nlohmann::json& schema, const nlohmann::json& node, const std::string& where) {
  int variants = 0;
  if (node.is_object() && node.contains("properties") && node["properties"].is_object()) {
    const nlohmann::json& properties = node["properties"];
    if (properties.contains("layout")) {
      ++variants;
      std::vector<std::string> names;  // required: every axis but those added after files were written
      for (const Axis& a : kAxes) {
        if (!a.key_omits_default) names.push_back(a.name);
        if (!properties.contains(a.name)) {
          ADD_FAILURE() << where << " lacks the axis " << a.name;
          continue;
        }
        ExpectPropertyMatches(schema, properties[a.name], a, where + "." + a.name);
      }
      EXPECT_EQ(node.value("required", nlohmann::json()), nlohmann::json(names)) << where;
    } else if (properties.contains("lang")) {
      ExpectPropertyMatches(schema, properties["lang"], AxisOf<&Variant::lang>(), where + ".lang");
    }
  }
  if (node.is_structured()) {
    for (const auto& [key, child] : node.items()) variants += CheckSchemaNode(schema, child, where + "/" + key);
  }
  return variants;
}

TEST(Axes, SchemasListTheTablesAxesAndValues) {
  std::set<std::string> with_variants;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(SKINTUNE_SOURCE_DIR) + "/configs")) {
    const std::string name = entry.path().filename().string();
    if (!name.ends_with(".schema.json")) continue;
    const nlohmann::json schema = ReadSchema(entry.path());
    if (CheckSchemaNode(schema, schema, name) > 0) with_variants.insert(name);
  }
  // Not vacuous: the two schemas that spell variants out were found and read.
  EXPECT_TRUE(with_variants.count("report.schema.json"));
  EXPECT_TRUE(with_variants.count("winners-db.schema.json"));
}

}  // namespace
}  // namespace skintune::internal
