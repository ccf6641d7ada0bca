#include <gtest/gtest.h>

#include <set>

#include "generator/axes.h"
#include "generator/covering.h"
#include "generator/space.h"

namespace skintune::internal {
namespace {

DeviceLimits Roomy() {
  DeviceLimits d;
  d.max_wg_size = 1024;
  d.local_memory_bytes = 48 * 1024;
  return d;
}

// 77 joints, normals and tangents, rigid joints, and morph targets that the
// mesh may apply or not (weights of 0): every morph value is of this data set.
ProblemShape Shape() {
  ProblemShape shape{77, 1, true, 1, true, true};
  shape.morph_targets = 4;
  return shape;
}
const ProblemShape kShape = Shape();

TEST(CoveringSet, EveryValueOfEveryAxisAppearsForEachLanguage) {
  for (Lang lang : {Lang::kOpenCl, Lang::kCuda, Lang::kGlslCompute, Lang::kGlslVertex}) {
    const CoveringSet set = BuildCoveringSet(lang, Roomy(), kShape);
    std::set<std::string> seen;
    for (const Variant& v : set.variants) {
      EXPECT_TRUE(CheckVariant(v, Roomy(), kShape).empty()) << v.Key();
      seen.insert({"b" + std::to_string(v.influences), Name(v.mixed), Name(v.layout), Name(v.position),
                   Name(v.index), Name(v.weight), Name(v.palette), Name(v.storage), Name(v.blend),
                   "v" + std::to_string(v.vertices_per_item), Name(v.assignment), "wg" + std::to_string(v.wg_size),
                   KeyToken(AxisOf<&Variant::normals>(), static_cast<int>(v.normals)),
                   KeyToken(AxisOf<&Variant::morph>(), static_cast<int>(v.morph))});
    }
    std::vector<std::string> expected = {"b1", "b2", "b3", "b4", "b5", "b6", "b7", "b8", "padded", "bucketed", "aos",
                                         "soa", "soa-split", "float4", "float3", "i32", "u16", "u8", "f32", "unorm16",
                                         "unorm8", "mat4", "mat3x4", "dualquat", "constant", "global", "image", "matrix",
                                         "point", "dq",
                                         "normals", "nonormals", "tangents", "nomorph", "morph-dense",
                                         "morph-sparse", "morph-dense-half", "morph-sparse-half"};
    if (lang == Lang::kGlslVertex) {
      expected.insert(expected.end(), {"v1", "contiguous", "wg0"});
    } else {
      expected.insert(expected.end(), {"local", "v1", "v2", "v4", "v8", "contiguous", "strided", "wg32", "wg64",
                                       "wg128", "wg256", "wg512", "wg1024"});
    }
    for (const std::string& value : expected) EXPECT_TRUE(seen.count(value)) << Name(lang) << " misses " << value;
  }
}

TEST(CoveringSet, EveryPairOfThePairedAxesAppears) {
  for (Lang lang : {Lang::kOpenCl, Lang::kGlslCompute}) {
    const CoveringSet set = BuildCoveringSet(lang, Roomy(), kShape);
    EXPECT_TRUE(set.uncoverable.empty());
    std::set<std::string> pairs;
    for (const Variant& v : set.variants) {
      const std::vector<std::string> values = {Name(v.layout), Name(v.index), Name(v.weight),
                                               Name(v.palette), Name(v.storage), Name(v.blend)};
      for (std::size_t a = 0; a < values.size(); ++a)
        for (std::size_t b = a + 1; b < values.size(); ++b) pairs.insert(values[a] + "&" + values[b]);
    }
    // 15 axis pairs: 9+9+9+12+9 + 9+9+12+9 + 9+12+9 + 12+5 + 12 value pairs (palette x blend: the
    // linear blends with mat4 and mat3x4, dq with dualquat alone).
    EXPECT_EQ(pairs.size(), 146u) << Name(lang);
    EXPECT_LE(set.variants.size(), 28u) << "a covering set should stay small";
  }
}

TEST(CoveringSet, ReportsPairsNoValidVariantCanHold) {
  const CoveringSet set = BuildCoveringSet(Lang::kGlslVertex, Roomy(), kShape);
  ASSERT_FALSE(set.uncoverable.empty());
  for (const std::string& pair : set.uncoverable) EXPECT_NE(pair.find("storage=local"), std::string::npos) << pair;
}

TEST(CoveringSet, DualQuaternionsOnlyWithTheirPaletteAndOnlyOnRigidMeshes) {
  for (const Variant& v : BuildCoveringSet(Lang::kOpenCl, Roomy(), kShape).variants)
    EXPECT_EQ(v.blend == Blend::kDualQuaternion, v.palette == PaletteFormat::kDualQuaternion) << v.Key();
  ProblemShape scaled = kShape;
  scaled.rigid_joints = false;
  const CoveringSet set = BuildCoveringSet(Lang::kOpenCl, Roomy(), scaled);
  EXPECT_TRUE(set.uncoverable.empty()) << "dq cannot skin a scaling mesh by construction, not for want of a device";
  for (const Variant& v : set.variants) EXPECT_NE(v.blend, Blend::kDualQuaternion) << v.Key();
}

// A mesh without morph targets has no morph variants; one whose targets move
// its vertices none without them.
TEST(CoveringSet, MorphValuesFollowTheDataSet) {
  ProblemShape none = kShape;
  none.morph_targets = 0;
  for (const Variant& v : BuildCoveringSet(Lang::kOpenCl, Roomy(), none).variants)
    EXPECT_EQ(v.morph, Morph::kNone) << v.Key();
  ProblemShape moving = kShape;
  moving.morph_moves = true;
  std::set<Morph> seen;
  for (const Variant& v : BuildCoveringSet(Lang::kOpenCl, Roomy(), moving).variants) {
    EXPECT_NE(v.morph, Morph::kNone) << v.Key();
    seen.insert(v.morph);
  }
  EXPECT_EQ(seen.size(), 4u) << "every layout and offset format of the morph targets";
}

TEST(CoveringSet, SkipsWorkGroupSizesAboveTheDeviceLimit) {
  DeviceLimits small = Roomy();
  small.max_wg_size = 256;
  for (const Variant& v : BuildCoveringSet(Lang::kOpenCl, small, kShape).variants) EXPECT_LE(v.wg_size, 256);
}

}  // namespace
}  // namespace skintune::internal
