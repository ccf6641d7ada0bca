// The public Model (skintune/skintune.h): loading glTF files and synthetic
// datasets, palettes of animations, the reference skinning, and its errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <glm/gtc/type_ptr.hpp>

#include "model/asset.h"
#include "model/gltf_import.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "skintune/skintune.h"

namespace skintune::internal {
namespace {

const std::string kCesium = std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf";

TEST(Model, LoadsCesiumManLikeTheImporter) {
  Result<Model> model = Model::Load(kCesium);
  ASSERT_TRUE(model.ok()) << model.status().message();
  const GltfImportResult imported = ImportGltf(kCesium);
  const SkinnedMesh& mesh = imported.asset.mesh;
  EXPECT_EQ(model->vertex_count(), mesh.vertex_count());
  EXPECT_EQ(model->joint_count(), mesh.joint_count);
  EXPECT_EQ(model->influences(), 4);
  EXPECT_TRUE(model->has_normals());
  EXPECT_EQ(model->warnings(), imported.warnings);  // CesiumMan: one renormalisation warning
  EXPECT_EQ(model->warnings().size(), 1u);
  const MeshView view = model->mesh();
  ASSERT_EQ(view.vertex_count, mesh.vertex_count());
  ASSERT_NE(view.normals, nullptr);
  for (std::size_t v = 0; v < mesh.vertex_count(); v += 97) {
    EXPECT_EQ(view.positions[v * 3 + 1], mesh.positions[v].y);
    EXPECT_EQ(view.normals[v * 3 + 2], mesh.normals[v].z);
    for (int i = 0; i < mesh.influences; ++i) {
      EXPECT_EQ(view.joints[v * mesh.influences + i], mesh.joints[v * mesh.influences + i]);
      EXPECT_EQ(view.weights[v * mesh.influences + i], mesh.weights[v * mesh.influences + i]);
    }
  }
  ASSERT_EQ(model->animation_count(), 1);
  EXPECT_GT(model->animation_duration(0), 1.0);
  EXPECT_EQ(model->animation_name(7), "");
}

TEST(Model, PaletteIsTheAssetsPaletteAtThatTimeColumnMajor) {
  Result<Model> model = Model::Load(kCesium);
  ASSERT_TRUE(model.ok());
  const SkinnedAsset asset = ImportGltf(kCesium).asset;
  for (double t : {0.0, 0.5, 1.3}) {
    std::vector<float> palette;
    ASSERT_TRUE(model->Palette(0, t, &palette).ok());
    const std::vector<glm::mat4> expected = asset.PaletteAt(0, t);
    ASSERT_EQ(palette.size(), expected.size() * 16);
    for (std::size_t j = 0; j < expected.size(); ++j)
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) EXPECT_EQ(palette[j * 16 + c * 4 + r], expected[j][c][r]) << j;
  }
  std::vector<float> rest;
  ASSERT_TRUE(model->Palette(-1, 0.0, &rest).ok());
  EXPECT_EQ(rest.size(), static_cast<std::size_t>(model->joint_count()) * 16);
}

TEST(Model, SkinReferenceIsTheGoldRoundedToFloat) {
  Result<Model> model = Model::Synthetic("2000-b4-seed5");
  ASSERT_TRUE(model.ok()) << model.status().message();
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("2000-b4-seed5"));
  std::vector<float> palette;
  ASSERT_TRUE(model->Palette(model->animation_count() > 0 ? 0 : -1, 0.25, &palette).ok());
  std::vector<float> positions;
  ASSERT_TRUE(model->SkinReference(palette.data(), palette.size(), &positions).ok());
  std::vector<glm::mat4> matrices;
  for (std::size_t j = 0; j < palette.size() / 16; ++j) matrices.push_back(glm::make_mat4(&palette[j * 16]));
  const GoldResult gold = SkinGold(asset.mesh, matrices);
  ASSERT_EQ(positions.size(), gold.positions.size() * 3);
  for (std::size_t v = 0; v < gold.positions.size(); ++v)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(positions[v * 3 + c], static_cast<float>(gold.positions[v][c])) << v;
}

TEST(Model, FindAnimationByNameOrIndexAndNotFoundListsThem) {
  Result<Model> model = Model::Load(kCesium);
  ASSERT_TRUE(model.ok());
  const Result<int> by_index = model->FindAnimation("0");
  ASSERT_TRUE(by_index.ok());
  EXPECT_EQ(*by_index, 0);
  const Result<int> missing = model->FindAnimation("dance");
  EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
  EXPECT_NE(missing.status().message().find("dance"), std::string::npos) << missing.status().message();
}

TEST(Model, ErrorsNameTheFileTheKeyOrTheArgument) {
  const Result<Model> missing = Model::Load("/nonexistent/model.gltf");
  EXPECT_EQ(missing.status().code(), ErrorCode::kIoError);
  EXPECT_NE(missing.status().message().find("/nonexistent/model.gltf"), std::string::npos);

  const std::string bad = (std::filesystem::temp_directory_path() / "skintune-model-test-bad.gltf").string();
  std::ofstream(bad) << "{\"asset\": {\"version\": \"2.0\"}, \"meshes\": 3}";
  const Result<Model> malformed = Model::Load(bad);
  EXPECT_EQ(malformed.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(malformed.status().message().find(bad), std::string::npos) << malformed.status().message();
  std::filesystem::remove(bad);

  const Result<Model> key = Model::Synthetic("100k-b9");
  EXPECT_EQ(key.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(key.status().message().find("100k-b9"), std::string::npos) << key.status().message();

  Result<Model> model = Model::Load(kCesium);
  ASSERT_TRUE(model.ok());
  std::vector<float> palette;
  EXPECT_EQ(model->Palette(1, 0.0, &palette).code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(model->Palette(0, std::nan(""), &palette).code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(model->Palette(0, 0.0, nullptr).code(), ErrorCode::kInvalidArgument);
  ASSERT_TRUE(model->Palette(0, 0.0, &palette).ok());
  std::vector<float> out;
  const Status short_palette = model->SkinReference(palette.data(), palette.size() - 16, &out);
  EXPECT_EQ(short_palette.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(short_palette.message().find("19 joints"), std::string::npos) << short_palette.message();

  Model moved = std::move(*model);
  EXPECT_EQ(model->Palette(0, 0.0, &palette).code(), ErrorCode::kInvalidState);
  EXPECT_EQ(model->vertex_count(), 0u);
  EXPECT_EQ(model->mesh().positions, nullptr);
  EXPECT_GT(moved.vertex_count(), 0u);
}

TEST(Model, CopiesAreIndependent) {
  Result<Model> model = Model::Synthetic("1000-b2");
  ASSERT_TRUE(model.ok());
  Model copy = *model;
  EXPECT_EQ(copy.vertex_count(), model->vertex_count());
  EXPECT_NE(copy.mesh().positions, model->mesh().positions);
  EXPECT_EQ(copy.mesh().positions[5], model->mesh().positions[5]);
}

}  // namespace
}  // namespace skintune::internal
