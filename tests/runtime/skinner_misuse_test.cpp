// Misuse of the public API is detected and reported as an error value with a
// message naming what was wrong (one test per misuse), on the OpenCL device
// (PoCL here; skipped without one).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "model/synthetic.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::Floats;
using testing::TempDir;
using testing::View;

constexpr Backend kOpenCl = Backend::kOpenCl;

class Misuse : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* pattern = std::getenv("SKINTUNE_TEST_OPENCL_DEVICE");
    Result<Device> device = Device::Open(pattern ? pattern : "", &kOpenCl, CacheIn(dir_));
    if (!device.ok()) GTEST_SKIP() << "no OpenCL device: " << device.status().message();
    device_ = std::move(*device);
  }

  static const SkinnedAsset& Asset() {
    static const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("900-b4-seed2-normals"));
    return asset;
  }

  // Create's error for `view` (and `options`); it must fail.
  Status CreateError(const MeshView& view, const SkinnerOptions& options = {}) {
    Result<Skinner> skinner = Skinner::Create(device_, WinnersDb::Empty(), view, options);
    EXPECT_FALSE(skinner.ok()) << "created " << skinner->selection().variant;
    return skinner.status();
  }

  Skinner Made(const SkinnerOptions& options = {}) {
    Result<Skinner> skinner = Skinner::Create(device_, WinnersDb::Empty(), view_.mesh, options);
    EXPECT_TRUE(skinner.ok()) << skinner.status().message();
    return skinner.ok() ? std::move(*skinner) : Skinner();
  }

  std::vector<float> Palette() const { return Floats(Asset().PaletteAt(0, 0.3)); }

  TempDir dir_;
  Device device_;
  View view_{Asset().mesh};
};

void ExpectError(const Status& status, ErrorCode code, const std::string& part) {
  EXPECT_FALSE(status.ok());
  EXPECT_EQ(status.code(), code) << status.message();
  EXPECT_NE(status.message().find(part), std::string::npos) << status.message();
}

TEST_F(Misuse, WrongPaletteSize) {
  Skinner skinner = Made();
  const std::vector<float> palette = Palette();
  ExpectError(skinner.SetPalette(palette.data(), palette.size() - 16), ErrorCode::kInvalidArgument,
              "expected 1 instances x 77 joints x 16 = 1232");
  ExpectError(skinner.SetPalette(nullptr, palette.size()), ErrorCode::kInvalidArgument, "matrices is null");
}

TEST_F(Misuse, SkinBeforeSetPalette) {
  Skinner skinner = Made();
  ExpectError(skinner.Skin(), ErrorCode::kInvalidState, "no palette yet");
}

TEST_F(Misuse, ReadBeforeSkin) {
  Skinner skinner = Made();
  const std::vector<float> palette = Palette();
  ASSERT_TRUE(skinner.SetPalette(palette.data(), palette.size()).ok());
  std::vector<float> out(skinner.vertex_count() * 3);
  ExpectError(skinner.ReadPositions(out.data(), out.size()), ErrorCode::kInvalidState, "nothing skinned yet");
}

TEST_F(Misuse, WrongReadSize) {
  Skinner skinner = Made();
  std::vector<float> out(skinner.vertex_count() * 3 + 1);
  ExpectError(skinner.ReadPositions(out.data(), out.size()), ErrorCode::kInvalidArgument, "float_count is 2701");
}

TEST_F(Misuse, ReadNormalsWithoutNormals) {
  Skinner skinner = Made();
  const std::vector<float> palette = Palette();
  ASSERT_TRUE(skinner.SetPalette(palette.data(), palette.size()).ok());
  ASSERT_TRUE(skinner.Skin().ok());
  std::vector<float> out(skinner.vertex_count() * 3);
  ExpectError(skinner.ReadNormals(out.data(), out.size()), ErrorCode::kInvalidState, "skins no normals");
}

TEST_F(Misuse, NormalsRequestedButTheMeshHasNone) {
  MeshView view = view_.mesh;
  view.normals = nullptr;
  SkinnerOptions options;
  options.normals = true;
  ExpectError(CreateError(view, options), ErrorCode::kInvalidArgument, "MeshView::normals is null");
}

TEST_F(Misuse, JointOutOfRange) {
  View view(Asset().mesh);
  view.joints[5 * 4 + 2] = 77;
  ExpectError(CreateError(view.mesh), ErrorCode::kInvalidArgument, "vertex 5 slot 2: joint 77 out of range (77 joints)");
}

TEST_F(Misuse, BadWeights) {
  SkinnedMesh mesh = Asset().mesh;
  mesh.weights[7 * 4 + 1] = std::numeric_limits<float>::quiet_NaN();
  ExpectError(CreateError(View(mesh).mesh), ErrorCode::kInvalidArgument, "vertex 7");
  mesh = Asset().mesh;
  mesh.weights[3 * 4] = -0.5f;
  ExpectError(CreateError(View(mesh).mesh), ErrorCode::kInvalidArgument, "vertex 3");
  mesh = Asset().mesh;
  mesh.weights[11 * 4] += 0.25f;  // sums to 1.25
  ExpectError(CreateError(View(mesh).mesh), ErrorCode::kInvalidArgument, "vertex 11");
}

TEST_F(Misuse, NullArraysAndZeroSizes) {
  MeshView view = view_.mesh;
  view.positions = nullptr;
  ExpectError(CreateError(view), ErrorCode::kInvalidArgument, "positions is null");
  view = view_.mesh;
  view.vertex_count = 0;
  ExpectError(CreateError(view), ErrorCode::kInvalidArgument, "vertex_count is 0");
  view = view_.mesh;
  view.influences = 9;
  ExpectError(CreateError(view), ErrorCode::kInvalidArgument, "influences 9 outside 1..8");
  view = view_.mesh;
  view.joint_count = 0;
  ExpectError(CreateError(view), ErrorCode::kInvalidArgument, "joint_count 0");
}

TEST_F(Misuse, ForcedVariantWithFewerInfluencesThanTheMesh) {
  SkinnerOptions options;
  options.variant = "opencl.b2";
  ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument, "influences_too_few");
}

TEST_F(Misuse, ForcedVariantOfAnotherLanguageOrBucketedOrMalformed) {
  SkinnerOptions options;
  options.variant = "cuda.b4";
  ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument, "does not run on opencl devices");
  options.variant = "opencl.b4.bucketed";
  ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument, "bucketed variants reorder");
  options.variant = "opencl.b4.tiled";
  ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument, "unknown token 'tiled'");
}

TEST_F(Misuse, InstancesOutOfRange) {
  SkinnerOptions options;
  options.instances = 0;
  ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument, "instances is 0");
}

TEST_F(Misuse, PaletteBuffersOutOfRange) {
  SkinnerOptions options;
  for (const int buffers : {-1, 0, 1, kMaxPaletteBuffers + 1}) {
    options.palette_buffers = buffers;
    ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument,
                "SkinnerOptions::palette_buffers is " + std::to_string(buffers) + ", expected 2 to 16");
  }
}

TEST_F(Misuse, PaletteThreadsOutOfRange) {
  SkinnerOptions options;
  for (const int threads : {-1, kMaxPaletteThreads + 1}) {
    options.palette_threads = threads;
    ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument,
                "SkinnerOptions::palette_threads is " + std::to_string(threads) +
                    ", expected 0 (skintune's choice) to " + std::to_string(kMaxPaletteThreads));
  }
}

// A crowd palette of 16 x 77 matrices (past the size the palette threads
// take) packed by the calling thread alone, by 2 threads and by skintune's
// choice: the same positions, byte for byte.
TEST_F(Misuse, PaletteThreadsChangeNothingButTheTime) {
  std::vector<float> palettes;
  for (int k = 0; k < 16; ++k) {
    const std::vector<float> p = Floats(Asset().PaletteAt(0, 0.05 * k));
    palettes.insert(palettes.end(), p.begin(), p.end());
  }
  std::vector<std::vector<float>> outs;
  for (const int threads : {0, 1, 2, kMaxPaletteThreads}) {
    SkinnerOptions options;
    options.instances = 16;
    options.palette_threads = threads;
    Skinner skinner = Made(options);
    ASSERT_TRUE(skinner.SetPalette(palettes.data(), palettes.size()).ok()) << threads;
    ASSERT_TRUE(skinner.Skin().ok());
    outs.emplace_back(16 * skinner.vertex_count() * 3);
    ASSERT_TRUE(skinner.ReadPositions(outs.back().data(), outs.back().size()).ok());
  }
  for (std::size_t i = 1; i < outs.size(); ++i)
    EXPECT_EQ(std::memcmp(outs[i].data(), outs[0].data(), outs[0].size() * sizeof(float)), 0) << i;
}

TEST_F(Misuse, WrongPaletteSizeForKInstances) {
  SkinnerOptions options;
  options.instances = 3;
  Skinner skinner = Made(options);
  const std::vector<float> palette = Palette();  // one instance's
  ExpectError(skinner.SetPalette(palette.data(), palette.size()), ErrorCode::kInvalidArgument,
              "expected 3 instances x 77 joints x 16 = 3696");
  std::vector<float> out(skinner.vertex_count() * 3);  // one instance's
  ExpectError(skinner.ReadPositions(out.data(), out.size()), ErrorCode::kInvalidArgument,
              "expected 3 instances x 900 vertices x 3 = 8100");
}

TEST_F(Misuse, ForcedConstantStorageThatCannotHoldKPalettes) {
  SkinnerOptions options;
  options.variant = "opencl.b4.mat4.constant";
  options.instances = 4096;  // 4096 x 77 x 64 B = 20 MB of __constant
  ExpectError(CreateError(view_.mesh, options), ErrorCode::kInvalidArgument, "constant_memory");
}

TEST_F(Misuse, FinishBeforeTheFirstSkinHasNothingToWaitFor) {
  Skinner skinner = Made();
  EXPECT_TRUE(skinner.Finish().ok());
  const std::vector<float> palette = Palette();
  ASSERT_TRUE(skinner.SetPalette(palette.data(), palette.size()).ok());
  ASSERT_TRUE(skinner.Skin().ok());
  EXPECT_TRUE(skinner.Finish().ok());
}

TEST_F(Misuse, MovedFromSkinner) {
  Skinner skinner = Made();
  Skinner taker = std::move(skinner);
  const std::vector<float> palette = Palette();
  // NOLINTBEGIN(bugprone-use-after-move): the point of the test
  ExpectError(skinner.SetPalette(palette.data(), palette.size()), ErrorCode::kInvalidState, "used after move");
  ExpectError(skinner.Skin(), ErrorCode::kInvalidState, "used after move");
  ExpectError(skinner.Finish(), ErrorCode::kInvalidState, "used after move");
  std::vector<float> out(taker.vertex_count() * 3);
  ExpectError(skinner.ReadPositions(out.data(), out.size()), ErrorCode::kInvalidState, "used after move");
  EXPECT_EQ(skinner.device_positions(), nullptr);
  EXPECT_EQ(skinner.vertex_count(), 0u);
  // NOLINTEND(bugprone-use-after-move)
  EXPECT_TRUE(taker.SetPalette(palette.data(), palette.size()).ok());
}

TEST_F(Misuse, MovedFromDeviceOrDatabase) {
  Device taker = std::move(device_);
  // NOLINTBEGIN(bugprone-use-after-move): the point of the test
  EXPECT_TRUE(device_.info().id.empty());
  EXPECT_EQ(device_.cache_stats().builds, 0);
  ExpectError(CreateError(view_.mesh), ErrorCode::kInvalidState, "Device was used after move");
  WinnersDb db = WinnersDb::Empty();
  WinnersDb db_taker = std::move(db);
  Result<Skinner> skinner = Skinner::Create(taker, db, view_.mesh);
  ExpectError(skinner.status(), ErrorCode::kInvalidState, "WinnersDb was used after move");
  // NOLINTEND(bugprone-use-after-move)
}

TEST_F(Misuse, SkinnerOutlivesItsDevice) {
  Skinner skinner = Made();
  device_ = Device();  // the Device object is gone; the Skinner keeps what it needs
  const std::vector<float> palette = Palette();
  ASSERT_TRUE(skinner.SetPalette(palette.data(), palette.size()).ok());
  EXPECT_TRUE(skinner.Skin().ok());
}

TEST_F(Misuse, SkinIntoGlBufferWithoutGlSharing) {
  Skinner skinner = Made();
  const std::vector<float> palette = Palette();
  ASSERT_TRUE(skinner.SetPalette(palette.data(), palette.size()).ok());
  ExpectError(skinner.SkinIntoGlBuffer(1), ErrorCode::kUnavailable, "GL sharing");
}

}  // namespace
}  // namespace skintune::internal
