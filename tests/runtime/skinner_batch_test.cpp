// Skinner::CreateBatch (skintune.h): different meshes (vertex counts, B 1..4,
// joint counts: CesiumMan, Fox and two synthetic ones) skinned in one launch
// on every backend and language of this machine (PoCL, llvmpipe, lavapipe
// here; CUDA where a GPU is), with forced variants of different layouts,
// formats and palette storages, each mesh checked against its OWN float64
// gold; the batch's accessors; the errors, naming the mesh by index. A
// backend without a device here is skipped with its reason.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "runtime/backend_table.h"
#include "runtime/selection.h"
#include "runtime/winners_db.h"
#include "tests/common/test_asset.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::Floats;
using testing::TempDir;
using testing::TestAsset;
using testing::Vec3s;
using testing::View;

// Four different meshes: B 4, 4, 2 and 1; 19, 24, 40 and 12 joints; 3273, 1728, 1500 and 2000 vertices.
const std::vector<std::string> kMeshes = {"CesiumMan.gltf", "Fox.gltf", "1500-b2-bones40-seed3", "2000-b1-bones12-seed2"};

struct Batch {
  std::vector<View> views;
  std::vector<MeshView> meshes;
  std::vector<std::vector<glm::mat4>> palettes;  // per mesh
  std::vector<float> matrices;                  // every mesh's, one after another
};

Batch MakeBatch(const std::vector<std::string>& keys) {
  Batch b;
  b.views.reserve(keys.size());
  for (std::size_t m = 0; m < keys.size(); ++m) {
    const SkinnedAsset& asset = TestAsset(keys[m]);
    b.views.emplace_back(asset.mesh);
    const AnimationClip& clip = asset.animations.front();
    b.palettes.push_back(asset.PaletteAt(0, clip.start + clip.duration() * (0.2 + 0.15 * static_cast<double>(m))));
    const std::vector<float> f = Floats(b.palettes.back());
    b.matrices.insert(b.matrices.end(), f.begin(), f.end());
  }
  for (const View& v : b.views) b.meshes.push_back(v.mesh);
  return b;
}

// Two variants per language: different layouts, formats, palette storages and blends.
std::vector<std::string> VariantsOf(Lang lang) {
  const std::string l = Name(lang);
  if (lang == Lang::kGlslVertex)
    return {l + ".b4.padded.soa-split.float3.u16.unorm16.mat3x4.constant.point.v1c.wg0",
            l + ".b4.padded.aos.float4.i32.f32.mat4.global.matrix.v1c.wg0"};
  if (!HasWorkGroups(lang))  // cpu: no work-groups, no constant or local memory
    return {l + ".b4.padded.soa-split.float3.u16.unorm16.mat3x4.global.point.v1c.wg0",
            l + ".b4.padded.aos.float4.i32.f32.mat4.global.matrix.v1c.wg0"};
  return {l + ".b4.padded.soa-split.float3.u16.unorm16.mat3x4.local.point.v2s.wg64",
          l + ".b4.padded.aos.float4.i32.f32.mat4.global.matrix.v1c.wg32"};
}

std::vector<int> BackendIndices() {
  std::vector<int> out;
  for (std::size_t i = 0; i < Backends().size(); ++i) out.push_back(static_cast<int>(i));
  return out;
}

class BatchOnEveryBackend : public ::testing::TestWithParam<int> {};

TEST_P(BatchOnEveryBackend, EveryLanguageSkinsEachMeshLikeItsOwnGold) {
  const auto backend = static_cast<Backend>(GetParam());
  TempDir dir;
  const char* pattern = backend == Backend::kOpenCl ? std::getenv("SKINTUNE_TEST_OPENCL_DEVICE") : nullptr;
  Result<Device> device = Device::Open(pattern ? pattern : "", &backend, CacheIn(dir));
  if (!device.ok()) GTEST_SKIP() << "no " << BackendName(backend) << " device: " << device.status().message();
  const Batch batch = MakeBatch(kMeshes);
  for (Lang lang : LanguagesOf(backend)) {
    for (const std::string& key : VariantsOf(lang)) {
      SCOPED_TRACE(key);
      SkinnerOptions options;
      options.variant = key;
      Result<Skinner> made = Skinner::CreateBatch(*device, WinnersDb::Empty(), batch.meshes.data(), batch.meshes.size(), options);
      ASSERT_TRUE(made.ok()) << made.status().message();
      Skinner& skinner = *made;
      EXPECT_EQ(skinner.shape(), SceneShape::kBatch);
      ASSERT_EQ(skinner.mesh_count(), kMeshes.size());
      EXPECT_EQ(skinner.vertex_count(), 3273u + 1728u + 1500u + 2000u);
      EXPECT_EQ(skinner.joint_count(), 19 + 24 + 40 + 12);
      const Status set = skinner.SetPalette(batch.matrices.data(), batch.matrices.size());
      ASSERT_TRUE(set.ok()) << set.message();
      const Status skinned = skinner.Skin();
      ASSERT_TRUE(skinned.ok()) << skinned.message();
      std::vector<float> positions(skinner.vertex_count() * 3);
      const Status read = skinner.ReadPositions(positions.data(), positions.size());
      ASSERT_TRUE(read.ok()) << read.message();
      const Variant variant = ParseVariantKey(skinner.selection().variant);
      for (std::size_t m = 0; m < kMeshes.size(); ++m) {
        SCOPED_TRACE("meshes[" + std::to_string(m) + "] " + kMeshes[m]);
        const SkinnedMesh& mesh = TestAsset(kMeshes[m]).mesh;
        ASSERT_EQ(skinner.vertex_count(m), mesh.vertex_count());
        ASSERT_EQ(skinner.joint_count(m), mesh.joint_count);
        const GoldResult gold = SkinGold(QuantisedMesh(mesh, variant), batch.palettes[m]);
        const auto first = positions.begin() + static_cast<std::ptrdiff_t>(skinner.vertex_offset(m) * 3);
        const std::vector<float> own(first, first + static_cast<std::ptrdiff_t>(mesh.vertex_count() * 3));
        const GoldComparison c = CompareToGold(gold.positions, Vec3s(own));
        EXPECT_EQ(c.non_finite, 0u);
        EXPECT_LT(c.max_relative, 1e-5) << "worst vertex " << c.worst_vertex;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, BatchOnEveryBackend, ::testing::ValuesIn(BackendIndices()),
                         [](const ::testing::TestParamInfo<int>& p) {
                           return std::string(BackendName(static_cast<Backend>(p.param)));
                         });

// The errors of a batch, on the first OpenCL device (PoCL here).
class BatchErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    const Backend opencl = Backend::kOpenCl;
    const char* pattern = std::getenv("SKINTUNE_TEST_OPENCL_DEVICE");
    Result<Device> device = Device::Open(pattern ? pattern : "", &opencl, CacheIn(dir_));
    if (!device.ok()) GTEST_SKIP() << "no OpenCL device: " << device.status().message();
    device_ = std::move(*device);
  }
  Status CreateStatus(const std::vector<MeshView>& meshes, const SkinnerOptions& options = {}) {
    return Skinner::CreateBatch(device_, WinnersDb::Empty(), meshes.empty() ? nullptr : meshes.data(), meshes.size(),
                                options)
        .status();
  }
  TempDir dir_;
  Device device_;
};

TEST_F(BatchErrors, AnEmptyBatchIsAnInvalidArgument) {
  const Status empty = CreateStatus({});
  EXPECT_EQ(empty.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(empty.message(), "Skinner::CreateBatch: the batch is empty (no meshes)");
}

TEST_F(BatchErrors, ABadMeshIsNamedByItsIndexVertexAndSlot) {
  Batch batch = MakeBatch(kMeshes);
  batch.views[2].joints[17 * 2 + 1] = 999;  // meshes[2] is 1500-b2-bones40
  const Status bad = CreateStatus(batch.meshes);
  EXPECT_EQ(bad.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(bad.message(), "Skinner::CreateBatch: meshes[2]: vertex 17 slot 1: joint 999 out of range (40 joints)");
  batch.meshes[1].weights = nullptr;
  EXPECT_EQ(CreateStatus(batch.meshes).message(), "Skinner::CreateBatch: meshes[1]: weights is null");
  SkinnerOptions normals;
  normals.normals = true;
  batch = MakeBatch({"500-b1-normals", "500-b2"});
  EXPECT_EQ(CreateStatus(batch.meshes, normals).message(),
            "Skinner::CreateBatch: meshes[1]: SkinnerOptions::normals is set but MeshView::normals is null");
}

TEST_F(BatchErrors, TheVariantsConstraintsHoldForTheWholeBatch) {
  // Three meshes of 100 joints: 300 in all, beyond u8 indices (256).
  const Batch batch = MakeBatch({"300-b2-bones100", "300-b2-bones100-seed2", "300-b1-bones100-seed3"});
  SkinnerOptions options;
  options.variant = "opencl.b2.padded.soa.float4.u8.f32.mat3x4.global.matrix.v1c.wg64";
  const Status u8 = CreateStatus(batch.meshes, options);
  EXPECT_EQ(u8.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(u8.message().find("Skinner::CreateBatch: SkinnerOptions::variant"), std::string::npos) << u8.message();
  EXPECT_NE(u8.message().find("index_range: index u8: 300 joints do not fit (at most 256)"), std::string::npos)
      << u8.message();
  options.variant = "opencl.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64";
  EXPECT_TRUE(CreateStatus(batch.meshes, options).ok());
  // Over 65536 joints in all: SkinnedMesh's 16-bit indices.
  const Batch huge = MakeBatch({"100-b1-bones30000", "100-b1-bones30000-seed2", "100-b1-bones30000-seed3"});
  const Status too_many = CreateStatus(huge.meshes);
  EXPECT_EQ(too_many.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(too_many.message().find("Skinner::CreateBatch: meshes[2]: the batch's joints reach 90000"),
            std::string::npos)
      << too_many.message();
}

// The database's batch entry for this device is chosen for a batch, its
// single-mesh entry for one mesh of the same size.
TEST_F(BatchErrors, ABatchTakesTheDatabasesBatchEntry) {
  const Batch batch = MakeBatch(kMeshes);
  WinnersEntry single;
  const DeviceInfo& info = device_.info();
  const DeviceIdParts parts = SplitDeviceId(info.id);
  single.device_id = info.id;
  single.backend = parts.backend;
  single.platform = parts.platform;
  single.device_name = parts.name;
  single.driver_version = parts.driver_version;
  single.vendor = info.vendor;
  single.device_type = info.type;
  single.variant = ParseVariantKey("opencl.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64");
  single.lang = Lang::kOpenCl;
  single.influences = 4;
  single.vertices = 8501;
  single.vertex_bucket = VertexBucket(single.vertices);
  single.dataset = "8501-b4";
  single.median_ms = 1.0;
  single.created = "2026-01-01T00:00:00Z";
  single.source = "test";
  WinnersEntry batched = single;
  batched.variant = ParseVariantKey("opencl.b4.padded.aos.float3.u16.f32.mat4.global.matrix.v2c.wg32");
  batched.shape = SceneKind::kBatch;
  batched.meshes = 4;
  batched.dataset = "CesiumMan.gltf+Fox.gltf+1500-b2+2000-b1";
  const Result<WinnersDb> db = WinnersDb::Parse(WinnersDbJson({single, batched}).dump(), "db.json");
  ASSERT_TRUE(db.ok()) << db.status().message();
  Result<Skinner> made = Skinner::CreateBatch(device_, *db, batch.meshes.data(), batch.meshes.size());
  ASSERT_TRUE(made.ok()) << made.status().message();
  EXPECT_EQ(made->selection().variant, batched.variant.Key()) << made->selection().reason;
  EXPECT_EQ(made->selection().level, MatchLevel::kExactDevice);
  const Status set = made->SetPalette(batch.matrices.data(), batch.matrices.size());
  ASSERT_TRUE(set.ok()) << set.message();
  const Result<WinnersDb> only_single = WinnersDb::Parse(WinnersDbJson({single}).dump(), "db.json");
  made = Skinner::CreateBatch(device_, *only_single, batch.meshes.data(), batch.meshes.size());
  ASSERT_TRUE(made.ok()) << made.status().message();
  EXPECT_EQ(made->selection().variant, single.variant.Key());
  EXPECT_NE(made->selection().reason.find("no batch entry: the single-mesh entry of the scene's total size (8501 vertices)"),
            std::string::npos)
      << made->selection().reason;
}

}  // namespace
}  // namespace skintune::internal
