// skintune skin --palette-out / --check / --variant: the palette a frame used,
// and another program's output checked against the gold.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <glm/gtc/type_ptr.hpp>

#include "generator/packer.h"
#include "generator/variant.h"
#include "model/asset.h"
#include "model/gltf_import.h"
#include "reference/mesh_io.h"
#include "reference/skinning.h"
#include "tests/common/scratch_dir.h"
#include "tests/tools/run_command.h"

namespace skintune::internal::testing {
namespace {

namespace fs = std::filesystem;
const std::string kCesium = std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf";
const std::string kUnorm8 = "opencl.b4.padded.soa.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals";

fs::path Scratch() { return ScratchDir("skintune_skin_check"); }

// The gold of CesiumMan at t = 0.5 on the weights `variant` quantises (or the mesh's).
std::vector<glm::vec3> Gold(const std::string& variant) {
  const SkinnedAsset asset = ImportGltf(kCesium).asset;
  const SkinnedMesh mesh = variant.empty() ? asset.mesh : QuantisedMesh(asset.mesh, ParseVariantKey(variant));
  const GoldResult gold = SkinGold(mesh, asset.PaletteAt(0, 0.5));
  return std::vector<glm::vec3>(gold.positions.begin(), gold.positions.end());
}

TEST(SkinCheckCli, PaletteOutIsTheFramesPaletteColumnMajor) {
  const fs::path dir = Scratch();
  const auto r = RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--palette-out",
                              (dir / "palette.bin").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string bytes = ReadAll(dir / "palette.bin");
  const std::vector<glm::mat4> expected = ImportGltf(kCesium).asset.PaletteAt(0, 0.5);
  ASSERT_EQ(bytes.size(), expected.size() * 64);
  for (std::size_t j = 0; j < expected.size(); ++j)
    EXPECT_EQ(std::memcmp(bytes.data() + j * 64, glm::value_ptr(expected[j]), 64), 0) << "joint " << j;
}

TEST(SkinCheckCli, AcceptsOutputWithinToleranceOfTheQuantisedGold) {
  const fs::path dir = Scratch();
  const std::string file = (dir / "theirs.stv").string();
  WriteSkinnedVertices(file, Gold(kUnorm8), {});
  const auto r = RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--check", file,
                              "--variant", kUnorm8});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("agrees with the gold with unorm8 weights"), std::string::npos) << r.out;
}

// Both errors: against the quantised gold (the check) and, next to it, against
// the unquantised source, in mesh units and of the bounding-box diagonal.
TEST(SkinCheckCli, ShowsTheErrorAgainstTheSourceNextToTheQuantisedOne) {
  const fs::path dir = Scratch();
  const std::string file = (dir / "theirs.stv").string();
  const std::vector<glm::vec3> theirs = Gold(kUnorm8);
  WriteSkinnedVertices(file, theirs, {});
  const auto r = RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--check", file,
                              "--variant", kUnorm8});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string marker = file + " against the unquantised source: largest error ";
  const std::size_t at = r.out.find(marker);
  ASSERT_NE(at, std::string::npos) << r.out;
  const double shown = std::stod(r.out.substr(at + marker.size()));
  const SkinnedAsset asset = ImportGltf(kCesium).asset;
  const GoldResult source = SkinGold(asset.mesh, asset.PaletteAt(0, 0.5));
  const double expected = CompareToGold(source.positions, theirs).max_absolute;
  EXPECT_GT(expected, 1e-4);  // unorm8 moves CesiumMan's vertices visibly
  EXPECT_NEAR(shown, expected, 1e-5 * expected) << r.out;
  const double diagonal = BoundingBoxDiagonal(asset.mesh.positions);
  const std::string of = " (mesh units), ";
  const double relative = std::stod(r.out.substr(r.out.find(of, at) + of.size()));
  EXPECT_NEAR(relative, expected / diagonal, 1e-5 * expected / diagonal) << r.out;
  EXPECT_NE(r.out.find("the unorm8 weights alone cost "), std::string::npos) << r.out;
}

TEST(SkinCheckCli, QuantisedOutputFailsAgainstTheUnquantisedGold) {
  const fs::path dir = Scratch();
  const std::string file = (dir / "theirs.stv").string();
  WriteSkinnedVertices(file, Gold(kUnorm8), {});
  const auto r = RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--check", file});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(file + ": vertex "), std::string::npos) << r.err;
}

TEST(SkinCheckCli, OneWrongVertexIsNamed) {
  const fs::path dir = Scratch();
  const std::string file = (dir / "theirs.stv").string();
  std::vector<glm::vec3> positions = Gold("");
  positions[1234].y += 0.01f;
  WriteSkinnedVertices(file, positions, {});
  const auto r = RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--check", file});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("vertex 1234 is off by"), std::string::npos) << r.err;
}

TEST(SkinCheckCli, WrongVertexCountAndMissingOutputsAreErrors) {
  const fs::path dir = Scratch();
  const std::string file = (dir / "short.stv").string();
  WriteSkinnedVertices(file, std::vector<glm::vec3>(10), {});
  const auto count = RunSkintune({"skin", "--mesh", kCesium, "--check", file});
  EXPECT_EQ(count.exit_code, 1);
  EXPECT_NE(count.err.find(file + ": 10 vertices, the mesh has 3273"), std::string::npos) << count.err;
  const auto nothing = RunSkintune({"skin", "--mesh", kCesium});
  EXPECT_EQ(nothing.exit_code, 2);  // usage: no output named
  EXPECT_NE(nothing.err.find("--out"), std::string::npos) << nothing.err;
  const auto variant_alone = RunSkintune({"skin", "--mesh", kCesium, "--out", file, "--variant", kUnorm8});
  EXPECT_EQ(variant_alone.exit_code, 2);
  EXPECT_NE(variant_alone.err.find("--variant requires --check"), std::string::npos) << variant_alone.err;
}

// `skintune skin --normals` of a glTF with morph targets (one dense, one
// sparse), tangents and a non-uniformly scaling joint
// (tests/data/RiggedSimple-morph.gltf, scripts/make-morph-gltf.py), at
// several times of its clip: within 1e-5 of an independent float64
// reference in positions and 1e-4 rad in normals. The reference morphs the
// base mesh by the offsets the script wrote (weights interpolated here from
// its keys), then skins it by the gold (normals by the inverse transpose:
// reference/skinning.h); the palette is the importer's.
// --check with a variant that applies the morph targets as halves: the gold
// of the offsets rounded as that variant stores them, morphed in float64.
// A file skinned that way agrees with it and not with the float32 offsets'
// gold, at a tolerance between the two.
TEST(SkinMorphCli, CheckOfAHalfMorphVariantTakesTheGoldOfItsRoundedOffsets) {
  const std::string file = std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple-morph.gltf";
  const SkinnedAsset asset = ImportGltf(file).asset;
  const double t = 0.45;
  const Variant half = ParseVariantKey("opencl.b4.soa.morph-sparse-half");
  const SkinnedMesh weighted = asset.MeshWithMorphWeightsAt(0, t);
  const std::vector<glm::mat4> palette = asset.PaletteAt(0, t);
  const GoldResult rounded = SkinGold(QuantisedMesh(weighted, half), palette);
  const GoldResult exact = SkinGold(weighted, palette);
  const std::vector<glm::vec3> theirs(rounded.positions.begin(), rounded.positions.end());
  const double apart = CompareToGold(exact.positions, theirs).max_relative;
  ASSERT_GT(apart, 4e-6) << "the half offsets must move the output for the check to tell them apart";
  const fs::path dir = Scratch();
  const std::string out = (dir / "half.stv").string();
  WriteSkinnedVertices(out, theirs, {}, {});
  const std::string tolerance = std::to_string(apart / 4);
  const auto with = RunSkintune({"skin", "--mesh", file, "--animation", "0", "--time", std::to_string(t), "--check",
                                 out, "--variant", half.Key(), "--tolerance", tolerance});
  EXPECT_EQ(with.exit_code, 0) << with.out << with.err;
  EXPECT_NE(with.out.find("agrees with the gold with f32 weights and sparse-half morph targets"), std::string::npos)
      << with.out;
  EXPECT_NE(with.out.find("the f32 weights and half morph offsets alone cost"), std::string::npos) << with.out;
  const auto without = RunSkintune(
      {"skin", "--mesh", file, "--animation", "0", "--time", std::to_string(t), "--check", out, "--tolerance", tolerance});
  EXPECT_EQ(without.exit_code, 1) << without.out << without.err;
}

TEST(SkinMorphCli, MorphsThenSkinsAtEveryTimeAgainstAnIndependentReference) {
  const std::string file = std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple-morph.gltf";
  GltfImportOptions with_normals;
  with_normals.normals = true;
  const SkinnedAsset asset = ImportGltf(file, with_normals).asset;
  const SkinnedMesh base = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple.gltf", with_normals).asset.mesh;
  ASSERT_EQ(asset.mesh.positions, base.positions) << "the morph file's base mesh is RiggedSimple's";
  const fs::path dir = Scratch();
  for (const double t : {0.0, 0.45, 1.3, 2.5}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    const std::string out = (dir / "skinned.bin").string();
    const auto r = RunSkintune({"skin", "--mesh", file, "--normals", "--animation", "0", "--time", std::to_string(t), "--out", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("morph targets applied first: 2"), std::string::npos) << r.out;
    // Weights: LINEAR keys (0.2, 0) at 0 s, (0.6, 1) at 1 s, (0, 0.5) at 2 s, clamped after.
    const double u = std::clamp(t, 0.0, 2.0);
    const double w0 = u <= 1.0 ? 0.2 + 0.4 * u : 0.6 - 0.6 * (u - 1.0);
    const double w1 = u <= 1.0 ? u : 1.0 - 0.5 * (u - 1.0);
    SkinnedMesh morphed = base;
    for (std::size_t v = 0; v < morphed.positions.size(); ++v) {
      glm::dvec3 p = glm::dvec3(base.positions[v]) + w0 * glm::dvec3(0.0, 0.0, 0.3);
      if (v < 20) p += w1 * glm::dvec3(0.1, 0.0, 0.0);
      morphed.positions[v] = glm::vec3(p);
      morphed.normals[v] = glm::vec3(glm::dvec3(base.normals[v]) + w1 * glm::dvec3(0.0, 0.2, 0.0));
    }
    const GoldResult gold = SkinGold(morphed, asset.PaletteAt(0, t), true);
    const SkinnedVertices skinned = ReadSkinnedVertices(out);
    ASSERT_EQ(skinned.positions.size(), gold.positions.size());
    ASSERT_EQ(skinned.normals.size(), gold.normals.size());
    EXPECT_LE(CompareToGold(gold.positions, skinned.positions).max_relative, 1e-5);
    double worst = 0.0;
    for (std::size_t v = 0; v < gold.normals.size(); ++v)
      worst = std::max(worst, std::acos(std::min(1.0, glm::dot(glm::normalize(glm::dvec3(skinned.normals[v])), gold.normals[v]))));
    EXPECT_LE(worst, 1e-4) << "radians";
    // Without the morph targets the positions would be off: the test can fail.
    EXPECT_GT(CompareToGold(SkinGold(base, asset.PaletteAt(0, t)).positions, skinned.positions).max_relative, 1e-3);
  }
  // Tangents: the blended 3x3 on the morphed mesh's tangents (the file has no
  // TANGENT offsets), renormalised, the handedness kept (no joint mirrors);
  // gold and serial alike; --impl fast and .obj refused before any work.
  GltfImportOptions with_tangents;
  with_tangents.tangents = true;
  const SkinnedAsset tangent_asset = ImportGltf(file, with_tangents).asset;
  ASSERT_TRUE(tangent_asset.mesh.has_tangents());
  for (const char* impl : {"gold", "serial"}) {
    const double t = 1.3;
    const std::string out = (dir / "tangents.stv").string();
    const auto r = RunSkintune({"skin", "--mesh", file, "--tangents", "--impl", impl, "--animation", "0", "--time",
                                std::to_string(t), "--out", out});
    ASSERT_EQ(r.exit_code, 0) << impl << ": " << r.err;
    const SkinnedVertices skinned = ReadSkinnedVertices(out);
    ASSERT_EQ(skinned.tangents.size(), tangent_asset.mesh.vertex_count()) << impl;
    const std::vector<glm::mat4> palette = tangent_asset.PaletteAt(0, t);
    const SkinnedMesh& m = tangent_asset.mesh;
    double worst = 0.0;
    for (std::size_t v = 0; v < m.vertex_count(); ++v) {
      glm::dmat3 a(0.0);
      for (int i = 0; i < m.influences; ++i)
        a += double(m.weights[v * m.influences + i]) * glm::dmat3(glm::dmat4(palette[m.joints[v * m.influences + i]]));
      ASSERT_GT(glm::determinant(a), 0.0);
      const glm::dvec3 expected = glm::normalize(a * glm::dvec3(m.tangents[v]));
      worst = std::max(worst, std::acos(std::min(1.0, glm::dot(glm::normalize(glm::dvec3(skinned.tangents[v])), expected))));
      ASSERT_EQ(skinned.tangents[v].w, m.tangents[v].w) << impl << " vertex " << v;
    }
    EXPECT_LE(worst, 1e-4) << impl << ": radians";
  }
  EXPECT_EQ(RunSkintune({"skin", "--mesh", file, "--tangents", "--impl", "fast", "--out", (dir / "f.stv").string()}).exit_code, 2);
  EXPECT_EQ(RunSkintune({"skin", "--mesh", file, "--tangents", "--out", (dir / "t.obj").string()}).exit_code, 2);
  EXPECT_FALSE(fs::exists(dir / "t.obj"));
  const auto untangled = RunSkintune({"skin", "--mesh", std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple.gltf",
                                      "--tangents", "--out", (dir / "u.stv").string()});
  EXPECT_NE(untangled.exit_code, 0);
  EXPECT_NE(untangled.err.find("meshes[0].primitives[0]: no TANGENT attribute"), std::string::npos) << untangled.err;

  // A tuning data set of the file takes its morph targets: only variants that apply them.
  const auto scene = RunSkintune({"variants", "--dataset", file, "--lang", "opencl", "--list"});
  EXPECT_EQ(scene.exit_code, 0) << scene.err;
  EXPECT_NE(scene.out.find(".morph-sparse-half\n"), std::string::npos) << scene.out;
  std::istringstream keys(scene.out);
  for (std::string line; std::getline(keys, line);) {
    if (line.starts_with("opencl.")) {
      EXPECT_NE(line.find(".morph-"), std::string::npos) << line;
    }
  }
}

// --blend dq: CesiumMan skinned by the dual-quaternion gold, which differs
// from the linear one on its twisting joints; --check compares against the
// blend asked for; only --impl gold skins with dual quaternions.
TEST(SkinCheckCli, BlendDqWritesTheDualQuaternionGoldAndChecksAgainstIt) {
  const fs::path dir = Scratch();
  const std::string out = (dir / "dq.stv").string();
  const auto r = RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--blend", "dq", "--out", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("(dual quaternions)"), std::string::npos) << r.out;
  const SkinnedAsset asset = ImportGltf(kCesium).asset;
  const std::vector<glm::mat4> palette = asset.PaletteAt(0, 0.5);
  const SkinnedVertices skinned = ReadSkinnedVertices(out);
  EXPECT_LE(CompareToGold(SkinGoldDualQuaternion(asset.mesh, palette).positions, skinned.positions).max_relative, 1e-6);
  EXPECT_GT(CompareToGold(SkinGold(asset.mesh, palette).positions, skinned.positions).max_absolute, 1e-4)
      << "dual quaternions move some vertex away from linear blending";
  EXPECT_EQ(RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--blend", "dq", "--check", out})
                .exit_code,
            0);
  EXPECT_NE(RunSkintune({"skin", "--mesh", kCesium, "--animation", "0", "--time", "0.5", "--check", out}).exit_code, 0)
      << "the linear gold disagrees";
  EXPECT_EQ(RunSkintune({"skin", "--mesh", kCesium, "--blend", "dq", "--impl", "serial", "--out", out}).exit_code, 2);
}

}  // namespace
}  // namespace skintune::internal::testing
