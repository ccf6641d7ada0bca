// ImportGltf: the three real models (counts, histograms, animations, rest pose
// reproduces POSITION, animated frames are plausible), mesh selection, GLB, and
// malformed variants of RiggedSimple.gltf generated into a temporary folder.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "base/error.h"
#include "model/gltf_import.h"
#include "reference/skinning.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string DataFile(const std::string& name) { return std::string(SKINTUNE_TEST_DATA_DIR) + "/" + name; }

// ---------------------------------------------------------------- base64, files, GLB

const char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::vector<std::uint8_t> DecodeBase64(const std::string& text) {
  std::vector<std::uint8_t> out;
  unsigned bits = 0;
  int count = 0;
  for (char ch : text) {
    const char* at = std::strchr(kBase64, ch);
    if (ch == '=' || ch == '\0' || at == nullptr) break;
    bits = (bits << 6) | static_cast<unsigned>(at - kBase64);
    if ((count += 6) >= 8) {
      count -= 8;
      out.push_back(static_cast<std::uint8_t>((bits >> count) & 0xFF));
    }
  }
  return out;
}

std::string EncodeBase64(const std::vector<std::uint8_t>& bytes) {
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, bytes.size() - i);
    unsigned chunk = static_cast<unsigned>(bytes[i]) << 16;
    if (n > 1) chunk |= static_cast<unsigned>(bytes[i + 1]) << 8;
    if (n > 2) chunk |= bytes[i + 2];
    out += kBase64[(chunk >> 18) & 63];
    out += kBase64[(chunk >> 12) & 63];
    out += n > 1 ? kBase64[(chunk >> 6) & 63] : '=';
    out += n > 2 ? kBase64[chunk & 63] : '=';
  }
  return out;
}

json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return json::parse(in);
}

// The bytes of buffers[0] (a base64 data URI in the test models).
std::vector<std::uint8_t> BufferBytes(const json& gltf) {
  const std::string uri = gltf["buffers"][0]["uri"];
  return DecodeBase64(uri.substr(uri.find(',') + 1));
}

void SetBufferBytes(json& gltf, const std::vector<std::uint8_t>& bytes) {
  gltf["buffers"][0]["uri"] = "data:application/octet-stream;base64," + EncodeBase64(bytes);
  gltf["buffers"][0]["byteLength"] = bytes.size();
}

template <typename T>
void Poke(std::vector<std::uint8_t>& bytes, std::size_t offset, T value) {
  ASSERT_LE(offset + sizeof value, bytes.size());
  std::memcpy(bytes.data() + offset, &value, sizeof value);
}

void AppendU32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// GLB container: 12-byte header, JSON chunk (space-padded), BIN chunk (zero-padded).
std::vector<std::uint8_t> MakeGlb(json gltf) {
  std::vector<std::uint8_t> bin = BufferBytes(gltf);
  gltf["buffers"][0].erase("uri");
  gltf["buffers"][0]["byteLength"] = bin.size();
  std::string text = gltf.dump();
  while (text.size() % 4 != 0) text += ' ';
  while (bin.size() % 4 != 0) bin.push_back(0);
  std::vector<std::uint8_t> out = {'g', 'l', 'T', 'F'};
  AppendU32(out, 2);
  AppendU32(out, static_cast<std::uint32_t>(12 + 8 + text.size() + 8 + bin.size()));
  AppendU32(out, static_cast<std::uint32_t>(text.size()));
  AppendU32(out, 0x4E4F534A);  // "JSON"
  out.insert(out.end(), text.begin(), text.end());
  AppendU32(out, static_cast<std::uint32_t>(bin.size()));
  AppendU32(out, 0x004E4942);  // "BIN\0"
  out.insert(out.end(), bin.begin(), bin.end());
  return out;
}

// A fresh folder per test, removed afterwards.
class GltfFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("skintune_gltf_" + std::to_string(::getpid()) + "_" +
                                        info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    rigged_ = ReadJson(DataFile("RiggedSimple.gltf"));
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string WriteBytes(const std::string& name, const std::string& bytes) {
    const fs::path path = dir_ / name;
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path.string();
  }
  std::string WriteBytes(const std::string& name, const std::vector<std::uint8_t>& bytes) {
    return WriteBytes(name, std::string(bytes.begin(), bytes.end()));
  }
  std::string WriteJson(const std::string& name, const json& gltf) { return WriteBytes(name, gltf.dump()); }

  // Writes RiggedSimple with `mutate` applied as Bad.gltf and expects ImportGltf to
  // fail with a message starting with the path and containing every fragment.
  void ExpectError(const std::function<void(json&)>& mutate, const std::vector<std::string>& fragments) {
    json gltf = rigged_;
    mutate(gltf);
    ExpectFileError(WriteJson("Bad.gltf", gltf), fragments);
  }
  void ExpectFileError(const std::string& path, const std::vector<std::string>& fragments,
                       const GltfImportOptions& options = {}) {
    try {
      ImportGltf(path, options);
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
      for (const std::string& f : fragments)
        EXPECT_NE(message.find(f), std::string::npos) << "'" << f << "' not in: " << message;
    }
  }

  fs::path dir_;
  json rigged_;
};

// RiggedSimple layout (see the file): accessors[1] JOINTS_0 (bufferViews[1], byteOffset 8528,
// stride 8), [3] POSITION, [4] WEIGHTS_0 (bufferViews[3], byteOffset 928, stride 16).
constexpr std::size_t kJointsAt = 8528, kJointsStride = 8, kWeightsAt = 928, kWeightsStride = 16;

// ---------------------------------------------------------------- the three models

struct ModelFacts {
  std::string file;
  std::size_t vertices;
  int joints;
  std::vector<std::size_t> histogram;  // vertices with 0, 1, 2, ... non-zero weights
  bool normals;
  std::vector<std::string> animation_names;
  std::vector<double> starts, ends;
  std::size_t channels;        // of animation 0
  bool placement_is_identity;  // rest-pose palette (see RestPoseSkinningReproducesThePositionData)
};

// How gtest (and so ctest) names a parameter.
void PrintTo(const ModelFacts& facts, std::ostream* out) { *out << facts.file; }

const ModelFacts kModels[] = {
    {"CesiumMan.gltf", 3273, 19, {0, 458, 1678, 717, 420}, true, {""}, {0.0}, {2.0}, 57, false},
    {"RiggedSimple.gltf", 160, 2, {0, 128, 32}, true, {""}, {0.0417}, {2.083}, 3, false},
    {"Fox.gltf",
     1728,
     24,
     {0, 772, 917, 33, 6},
     false,
     {"Survey", "Walk", "Run"},
     {0.0, 0.0, 0.0},
     {3.417, 0.708, 1.158},
     21,
     true},
};

class RealModel : public ::testing::TestWithParam<ModelFacts> {
 protected:
  const GltfImportResult& Load() {
    if (!result_) result_ = std::make_unique<GltfImportResult>(ImportGltf(DataFile(GetParam().file)));
    return *result_;
  }
  std::unique_ptr<GltfImportResult> result_;
};

TEST_P(RealModel, HasTheDocumentedVertexAndJointCounts) {
  const SkinnedAsset& asset = Load().asset;
  EXPECT_EQ(asset.source, DataFile(GetParam().file));
  EXPECT_EQ(asset.mesh.vertex_count(), GetParam().vertices);
  EXPECT_EQ(asset.mesh.joint_count, GetParam().joints);
  EXPECT_EQ(asset.skeleton.joint_count(), GetParam().joints);
  EXPECT_EQ(asset.mesh.has_normals(), GetParam().normals);
  EXPECT_TRUE(Validate(asset.mesh).ok()) << Validate(asset.mesh).Summary();
}

TEST_P(RealModel, HasTheDocumentedInfluenceHistogram) {
  const SkinnedMesh& mesh = Load().asset.mesh;
  EXPECT_EQ(mesh.influences, static_cast<int>(GetParam().histogram.size()) - 1);
  EXPECT_EQ(InfluenceHistogram(mesh), GetParam().histogram);
}

TEST_P(RealModel, HasTheDocumentedAnimations) {
  const auto& clips = Load().asset.animations;
  const ModelFacts& facts = GetParam();
  ASSERT_EQ(clips.size(), facts.animation_names.size());
  for (std::size_t a = 0; a < clips.size(); ++a) {
    EXPECT_EQ(clips[a].name, facts.animation_names[a]);
    EXPECT_NEAR(clips[a].start, facts.starts[a], 1e-3) << a;
    EXPECT_NEAR(clips[a].end, facts.ends[a], 1e-3) << a;
    EXPECT_EQ(clips[a].channels.size(), facts.channels) << a;
  }
}

// glTF skins in model space: the joints' ancestors apply (CesiumMan and RiggedSimple
// hang their skeleton under a Z-up root node). So in the rest pose every palette
// entry is the same rigid placement M, and skinning gives M * POSITION; for Fox M = I.
TEST_P(RealModel, RestPoseSkinningReproducesThePositionData) {
  const SkinnedAsset& asset = Load().asset;
  const std::vector<glm::mat4> palette = asset.PaletteAt(-1, 0.0);
  const glm::dmat4 placement(palette.at(0));
  for (std::size_t j = 0; j < palette.size(); ++j) {
    for (int c = 0; c < 4; ++c) {
      const double scale = c == 3 ? glm::length(placement[3]) : 1.0;
      EXPECT_LT(glm::length(glm::dvec4(palette[j][c]) - placement[c]), 1e-5 * scale)
          << "joint " << j << " column " << c;
    }
  }
  const glm::dmat3 r(placement);
  const glm::dmat3 rtr = glm::transpose(r) * r;
  for (int c = 0; c < 3; ++c)
    EXPECT_LT(glm::length(rtr[c] - glm::dmat3(1.0)[c]), 1e-5) << "placement is not rigid";
  if (GetParam().placement_is_identity) {
    for (int c = 0; c < 4; ++c)
      EXPECT_LT(glm::length(placement[c] - glm::dmat4(1.0)[c]), 1e-5) << "column " << c;
  }
  const GoldResult gold = SkinGold(asset.mesh, palette);
  double size = 0.0, worst = 0.0;
  for (std::size_t v = 0; v < asset.mesh.vertex_count(); ++v) {
    const glm::dvec3 p(asset.mesh.positions[v]);
    size = std::max(size, glm::length(p));
    worst = std::max(worst, glm::length(gold.positions[v] - glm::dvec3(placement * glm::dvec4(p, 1.0))));
  }
  EXPECT_LT(worst, 1e-4 * size) << "size " << size;
}

struct Box {
  glm::dvec3 lo{1e300}, hi{-1e300};
  void Add(const glm::dvec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  double Diagonal() const { return glm::length(hi - lo); }
};

TEST_P(RealModel, MidAnimationFrameHasAPlausibleBoundingBox) {
  const SkinnedAsset& asset = Load().asset;
  const AnimationClip& clip = asset.animations.at(0);
  const GoldResult frame = SkinGold(asset.mesh, asset.PaletteAt(0, 0.5 * (clip.start + clip.end)));
  Box rest, posed;
  double moved = 0.0;
  for (std::size_t v = 0; v < asset.mesh.vertex_count(); ++v) {
    const glm::dvec3& p = frame.positions[v];
    ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << "vertex " << v;
    rest.Add(glm::dvec3(asset.mesh.positions[v]));
    posed.Add(p);
    moved = std::max(moved, glm::length(p - glm::dvec3(asset.mesh.positions[v])));
  }
  EXPECT_GT(posed.Diagonal(), 0.25 * rest.Diagonal());
  EXPECT_LT(posed.Diagonal(), 4.0 * rest.Diagonal());
  EXPECT_LT(glm::length(0.5 * (posed.lo + posed.hi) - 0.5 * (rest.lo + rest.hi)), 2.0 * rest.Diagonal());
  EXPECT_GT(moved, 1e-2 * rest.Diagonal()) << "the frame is the rest pose";
}

TEST_P(RealModel, StrictModeAcceptsOnlyNormalisedWeights) {
  const std::string path = DataFile(GetParam().file);
  GltfImportOptions strict;
  strict.strict = true;
  if (GetParam().file != "CesiumMan.gltf") {
    EXPECT_NO_THROW(ImportGltf(path, strict));
    EXPECT_TRUE(Load().warnings.empty());
    return;
  }
  try {
    ImportGltf(path, strict);
    ADD_FAILURE() << "strict import accepted CesiumMan's non-normalised weights";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
    EXPECT_NE(message.find("vertex "), std::string::npos) << message;
    EXPECT_NE(message.find("weights sum to"), std::string::npos) << message;
    EXPECT_NE(message.find("210 such vertices"), std::string::npos) << message;
  }
}

INSTANTIATE_TEST_SUITE_P(Models, RealModel, ::testing::ValuesIn(kModels),
                         [](const ::testing::TestParamInfo<ModelFacts>& param) {
                           return param.param.file.substr(0, param.param.file.find('.'));
                         });

TEST(GltfImport, CesiumManGivesOneWarningAbout210RenormalisedVertices) {
  const std::string path = DataFile("CesiumMan.gltf");
  const GltfImportResult result = ImportGltf(path);
  ASSERT_EQ(result.warnings.size(), 1u);
  const std::string& warning = result.warnings[0];
  EXPECT_EQ(warning.rfind(path + ": renormalised weights of 210 vertices (worst: vertex ", 0), 0u) << warning;
  EXPECT_NE(warning.find(", sum 0.18"), std::string::npos) << warning;  // README: sums from 0.185
}

TEST(GltfImport, NormalsAreSkippedWhenNotRequested) {
  GltfImportOptions options;
  options.normals = false;
  EXPECT_FALSE(ImportGltf(DataFile("CesiumMan.gltf"), options).asset.mesh.has_normals());
}

// ---------------------------------------------------------------- mesh selection

TEST(GltfImport, SelectsTheSkinnedMeshByNodeName) {
  GltfImportOptions options;
  options.mesh = "fox";
  EXPECT_EQ(ImportGltf(DataFile("Fox.gltf"), options).asset.mesh.name, "fox1");
}

TEST(GltfImport, SelectsTheSkinnedMeshByMeshName) {
  GltfImportOptions options;
  options.mesh = "Cylinder";
  const SkinnedAsset asset = ImportGltf(DataFile("RiggedSimple.gltf"), options).asset;
  EXPECT_EQ(asset.mesh.name, "Cylinder");
  EXPECT_EQ(asset.mesh.vertex_count(), 160u);
}

TEST_F(GltfFiles, SelectsTheSecondOfTwoSkinnedMeshesByName) {
  json gltf = rigged_;
  json mesh = gltf["meshes"][0];
  mesh["name"] = "Copy";
  mesh["primitives"][0]["attributes"].erase("NORMAL");
  gltf["meshes"].push_back(mesh);
  gltf["nodes"].push_back({{"name", "CopyNode"}, {"mesh", 1}, {"skin", 0}});
  const std::string path = WriteJson("Two.gltf", gltf);
  EXPECT_TRUE(ImportGltf(path).asset.mesh.has_normals());  // the first one by default
  GltfImportOptions options;
  options.mesh = "CopyNode";
  const SkinnedAsset asset = ImportGltf(path, options).asset;
  EXPECT_EQ(asset.mesh.name, "Copy");
  EXPECT_FALSE(asset.mesh.has_normals());
}

TEST_F(GltfFiles, UnknownMeshNameErrorListsTheSkinnedMeshes) {
  GltfImportOptions options;
  options.mesh = "Dragon";
  ExpectFileError(DataFile("Fox.gltf"), {"no skinned mesh named 'Dragon'", "'fox'", "'fox1'"}, options);
}

// ---------------------------------------------------------------- file kinds

TEST_F(GltfFiles, GlbContainerLoadsEqualToTheGltf) {
  const SkinnedAsset gltf = ImportGltf(DataFile("RiggedSimple.gltf")).asset;
  const std::string path = WriteBytes("RiggedSimple.glb", MakeGlb(rigged_));
  const SkinnedAsset glb = ImportGltf(path).asset;
  EXPECT_EQ(glb.source, path);
  EXPECT_EQ(glb.mesh.name, gltf.mesh.name);
  EXPECT_EQ(glb.mesh.influences, gltf.mesh.influences);
  EXPECT_EQ(glb.mesh.positions, gltf.mesh.positions);
  EXPECT_EQ(glb.mesh.normals, gltf.mesh.normals);
  EXPECT_EQ(glb.mesh.joints, gltf.mesh.joints);
  EXPECT_EQ(glb.mesh.weights, gltf.mesh.weights);
  EXPECT_EQ(glb.skeleton.joints, gltf.skeleton.joints);
  EXPECT_EQ(glb.skeleton.inverse_bind, gltf.skeleton.inverse_bind);
  ASSERT_EQ(glb.animations.size(), gltf.animations.size());
  EXPECT_EQ(glb.animations[0].channels[1].values, gltf.animations[0].channels[1].values);
  EXPECT_EQ(glb.PaletteAt(0, 1.0), gltf.PaletteAt(0, 1.0));
}

TEST_F(GltfFiles, GlbIsRecognisedByItsMagicNotItsExtension) {
  const std::string path = WriteBytes("binary_named.gltf", MakeGlb(rigged_));
  EXPECT_EQ(ImportGltf(path).asset.mesh.vertex_count(), 160u);
}

TEST_F(GltfFiles, RandomTextIsNotAGltfFile) {
  ExpectFileError(WriteBytes("notes.gltf", std::string("this is not a model\n")), {"not a glTF 2.0 file ("});
}

TEST_F(GltfFiles, EmptyFileIsNotAGltfFile) {
  ExpectFileError(WriteBytes("empty.gltf", std::string()), {"not a glTF 2.0 file"});
}

TEST_F(GltfFiles, MissingFileCannotBeOpened) {
  ExpectFileError((dir_ / "nowhere.gltf").string(), {"cannot open file"});
}

TEST_F(GltfFiles, FileWithoutSkinnedMeshIsRejected) {
  ExpectError([](json& g) { g["nodes"][2].erase("skin"); }, {"no skinned mesh"});
}

// ---------------------------------------------------------------- accessors

TEST_F(GltfFiles, AttributeNamingAMissingAccessorIsRejected) {
  ExpectError([](json& g) { g["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] = 99; },
              {"accessors[99] (JOINTS_0 of meshes[0].primitives[0])", "does not exist"});
}

TEST_F(GltfFiles, JointsAsFloatIsRejected) {
  ExpectError([](json& g) { g["accessors"][1]["componentType"] = 5126; },
              {"accessors[1] (JOINTS_0 of meshes[0].primitives[0])",
               "component type FLOAT not allowed (expected UNSIGNED_BYTE or UNSIGNED_SHORT)"});
}

TEST_F(GltfFiles, PositionAsVec2IsRejected) {
  ExpectError(
      [](json& g) { g["accessors"][3]["type"] = "VEC2"; },
      {"accessors[3] (POSITION of meshes[0].primitives[0])", "type VEC2 not allowed (expected VEC3)"});
}

TEST_F(GltfFiles, UnnormalisedIntegerWeightsAreRejected) {
  ExpectError([](json& g) { g["accessors"][4]["componentType"] = 5121; },
              {"accessors[4] (WEIGHTS_0 of meshes[0].primitives[0])", "UNSIGNED_BYTE must be normalized"});
}

TEST_F(GltfFiles, TruncatedBufferIsRejected) {
  ExpectError(
      [](json& g) {
        std::vector<std::uint8_t> bytes = BufferBytes(g);
        bytes.resize(9000);  // JOINTS_0's bufferViews[1] spans 8528..9808
        SetBufferBytes(g, bytes);
      },
      {"accessors[1] (JOINTS_0", "bufferViews[1]", "does not fit in buffers[0] (9000 bytes)"});
}

TEST_F(GltfFiles, AccessorLongerThanItsBufferViewIsRejected) {
  ExpectError([](json& g) { g["bufferViews"][2]["byteLength"] = 3000; },  // POSITION needs 1920 + 160 * 12
              {"accessors[3] (POSITION", "need 3840 bytes", "bufferViews[2] has byteLength 3000"});
}

TEST_F(GltfFiles, SparseAccessorOverridesSelectedElements) {
  json gltf = rigged_;
  std::vector<std::uint8_t> bytes = BufferBytes(gltf);
  const std::size_t at = bytes.size();
  bytes.resize(at + 4 + 12);
  Poke<std::uint16_t>(bytes, at, 10);                                        // vertex 10 ...
  for (int c = 0; c < 3; ++c) Poke<float>(bytes, at + 4 + 4 * c, 7.0f + c);  // ... moves to (7, 8, 9)
  SetBufferBytes(gltf, bytes);
  gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", at}, {"byteLength", 2}});
  gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", at + 4}, {"byteLength", 12}});
  gltf["accessors"][3]["sparse"] = {{"count", 1},
                                    {"indices", {{"bufferView", 8}, {"componentType", 5123}}},
                                    {"values", {{"bufferView", 9}}}};
  const SkinnedAsset original = ImportGltf(DataFile("RiggedSimple.gltf")).asset;
  const SkinnedAsset sparse = ImportGltf(WriteJson("Sparse.gltf", gltf)).asset;
  EXPECT_EQ(sparse.mesh.positions[10], glm::vec3(7, 8, 9));
  EXPECT_EQ(sparse.mesh.positions[9], original.mesh.positions[9]);
  EXPECT_EQ(sparse.mesh.positions[11], original.mesh.positions[11]);
}

TEST_F(GltfFiles, SecondInfluenceSetIsReadAndCompacted) {
  json gltf = rigged_;
  // JOINTS_1 reuses JOINTS_0; WEIGHTS_1 has no bufferView, so it is all zeros.
  gltf["accessors"].push_back({{"componentType", 5126}, {"count", 160}, {"type", "VEC4"}});
  gltf["meshes"][0]["primitives"][0]["attributes"]["JOINTS_1"] = 1;
  gltf["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_1"] = gltf["accessors"].size() - 1;
  const SkinnedAsset original = ImportGltf(DataFile("RiggedSimple.gltf")).asset;
  const SkinnedAsset two_sets = ImportGltf(WriteJson("TwoSets.gltf", gltf)).asset;
  EXPECT_EQ(two_sets.mesh.influences, original.mesh.influences);
  EXPECT_EQ(two_sets.mesh.joints, original.mesh.joints);
  EXPECT_EQ(two_sets.mesh.weights, original.mesh.weights);
}

TEST_F(GltfFiles, JointsWithoutWeightsSetIsRejected) {
  ExpectError([](json& g) { g["meshes"][0]["primitives"][0]["attributes"]["JOINTS_1"] = 1; },
              {"meshes[0].primitives[0]", "JOINTS_1 without WEIGHTS_1"});
}

// ---------------------------------------------------------------- influences

TEST_F(GltfFiles, JointOutsideTheSkinIsRejected) {
  ExpectError(
      [](json& g) {
        std::vector<std::uint8_t> bytes = BufferBytes(g);
        Poke<std::uint16_t>(bytes, kJointsAt + 7 * kJointsStride, 5);  // vertex 7 slot 0 (weight > 0.7)
        SetBufferBytes(g, bytes);
      },
      {"accessors[1] (JOINTS_0 of meshes[0].primitives[0])", "vertex 7 slot 0",
       "joint 5 is outside the skin (2 joints)"});
}

// Appends `floats` to buffers[0] as a new buffer view and accessor (FLOAT,
// `type`, `count` elements); returns the accessor's index.
int AppendFloatAccessor(json& gltf, const std::vector<float>& floats, const char* type, std::size_t count) {
  std::vector<std::uint8_t> bytes = BufferBytes(gltf);
  while (bytes.size() % 4 != 0) bytes.push_back(0);
  const std::size_t offset = bytes.size();
  bytes.resize(offset + floats.size() * sizeof(float));
  std::memcpy(bytes.data() + offset, floats.data(), floats.size() * sizeof(float));
  SetBufferBytes(gltf, bytes);
  gltf["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", floats.size() * sizeof(float)}});
  gltf["accessors"].push_back({{"bufferView", gltf["bufferViews"].size() - 1},
                               {"componentType", 5126},
                               {"count", count},
                               {"type", type}});
  return static_cast<int>(gltf["accessors"].size() - 1);
}

// RiggedSimple (160 vertices) with two morph targets: target 0 moves vertex v
// by (0.01 v, 0, 0.5), target 1 by (0, -0.2, 0) and turns its normal by
// (0, 0, 1); default weights (0.5, 0.25); with `animated`, a LINEAR weights
// channel on the skinned node (keys at 0 s: (0, 0), 1 s: (1, 0.5)).
json MorphedRigged(json gltf, bool animated) {
  constexpr std::size_t n = 160;
  std::vector<float> d0, d1, n1;
  for (std::size_t v = 0; v < n; ++v) {
    d0.insert(d0.end(), {0.01f * static_cast<float>(v), 0.0f, 0.5f});
    d1.insert(d1.end(), {0.0f, -0.2f, 0.0f});
    n1.insert(n1.end(), {0.0f, 0.0f, 1.0f});
  }
  const int a0 = AppendFloatAccessor(gltf, d0, "VEC3", n), a1 = AppendFloatAccessor(gltf, d1, "VEC3", n),
            an = AppendFloatAccessor(gltf, n1, "VEC3", n);
  gltf["meshes"][0]["primitives"][0]["targets"] = json::array({{{"POSITION", a0}}, {{"POSITION", a1}, {"NORMAL", an}}});
  gltf["meshes"][0]["weights"] = {0.5, 0.25};
  if (animated) {
    const int times = AppendFloatAccessor(gltf, {0.0f, 1.0f}, "SCALAR", 2);
    const int values = AppendFloatAccessor(gltf, {0.0f, 0.0f, 1.0f, 0.5f}, "SCALAR", 4);
    json& anim = gltf["animations"][0];
    anim["samplers"].push_back({{"input", times}, {"output", values}, {"interpolation", "LINEAR"}});
    anim["channels"].push_back({{"sampler", anim["samplers"].size() - 1}, {"target", {{"node", 2}, {"path", "weights"}}}});
  }
  return gltf;
}

// Morph targets are read with their default weights and the skinned node's
// weights channel; MeshAt applies them before skinning (checked against the
// offsets computed here, at the defaults and at three times of the clip);
// what skins only the mesh (the tuner, the runtime) refuses an asset whose
// targets move vertices, and accepts one whose cannot.
TEST_F(GltfFiles, MorphTargetsAreReadAndAppliedAtTheClipsWeights) {
  GltfImportOptions with_normals;
  with_normals.normals = true;
  const SkinnedAsset base = ImportGltf(DataFile("RiggedSimple.gltf"), with_normals).asset;
  const GltfImportResult result = ImportGltf(WriteJson("Morph.gltf", MorphedRigged(rigged_, true)), with_normals);
  const SkinnedAsset& asset = result.asset;
  ASSERT_EQ(asset.mesh.morph.count(), 2u);
  EXPECT_EQ(asset.mesh.morph.where, "meshes[0].primitives[0].targets");
  EXPECT_EQ(asset.mesh.morph.weights, (std::vector<double>{0.5, 0.25}));
  const auto expect_at = [&](int clip, double t, double w0, double w1) {
    const std::vector<double> w = asset.MorphWeightsAt(clip, t);
    ASSERT_EQ(w.size(), 2u);
    EXPECT_NEAR(w[0], w0, 1e-12) << t;
    EXPECT_NEAR(w[1], w1, 1e-12) << t;
    const SkinnedMesh mesh = asset.MeshAt(clip, t);
    ASSERT_EQ(mesh.vertex_count(), base.mesh.vertex_count());
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      const glm::dvec3 expected =
          glm::dvec3(base.mesh.positions[v]) + w0 * glm::dvec3(0.01 * static_cast<double>(v), 0.0, 0.5) + w1 * glm::dvec3(0.0, -0.2, 0.0);
      ASSERT_NEAR(glm::length(glm::dvec3(mesh.positions[v]) - expected), 0.0, 1e-5) << "vertex " << v << " t " << t;
      const glm::dvec3 normal = glm::dvec3(base.mesh.normals[v]) + w1 * glm::dvec3(0.0, 0.0, 1.0);
      ASSERT_NEAR(glm::length(glm::dvec3(mesh.normals[v]) - normal), 0.0, 1e-6) << "vertex " << v;
    }
  };
  expect_at(-1, 0.0, 0.5, 0.25);  // the rest pose: the default weights
  expect_at(0, 0.0, 0.0, 0.0);
  expect_at(0, 0.25, 0.25, 0.125);
  expect_at(0, 0.8, 0.8, 0.4);
  expect_at(0, 5.0, 1.0, 0.5);  // clamped to the last key
  // Zero weights and no weights channel: accepted, weights 0.
  json quiet = MorphedRigged(rigged_, false);
  quiet["meshes"][0]["weights"] = {0.0, 0.0};
  const SkinnedAsset still = ImportGltf(WriteJson("Quiet.gltf", quiet)).asset;
  EXPECT_EQ(still.mesh.morph.weights, (std::vector<double>{0.0, 0.0}));
  // The node's weights override the mesh's.
  json node = MorphedRigged(rigged_, false);
  node["nodes"][2]["weights"] = {0.0, 1.0};
  EXPECT_EQ(ImportGltf(WriteJson("Node.gltf", node)).asset.mesh.morph.weights, (std::vector<double>{0.0, 1.0}));
}

// TANGENT is read when asked for (every primitive), its handedness checked;
// a morph target's TANGENT offsets move the tangents' xyz and keep w.
TEST_F(GltfFiles, TangentsAreReadWhenAskedForWithTheirMorphOffsets) {
  constexpr std::size_t n = 160;
  json gltf = MorphedRigged(rigged_, false);
  std::vector<float> tangents, offsets;
  for (std::size_t v = 0; v < n; ++v) {
    tangents.insert(tangents.end(), {1.0f, 0.0f, 0.0f, v % 2 ? -1.0f : 1.0f});
    offsets.insert(offsets.end(), {0.0f, 0.5f, 0.0f});
  }
  const int tangent = AppendFloatAccessor(gltf, tangents, "VEC4", n);
  gltf["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = tangent;
  gltf["meshes"][0]["primitives"][0]["targets"][1]["TANGENT"] = AppendFloatAccessor(gltf, offsets, "VEC3", n);
  GltfImportOptions options;
  options.tangents = true;
  const SkinnedAsset asset = ImportGltf(WriteJson("Tangents.gltf", gltf), options).asset;
  ASSERT_EQ(asset.mesh.tangents.size(), n);
  EXPECT_EQ(asset.mesh.tangents[1], glm::vec4(1, 0, 0, -1));
  const SkinnedMesh morphed = asset.MeshAt(-1, 0.0);  // default weights (0.5, 0.25)
  EXPECT_EQ(morphed.tangents[1], glm::vec4(1, 0.125f, 0, -1));
  EXPECT_EQ(ImportGltf(WriteJson("Tangents.gltf", gltf)).asset.mesh.tangents.size(), 0u) << "not asked for";
  tangents[4 * 3 + 3] = 0.5f;
  gltf["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = AppendFloatAccessor(gltf, tangents, "VEC4", n);
  ExpectFileError(WriteJson("Bad.gltf", gltf), {"TANGENT of meshes[0].primitives[0]", "vertex 3: handedness (w) is 0.5"},
                  options);
}

// A morph target's offsets of an attribute skintune does not carry (here
// TEXCOORD_0) are not applied, and the import says so once, naming them;
// targets of positions and normals alone say nothing.
TEST_F(GltfFiles, MorphOffsetsOfAttributesNotSkinnedAreNamedInAWarning) {
  const auto morph_warnings = [](const GltfImportResult& result) {
    std::vector<std::string> out;
    for (const std::string& w : result.warnings)
      if (w.find("not applied") != std::string::npos) out.push_back(w);
    return out;
  };
  json gltf = MorphedRigged(rigged_, false);
  EXPECT_TRUE(morph_warnings(ImportGltf(WriteJson("Plain.gltf", gltf))).empty());
  constexpr std::size_t n = 160;
  const std::vector<float> uv(2 * n, 0.25f), colour(3 * n, 0.5f);
  gltf["meshes"][0]["primitives"][0]["targets"][0]["TEXCOORD_0"] = AppendFloatAccessor(gltf, uv, "VEC2", n);
  gltf["meshes"][0]["primitives"][0]["targets"][1]["TEXCOORD_0"] = AppendFloatAccessor(gltf, uv, "VEC2", n);
  gltf["meshes"][0]["primitives"][0]["targets"][1]["COLOR_0"] = AppendFloatAccessor(gltf, colour, "VEC3", n);
  const GltfImportResult result = ImportGltf(WriteJson("Uv.gltf", gltf));
  const std::vector<std::string> warnings = morph_warnings(result);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("Uv.gltf: meshes[0].primitives[0].targets: offsets of COLOR_0, TEXCOORD_0 not applied"),
            std::string::npos)
      << warnings[0];
  EXPECT_EQ(result.asset.mesh.morph.count(), 2u);
}

// Malformed morph data is one error naming the element.
TEST_F(GltfFiles, MalformedMorphTargetsAreRejected) {
  ExpectError(
      [](json& g) {
        g = MorphedRigged(g, false);
        g["meshes"][0]["weights"] = {0.5};
      },
      {"meshes[0].weights: 1 weights for 2 morph targets"});
  ExpectError(
      [](json& g) {
        g = MorphedRigged(g, false);
        g["meshes"][0]["primitives"][0]["targets"][0]["POSITION"] = AppendFloatAccessor(g, {1, 2, 3}, "VEC3", 1);
      },
      {"POSITION of meshes[0].primitives[0].targets[0]", "count 1 differs from POSITION's count 160"});
  ExpectError(
      [](json& g) {
        g = MorphedRigged(g, true);
        g["accessors"][g["animations"][0]["samplers"].back()["output"].get<int>()]["count"] = 3;
      },
      {"has 3 values for 2 keys of 2 morph targets (expected 4)"});
}

TEST_F(GltfFiles, NegativeWeightIsRejected) {
  ExpectError(
      [](json& g) {
        std::vector<std::uint8_t> bytes = BufferBytes(g);
        Poke<float>(bytes, kWeightsAt + 3 * kWeightsStride + 4, -0.5f);
        SetBufferBytes(g, bytes);
      },
      {"accessors[4] (WEIGHTS_0 of meshes[0].primitives[0])", "vertex 3 slot 1", "weight -0.5 is negative"});
}

TEST_F(GltfFiles, NanWeightIsRejected) {
  ExpectError(
      [](json& g) {
        std::vector<std::uint8_t> bytes = BufferBytes(g);
        Poke<float>(bytes, kWeightsAt + 12 * kWeightsStride, std::nanf(""));
        SetBufferBytes(g, bytes);
      },
      {"accessors[4] (WEIGHTS_0 of meshes[0].primitives[0])", "vertex 12 slot 0", "weight is NaN"});
}

TEST_F(GltfFiles, AllZeroWeightsAreRejected) {
  ExpectError(
      [](json& g) {
        std::vector<std::uint8_t> bytes = BufferBytes(g);
        for (int k = 0; k < 4; ++k) Poke<float>(bytes, kWeightsAt + 5 * kWeightsStride + 4 * k, 0.0f);
        SetBufferBytes(g, bytes);
      },
      {"meshes[0].primitives[0]", "vertex 5", "all weights are zero"});
}

TEST_F(GltfFiles, NonNormalisedWeightsAreRenormalisedWithOneWarning) {
  json gltf = rigged_;
  std::vector<std::uint8_t> bytes = BufferBytes(gltf);
  for (int v : {20, 21}) {
    for (int k = 0; k < 4; ++k) {
      float w;
      std::memcpy(&w, bytes.data() + kWeightsAt + v * kWeightsStride + 4 * k, 4);
      Poke<float>(bytes, kWeightsAt + v * kWeightsStride + 4 * k, w * (v == 20 ? 0.5f : 0.9f));
    }
  }
  SetBufferBytes(gltf, bytes);
  const std::string path = WriteJson("Loose.gltf", gltf);
  const GltfImportResult result = ImportGltf(path);
  ASSERT_EQ(result.warnings.size(), 1u);
  EXPECT_EQ(result.warnings[0], path + ": renormalised weights of 2 vertices (worst: vertex 20, sum 0.5)");
  EXPECT_TRUE(Validate(result.asset.mesh).ok());
  GltfImportOptions strict;
  strict.strict = true;
  ExpectFileError(path, {"vertex 20: weights sum to 0.5", "2 such vertices"}, strict);
}

// ---------------------------------------------------------------- skeleton and animations

TEST_F(GltfFiles, SkinJointNamingAMissingNodeIsRejected) {
  ExpectError([](json& g) { g["skins"][0]["joints"][1] = 42; },
              {"skins[0].joints[1]", "node 42 does not exist"});
}

TEST_F(GltfFiles, NodeWithTwoParentsIsRejected) {
  ExpectError([](json& g) { g["nodes"][0]["children"].push_back(4); }, {"nodes[4] has two parents"});
}

TEST_F(GltfFiles, InverseBindMatricesOfWrongTypeAreRejected) {
  ExpectError([](json& g) { g["accessors"][9]["type"] = "MAT3"; },
              {"accessors[9] (inverseBindMatrices of skins[0])", "type MAT3 not allowed (expected MAT4)"});
}

TEST_F(GltfFiles, AnimationOutputCountMismatchIsRejected) {
  ExpectError([](json& g) { g["animations"][0]["samplers"][1]["interpolation"] = "CUBICSPLINE"; },
              {"animations[0].samplers[1]", "50 values for 50 keys (expected 150)"});
}

TEST_F(GltfFiles, NonIncreasingKeyTimesAreRejected) {
  ExpectError(
      [](json& g) {
        std::vector<std::uint8_t> bytes = BufferBytes(g);
        Poke<float>(bytes, 9808 + 4 * 3, 0.0f);  // accessors[5] (times) is bufferViews[4] at 9808
        SetBufferBytes(g, bytes);
      },
      {"animations[0]", "not strictly increasing: key 3"});
}

// A weights channel on another node moves another mesh: skipped. On the
// skinned node of a mesh without morph targets it is malformed.
TEST_F(GltfFiles, MorphWeightChannelsOfOtherNodesAreSkippedOfTheSkinnedMeshWithoutTargetsRejected) {
  json gltf = rigged_;
  gltf["animations"][0]["channels"].push_back({{"sampler", 0}, {"target", {{"node", 3}, {"path", "weights"}}}});
  EXPECT_EQ(ImportGltf(WriteJson("Other.gltf", gltf)).asset.animations[0].channels.size(), 3u);
  ExpectError(
      [](json& g) {
        g["animations"][0]["channels"].push_back({{"sampler", 0}, {"target", {{"node", 2}, {"path", "weights"}}}});
      },
      {"animations[0].channels[3]: animates the morph weights of a mesh without morph targets"});
}

}  // namespace
}  // namespace skintune::internal
