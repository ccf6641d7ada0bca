// The public API on OpenCL (PoCL here): Device, Skinner, the program cache on
// disk and the misuse errors. Every result is compared with the float64 gold.
// The device: the first OpenCL device, or the first whose id, name, vendor or
// platform contains $SKINTUNE_TEST_OPENCL_DEVICE (then a missing device fails).
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <cstdlib>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "model/gltf_import.h"
#include "model/synthetic.h"
#include "runtime/winners_db.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::ExpectInstancesLikeTheGold;
using testing::ExpectOverflowWritesNothing;
using testing::ExpectSkinsLikeTheGold;
using testing::Poses;
using testing::Floats;
using testing::TempDir;
using testing::View;

constexpr Backend kOpenCl = Backend::kOpenCl;

// The test device, or null with the reason.
Result<Device> OpenTestDevice(const DeviceOptions& options) {
  const char* pattern = std::getenv("SKINTUNE_TEST_OPENCL_DEVICE");
  return Device::Open(pattern ? pattern : "", &kOpenCl, options);
}

#define OPEN_OR_SKIP(device, options)                                                    \
  Result<Device> device = OpenTestDevice(options);                                       \
  if (!device.ok()) {                                                                    \
    if (std::getenv("SKINTUNE_TEST_OPENCL_DEVICE")) FAIL() << device.status().message(); \
    GTEST_SKIP() << "no OpenCL device: " << device.status().message();                   \
  }

const SkinnedAsset& Cesium() {
  static const SkinnedAsset asset = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
  return asset;
}

const SkinnedAsset& Synthetic(const std::string& key) {
  static std::map<std::string, SkinnedAsset> cache;
  auto found = cache.find(key);
  if (found == cache.end()) found = cache.emplace(key, GenerateDataset(ParseDatasetKey(key))).first;
  return found->second;
}

std::vector<glm::mat4> Animated(const SkinnedAsset& asset, double fraction = 0.37) {
  const AnimationClip& clip = asset.animations.front();
  return asset.PaletteAt(0, clip.start + (clip.end - clip.start) * fraction);
}

Skinner MustCreate(Device& device, const WinnersDb& db, const MeshView& mesh, const SkinnerOptions& options = {}) {
  Result<Skinner> skinner = Skinner::Create(device, db, mesh, options);
  EXPECT_TRUE(skinner.ok()) << skinner.status().message();
  return skinner.ok() ? std::move(*skinner) : Skinner();
}

// ---------------------------------------------------------------- devices

TEST(OpenClDevice, ListAndOpenAgreeOnTheDevicesIdentity) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const DeviceInfo& info = device->info();
  EXPECT_EQ(info.backend, Backend::kOpenCl);
  EXPECT_EQ(info.id, "opencl:" + info.platform + "/" + info.name + "/" + info.driver_version);
  EXPECT_FALSE(info.vendor.empty());
  EXPECT_FALSE(info.type.empty());
  bool listed = false;
  for (const DeviceInfo& d : Device::List()) listed = listed || d.id == info.id;
  EXPECT_TRUE(listed) << info.id << " not in Device::List()";
  const Result<Device> best = Device::OpenBest(CacheIn(dir));
  ASSERT_TRUE(best.ok()) << best.status().message();
  EXPECT_FALSE(best->info().id.empty());
}

TEST(OpenClDevice, OpenOfAnUnknownDeviceIsNotFoundNamingThePattern) {
  const Result<Device> device = Device::Open("no such device 7f3a", &kOpenCl);
  ASSERT_FALSE(device.ok());
  EXPECT_EQ(device.status().code(), ErrorCode::kNotFound);
  EXPECT_NE(device.status().message().find("'no such device 7f3a'"), std::string::npos) << device.status().message();
}

TEST(OpenClDevice, FromOpenClAdoptsTheCallersContextAndQueue) {
  cl_platform_id platform = nullptr;
  cl_device_id cl_device = nullptr;
  if (clGetPlatformIDs(1, &platform, nullptr) != CL_SUCCESS ||
      clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, 1, &cl_device, nullptr) != CL_SUCCESS)
    GTEST_SKIP() << "no OpenCL device";
  cl_int err = CL_SUCCESS;
  cl_context context = clCreateContext(nullptr, 1, &cl_device, nullptr, nullptr, &err);
  ASSERT_EQ(err, CL_SUCCESS);
  cl_command_queue queue = clCreateCommandQueue(context, cl_device, 0, &err);
  ASSERT_EQ(err, CL_SUCCESS);
  TempDir dir;
  {
    Result<Device> device = Device::FromOpenCl(cl_device, context, queue, CacheIn(dir));
    ASSERT_TRUE(device.ok()) << device.status().message();
    EXPECT_FALSE(device->has_gl_sharing());
    const SkinnedAsset& asset = Synthetic("700-b3-seed4-normals");
    const View view(asset.mesh);
    Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh);
    ExpectSkinsLikeTheGold(skinner, asset.mesh, Animated(asset));
  }
  // Retained and released: the caller's handles are still valid.
  EXPECT_EQ(clReleaseCommandQueue(queue), CL_SUCCESS);
  EXPECT_EQ(clReleaseContext(context), CL_SUCCESS);

  const Result<Device> null_queue = Device::FromOpenCl(cl_device, context, nullptr);
  ASSERT_FALSE(null_queue.ok());
  EXPECT_EQ(null_queue.status().code(), ErrorCode::kInvalidArgument);
  const Result<Device> null_device = Device::FromOpenCl(nullptr, context, queue);
  EXPECT_EQ(null_device.status().code(), ErrorCode::kInvalidArgument);
}

// ---------------------------------------------------------------- skinning

TEST(OpenClSkinner, SkinsCesiumManWithTheBuiltInDefaultLikeTheGold) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const View view(Cesium().mesh);
  SkinnerOptions options;
  options.normals = true;
  Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh, options);
  EXPECT_EQ(skinner.selection().level, MatchLevel::kGenericDefault);
  EXPECT_EQ(skinner.vertex_count(), Cesium().mesh.vertex_count());
  EXPECT_EQ(skinner.joint_count(), Cesium().mesh.joint_count);
  EXPECT_EQ(skinner.instances(), 1);
  EXPECT_EQ(skinner.output_stride_bytes(), 16u);
  EXPECT_NE(skinner.device_positions(), nullptr);
  ExpectSkinsLikeTheGold(skinner, Cesium().mesh, Animated(Cesium(), 0.2));
  // Frame after frame, the same Skinner.
  ExpectSkinsLikeTheGold(skinner, Cesium().mesh, Animated(Cesium(), 0.8));
}

// docs/INPUTS.md "Finite outputs": a NaN palette entry is refused where it enters, and an
// output that overflows float32 (a finite palette of 3e38) never reaches the
// caller's buffer.
TEST(OpenClSkinner, NonFinitePaletteAndOutputAreErrorsNeverData) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const View view(Cesium().mesh);
  Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh);
  std::vector<float> palette(static_cast<std::size_t>(skinner.joint_count()) * 16, 0.0f);
  for (std::size_t j = 0; j < palette.size() / 16; ++j)
    for (int d = 0; d < 4; ++d) palette[j * 16 + d * 5] = 1.0f;
  std::vector<float> bad = palette;
  bad[3 * 16 + 2 * 4 + 1] = std::numeric_limits<float>::quiet_NaN();
  const Status nan = skinner.SetPalette(bad.data(), bad.size());
  EXPECT_EQ(nan.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(nan.message().rfind("Skinner::SetPalette: matrix 3 (instance 0, joint 3) element [2][1] is nan", 0), 0u)
      << nan.message();
  // Finite, but the product overflows: x' = 3e38 * (x + 1) in every matrix.
  std::vector<float> huge = palette;
  for (std::size_t j = 0; j < huge.size() / 16; ++j) huge[j * 16] = huge[j * 16 + 12] = 3e38f;
  ExpectOverflowWritesNothing(skinner, huge);
}

// A read-back of more than one 64k-vertex chunk (runtime/skinner.cpp: the
// chunks are copied back one by one and scanned as they land): float3 and
// float4 outputs match the gold across the chunk boundaries, and an output
// that overflows only in the last chunk is still an error that leaves the
// caller's array untouched.
TEST(OpenClSkinner, AReadBackInChunksIsTheGoldAndAnOverflowInTheLastChunkWritesNothing) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const SkinnedAsset& asset = Synthetic("150001-b2-seed7");
  const View view(asset.mesh);
  for (const char* key : {"opencl.b2.padded.soa.float3.u16.f32.mat3x4.global.matrix.v1c.wg128",
                          "opencl.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128"}) {
    SCOPED_TRACE(key);
    SkinnerOptions options;
    options.variant = key;
    Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh, options);
    ExpectSkinsLikeTheGold(skinner, asset.mesh, Animated(asset, 0.3));
    ExpectOverflowWritesNothing(skinner, testing::OverflowingLastVertex(asset.mesh, Animated(asset, 0.3)));
  }
}

// A palette that cannot overflow float32 is read back in one pass, each
// grain scanned as it is copied: still the gold; and a NaN that only a broken
// kernel could leave (written into the output buffer here, after the kernel)
// is an error naming its vertex, with the caller's array holding no
// non-finite value and nothing of that vertex.
TEST(OpenClSkinner, AOnePassReadBackIsTheGoldAndABrokenKernelsNanNeverReachesTheArray) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const SkinnedAsset& asset = Synthetic("150001-b2-seed7");
  const View view(asset.mesh);
  SkinnerOptions options;
  options.variant = "opencl.b2.padded.soa.float3.u16.f32.mat3x4.global.matrix.v1c.wg128";
  Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh, options);
  ExpectSkinsLikeTheGold(skinner, asset.mesh, Animated(asset, 0.6));
  ASSERT_TRUE(skinner.Finish().ok());
  // The Skinner's output buffer, written through a queue of the test's own.
  const auto output = static_cast<cl_mem>(skinner.device_positions());
  cl_context context = nullptr;
  ASSERT_EQ(clGetMemObjectInfo(output, CL_MEM_CONTEXT, sizeof context, &context, nullptr), CL_SUCCESS);
  cl_device_id cl_device = nullptr;
  ASSERT_EQ(clGetContextInfo(context, CL_CONTEXT_DEVICES, sizeof cl_device, &cl_device, nullptr), CL_SUCCESS);
  cl_int err = CL_SUCCESS;
  cl_command_queue queue = clCreateCommandQueue(context, cl_device, 0, &err);
  ASSERT_EQ(err, CL_SUCCESS);
  constexpr std::size_t kBad = 40000;  // in the third 16k-vertex grain, the first 64k chunk
  const float nan = std::numeric_limits<float>::quiet_NaN();
  ASSERT_EQ(clEnqueueWriteBuffer(queue, output, CL_TRUE, (kBad * 3 + 1) * sizeof(float), sizeof nan, &nan, 0, nullptr,
                                 nullptr),
            CL_SUCCESS);
  clReleaseCommandQueue(queue);
  std::vector<float> out(asset.mesh.vertex_count() * 3, 7.0f);
  const Status read = skinner.ReadPositions(out.data(), out.size());
  EXPECT_EQ(read.code(), ErrorCode::kDeviceError);
  EXPECT_EQ(read.message().rfind("Skinner::ReadPositions: vertex 40000 of instance 0 is (", 0), 0u) << read.message();
  EXPECT_NE(read.message().find("cannot overflow float32: the kernel is broken"), std::string::npos) << read.message();
  EXPECT_TRUE(std::all_of(out.begin(), out.end(), [](float v) { return std::isfinite(v); }));
  for (int c = 0; c < 3; ++c) EXPECT_EQ(out[kBad * 3 + c], 7.0f) << c;
}

// Packed normals and tangents left on the device: device_normals() and
// device_tangents() are cl_mem buffers of one word a vertex
// (normal_stride_bytes() 4) holding what ReadPackedNormals / ReadPackedTangents
// give; a Skinner of float32 normals has no tangent buffer and its normals'
// stride is the position format's.
TEST(OpenClSkinner, PackedNormalsLeftOnTheDeviceAreTheWordsReadBack) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const SkinnedAsset& asset = Synthetic("3001-b4-seed9-tangents");
  const View view(asset.mesh);
  SkinnerOptions options;
  options.tangents = true;
  options.normal_format = skintune::NormalFormat::kOct16;
  options.variant = "opencl.b4.soa";
  Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh, options);
  EXPECT_EQ(skinner.normal_stride_bytes(), 4u);
  EXPECT_EQ(skinner.tangent_stride_bytes(), 4u);
  const std::vector<float> matrices = Floats(Animated(asset, 0.3));
  ASSERT_TRUE(skinner.SetPalette(matrices.data(), matrices.size()).ok());
  ASSERT_TRUE(skinner.Skin().ok());
  ASSERT_TRUE(skinner.Finish().ok());
  const std::size_t n = asset.mesh.vertex_count();
  for (const bool tangents : {false, true}) {
    const auto buffer = static_cast<cl_mem>(tangents ? skinner.device_tangents() : skinner.device_normals());
    ASSERT_NE(buffer, nullptr);
    std::size_t bytes = 0;
    ASSERT_EQ(clGetMemObjectInfo(buffer, CL_MEM_SIZE, sizeof bytes, &bytes, nullptr), CL_SUCCESS);
    ASSERT_GE(bytes, n * 4);
    cl_context context = nullptr;
    ASSERT_EQ(clGetMemObjectInfo(buffer, CL_MEM_CONTEXT, sizeof context, &context, nullptr), CL_SUCCESS);
    cl_device_id cl_device = nullptr;
    ASSERT_EQ(clGetContextInfo(context, CL_CONTEXT_DEVICES, sizeof cl_device, &cl_device, nullptr), CL_SUCCESS);
    cl_int err = CL_SUCCESS;
    cl_command_queue queue = clCreateCommandQueue(context, cl_device, 0, &err);
    ASSERT_EQ(err, CL_SUCCESS);
    std::vector<std::uint32_t> on_device(n), read(n);
    ASSERT_EQ(clEnqueueReadBuffer(queue, buffer, CL_TRUE, 0, n * 4, on_device.data(), 0, nullptr, nullptr), CL_SUCCESS);
    clReleaseCommandQueue(queue);
    ASSERT_TRUE((tangents ? skinner.ReadPackedTangents(read.data(), n) : skinner.ReadPackedNormals(read.data(), n)).ok());
    EXPECT_EQ(on_device, read) << (tangents ? "tangents" : "normals");  // the order is the mesh's (padded)
  }
  SkinnerOptions f32;
  f32.normals = true;
  f32.variant = "opencl.b4.soa.float3";
  Skinner plain = MustCreate(*device, WinnersDb::Empty(), view.mesh, f32);
  EXPECT_EQ(plain.normal_stride_bytes(), 12u);
  EXPECT_EQ(plain.tangent_stride_bytes(), 0u);
  EXPECT_EQ(plain.device_tangents(), nullptr);
}

// A crowd's palette (64 CesiumMen, 1216 matrices) matches its gold, and the
// error names the first non-finite matrix however many there are; a rejected
// palette takes no slot.
TEST(OpenClSkinner, ACrowdsPaletteMatchesTheGoldAndItsFirstNanIsNamed) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const View view(Cesium().mesh);
  SkinnerOptions options;
  options.instances = 64;
  Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh, options);
  std::vector<std::vector<glm::mat4>> palettes;
  for (int k = 0; k < 64; ++k) palettes.push_back(Animated(Cesium(), (k + 0.5) / 64.0));
  ExpectInstancesLikeTheGold(skinner, Cesium().mesh, palettes);
  std::vector<float> matrices;
  for (const auto& p : palettes) {
    const std::vector<float> f = testing::Floats(p);
    matrices.insert(matrices.end(), f.begin(), f.end());
  }
  const int joints = Cesium().mesh.joint_count;
  const auto nan_at = [&](std::vector<std::size_t> bad) {
    std::vector<float> m = matrices;
    for (std::size_t j : bad) m[j * 16 + 5] = std::numeric_limits<float>::quiet_NaN();
    return skinner.SetPalette(m.data(), m.size());
  };
  for (const std::vector<std::size_t>& bad : {std::vector<std::size_t>{1100}, {1100, 5}, {1215, 1030}}) {
    std::size_t first = *std::min_element(bad.begin(), bad.end());
    const Status status = nan_at(bad);
    EXPECT_EQ(status.code(), ErrorCode::kInvalidArgument);
    const std::string expected = "Skinner::SetPalette: matrix " + std::to_string(first) + " (instance " +
                                 std::to_string(first / joints) + ", joint " + std::to_string(first % joints) +
                                 ") element [1][1] is nan";
    EXPECT_EQ(status.message().rfind(expected, 0), 0u) << status.message();
  }
  // The rejected palettes took no slot: the last good one is still what Skin uses.
  ExpectInstancesLikeTheGold(skinner, Cesium().mesh, palettes);
}

TEST(OpenClSkinner, ForcedVariantsOfEveryLayoutAndFormatMatchTheGoldInMeshOrder) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const std::vector<std::string> keys = {
      "opencl.b4.padded.aos.float3.u8.unorm8.mat3x4.constant.point.v2c.wg64",
      "opencl.b4.padded.soa-split.float4.u16.unorm16.mat3x4.local.matrix.v4s.wg128",
      "opencl.b4.padded.soa.float3.i32.f32.mat4.image.matrix.v1c.wg32",
      "opencl.b8.padded.aos.float4.u16.f32.mat4.global.point.v8c.wg256",
  };
  const SkinnedAsset& asset = Synthetic("3001-b4-random-seed5-normals");
  const View view(asset.mesh);
  for (const std::string& key : keys) {
    for (bool normals : {false, true}) {
      SCOPED_TRACE(key + (normals ? " with normals" : ""));
      SkinnerOptions options;
      options.variant = key;
      options.normals = normals;
      Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh, options);
      EXPECT_EQ(skinner.selection().level, MatchLevel::kForced);
      EXPECT_STREQ(MatchLevelName(skinner.selection().level), "forced");
      EXPECT_EQ(skinner.output_stride_bytes(), key.find("float3") != std::string::npos ? 12u : 16u);
      ExpectSkinsLikeTheGold(skinner, asset.mesh, Animated(asset));
    }
  }
}

// A database whose entry for this very device is `key` (tuned on b4 at 25k
// vertices), whose weights cost `quantisation_rel` of the diagonal (0: as if
// tuned on weights its format holds exactly, within every budget).
WinnersEntry EntryFor(const DeviceInfo& device, const std::string& key, double quantisation_rel = 0.0,
                      double ms = 0.5) {
  WinnersEntry e;
  e.device_id = device.id;
  e.backend = "opencl";
  e.platform = device.platform;
  e.vendor = device.vendor;
  e.device_name = device.name;
  e.driver_version = device.driver_version;
  e.device_type = device.type;
  e.variant = ParseVariantKey(key);
  e.lang = e.variant.lang;
  e.influences = e.variant.influences;
  e.vertex_bucket = "25k";
  e.vertices = 25000;
  e.dataset = "25k-b4";
  e.median_ms = ms;
  e.created = "2025-01-31T12:00:00Z";
  e.source = "test";
  e.source_error = {true, 1.0, quantisation_rel + 1e-7, quantisation_rel + 1e-7, 0.0, quantisation_rel};
  return e;
}

WinnersDb DbOf(const std::vector<WinnersEntry>& entries) {
  const Result<WinnersDb> db = WinnersDb::Parse(WinnersDbJson(entries).dump(), "test-db.json");
  EXPECT_TRUE(db.ok()) << db.status().message();
  return db.ok() ? *db : WinnersDb::Empty();
}

WinnersDb DbFor(const DeviceInfo& device, const std::string& key) { return DbOf({EntryFor(device, key)}); }

TEST(OpenClSkinner, UsesThisDevicesDatabaseEntryAndRunsABucketedWinnerPadded) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const View view(Cesium().mesh);
  const WinnersDb db = DbFor(device->info(), "opencl.b4.padded.soa-split.float4.u16.unorm16.mat3x4.local.matrix.v2c.wg64");
  Skinner skinner = MustCreate(*device, db, view.mesh);
  EXPECT_EQ(skinner.selection().level, MatchLevel::kExactDevice);
  EXPECT_EQ(skinner.selection().variant, "opencl.b4.padded.soa-split.float4.u16.unorm16.mat3x4.local.matrix.v2c.wg64.nonormals");
  ExpectSkinsLikeTheGold(skinner, Cesium().mesh, Animated(Cesium()));

  const WinnersDb bucketed = DbFor(device->info(), "opencl.b4.bucketed.aos.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64");
  Skinner padded = MustCreate(*device, bucketed, view.mesh);
  EXPECT_EQ(padded.selection().variant, "opencl.b4.padded.aos.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals");
  EXPECT_NE(padded.selection().reason.find("runs padded"), std::string::npos) << padded.selection().reason;
  ExpectSkinsLikeTheGold(padded, Cesium().mesh, Animated(Cesium()));
}

// A winner per precision class: the fastest (unorm8) costs 1e-3 of the
// diagonal. The default budget takes unorm16, a larger one unorm8, and a mesh
// whose weights are on unorm8's grid (a glTF's unorm8 WEIGHTS) unorm8 at the
// default: it costs that mesh nothing.
TEST(OpenClSkinner, TheErrorBudgetChoosesThePrecisionClassAndExactWeightsCostNothing) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  const std::string base = "opencl.b4.padded.soa.float4.u16.%.mat3x4.global.matrix.v1c.wg64";
  auto key = [&](const char* weight) {
    return base.substr(0, base.find('%')) + weight + base.substr(base.find('%') + 1);
  };
  const WinnersDb db = DbOf({EntryFor(device->info(), key("f32"), 0.0, 3.0),
                             EntryFor(device->info(), key("unorm16"), 5e-6, 2.0),
                             EntryFor(device->info(), key("unorm8"), 1e-3, 1.0)});
  const View view(Cesium().mesh);
  Skinner standard = MustCreate(*device, db, view.mesh);
  EXPECT_EQ(standard.selection().variant, key("unorm16") + ".nonormals");
  // The option that admits the faster class, by name, and how far to raise it.
  EXPECT_NE(standard.selection().reason.find("unorm8: quantisation error 1.00e-03 of the diagonal, over the budget "
                                             "SkinnerOptions::max_error 1.00e-04 (raising it to 1.00e-03 admits it)"),
            std::string::npos)
      << standard.selection().reason;
  ExpectSkinsLikeTheGold(standard, Cesium().mesh, Animated(Cesium()));
  SkinnerOptions loose;
  loose.max_error = 1e-2;
  EXPECT_EQ(MustCreate(*device, db, view.mesh, loose).selection().variant, key("unorm8") + ".nonormals");
  SkinnerOptions exact_only;
  exact_only.max_error = 0.0;
  EXPECT_EQ(MustCreate(*device, db, view.mesh, exact_only).selection().variant, key("f32") + ".nonormals");

  const SkinnedAsset unorm8 = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple-unorm8.gltf").asset;
  const View exact(unorm8.mesh);
  // RiggedSimple uses 2 bones per vertex: the b4 entries hold it.
  Skinner gltf = MustCreate(*device, db, exact.mesh);
  EXPECT_EQ(gltf.selection().variant, key("unorm8") + ".nonormals");
  ExpectSkinsLikeTheGold(gltf, unorm8.mesh, unorm8.PaletteAt(0, 0.5));

  for (double bad : {-1.0, std::numeric_limits<double>::quiet_NaN()}) {
    SkinnerOptions o;
    o.max_error = bad;
    const Result<Skinner> r = Skinner::Create(*device, db, view.mesh, o);
    EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("SkinnerOptions::max_error"), std::string::npos) << r.status().message();
  }
}

// One --device rule: "pocl" opens PoCL, whose platform is "Portable Computing Language".
TEST(OpenClDevice, OpenPoclMatchesPortableComputingLanguage) {
  bool has_pocl = false;
  for (const DeviceInfo& d : Device::List()) has_pocl |= d.platform == "Portable Computing Language";
  if (!has_pocl) GTEST_SKIP() << "no PoCL device here";
  TempDir dir;
  const Result<Device> device = Device::Open("pocl", &kOpenCl, CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  EXPECT_EQ(device->info().platform, "Portable Computing Language");
}

TEST(OpenClSkinner, SkipsADatabaseEntryThatCannotHoldTheMesh) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  // u8 indices cannot address 300 joints: the entry is skipped, the default runs.
  const SkinnedAsset& asset = Synthetic("2000-b2-bones300-random-seed9");
  const View view(asset.mesh);
  const WinnersDb db = DbFor(device->info(), "opencl.b2.soa.u8.wg64");
  Skinner skinner = MustCreate(*device, db, view.mesh);
  EXPECT_EQ(skinner.selection().level, MatchLevel::kGenericDefault);
  EXPECT_NE(skinner.selection().reason.find("index_range"), std::string::npos) << skinner.selection().reason;
  ExpectSkinsLikeTheGold(skinner, asset.mesh, asset.PaletteAt(0, 0.5));
}

TEST(OpenClSkinner, SkinsKInstancesInOneLaunchEachWithItsOwnPalette) {
  TempDir dir;
  OPEN_OR_SKIP(device, CacheIn(dir));
  struct Case {
    int instances;
    const SkinnedAsset* asset;
    std::string variant;  // "" = the built-in default
    bool normals;
  };
  const std::vector<Case> cases = {
      {1, &Cesium(), "", true},
      {7, &Cesium(), "", true},
      {7, &Synthetic("600-b3-random-seed8-normals"), "opencl.b3.aos.float3.u8.unorm8.mat3x4.local.point.v2s.wg64", true},
      {64, &Synthetic("600-b3-random-seed8-normals"), "", false},
      {64, &Synthetic("600-b3-random-seed8-normals"), "opencl.b3.soa-split.u16.unorm16.image.v4c.wg128", false},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(std::to_string(c.instances) + " instances of " + c.variant);
    const View view(c.asset->mesh);
    SkinnerOptions options;
    options.instances = c.instances;
    options.variant = c.variant;
    options.normals = c.normals;
    Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh, options);
    EXPECT_EQ(skinner.instances(), c.instances);
    ExpectInstancesLikeTheGold(skinner, c.asset->mesh, Poses(*c.asset, c.instances));
  }
}

// ---------------------------------------------------------------- program cache

TEST(OpenClProgramCache, SecondDeviceWithTheSameCacheDirectoryCompilesNothing) {
  TempDir dir;
  const SkinnedAsset& asset = Synthetic("1500-b2-seed3");
  const View view(asset.mesh);
  {
    OPEN_OR_SKIP(first, CacheIn(dir));
    Skinner a = MustCreate(*first, WinnersDb::Empty(), view.mesh);
    EXPECT_EQ(first->cache_stats().builds, 1);
    EXPECT_EQ(first->cache_stats().disk_hits, 0);
    Skinner b = MustCreate(*first, WinnersDb::Empty(), view.mesh);  // same kernel, same Device
    EXPECT_EQ(first->cache_stats().builds, 1);
    EXPECT_EQ(first->cache_stats().memory_hits, 1);
    EXPECT_EQ(dir.Files().size(), 1u);
  }
  OPEN_OR_SKIP(second, CacheIn(dir));
  Skinner c = MustCreate(*second, WinnersDb::Empty(), view.mesh);
  EXPECT_EQ(second->cache_stats().builds, 0);
  EXPECT_EQ(second->cache_stats().disk_hits, 1);
  ExpectSkinsLikeTheGold(c, asset.mesh, asset.PaletteAt(0, 0.25));
}

TEST(OpenClProgramCache, ACorruptCacheFileIsRebuiltNotAnError) {
  TempDir dir;
  const SkinnedAsset& asset = Synthetic("1500-b2-seed3");
  const View view(asset.mesh);
  {
    OPEN_OR_SKIP(first, CacheIn(dir));
    MustCreate(*first, WinnersDb::Empty(), view.mesh);
  }
  ASSERT_EQ(dir.Files().size(), 1u);
  const std::filesystem::path file = dir.Files().front();
  const auto size = std::filesystem::file_size(file);
  for (const char* damage : {"flip", "truncate"}) {
    SCOPED_TRACE(damage);
    if (std::string(damage) == "flip") {
      std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
      f.seekp(static_cast<std::streamoff>(size - 7));
      f.put('\x5a');
    } else {
      std::filesystem::resize_file(file, size / 2);
    }
    OPEN_OR_SKIP(device, CacheIn(dir));
    Skinner skinner = MustCreate(*device, WinnersDb::Empty(), view.mesh);
    EXPECT_EQ(device->cache_stats().builds, 1);
    EXPECT_EQ(device->cache_stats().disk_hits, 0);
    ExpectSkinsLikeTheGold(skinner, asset.mesh, asset.PaletteAt(0, 0.25));
    OPEN_OR_SKIP(again, CacheIn(dir));  // rewritten: a hit again
    MustCreate(*again, WinnersDb::Empty(), view.mesh);
    EXPECT_EQ(again->cache_stats().disk_hits, 1);
  }
}

TEST(OpenClProgramCache, DashMeansNoDiskCache) {
  TempDir dir;
  DeviceOptions options;
  options.program_cache_dir = "-";
  OPEN_OR_SKIP(device, options);
  const View view(Synthetic("1500-b2-seed3").mesh);
  MustCreate(*device, WinnersDb::Empty(), view.mesh);
  OPEN_OR_SKIP(again, options);
  MustCreate(*again, WinnersDb::Empty(), view.mesh);
  EXPECT_EQ(again->cache_stats().builds, 1);
  EXPECT_EQ(again->cache_stats().disk_hits, 0);
}

}  // namespace
}  // namespace skintune::internal
