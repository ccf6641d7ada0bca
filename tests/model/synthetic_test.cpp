// Tests of the synthetic datasets (model/synthetic.h) and configs/paper.json.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "reference/skinning.h"
#include "base/memory_limit.h"
#include "model/synthetic.h"

namespace skintune::internal {
namespace {

DatasetSpec Spec(std::size_t vertices, int influences, bool random = false) {
  DatasetSpec spec;
  spec.vertices = vertices;
  spec.influences = influences;
  spec.random_bones = random;
  return spec;
}

std::string ErrorOf(const std::string& key) {
  try {
    ParseDatasetKey(key);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

std::string ValidateError(const DatasetSpec& spec) {
  try {
    spec.Validate();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

bool SameSpec(const DatasetSpec& a, const DatasetSpec& b) {
  return a.vertices == b.vertices && a.influences == b.influences && a.bones == b.bones &&
         a.random_bones == b.random_bones && a.seed == b.seed && a.normals == b.normals && a.tangents == b.tangents && a.frames == b.frames;
}

template <typename T>
bool SameBytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool SameAsset(const SkinnedAsset& a, const SkinnedAsset& b) {
  if (!SameBytes(a.mesh.positions, b.mesh.positions) || !SameBytes(a.mesh.normals, b.mesh.normals) || !SameBytes(a.mesh.tangents, b.mesh.tangents) ||
      !SameBytes(a.mesh.joints, b.mesh.joints) || !SameBytes(a.mesh.weights, b.mesh.weights) ||
      !SameBytes(a.skeleton.inverse_bind, b.skeleton.inverse_bind) || a.animations.size() != b.animations.size()) {
    return false;
  }
  for (std::size_t c = 0; c < a.animations[0].channels.size(); ++c) {
    if (!SameBytes(a.animations[0].channels[c].values, b.animations[0].channels[c].values)) return false;
  }
  return true;
}

// ------------------------------------------------------------------ keys

TEST(SyntheticKey, RoundTripsThroughParse) {
  std::vector<DatasetSpec> specs = {Spec(100000, 2), Spec(1600000, 4, true), Spec(12345, 1), Spec(2000000, 8)};
  DatasetSpec odd = Spec(5000, 8);
  odd.bones = 12;
  odd.seed = 3;
  odd.normals = true;
  specs.push_back(odd);
  for (const DatasetSpec& spec : specs) {
    EXPECT_TRUE(SameSpec(ParseDatasetKey(spec.Key()), spec)) << spec.Key();
  }
}

TEST(SyntheticKey, PrintsShortestVertexCountAndOnlyNonDefaultOptions) {
  EXPECT_EQ(Spec(100000, 2).Key(), "100k-b2");
  EXPECT_EQ(Spec(1600000, 4).Key(), "1600k-b4");
  EXPECT_EQ(Spec(2000000, 1).Key(), "2m-b1");
  EXPECT_EQ(Spec(12345, 3).Key(), "12345-b3");
  DatasetSpec all = Spec(5000, 8, true);
  all.bones = 12;
  all.seed = 3;
  all.normals = true;
  EXPECT_EQ(all.Key(), "5k-b8-bones12-random-seed3-normals");
}

TEST(SyntheticKey, ParsesSuffixesAndOptions) {
  const DatasetSpec a = ParseDatasetKey("5000-b8-bones12-seed3-normals");
  EXPECT_EQ(a.vertices, 5000u);
  EXPECT_EQ(a.influences, 8);
  EXPECT_EQ(a.bones, 12);
  EXPECT_EQ(a.seed, 3u);
  EXPECT_TRUE(a.normals);
  EXPECT_FALSE(a.random_bones);
  EXPECT_EQ(ParseDatasetKey("2m-b1").vertices, 2000000u);
  EXPECT_EQ(ParseDatasetKey("1600k-b4-random").vertices, 1600000u);
  EXPECT_TRUE(ParseDatasetKey("1600k-b4-random").random_bones);
}

TEST(SyntheticKey, DefaultMeans100kB2) {
  EXPECT_EQ(ParseDatasetKey("default").Key(), "100k-b2");
  EXPECT_TRUE(SameSpec(ParseDatasetKey("default"), ParseDatasetKey("100k-b2")));
}

struct BadKeyCase {
  const char* key;
  const char* problem;  // expected in the message
};

class SyntheticMalformedKey : public testing::TestWithParam<BadKeyCase> {};

TEST_P(SyntheticMalformedKey, ThrowsErrorNamingKeyProblemAndFormat) {
  const std::string message = ErrorOf(GetParam().key);
  EXPECT_EQ(message.rfind("dataset '" + std::string(GetParam().key) + "': ", 0), 0u) << message;
  EXPECT_NE(message.find(GetParam().problem), std::string::npos) << message;
  EXPECT_NE(message.find("(expected <vertices>-b<influences>[-bones<N>][-random][-seed<S>][-rigid][-morph<T>][-normals|-tangents], e.g. 100k-b2)"),
            std::string::npos)
      << message;
}

INSTANTIATE_TEST_SUITE_P(
    Keys, SyntheticMalformedKey,
    testing::Values(BadKeyCase{"", "empty key"}, BadKeyCase{"abc-b2", "vertex count 'abc'"},
                    BadKeyCase{"100x-b2", "vertex count '100x'"}, BadKeyCase{"k-b2", "vertex count 'k'"},
                    BadKeyCase{"99999999999999999999-b2", "fits in 64 bits"},
                    BadKeyCase{"100k", "missing influence count"}, BadKeyCase{"100k-x2", "missing influence count"},
                    BadKeyCase{"100k-b", "influence count must be"}, BadKeyCase{"100k-bx", "influence count must be"},
                    BadKeyCase{"100k-b2-", "stray '-'"}, BadKeyCase{"100k--b2", "stray '-'"},
                    BadKeyCase{"100k-b2-foo", "unknown option 'foo'"},
                    BadKeyCase{"100k-b2-random-random", "option 'random' given twice"},
                    BadKeyCase{"100k-b2-seed1-seed2", "option 'seed' given twice"},
                    BadKeyCase{"100k-b2-bones", "bone count must be"}, BadKeyCase{"100k-b2-bones70000", "bone count"},
                    BadKeyCase{"100k-b2-seedx", "seed must be"}, BadKeyCase{"0-b2", "vertices must be at least 1"},
                    BadKeyCase{"100k-b0", "influences 0 outside 1..8"},
                    BadKeyCase{"100k-b9", "influences 9 outside 1..8"}, BadKeyCase{"100k-b2-bones0", "bones 0"},
                    BadKeyCase{"100k-b8-bones4", "influences 8 exceed bones 4"},
                    // docs/INPUTS.md "Limits": beyond what 32-bit vertex indices address.
                    BadKeyCase{"100000m-b8", "100000000000 vertices exceed the 2^32 - 1 = 4294967295"},
                    BadKeyCase{"4294968k-b1", "exceed the 2^32 - 1"}));

// docs/INPUTS.md "Limits": the memory a size needs is checked before anything is
// allocated, and the message says what fits.
TEST(SyntheticMemory, TooBigForTheMemoryGivenIsRefusedSayingWhatFits) {
  const DatasetSpec spec = ParseDatasetKey("300m-b8");
  EXPECT_EQ(DatasetBytesPerVertex(spec), 12u + 8u * 6u);
  std::string message;
  try {
    CheckMemoryFor("dataset '300m-b8'", spec.vertices, DatasetBytesPerVertex(spec), "the generated mesh",
                   {1ull << 30, "a test's 1 GiB"});
  } catch (const Error& e) {
    message = e.what();
  }
  EXPECT_EQ(message,
            "dataset '300m-b8': needs about 16.8 GiB of memory (300000000 vertices x 60 B: the generated mesh) but "
            "1.0 GiB are available (a test's 1 GiB): at most about 17800k vertices fit");
  EXPECT_NO_THROW(CheckMemoryFor("x", 1000, 60, "y", {60000, "z"}));
  EXPECT_THROW(CheckMemoryFor("x", 1001, 60, "y", {60000, "z"}), Error);
  EXPECT_NO_THROW(CheckMemoryFor("x", 1ull << 40, 60, "y", {0, "unknown"}));  // unknown: no check
  // Far beyond 64 bits of bytes, said without overflowing.
  try {
    CheckMemoryFor("x", 1ull << 62, 1000, "y", {1ull << 30, "z"});
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("needs more than 16 EiB"), std::string::npos) << e.what();
  }
  EXPECT_EQ(FormatVertexCount(17895697), "17800k");  // a dataset key: no decimals
  EXPECT_EQ(FormatVertexCount(123456), "123k");
  EXPECT_EQ(FormatVertexCount(999), "999");
  EXPECT_EQ(FormatVertexCount(2500000), "2500k");
  EXPECT_EQ(FormatVertexCount(4294967295), "4290m");
  EXPECT_GT(HostMemoryAvailable().bytes, 0u);
}

// ------------------------------------------------------------------ Validate

TEST(SyntheticValidate, RejectsEachBadField) {
  DatasetSpec s = Spec(0, 2);
  EXPECT_NE(ValidateError(s).find("vertices"), std::string::npos);
  s = Spec(10, 0);
  EXPECT_NE(ValidateError(s).find("influences 0"), std::string::npos);
  s = Spec(10, 9);
  EXPECT_NE(ValidateError(s).find("influences 9"), std::string::npos);
  s = Spec(10, 2);
  s.bones = 0;
  EXPECT_NE(ValidateError(s).find("bones 0"), std::string::npos);
  s.bones = 65536;
  EXPECT_NE(ValidateError(s).find("bones 65536"), std::string::npos);
  s = Spec(10, 4);
  s.bones = 3;
  EXPECT_NE(ValidateError(s).find("exceed bones 3"), std::string::npos);
  s = Spec(10, 2);
  s.frames = 0;
  EXPECT_NE(ValidateError(s).find("frames"), std::string::npos);
  EXPECT_EQ(ValidateError(Spec(10, 2)), "(no error)");
  EXPECT_THROW(GenerateDataset(Spec(0, 2)), Error);
}

// ------------------------------------------------------------------ mesh

TEST(SyntheticMesh, HasExactlyTheRequestedVertexCount) {
  for (std::size_t n : {1u, 2u, 76u, 77u, 78u, 12345u}) {
    const SkinnedAsset asset = GenerateDataset(Spec(n, 2));
    EXPECT_EQ(asset.mesh.vertex_count(), n);
    EXPECT_EQ(asset.mesh.joints.size(), n * 2);
    EXPECT_EQ(asset.mesh.weights.size(), n * 2);
  }
  DatasetSpec tiny = Spec(5, 1);
  tiny.bones = 1;
  EXPECT_EQ(GenerateDataset(tiny).mesh.vertex_count(), 5u);
}

TEST(SyntheticMesh, WeightsArePositiveSortedAndSumToOne) {
  for (bool random : {false, true}) {
    for (int b : {1, 2, 4, 8}) {
      const SkinnedMesh mesh = GenerateDataset(Spec(20000, b, random)).mesh;
      ASSERT_EQ(mesh.influences, b);
      double worst = 0.0;
      for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
        double sum = 0.0;
        for (int k = 0; k < b; ++k) {
          const float w = mesh.weights[v * b + k];
          ASSERT_GT(w, 0.0f) << "vertex " << v << " slot " << k;
          if (k > 0) {
            ASSERT_LE(w, mesh.weights[v * b + k - 1]) << "vertex " << v;
          }
          sum += w;
        }
        worst = std::max(worst, std::abs(sum - 1.0));
      }
      EXPECT_LT(worst, 1e-6) << "B=" << b << " random=" << random;
      EXPECT_TRUE(Validate(mesh).ok()) << Validate(mesh).Summary();
    }
  }
}

TEST(SyntheticMesh, JointIndicesAreInRangeAndDistinctPerVertex) {
  for (bool random : {false, true}) {
    DatasetSpec spec = Spec(5000, 8, random);
    spec.bones = 9;
    for (int bones : {9, 77, 300}) {
      spec.bones = bones;
      const SkinnedMesh mesh = GenerateDataset(spec).mesh;
      EXPECT_EQ(mesh.joint_count, bones);
      for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
        std::set<int> used;
        for (int k = 0; k < 8; ++k) {
          ASSERT_LT(mesh.joints[v * 8 + k], bones);
          used.insert(mesh.joints[v * 8 + k]);
        }
        ASSERT_EQ(used.size(), 8u) << "vertex " << v << " bones " << bones << " random " << random;
      }
    }
  }
}

TEST(SyntheticMesh, NormalsAreUnitLengthOnlyWhenRequested) {
  EXPECT_FALSE(GenerateDataset(Spec(1000, 2)).mesh.has_normals());
  DatasetSpec spec = Spec(10000, 2);
  spec.normals = true;
  const SkinnedMesh mesh = GenerateDataset(spec).mesh;
  ASSERT_EQ(mesh.normals.size(), mesh.vertex_count());
  for (const glm::vec3& n : mesh.normals) ASSERT_NEAR(glm::length(n), 1.0f, 1e-6f);
  EXPECT_FALSE(mesh.has_tangents());
}

TEST(SyntheticMesh, TangentsComeWithNormalsAlongTheBoneWithBothHandednesses) {
  const DatasetSpec spec = ParseDatasetKey("3000-b3-tangents");
  EXPECT_TRUE(spec.normals);
  EXPECT_TRUE(spec.tangents);
  EXPECT_EQ(spec.Key(), "3k-b3-tangents");
  const SkinnedMesh mesh = GenerateDataset(spec).mesh;
  ASSERT_EQ(mesh.normals.size(), mesh.vertex_count());
  ASSERT_EQ(mesh.tangents.size(), mesh.vertex_count());
  int left = 0, right = 0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const glm::vec4& t = mesh.tangents[v];
    ASSERT_NEAR(glm::length(glm::vec3(t)), 1.0f, 1e-6f) << v;
    ASSERT_TRUE(t.w == 1.0f || t.w == -1.0f) << v;
    (t.w > 0 ? right : left)++;
  }
  EXPECT_GT(left, 1000);
  EXPECT_GT(right, 1000);
}

TEST(SyntheticMesh, GenerationIsBitIdenticalForTheSameSpec) {
  for (bool random : {false, true}) {
    DatasetSpec spec = Spec(20000, 4, random);
    spec.normals = true;
    EXPECT_TRUE(SameAsset(GenerateDataset(spec), GenerateDataset(spec)));
  }
}

TEST(SyntheticMesh, DifferentSeedsGiveDifferentData) {
  for (bool random : {false, true}) {
    DatasetSpec a = Spec(20000, 4, random), b = a;
    b.seed = 2;
    const SkinnedAsset x = GenerateDataset(a), y = GenerateDataset(b);
    EXPECT_FALSE(SameBytes(x.mesh.positions, y.mesh.positions));
    EXPECT_FALSE(SameBytes(x.animations[0].channels[0].values, y.animations[0].channels[0].values));
    if (random) {
      EXPECT_FALSE(SameBytes(x.mesh.joints, y.mesh.joints));
    }
  }
}

double SharedFirstJointFraction(const SkinnedMesh& mesh) {
  const auto b = static_cast<std::size_t>(mesh.influences);
  std::size_t shared = 0;
  for (std::size_t v = 1; v < mesh.vertex_count(); ++v) shared += mesh.joints[v * b] == mesh.joints[(v - 1) * b];
  return static_cast<double>(shared) / static_cast<double>(mesh.vertex_count() - 1);
}

double MeanJointsPer32Block(const SkinnedMesh& mesh) {
  const auto b = static_cast<std::size_t>(mesh.influences);
  double total = 0.0;
  const std::size_t blocks = mesh.vertex_count() / 32;
  for (std::size_t block = 0; block < blocks; ++block) {
    std::set<int> used(mesh.joints.begin() + block * 32 * b, mesh.joints.begin() + (block + 1) * 32 * b);
    total += static_cast<double>(used.size());
  }
  return total / static_cast<double>(blocks);
}

TEST(SyntheticMesh, LocalityModeNeighboursShareFirstJointRandomModeDoNot) {
  EXPECT_GT(SharedFirstJointFraction(GenerateDataset(Spec(100000, 4)).mesh), 0.9);
  EXPECT_LT(SharedFirstJointFraction(GenerateDataset(Spec(100000, 4, true)).mesh), 0.1);
}

TEST(SyntheticMesh, LocalityModeBlocksOf32UseFewJointsRandomModeMany) {
  const double local = MeanJointsPer32Block(GenerateDataset(Spec(100000, 4)).mesh);
  const double random = MeanJointsPer32Block(GenerateDataset(Spec(100000, 4, true)).mesh);
  EXPECT_LE(local, 8.0);
  EXPECT_GE(random, 40.0);
}

// ------------------------------------------------------------------ rig

TEST(SyntheticRig, DefaultRigHas77JointsOneRootAndParentsFirst) {
  const Skeleton& skeleton = GenerateDataset(Spec(1000, 2)).skeleton;
  ASSERT_EQ(skeleton.joint_count(), 77);
  ASSERT_EQ(skeleton.nodes.size(), 77u);
  int roots = 0;
  std::set<std::string> names;
  for (int i = 0; i < 77; ++i) {
    EXPECT_EQ(skeleton.joints[i], i);
    const int parent = skeleton.nodes[i].parent;
    roots += parent < 0;
    EXPECT_LT(parent, i);
    names.insert(skeleton.nodes[i].name);
  }
  EXPECT_EQ(roots, 1);
  EXPECT_EQ(skeleton.nodes[0].parent, -1);
  EXPECT_EQ(names.size(), 77u) << "joint names are unique";
  EXPECT_NO_THROW(skeleton.Validate("synthetic"));
}

TEST(SyntheticRig, OtherBoneCountsGiveValidHierarchiesOfThatSize) {
  for (int bones : {1, 2, 8, 34, 78, 81, 500, 65535}) {
    DatasetSpec spec = Spec(bones == 65535 ? 70000 : 2000, 2);
    spec.bones = bones;
    spec.influences = std::min(2, bones);
    spec.frames = 2;
    const SkinnedAsset asset = GenerateDataset(spec);
    ASSERT_EQ(asset.skeleton.joint_count(), bones);
    EXPECT_EQ(asset.mesh.joint_count, bones);
    for (int i = 0; i < bones; ++i) ASSERT_EQ(asset.skeleton.nodes[i].parent < 0, i == 0) << i;
    for (int i = 1; i < bones; ++i) ASSERT_LT(asset.skeleton.nodes[i].parent, i);
    EXPECT_NO_THROW(asset.skeleton.Validate("synthetic"));
  }
}

TEST(SyntheticRig, RestPaletteIsIdentity) {
  const SkinnedAsset asset = GenerateDataset(Spec(1000, 2));
  const std::vector<glm::dmat4> palette = asset.skeleton.PaletteD(asset.skeleton.RestPose());
  ASSERT_EQ(palette.size(), 77u);
  for (std::size_t j = 0; j < palette.size(); ++j) {
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) ASSERT_NEAR(palette[j][c][r], c == r ? 1.0 : 0.0, 1e-9) << "joint " << j;
    }
  }
}

TEST(SyntheticRig, SkinningTheRestPoseReturnsTheBindPose) {
  const SkinnedAsset asset = GenerateDataset(Spec(20000, 4));
  const std::vector<glm::mat4> palette = asset.PaletteAt(-1, 0.0);
  const GoldResult gold = SkinGold(asset.mesh, palette);
  ASSERT_EQ(gold.positions.size(), asset.mesh.vertex_count());
  for (std::size_t v = 0; v < gold.positions.size(); ++v) {
    ASSERT_LT(glm::length(gold.positions[v] - glm::dvec3(asset.mesh.positions[v])), 1e-5) << "vertex " << v;
  }
}

// ------------------------------------------------------------------ animation

TEST(SyntheticAnimation, OneLinearClipWithTheRequestedKeysAt30Fps) {
  DatasetSpec spec = Spec(1000, 2);
  spec.frames = 45;
  const SkinnedAsset asset = GenerateDataset(spec);
  ASSERT_EQ(asset.animations.size(), 1u);
  const AnimationClip& clip = asset.animations[0];
  EXPECT_EQ(clip.name, "synthetic");
  EXPECT_EQ(asset.FindAnimation("synthetic"), 0);
  EXPECT_EQ(asset.source, spec.Key());
  EXPECT_NO_THROW(clip.Validate(77, "synthetic"));
  EXPECT_NEAR(clip.start, 0.0, 1e-9);
  EXPECT_NEAR(clip.end, 44.0 / 30.0, 1e-6);
  std::set<int> rotated;
  for (const Channel& channel : clip.channels) {
    EXPECT_EQ(channel.interpolation, Interpolation::kLinear);
    EXPECT_EQ(channel.times.size(), 45u);
    if (channel.path == ChannelPath::kRotation) rotated.insert(channel.node);
    if (channel.path == ChannelPath::kTranslation) {
      EXPECT_EQ(channel.node, 0);
    }
  }
  EXPECT_EQ(rotated.size(), 77u);
}

// Every joint moves between frames, and its palette is a general affine map:
// the joints scale non-uniformly (up to +-20% an axis, so a normal rule other
// than the normal matrix fails verification), and their 3x3s keep a positive
// determinant (no mirror) within the scale's bounds.
TEST(SyntheticAnimation, PalettesDifferBetweenFramesAndScaleNonUniformly) {
  const SkinnedAsset asset = GenerateDataset(Spec(1000, 2));
  const std::vector<glm::mat4> a = asset.PaletteAt(0, 0.0), b = asset.PaletteAt(0, 20.0 / 30.0);
  const std::vector<glm::mat4> rest = asset.PaletteAt(-1, 0.0);
  std::size_t moved = 0;
  double most_anisotropic = 1.0;
  for (std::size_t j = 0; j < a.size(); ++j) {
    moved += a[j] != b[j];
    for (const glm::mat4& m : {a[j], b[j]}) {
      const glm::dmat3 r{glm::mat3(m)};
      EXPECT_GT(glm::determinant(r), 0.0) << j;
      // The singular values' spread: sqrt of the extreme eigenvalues of r^T r.
      const glm::dmat3 g = glm::transpose(r) * r;
      double lo = 1e300, hi = 0.0;
      for (int c = 0; c < 3; ++c) {
        const double len = std::sqrt(g[c][c]);  // a column's length: between the extremes
        lo = std::min(lo, len), hi = std::max(hi, len);
      }
      EXPECT_GT(lo, 0.2) << j;
      EXPECT_LT(hi, 5.0) << j;
      most_anisotropic = std::max(most_anisotropic, hi / lo);
    }
  }
  EXPECT_EQ(moved, a.size());
  EXPECT_NE(a, rest);
  EXPECT_GT(most_anisotropic, 1.2) << "the joints scale non-uniformly";
}

// ------------------------------------------------------------------ configs/paper.json

TEST(SyntheticPaperConfig, ListsTheSixteenPaperDatasets) {
  std::ifstream file(std::string(SKINTUNE_SOURCE_DIR) + "/configs/paper.json");
  ASSERT_TRUE(file) << "configs/paper.json";
  const nlohmann::json config = nlohmann::json::parse(file);
  ASSERT_TRUE(config.contains("description"));
  ASSERT_TRUE(config.contains("paper"));
  EXPECT_EQ(ParseDatasetKey(config.at("figure1").at("dataset").get<std::string>()).Key(), "100k-b2");
  const nlohmann::json& datasets = config.at("datasets");
  ASSERT_EQ(datasets.size(), 16u);
  std::set<std::string> keys;
  for (const nlohmann::json& d : datasets) {
    const std::string key = d.at("key").get<std::string>();
    const DatasetSpec spec = ParseDatasetKey(key);
    EXPECT_EQ(spec.Key(), key);
    EXPECT_EQ(spec.vertices, d.at("vertices").get<std::size_t>()) << key;
    EXPECT_EQ(spec.influences, d.at("influences").get<int>()) << key;
    EXPECT_EQ(spec.bones, d.at("bones").get<int>()) << key;
    EXPECT_EQ(spec.bones, 77);
    EXPECT_FALSE(spec.random_bones);
    EXPECT_EQ(d.at("name").get<std::string>(), "paper-" + key);
    keys.insert(key);
  }
  for (const char* v : {"25k", "100k", "400k", "1600k"}) {
    for (int b = 1; b <= 4; ++b) EXPECT_EQ(keys.count(std::string(v) + "-b" + std::to_string(b)), 1u);
  }
}

}  // namespace
}  // namespace skintune::internal
