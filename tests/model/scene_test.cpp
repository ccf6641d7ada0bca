// Scenes (model/scene.h): the key grammar (one mesh, K instances, a
// batch, a seeded mix), the concatenation of a batch (vertex and joint
// offsets, padding to the batch's B, the gold of the batch equal to each
// mesh's own), and the errors naming the key or the mesh.
#include <gtest/gtest.h>

#include <numeric>
#include <string>

#include "base/error.h"
#include "model/scene.h"
#include "reference/skinning.h"
#include "model/synthetic.h"

namespace skintune::internal {
namespace {

std::string ErrorOf(const std::string& key) {
  try {
    (void)ParseSceneKey(key);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(SceneKey, OneMeshInstancesAndBatches) {
  const SceneSpec one = ParseSceneKey("25k-b4");
  EXPECT_EQ(one.meshes, std::vector<std::string>{"25k-b4"});
  EXPECT_EQ(one.instances, 1);
  EXPECT_FALSE(one.batch);

  const SceneSpec crowd = ParseSceneKey("25k-b4-x64");
  EXPECT_EQ(crowd.meshes, std::vector<std::string>{"25k-b4"});
  EXPECT_EQ(crowd.instances, 64);
  EXPECT_FALSE(crowd.batch);
  EXPECT_EQ(ParseSceneKey("data/Fox.gltf-x8").meshes, std::vector<std::string>{"data/Fox.gltf"});

  const SceneSpec batch = ParseSceneKey("data/CesiumMan.gltf+5k-b2+100k-b4-random");
  EXPECT_EQ(batch.meshes, (std::vector<std::string>{"data/CesiumMan.gltf", "5k-b2", "100k-b4-random"}));
  EXPECT_TRUE(batch.batch);
  EXPECT_EQ(batch.instances, 1);
}

TEST(SceneKey, AMixIsSeededMeshesOf5kTo100kEveryInfluenceCountSummingToItsTotal) {
  const SceneSpec mix = ParseSceneKey("mix1600k-b4");
  ASSERT_TRUE(mix.batch);
  EXPECT_EQ(ParseSceneKey("mix1600k-b4").meshes, mix.meshes);  // deterministic
  EXPECT_NE(ParseSceneKey("mix1600k-b4-seed2").meshes, mix.meshes);
  std::size_t total = 0;
  std::vector<int> influences(5, 0);
  for (const std::string& key : mix.meshes) {
    const DatasetSpec spec = ParseDatasetKey(key);
    EXPECT_GE(spec.vertices, kMixMinVertices) << key;
    EXPECT_LE(spec.vertices, kMixMaxVertices) << key;
    EXPECT_GE(spec.bones, 20) << key;
    EXPECT_LE(spec.bones, 77) << key;
    ASSERT_LE(spec.influences, 4) << key;
    ++influences[static_cast<std::size_t>(spec.influences)];
    total += spec.vertices;
  }
  EXPECT_EQ(total, 1600000u);
  for (int b = 1; b <= 4; ++b) EXPECT_GT(influences[static_cast<std::size_t>(b)], 0) << "b" << b;
  EXPECT_EQ(ParseSceneKey("mix10k-b2").meshes.size(), 2u);
  // A mix is a batch member like any other.
  EXPECT_EQ(ParseSceneKey("a.gltf+mix20k-b1").meshes.size(), 1 + ParseSceneKey("mix20k-b1").meshes.size());
}

TEST(SceneKey, MalformedKeysNameThePart) {
  EXPECT_NE(ErrorOf("5k-b2++5k-b1").find("scene '5k-b2++5k-b1': meshes[1] is empty"), std::string::npos);
  EXPECT_NE(ErrorOf("5k-b2-x4+5k-b1").find("meshes[0] '5k-b2-x4': a batch's meshes are skinned once each"),
            std::string::npos);
  EXPECT_NE(ErrorOf("5k-b2-x1").find("instances '1' outside 2..65536"), std::string::npos);
  EXPECT_NE(ErrorOf("mix9k-b2").find("at least two meshes"), std::string::npos);
  EXPECT_NE(ErrorOf("mix100k-b2-bones9").find("'-bones' is not an option"), std::string::npos);
  EXPECT_NE(ErrorOf("5k-b2+5k-b9").find("dataset '5k-b9'"), std::string::npos) << ErrorOf("5k-b2+5k-b9");
  EXPECT_EQ(ErrorOf("5k-b9"), [] {  // one mesh: the dataset's own message
    try {
      (void)ParseDatasetKey("5k-b9");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  }());
}

// "-anim": a scene of one mesh or its instances animated on the device.
TEST(SceneKey, AnimatedScenesAreOneMeshOrItsInstancesPlayingTheModelsClips) {
  const SceneSpec crowd = ParseSceneKey("25k-b4-x64-anim");
  EXPECT_TRUE(crowd.animated);
  EXPECT_EQ(crowd.instances, 64);
  EXPECT_EQ(crowd.meshes, std::vector<std::string>{"25k-b4"});
  EXPECT_FALSE(ParseSceneKey("25k-b4-x64").animated);
  const SceneSpec fox = ParseSceneKey("data/Fox.gltf-x6-anim");
  EXPECT_TRUE(fox.animated);
  EXPECT_EQ(fox.instances, 6);
  EXPECT_EQ(fox.meshes, std::vector<std::string>{"data/Fox.gltf"});
  EXPECT_TRUE(ParseSceneKey("5k-b2-anim").animated);
  EXPECT_FALSE(ParseSceneKey("5k-b2-anim").blended);
  const SceneSpec blended = ParseSceneKey("5k-b2-x8-animblend");
  EXPECT_TRUE(blended.animated && blended.blended);
  EXPECT_EQ(blended.instances, 8);
  EXPECT_EQ(blended.meshes, std::vector<std::string>{"5k-b2"});
  EXPECT_NE(ErrorOf("5k-b2+5k-b1-animblend").find("'-animblend' animates a scene of one mesh"), std::string::npos);
  EXPECT_EQ(ParseSceneKey("5k-b2-anim").instances, 1);
  EXPECT_NE(ErrorOf("5k-b2+5k-b1-anim").find("'-anim' animates a scene of one mesh or its instances, not a batch"),
            std::string::npos);
  EXPECT_NE(ErrorOf("mix20k-b2-anim").find("not a batch"), std::string::npos);
  // Loaded, the asset keeps its mesh (baking measures its error on it) and its clips.
  const SkinnedScene scene = LoadScene(ParseSceneKey(std::string(SKINTUNE_TEST_DATA_DIR) + "/Fox.gltf-x3-anim"));
  EXPECT_EQ(scene.mesh().vertex_count(), 1728u);
  EXPECT_EQ(scene.assets.front().mesh.vertex_count(), 1728u);
  EXPECT_EQ(scene.assets.front().animations.size(), 3u);
}

TEST(MeshBatch, ConcatenatesWithOffsetJointsAndPadsToTheLargestB) {
  const SkinnedAsset a = GenerateDataset(ParseDatasetKey("300-b1-bones5-normals"));
  const SkinnedAsset b = GenerateDataset(ParseDatasetKey("200-b3-bones12-seed2-normals"));
  const SkinnedAsset c = GenerateDataset(ParseDatasetKey("100-b2-bones7-seed3-normals"));
  const std::vector<const SkinnedMesh*> meshes{&a.mesh, &b.mesh, &c.mesh};
  const MeshBatch batch = ConcatenateMeshes(meshes);
  EXPECT_EQ(batch.vertex_offsets, (std::vector<std::size_t>{0, 300, 500, 600}));
  EXPECT_EQ(batch.joint_offsets, (std::vector<int>{0, 5, 17, 24}));
  EXPECT_EQ(batch.mesh.influences, 3);
  EXPECT_EQ(batch.mesh.joint_count, 24);
  ASSERT_TRUE(batch.mesh.has_normals());
  EXPECT_TRUE(Validate(batch.mesh).ok()) << Validate(batch.mesh).Summary();
  // Mesh 1's vertex 7, slot 2: its joint + 5; mesh 0's padding slots: weight 0 on its own first joint.
  EXPECT_EQ(batch.mesh.joints[(300 + 7) * 3 + 2], b.mesh.joints[7 * 3 + 2] + 5);
  EXPECT_EQ(batch.mesh.joints[10 * 3 + 1], 0);
  EXPECT_EQ(batch.mesh.weights[10 * 3 + 1], 0.0f);
  EXPECT_EQ(batch.mesh.joints[(500 + 4) * 3 + 2], 17);
  EXPECT_EQ(batch.mesh.weights[(500 + 4) * 3 + 2], 0.0f);

  // The batch's gold with the palettes one after another is each mesh's own gold.
  std::vector<glm::mat4> palette;
  std::vector<std::vector<glm::mat4>> own;
  for (const SkinnedAsset* asset : {&a, &b, &c}) {
    own.push_back(asset->PaletteAt(0, 0.4));
    palette.insert(palette.end(), own.back().begin(), own.back().end());
  }
  const GoldResult all = SkinGold(batch.mesh, palette, true);
  for (std::size_t m = 0; m < 3; ++m) {
    const GoldResult one = SkinGold(*meshes[m], own[m], true);
    for (std::size_t v = 0; v < one.positions.size(); ++v) {
      ASSERT_EQ(all.positions[batch.vertex_offsets[m] + v], one.positions[v]) << "mesh " << m << " vertex " << v;
      ASSERT_EQ(all.normals[batch.vertex_offsets[m] + v], one.normals[v]) << "mesh " << m << " vertex " << v;
    }
  }
}

TEST(MeshBatch, ErrorsNameTheMesh) {
  auto error_of = [](std::vector<const SkinnedMesh*> meshes) {
    try {
      (void)ConcatenateMeshes(meshes);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error_of({}), "meshes: the batch is empty");
  const SkinnedAsset a = GenerateDataset(ParseDatasetKey("50-b1-bones30000"));
  SkinnedMesh empty;
  empty.influences = 1;
  empty.joint_count = 3;
  EXPECT_EQ(error_of({&a.mesh, &empty}), "meshes[1]: no vertices");
  EXPECT_NE(error_of({&a.mesh, &a.mesh, &a.mesh}).find("meshes[2]: the batch's joints reach 90000"), std::string::npos);
  // Normals only when every mesh has them.
  const SkinnedAsset n = GenerateDataset(ParseDatasetKey("50-b1-normals"));
  EXPECT_FALSE(ConcatenateMeshes(std::vector<const SkinnedMesh*>{&n.mesh, &a.mesh}).mesh.has_normals());
}

TEST(Scene, LoadsInstancesAndBatchesWithTheirMeshes) {
  const SkinnedScene crowd = LoadScene(ParseSceneKey("500-b2-x3"));
  EXPECT_EQ(crowd.mesh().vertex_count(), 500u);
  EXPECT_EQ(crowd.total_vertices(), 1500u);
  const SkinnedScene batch = LoadScene(ParseSceneKey(std::string(SKINTUNE_TEST_DATA_DIR) + "/Fox.gltf+500-b2"));
  EXPECT_EQ(batch.mesh().vertex_count(), 1728u + 500u);
  EXPECT_EQ(batch.mesh().joint_count, 24 + 77);
  EXPECT_EQ(batch.assets.size(), 2u);
  try {
    (void)LoadScene(ParseSceneKey("500-b2+missing.gltf"));
    FAIL() << "a missing glTF file loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("scene '500-b2+missing.gltf': meshes[1] 'missing.gltf': "), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace skintune::internal
