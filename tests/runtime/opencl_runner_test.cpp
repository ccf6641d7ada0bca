// Every OpenCL variant axis value, run on a real OpenCL device (PoCL in CI)
// against the float64 gold, on a fresh random synthetic mesh each run (the
// seed is printed; SKINTUNE_TEST_SEED=<n> reproduces a run) and on CesiumMan
// for the bucketed launches. Plus: the poisoned output catches a kernel that
// skips vertices, the guard one that writes past the end, and a build error
// carries its log.
#include <gtest/gtest.h>

#include <cstdlib>
#include <iostream>

#include "runner_test_support.h"
#include "runtime/opencl_devices.h"
#include "runtime/opencl_runner.h"

namespace skintune {
namespace {

using testing::Asset;
using testing::Case;
using testing::CaseName;
using testing::ExpectCaseMatchesGold;
using testing::ExpectCoveringSetMatchesGold;
using testing::ExpectHalfPoisoned;
using testing::ExpectRunFails;
using testing::Faulty;
using testing::LaunchTimes;
using testing::Seed;
using testing::WithFault;

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

class OpenClVariant : public ::testing::TestWithParam<Case> {};

TEST_P(OpenClVariant, MatchesTheGold) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const Case& c = GetParam();
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + ", seed " + std::to_string(Seed()) +
               " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name());
  ExpectCaseMatchesGold(*runner, c, ParseVariantKey(c.key), LaunchTimes::kAny);
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
  ExpectCoveringSetMatchesGold(*runner, set, LaunchTimes::kAny);
  std::cout << "[ covering ] " << set.variants.size() << " OpenCL variants verified on " << runner->device_name()
            << "\n";
}

// The faulty kernels: one padded soa launch (WithFault).
constexpr const char* kFaultKey = "opencl.b2.soa.float4.u16.f32.wg64";

TEST(OpenClRunner, PoisonedOutputCatchesAKernelThatSkipsVertices) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault(kFaultKey, "if (v >= n) break;", "if (v >= n / 2) break;");
  ExpectHalfPoisoned(f, runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant)));
}

TEST(OpenClRunner, GuardCatchesAKernelThatWritesPastTheEnd) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault(kFaultKey, "STORE_XYZ(out_positions, first + v,", "STORE_XYZ(out_positions, first + v + 64,");
  ExpectRunFails(*runner, f, "a kernel writing 64 vertices past its output was not caught",
                 {"OpenCL guard", "out_positions", "wrote past the end"});
}

TEST(OpenClRunner, BuildFailureCarriesTheBuildLog) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault(kFaultKey, "if (v >= n) break;", "if (v >= n) break; undeclared_name_xyz = 1;");
  ExpectRunFails(*runner, f, "a kernel with an undeclared name built", {"OpenCL build", "undeclared_name_xyz"});
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
