// The language cpu (the fast path's kernels, cpu_kernels/cpu_kernels.h) through
// the runner driver on the host: every kernel of the table (B 1..8 x index
// u32/u16/u8 x weight f32/unorm16/unorm8 x mat4/mat3x4 x matrix/point, and
// dualquat dq) on fresh random meshes against the float64 gold of the
// weights as the variant stores them (the dual-quaternion gold for dq, on
// rigid palettes), with poisoned outputs and guards, across the three
// layouts, both position formats and normals; bucketed meshes, instances,
// timing with the per-variant schedule choice, the same-size copy, and the
// errors of bad kernel texts and storages. The seed is printed;
// SKINTUNE_TEST_SEED=<n> reproduces a run.
#include <gtest/gtest.h>

#include <iostream>
#include <random>

#include <glm/gtc/quaternion.hpp>

#include "generator/copy_kernel.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "cpu_kernels/cpu_kernels.h"
#include "base/error.h"
#include "runner_test_support.h"
#include "runtime/backend_table.h"
#include "runtime/backends/cpu/cpu_runner.h"

namespace skintune::internal {
namespace {

using namespace skintune::internal::testing;  // the runner tests' helpers (runner_test_support.h)

CpuRunner& Runner() {
  static CpuRunner runner;
  static const bool once = [] {
    std::cout << "[ cpu      ] " << runner.device_name() << ", seed " << Seed() << "\n";
    return true;
  }();
  (void)once;
  return runner;
}

// The variant running the table's kernel `key`, its layout, position format
// and normals rotated by `i`.
Variant VariantOf(const CpuKernelKey& key, std::size_t i) {
  Variant v = ParseVariantKey("cpu.v1c.wg0.global");
  v.influences = key.influences;
  switch (key.index) {
    case CpuIndex::kU32: v.index = IndexFormat::kI32; break;
    case CpuIndex::kU16: v.index = IndexFormat::kU16; break;
    case CpuIndex::kU8: v.index = IndexFormat::kU8; break;
  }
  switch (key.weight) {
    case CpuWeight::kF32: v.weight = WeightFormat::kF32; break;
    case CpuWeight::kUnorm16: v.weight = WeightFormat::kUnorm16; break;
    case CpuWeight::kUnorm8: v.weight = WeightFormat::kUnorm8; break;
  }
  v.palette = key.palette_rows == 2   ? PaletteFormat::kDualQuaternion
              : key.palette_rows == 3 ? PaletteFormat::kMat3x4
                                      : PaletteFormat::kMat4;
  v.blend = key.dual_quaternion ? Blend::kDualQuaternion : key.point_blend ? Blend::kPoint : Blend::kMatrix;
  const Layout layouts[] = {Layout::kAos, Layout::kSoa, Layout::kSoaSplit};
  v.layout = layouts[i % 3];
  v.position = (i / 3) % 2 ? PositionFormat::kFloat3 : PositionFormat::kFloat4;
  v.normals = (i / 2) % 2 == 1 ? Normals::kNormals : Normals::kNone;
  return v;
}

// The table's linear-blend keys (matrix and point), in table order.
std::vector<CpuKernelKey> LinearKeys() {
  std::vector<CpuKernelKey> keys = AllCpuKernelKeys();
  std::erase_if(keys, [](const CpuKernelKey& k) { return k.dual_quaternion; });
  return keys;
}

TEST(CpuRunner, EveryKernelOfTheTableMatchesTheGold) {
  const std::vector<CpuKernelKey> keys = LinearKeys();
  ASSERT_EQ(keys.size(), 8u * 3 * 3 * 2 * 2);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const Variant variant = VariantOf(keys[i], i);
    const std::string mesh = "b" + std::to_string(variant.influences) + (i % 2 ? "-random" : "");
    SCOPED_TRACE(CpuKernelName(keys[i]) + ": " + variant.Key() + " on " + mesh + ", seed " + std::to_string(Seed()));
    ExpectRunMatchesGold(Runner(), variant, mesh, LaunchTimes::kNonNegative);
    if (HasFailure()) return;  // one failing kernel says enough
  }
}

// Every dual-quaternion kernel through the device (BLEND 2, PALETTE_ROWS 2,
// the packer's 2-row palette) against the dual-quaternion gold of the
// weights as stored, on the rigid twin of each mesh at a frame of its
// animation (ExpectRunMatchesGold); its layouts and position formats turned
// as the linear kernels' are (float4 with tangents), and positions only,
// normals, and normals and tangents in turn. (Uniformly random rotations per
// joint, which no rig has, blend 8 quaternions into a short one whose
// normalisation amplifies float32 rounding: 1.3e-5 of a vertex's position
// on one seed of 30; tests/cpu_kernels/cpu_kernels_test.cpp checks the
// kernels' antipodality on such palettes, with fixed seeds.)
TEST(CpuRunner, EveryDualQuaternionKernelMatchesTheDualQuaternionGold) {
  std::vector<CpuKernelKey> keys = AllCpuKernelKeys();
  std::erase_if(keys, [](const CpuKernelKey& k) { return !k.dual_quaternion; });
  ASSERT_EQ(keys.size(), 8u * 3 * 3);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    Variant variant = VariantOf(keys[i], i);
    const Normals normals[] = {Normals::kNone, Normals::kNormals, Normals::kTangents};
    variant.normals = normals[i / 2 % 3];
    if (SkinsTangents(variant)) variant.position = PositionFormat::kFloat4;  // the tangents' 16-byte stride
    const std::string mesh = "b" + std::to_string(variant.influences) + (i % 2 ? "-random" : "");
    SCOPED_TRACE(CpuKernelName(keys[i]) + ": " + variant.Key() + " on " + mesh + ", seed " + std::to_string(Seed()));
    ExpectRunMatchesGold(Runner(), variant, mesh, LaunchTimes::kNonNegative);
    if (HasFailure()) return;  // one failing kernel says enough
  }
}

// The morph targets' pass before the table's kernels: every morph value in
// every layout, with positions only, normals, and normals and tangents, on
// meshes with morph targets (testing::kMorphMesh: dense and sparse targets,
// one at weight 0), against the gold of the mesh morphed in float64.
TEST(CpuRunner, MorphTargetsOfEveryValueAndLayoutMatchTheGold) {
  const Morph morphs[] = {Morph::kDense, Morph::kSparse, Morph::kDenseHalf, Morph::kSparseHalf};
  const Layout layouts[] = {Layout::kAos, Layout::kSoa, Layout::kSoaSplit};
  const Normals normals[] = {Normals::kNone, Normals::kNormals, Normals::kTangents};
  int i = 0;
  for (const Morph morph : morphs)
    for (const Layout layout : layouts)
      for (const Normals n : normals) {
        Variant variant = ParseVariantKey("cpu.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg0");
        variant.influences = 1 + i % 8;
        variant.morph = morph;
        variant.layout = layout;
        variant.normals = n;
        variant.weight = i % 3 == 0 ? WeightFormat::kUnorm16 : WeightFormat::kF32;
        variant.position = SkinsTangents(variant) || i % 2 ? PositionFormat::kFloat4 : PositionFormat::kFloat3;
        const std::string mesh = "b" + std::to_string(variant.influences) + (i % 2 ? "-random" : "");
        SCOPED_TRACE(variant.Key() + " on " + mesh + ", seed " + std::to_string(Seed()));
        ExpectRunMatchesGold(Runner(), variant, mesh, LaunchTimes::kNonNegative);
        if (HasFailure()) return;
        ++i;
      }
}

TEST(CpuRunner, BucketedCesiumManRunsOneKernelPerInfluenceCount) {
  const Case c{"cpu.b4.bucketed.soa-split.float3.u8.unorm16.mat4.global.matrix.v1c.wg0.normals", "cesium"};
  ExpectCaseMatchesGold(Runner(), c, ParseVariantKey(c.key), LaunchTimes::kNonNegative);
}

TEST(CpuRunner, InstancesEachSkinWithTheirOwnPalette) {
  for (const InstanceCase c : {InstanceCase{"cpu.b2.padded.soa.float4.u16.f32.mat4.global.matrix.v1c.wg0", "b2", 3},
                               InstanceCase{"cpu.b4.bucketed.aos.float3.u8.unorm8.mat3x4.global.point.v1c.wg0.normals",
                                            "cesium", 2}}) {
    SCOPED_TRACE(c.key);
    DeviceLimits limits;
    limits.image_support = false;
    ExpectInstanceCaseMatchesGold(Runner(), c, limits);
  }
}

// One variant on two meshes in one process (a tuner worker's data sets, a
// program's meshes) gets a schedule per mesh: chunks chosen for 5k vertices
// are none of a 100-vertex mesh's candidates, and the 5k mesh keeps its own.
TEST(CpuRunner, TheScheduleIsChosenPerFrameShapeNotOncePerVariant) {
  CpuRunner runner;
  const Variant variant = ParseVariantKey("cpu.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg0");
  const auto time = [&](const SkinnedAsset& asset) {
    const PackedMesh packed = Pack(asset.mesh, variant);
    const std::vector<KernelSource> kernels = {Emit(variant, 0, static_cast<int>(packed.palette_joints))};
    const std::vector<std::vector<std::uint8_t>> sets = {PackPalette(Palette(asset), variant)};
    const Prepared prepared = runner.Prepare(packed, kernels, sets);
    EXPECT_EQ(runner.Time(prepared, 1, 3, 1).size(), 3u);
    const std::optional<CpuChoice> choice = runner.ScheduleOf(variant.Key());
    EXPECT_TRUE(choice.has_value());
    return choice.value_or(CpuChoice{});
  };
  const SkinnedAsset& large = Asset("b4");  // 5000 vertices and a tail
  const SkinnedAsset tiny = GenerateDataset(ParseDatasetKey("100-b4-seed" + std::to_string(Seed())));
  const CpuChoice for_large = time(large);
  EXPECT_GE(for_large.schedule.chunk, 256u) << Describe(for_large);
  const CpuChoice for_tiny = time(tiny);
  EXPECT_LE(for_tiny.schedule.chunk, 128u) << "the 5k mesh's schedule was reused: " << Describe(for_tiny);
  const CpuChoice again = time(large);
  EXPECT_EQ(again.schedule.chunk, for_large.schedule.chunk);
  EXPECT_EQ(again.schedule.threads, for_large.schedule.threads);
}

TEST(CpuRunner, TimingChoosesThreadsChunksAndStoresPerVariantAndTimesTheCopy) {
  const SkinnedAsset& asset = Asset("b4");
  const Variant variant = ParseVariantKey("cpu.b4.padded.soa-split.float3.u8.unorm16.mat4.global.matrix.v1c.wg0");
  const PackedMesh packed = Pack(asset.mesh, variant);
  const std::vector<KernelSource> kernels = {Emit(variant, 0, static_cast<int>(packed.palette_joints))};
  const std::vector<std::vector<std::uint8_t>> sets = {PackPalette(Palette(asset), variant),
                                                       PackPalette(asset.PaletteAt(-1, 0.0), variant)};
  EXPECT_FALSE(Runner().ScheduleOf(variant.Key()).has_value());
  const Prepared prepared = Runner().Prepare(packed, kernels, sets);
  for (const int frames : {1, 4}) {
    const std::vector<double> ms = Runner().Time(prepared, 2, 5, frames);
    ASSERT_EQ(ms.size(), 5u) << frames << " frames per burst";
    for (const double t : ms) EXPECT_GT(t, 0.0);
  }
  const std::optional<CpuChoice> choice = Runner().ScheduleOf(variant.Key());
  ASSERT_TRUE(choice.has_value());
  EXPECT_GE(choice->schedule.threads, 1u);
  EXPECT_GT(choice->schedule.chunk, 0u);
  std::cout << "[ schedule ] " << Describe(*choice) << "\n";
  // The chosen schedule is the one verification uses afterwards: still the gold.
  ExpectRunMatchesGold(Runner(), variant, "b4", LaunchTimes::kNonNegative);

  const CopyKernel copy = EmitCopy(Lang::kCpu, 1 << 20);
  EXPECT_EQ(copy.kernel.lang, Lang::kCpu);
  const RunResult copied = Runner().Run(copy.mesh, std::span<const KernelSource>(&copy.kernel, 1));
  EXPECT_EQ(copied.poisoned_vertices, 0u);
  EXPECT_EQ(copied.positions, copy.mesh.launches[0].inputs[0].bytes);
  const Prepared copies = Runner().PrepareCopy(Lang::kCpu, 1 << 20, 3);
  const std::vector<double> ms = Runner().Time(copies, 1, 3, 4);
  ASSERT_EQ(ms.size(), 3u);
  for (const double t : ms) EXPECT_GT(t, 0.0);
}

TEST(CpuRunner, KernelTextsThatAreNotParameterBlocksFailToBuildNamingTheLine) {
  const KernelSource good = Emit(ParseVariantKey("cpu.b2.soa.v1c.wg0"), 0, 77);
  Runner().Build(good);
  const auto expect_build_error = [](KernelSource s, const std::string& part) {
    s.source_hash = SourceHash(s.text);
    try {
      Runner().Build(s);
      ADD_FAILURE() << "built: " << s.text;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind("CPU build: ", 0), 0u) << message;
      EXPECT_NE(message.find(part), std::string::npos) << message;
    }
  };
  KernelSource junk = good;
  junk.text += "float x = 1;\n";
  expect_build_error(junk, "'float x = 1;' is not a parameter");
  KernelSource not_a_number = good;
  not_a_number.text += "#define INFLUENCES four\n";
  expect_build_error(not_a_number, "'#define INFLUENCES four' is not a parameter");
  KernelSource nine = good;
  nine.text += "#define INFLUENCES 9\n";  // the last definition wins
  expect_build_error(nine, "9 influences (expected 1..8)");
  KernelSource missing = good;
  missing.text.replace(missing.text.find("#define WEIGHT_FORMAT"), 2, "//");
  expect_build_error(missing, "no #define WEIGHT_FORMAT");
  KernelSource no_blend = good;
  no_blend.text.replace(no_blend.text.find("#define BLEND"), 2, "//");
  expect_build_error(no_blend, "no #define BLEND");
  KernelSource blend_3 = good;
  blend_3.text += "#define BLEND 3\n";
  expect_build_error(blend_3, "BLEND 3 (expected 0 matrix, 1 point or 2 dual quaternion)");
  // A dual-quaternion palette with a linear blend, and the dual-quaternion blend with a matrix palette.
  KernelSource rows_2 = good;
  rows_2.text += "#define PALETTE_ROWS 2\n";
  expect_build_error(rows_2,
                     "PALETTE_ROWS 2 with BLEND 0: a dual-quaternion palette (PALETTE_ROWS 2) is read by BLEND 2 only");
  KernelSource blend_2 = good;
  blend_2.text += "#define BLEND 2\n";
  expect_build_error(blend_2, "PALETTE_ROWS 3 with BLEND 2");
  KernelSource dual_quaternion = good;
  dual_quaternion.text += "#define BLEND 2\n#define PALETTE_ROWS 2\n";
  dual_quaternion.source_hash = SourceHash(dual_quaternion.text);
  Runner().Build(dual_quaternion);
  KernelSource other = good;
  other.lang = Lang::kOpenCl;
  expect_build_error(other, "kernel language is opencl");
}

TEST(CpuRunner, PalettesOutsideHostMemoryAreALaunchError) {
  // The device's limits rule these out of tuning (constant 0 B, no local
  // memory, no images); a direct run says why.
  const Faulty f = WithFault("cpu.b2.soa.constant.v1c.wg0", "", "");
  ExpectRunFails(Runner(), f, "constant storage ran on the cpu device", {"CPU launch: ", "storage constant"});
}

TEST(CpuRunner, WrongResultFaultIsCaughtByTheGold) {
  Faulty f = WithFault("cpu.b2.soa.v1c.wg0", "", "");
  f.kernels[0].text += "#define SKINTUNE_FAULT_WRONG 1\n";
  f.kernels[0].source_hash = SourceHash(f.kernels[0].text);
  const RunResult result = Runner().Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant));
  const GoldComparison c = CompareToGold(SkinGold(Asset("b2").mesh, f.palette).positions, Unpack(f.packed, result.positions));
  EXPECT_GT(c.max_relative, kTolerance);
  EXPECT_EQ(c.worst_vertex, 0u);
}

TEST(CpuDevice, IsOneDeviceInTheTableWithNoWorkGroupsAndHostOnlyPalettes) {
  const Discovered d = DiscoverDevices("cpu");
  ASSERT_EQ(d.devices.size(), 1u);
  const FoundDevice& cpu = d.devices.front();
  EXPECT_EQ(cpu.identity.Id().rfind("cpu:skintune/", 0), 0u) << cpu.identity.Id();
  EXPECT_EQ(cpu.identity.type, "cpu");
  EXPECT_GE(cpu.identity.compute_units, 1u);
  EXPECT_GT(cpu.identity.last_level_cache_bytes, 0u);
  const ProblemShape shape{77, 4, false, 1};
  EXPECT_TRUE(CheckVariant(ParseVariantKey("cpu.b4.soa.global.v1c.wg0"), cpu.limits, shape).empty());
  for (const char* key : {"cpu.b4.soa.constant.v1c.wg0", "cpu.b4.soa.local.v1c.wg0", "cpu.b4.soa.image.v1c.wg0",
                          "cpu.b4.soa.global.v1c.wg64", "cpu.b4.soa.global.v2c.wg0"}) {
    EXPECT_FALSE(CheckVariant(ParseVariantKey(key), cpu.limits, shape).empty()) << key;
  }
}

}  // namespace
}  // namespace skintune::internal
