// Every OpenCL variant axis value, run on a real OpenCL device (PoCL in CI)
// against the float64 gold, on a fresh random synthetic mesh each run (the
// seed is printed; SKINTUNE_TEST_SEED=<n> reproduces a run) and on CesiumMan
// for the bucketed launches. Plus: the poisoned output catches a kernel that
// skips vertices, the guard one that writes past the end, and a build error
// carries its log.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdlib>
#include <iostream>
#include <map>
#include <ostream>
#include <random>

#include "generator/covering.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "reference/error.h"
#include "reference/gltf_import.h"
#include "reference/skinning.h"
#include "reference/synthetic.h"
#include "runtime/opencl_devices.h"
#include "runtime/opencl_runner.h"

namespace skintune {
namespace {

constexpr double kTolerance = 1e-5;

std::uint64_t Seed() {
  static const std::uint64_t seed = []() -> std::uint64_t {
    if (const char* env = std::getenv("SKINTUNE_TEST_SEED")) return static_cast<std::uint64_t>(std::strtoull(env, nullptr, 10));
    return static_cast<std::uint64_t>(std::random_device{}()) % 1000000 + 1;
  }();
  return seed;
}

// The device these tests run on: the first OpenCL device, or the first whose
// "platform-vendor platform / name" contains $SKINTUNE_TEST_OPENCL_DEVICE.
// Null (with the reason) when the machine has none.
const OpenClDeviceInfo* TestDevice(std::string& why) {
  static std::string reason;
  static const std::vector<OpenClDeviceInfo> devices = [] {
    const char* pattern = std::getenv("SKINTUNE_TEST_OPENCL_DEVICE");
    const OpenClInventory inventory = EnumerateOpenCl();
    std::vector<OpenClDeviceInfo> found = MatchDevices(inventory, pattern ? pattern : "");
    if (found.empty()) {
      reason = pattern ? "no OpenCL device matches SKINTUNE_TEST_OPENCL_DEVICE='" + std::string(pattern) + "'"
                       : "no OpenCL device on this machine: " + inventory.status;
    }
    return found;
  }();
  why = reason;
  return devices.empty() ? nullptr : &devices.front();
}

OpenClRunner* Runner(std::string& why) {
  static std::unique_ptr<OpenClRunner> runner = [&why]() -> std::unique_ptr<OpenClRunner> {
    const OpenClDeviceInfo* d = TestDevice(why);
    return d ? std::make_unique<OpenClRunner>(d->platform_index, d->device_index) : nullptr;
  }();
  if (!runner) {
    TestDevice(why);
    // An explicitly requested device that is missing is a failure, not a skip.
    if (std::getenv("SKINTUNE_TEST_OPENCL_DEVICE")) ADD_FAILURE() << why;
  }
  return runner.get();
}

// "cesium" or a synthetic dataset: <influences> bone slots, optionally random bones.
struct Case {
  const char* key;
  const char* mesh;  // "cesium", or a dataset key suffix such as "b3" / "b3-random"
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.key << " on " << c.mesh; }

const SkinnedAsset& Asset(const std::string& mesh) {
  static std::map<std::string, SkinnedAsset> cache;
  if (auto found = cache.find(mesh); found != cache.end()) return found->second;
  if (mesh == "cesium") {
    return cache[mesh] = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
  }
  // 5000 vertices plus a seed-dependent tail, so launches end mid-work-group.
  const std::string key = std::to_string(5000 + Seed() % 97) + "-" + mesh + "-seed" + std::to_string(Seed()) +
                          "-normals";
  return cache[mesh] = GenerateDataset(ParseDatasetKey(key));
}

std::vector<glm::mat4> Palette(const SkinnedAsset& asset) {
  if (asset.animations.empty()) return asset.PaletteAt(-1, 0.0);
  const AnimationClip& clip = asset.animations.front();
  const double t = clip.start + (clip.end - clip.start) * static_cast<double>(Seed() % 1000) / 1000.0;
  return asset.PaletteAt(0, t);
}

void ExpectMatchesGold(const PackedMesh& packed, const OpenClRunResult& result, const SkinnedMesh& mesh,
                       std::span<const glm::mat4> palette) {
  const SkinnedMesh quantised = QuantisedMesh(mesh, packed.variant);
  const GoldResult gold = SkinGold(quantised, palette, packed.variant.normals);
  EXPECT_EQ(result.poisoned_vertices, 0u);
  const GoldComparison p = CompareToGold(gold.positions, Unpack(packed, result.positions));
  EXPECT_EQ(p.non_finite, 0u) << "first at vertex " << p.worst_vertex;
  EXPECT_LT(p.max_relative, kTolerance) << "positions, worst vertex " << p.worst_vertex;
  if (packed.variant.normals) {
    const GoldComparison n = CompareToGold(gold.normals, Unpack(packed, result.normals));
    EXPECT_EQ(n.non_finite, 0u) << "first at vertex " << n.worst_vertex;
    EXPECT_LT(n.max_relative, kTolerance) << "normals, worst vertex " << n.worst_vertex;
  }
  EXPECT_EQ(result.launch_ms.size(), packed.launches.size());
}

class OpenClVariant : public ::testing::TestWithParam<Case> {};

TEST_P(OpenClVariant, MatchesTheGold) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const Case& c = GetParam();
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + ", seed " + std::to_string(Seed()) +
               " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name());
  const SkinnedAsset& asset = Asset(c.mesh);
  const Variant variant = ParseVariantKey(c.key);
  const PackedMesh packed = Pack(asset.mesh, variant);
  const std::vector<glm::mat4> palette = Palette(asset);
  const OpenClRunResult result = runner->Run(packed, PackPalette(palette, variant));
  ExpectMatchesGold(packed, result, asset.mesh, palette);
  if (variant.mixed == MixedCounts::kBucketed && std::string(c.mesh) == "cesium") {
    EXPECT_EQ(packed.launches.size(), 4u);  // CesiumMan: vertices with 1, 2, 3 and 4 bones
  }
}

// Every value of every axis at least once; every layout with every index
// format, every weight format and every storage.
const Case kCases[] = {
    // layout x index x weight
    {"opencl.b4.padded.aos.float4.i32.f32.mat4.constant.matrix.v1c.wg64.nonormals", "b4"},
    {"opencl.b3.padded.aos.float3.u16.unorm16.mat3x4.local.point.v2c.wg32.normals", "b3"},
    {"opencl.b1.padded.aos.float4.u8.unorm8.mat3x4.image.matrix.v4s.wg256.normals", "b1"},
    {"opencl.b2.padded.soa.float3.i32.unorm16.mat3x4.global.point.v8c.wg128.nonormals", "b2"},
    {"opencl.b5.padded.soa.float4.u16.unorm8.mat4.image.matrix.v2s.wg64.normals", "b5-random"},
    {"opencl.b8.padded.soa.float3.u8.f32.mat4.local.matrix.v1c.wg1024.nonormals", "b8"},
    {"opencl.b6.padded.soa-split.float4.i32.unorm8.mat3x4.constant.point.v4c.wg32.normals", "b6-random"},
    {"opencl.b7.padded.soa-split.float3.u16.f32.mat4.global.matrix.v8s.wg512.nonormals", "b7"},
    {"opencl.b4.padded.soa-split.float4.u8.unorm16.mat3x4.local.matrix.v2c.wg256.normals", "b4"},
    // the storage each layout has not seen yet
    {"opencl.b4.padded.aos.float3.u16.unorm8.mat4.global.point.v1c.wg128.normals", "b4"},
    {"opencl.b4.padded.soa.float4.u16.f32.mat3x4.constant.matrix.v1c.wg128.normals", "b4-random"},
    {"opencl.b3.padded.soa-split.float3.u8.unorm8.mat4.image.point.v4s.wg64.normals", "b3"},
    // padding: more slots than the mesh uses
    {"opencl.b8.padded.aos.float4.i32.f32.mat3x4.global.matrix.v1c.wg128.nonormals", "b3"},
    {"opencl.b4.padded.soa-split.float3.u8.f32.mat3x4.constant.matrix.v2c.wg64.normals", "cesium"},
    // bucketed: one launch per influence count, each with its own kernel
    {"opencl.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.normals", "cesium"},
    {"opencl.b4.bucketed.aos.float3.u8.unorm8.mat4.local.point.v2s.wg64.normals", "cesium"},
    {"opencl.b4.bucketed.soa-split.float4.u16.unorm16.mat3x4.image.matrix.v4c.wg32.nonormals", "cesium"},
    {"opencl.b2.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v8s.wg256.nonormals", "b2"},
    {"opencl.b4.bucketed.soa.float3.i32.unorm16.mat4.constant.point.v8s.wg512.normals", "cesium"},
    {"opencl.b6.bucketed.soa-split.float3.u8.unorm8.mat4.local.point.v2c.wg64.normals", "cesium"},
    {"opencl.b8.padded.soa.float4.u16.unorm16.mat4.global.matrix.v1c.wg128.normals", "cesium"},
    // more crossings: point blend with every storage and layout, local copies with large groups
    {"opencl.b4.padded.aos.float4.u8.f32.mat3x4.constant.point.v8s.wg256.normals", "b4"},
    {"opencl.b2.padded.aos.float3.i32.unorm16.mat4.image.point.v2c.wg512.nonormals", "b2"},
    {"opencl.b6.padded.aos.float4.u16.unorm8.mat4.local.matrix.v4c.wg1024.normals", "b6"},
    {"opencl.b1.padded.soa.float4.u8.unorm16.mat4.constant.point.v4s.wg32.normals", "b1"},
    {"opencl.b3.padded.soa.float3.u16.f32.mat3x4.local.point.v8s.wg256.normals", "b3-random"},
    {"opencl.b7.padded.soa.float4.i32.unorm8.mat3x4.image.point.v1c.wg64.normals", "b7"},
    {"opencl.b8.padded.soa-split.float4.u16.f32.mat4.local.point.v8c.wg128.normals", "b8-random"},
    {"opencl.b5.padded.soa-split.float3.i32.unorm16.mat3x4.constant.matrix.v2s.wg1024.normals", "b5"},
    {"opencl.b1.padded.soa-split.float4.u8.unorm8.mat3x4.global.point.v1c.wg32.normals", "b1"},
};

std::string CaseName(const ::testing::TestParamInfo<Case>& info) {
  std::string name = std::to_string(info.index) + "_" + info.param.key + "_" + info.param.mesh;
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return name;
}

INSTANTIATE_TEST_SUITE_P(EveryAxis, OpenClVariant, ::testing::ValuesIn(kCases), CaseName);

// The generated covering set for this device (generator/covering.h): every
// value of every axis and every pair of layout x index x weight x palette x
// storage x blend, each variant on a fresh mesh with its own influence count.
TEST(OpenClCoveringSet, EveryVariantMatchesTheGold) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const DeviceLimits limits = LimitsOf(*TestDevice(why));
  const CoveringSet set = BuildCoveringSet(Lang::kOpenCl, limits, {77, 1, true});
  ASSERT_TRUE(set.uncoverable.empty());
  for (std::size_t i = 0; i < set.variants.size(); ++i) {
    const Variant& variant = set.variants[i];
    const std::string mesh = "b" + std::to_string(variant.influences) + (i % 2 ? "-random" : "");
    SCOPED_TRACE(variant.Key() + " on " + mesh + ", seed " + std::to_string(Seed()));
    const SkinnedAsset& asset = Asset(mesh);
    const PackedMesh packed = Pack(asset.mesh, variant);
    const std::vector<glm::mat4> palette = Palette(asset);
    ExpectMatchesGold(packed, runner->Run(packed, PackPalette(palette, variant)), asset.mesh, palette);
  }
  std::cout << "[ covering ] " << set.variants.size() << " OpenCL variants verified on " << runner->device_name()
            << "\n";
}

// One padded soa launch with an edit of the emitted text; `from` must occur once.
struct Faulty {
  PackedMesh packed;
  std::vector<glm::mat4> palette;
  std::vector<KernelSource> kernels;
};

Faulty WithFault(const std::string& from, const std::string& to) {
  Faulty f;
  const SkinnedAsset& asset = Asset("b2");
  f.packed = Pack(asset.mesh, ParseVariantKey("opencl.b2.soa.float4.u16.f32.wg64"));
  f.palette = Palette(asset);
  KernelSource s = Emit(f.packed.variant, 0, static_cast<int>(f.packed.palette_joints));
  const std::size_t at = s.text.find(from);
  EXPECT_NE(at, std::string::npos) << "'" << from << "' not in the template any more: update the test";
  EXPECT_EQ(s.text.find(from, at + 1), std::string::npos) << "'" << from << "' occurs twice";
  if (at != std::string::npos) s.text.replace(at, from.size(), to);
  s.source_hash = SourceHash(s.text);
  f.kernels.push_back(std::move(s));
  return f;
}

TEST(OpenClRunner, PoisonedOutputCatchesAKernelThatSkipsVertices) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault("if (v >= n) break;", "if (v >= n / 2) break;");
  const OpenClRunResult result = runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant));
  const std::size_t n = f.packed.vertex_count;
  EXPECT_EQ(result.poisoned_vertices, n - n / 2);
  const GoldResult gold = SkinGold(Asset("b2").mesh, f.palette);
  const GoldComparison c = CompareToGold(gold.positions, Unpack(f.packed, result.positions));
  EXPECT_EQ(c.non_finite, n - n / 2);
  EXPECT_FALSE(c.max_relative < kTolerance);
}

TEST(OpenClRunner, GuardCatchesAKernelThatWritesPastTheEnd) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault("STORE_XYZ(out_positions, first + v,", "STORE_XYZ(out_positions, first + v + 64,");
  try {
    runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant));
    ADD_FAILURE() << "a kernel writing 64 vertices past its output was not caught";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("OpenCL guard"), std::string::npos) << message;
    EXPECT_NE(message.find("out_positions"), std::string::npos) << message;
    EXPECT_NE(message.find("wrote past the end"), std::string::npos) << message;
  }
}

TEST(OpenClRunner, BuildFailureCarriesTheBuildLog) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault("if (v >= n) break;", "if (v >= n) break; undeclared_name_xyz = 1;");
  try {
    runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant));
    ADD_FAILURE() << "a kernel with an undeclared name built";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("OpenCL build"), std::string::npos) << message;
    EXPECT_NE(message.find("undeclared_name_xyz"), std::string::npos) << message;
  }
}

TEST(OpenClRunner, RejectsAPaletteOfTheWrongSizeAndAMissingDevice) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const PackedMesh packed = Pack(Asset("b2").mesh, ParseVariantKey("opencl.b2.soa"));
  const std::vector<std::uint8_t> short_palette(16);
  try {
    runner->Run(packed, short_palette);
    ADD_FAILURE() << "a 16-byte palette was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("palette has 16 bytes"), std::string::npos) << e.what();
  }
  try {
    OpenClRunner missing(0, 1000);
    ADD_FAILURE() << "device 1000 exists";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("OpenCL setup"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skintune
