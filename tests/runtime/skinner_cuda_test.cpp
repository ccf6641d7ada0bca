// The public API on CUDA. Here (no GPU) it checks what can run without a
// driver: the PTX cache through NVRTC (a second start compiles nothing), and
// that devices are absent rather than broken (List, Open, FromCuda answer
// kUnavailable / kNotFound). On a machine with a CUDA GPU the Skinner tests
// run against the gold: the built-in default and forced variants of every
// palette storage, K instances, FromCuda on the caller's context and stream,
// and the disk cache across Devices. Each test that cannot run skips with
// what is missing.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "generator/emit.h"
#include "base/error.h"
#include "model/gltf_import.h"
#include "model/synthetic.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/cuda/cuda_runner.h"
#include "runtime/program_cache.h"
#include "runtime/selection.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::ExpectInstancesLikeTheGold;
using testing::ExpectSkinsLikeTheGold;
using testing::Poses;
using testing::TempDir;
using testing::View;

constexpr Backend kCuda = Backend::kCuda;

const CudaAvailability& Available() {
  static const CudaAvailability a = Probe();
  return a;
}

const SkinnedAsset& Cesium() {
  static const SkinnedAsset asset = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
  return asset;
}

// ---------------------------------------------------------------- no GPU needed

TEST(CudaProgramCache, PtxIsCompiledOnceThenLoadedFromDisk) {
  if (!Available().nvrtc) GTEST_SKIP() << "NVRTC cannot be loaded: " << Available().nvrtc_missing;
  TempDir dir;
  const std::string device_id = "cuda:CUDA/Test GPU/1.0 (CUDA 12.4)";
  std::vector<KernelSource> kernels = {Emit(GenericDefault(Lang::kCuda, 4, Normals::kNormals, DeviceLimits{}), 0, 77)};
  EmitOptions instanced;
  instanced.instanced = true;
  instanced.max_instances = 8;
  kernels.push_back(Emit(ParseVariantKey("cuda.b4.constant.mat3x4"), 0, 77, instanced));
  std::vector<std::string> first_ptx;
  {
    ProgramCache cache(dir.str());
    for (const KernelSource& k : kernels) first_ptx.push_back(CompilePtxCached(k, "compute_90", &cache, device_id));
    EXPECT_EQ(cache.counters().builds, 2);
    EXPECT_EQ(cache.counters().disk_hits, 0);
    for (const std::string& ptx : first_ptx) EXPECT_NE(ptx.find(".entry skin"), std::string::npos);
  }
  ProgramCache again(dir.str());  // a second start
  for (std::size_t i = 0; i < kernels.size(); ++i)
    EXPECT_EQ(CompilePtxCached(kernels[i], "compute_90", &again, device_id), first_ptx[i]);
  EXPECT_EQ(again.counters().builds, 0);
  EXPECT_EQ(again.counters().disk_hits, 2);
  // Another architecture or device is another program.
  CompilePtxCached(kernels[0], "compute_80", &again, device_id);
  CompilePtxCached(kernels[0], "compute_90", &again, "cuda:CUDA/Test GPU/2.0 (CUDA 12.8)");
  EXPECT_EQ(again.counters().builds, 2);
}

TEST(CudaProgramCache, ABuildErrorCarriesTheNvrtcLog) {
  if (!Available().nvrtc) GTEST_SKIP() << "NVRTC cannot be loaded: " << Available().nvrtc_missing;
  KernelSource broken = Emit(GenericDefault(Lang::kCuda, 2, Normals::kNone, DeviceLimits{}), 0, 77);
  broken.text += "\nthis is not CUDA;\n";
  broken.source_hash = SourceHash(broken.text);
  TempDir dir;
  ProgramCache cache(dir.str());
  try {
    CompilePtxCached(broken, "compute_90", &cache, "cuda:CUDA/Test GPU/1.0");
    ADD_FAILURE() << "compiled";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("CUDA build: ", 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("log:"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(dir.Files().empty());
}

TEST(CudaDevice, WithoutADriverCudaDevicesAreAbsentNotBroken) {
  if (Available().driver) GTEST_SKIP() << "a CUDA driver is present: " << Available().Describe();
  for (const DeviceInfo& d : Device::List()) EXPECT_NE(d.backend, Backend::kCuda) << d.id;
  const Result<Device> open = Device::Open("", &kCuda);
  ASSERT_FALSE(open.ok());
  EXPECT_EQ(open.status().code(), ErrorCode::kNotFound) << open.status().message();
  int fake_context = 0;
  const Result<Device> adopted = Device::FromCuda(&fake_context, nullptr);
  ASSERT_FALSE(adopted.ok());
  EXPECT_EQ(adopted.status().code(), ErrorCode::kUnavailable);
  EXPECT_NE(adopted.status().message().find("CUDA driver"), std::string::npos) << adopted.status().message();
  // OpenBest still finds whatever else there is, or says there is nothing.
  const Result<Device> best = Device::OpenBest();
  if (!best.ok()) {
    EXPECT_EQ(best.status().code(), ErrorCode::kNotFound) << best.status().message();
  }
}

// ---------------------------------------------------------------- on a GPU

#define OPEN_CUDA_OR_SKIP(device, options)                                                            \
  if (!Available().CanRun()) GTEST_SKIP() << "no CUDA device: " << Available().Describe();           \
  Result<Device> device = Device::Open("", &kCuda, options);                                          \
  ASSERT_TRUE(device.ok()) << device.status().message()

TEST(CudaSkinner, SkinsCesiumManWithTheDefaultAndEveryPaletteStorage) {
  TempDir dir;
  OPEN_CUDA_OR_SKIP(device, CacheIn(dir));
  const View view(Cesium().mesh);
  const AnimationClip& clip = Cesium().animations.front();
  const std::vector<glm::mat4> palette = Cesium().PaletteAt(0, clip.start + 0.4 * (clip.end - clip.start));
  for (const std::string& key : {std::string(), std::string("cuda.b4.soa-split.u16.unorm16.mat3x4.constant.v2s.wg128"),
                                 std::string("cuda.b4.aos.float3.u8.unorm8.local.point.v4c.wg256"),
                                 std::string("cuda.b4.soa.image.mat4.v1c.wg64")}) {
    SCOPED_TRACE(key.empty() ? "built-in default" : key);
    SkinnerOptions options;
    options.variant = key;
    options.normals = true;
    Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_NE(skinner->device_positions(), nullptr);
    ExpectSkinsLikeTheGold(*skinner, Cesium().mesh, palette);
  }
}

TEST(CudaSkinner, SkinsKInstancesInOneLaunch) {
  TempDir dir;
  OPEN_CUDA_OR_SKIP(device, CacheIn(dir));
  // 12 joints: 64 palettes of mat3x4 (36 KiB) fit CUDA's 64 KiB of constant memory.
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("600-b3-bones12-random-seed8-normals"));
  const View view(asset.mesh);
  for (int k : {1, 7, 64}) {
    for (const std::string& key : {std::string(), std::string("cuda.b3.constant.mat3x4.u8.unorm8")}) {
      SCOPED_TRACE(std::to_string(k) + " instances of " + key);
      SkinnerOptions options;
      options.instances = k;
      options.variant = key;
      Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.mesh, options);
      ASSERT_TRUE(skinner.ok()) << skinner.status().message();
      ExpectInstancesLikeTheGold(*skinner, asset.mesh, Poses(asset, k));
    }
  }
}

TEST(CudaSkinner, FromCudaUsesTheCallersContextAndASecondDeviceCompilesNothing) {
  if (!Available().CanRun()) GTEST_SKIP() << "no CUDA device: " << Available().Describe();
  const cuda::DriverApi* api = cuda::Driver();
  ASSERT_NE(api, nullptr);
  cuda::Device cu_device = 0;
  cuda::Context context = nullptr;
  ASSERT_EQ(api->cuDeviceGet(&cu_device, 0), cuda::kSuccess);
  ASSERT_EQ(api->cuDevicePrimaryCtxRetain(&context, cu_device), cuda::kSuccess);
  TempDir dir;
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("2000-b2-seed3"));
  const View view(asset.mesh);
  {
    Result<Device> device = Device::FromCuda(context, nullptr, CacheIn(dir));
    ASSERT_TRUE(device.ok()) << device.status().message();
    Result<Skinner> skinner = Skinner::Create(*device, WinnersDb::Empty(), view.mesh);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    ExpectSkinsLikeTheGold(*skinner, asset.mesh, asset.PaletteAt(0, 0.5));
    EXPECT_EQ(device->cache_stats().builds, 1);
  }
  {
    Result<Device> second = Device::FromCuda(context, nullptr, CacheIn(dir));
    ASSERT_TRUE(second.ok()) << second.status().message();
    Result<Skinner> skinner = Skinner::Create(*second, WinnersDb::Empty(), view.mesh);
    ASSERT_TRUE(skinner.ok()) << skinner.status().message();
    EXPECT_EQ(second->cache_stats().builds, 0);
    EXPECT_EQ(second->cache_stats().disk_hits, 1);
    ExpectSkinsLikeTheGold(*skinner, asset.mesh, asset.PaletteAt(0, 0.5));
  }
  api->cuDevicePrimaryCtxRelease(cu_device);
}

}  // namespace
}  // namespace skintune::internal
