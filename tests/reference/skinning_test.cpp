#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "base/error.h"
#include "model/gltf_import.h"
#include "reference/candy_wrapper.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "tests/model/test_meshes.h"

namespace skintune::internal {
namespace {

using testing::RandomMesh;

std::vector<glm::mat4> RandomPalette(int joints, unsigned seed) {
  std::vector<glm::mat4> palette;
  for (int j = 0; j < joints; ++j) {
    const float a = 0.37f * float(j + seed), b = 0.11f * float(j * seed + 1);
    glm::mat4 m = glm::translate(glm::mat4(1.0f), glm::vec3(std::sin(a), std::cos(b), 0.5f * a - 3.0f));
    m = glm::rotate(m, a, glm::normalize(glm::vec3(1.0f, b, 0.3f)));
    // Non-uniform scale, so the normal rule shows (the plain upper 3x3 would
    // fail the agreement tests below against the gold's normal matrix).
    palette.push_back(glm::scale(m, glm::vec3(1.0f + 0.1f * std::sin(b), 1.0f - 0.3f * std::cos(a), 1.2f)));
  }
  return palette;
}

// Runs serial and fast against the gold; returns the worst relative error.
double WorstAgainstGold(const SkinnedMesh& mesh, const std::vector<glm::mat4>& palette, unsigned threads = 0) {
  const std::size_t n = mesh.vertex_count();
  const GoldResult gold = SkinGold(mesh, palette, mesh.has_normals());
  std::vector<glm::vec3> serial(n), fast(n), serial_n(mesh.has_normals() ? n : 0), fast_n(serial_n.size());
  SkinSerial(mesh, palette, serial, serial_n);
  FastSkinner(mesh, threads).Run(palette, fast, fast_n);
  double worst = std::max(CompareToGold(gold.positions, serial).max_relative,
                          CompareToGold(gold.positions, fast).max_relative);
  if (mesh.has_normals()) {
    worst = std::max({worst, CompareToGold(gold.normals, serial_n).max_relative,
                      CompareToGold(gold.normals, fast_n).max_relative});
  }
  return worst;
}

TEST(SkinGold, IdentityPaletteReturnsTheRestPose) {
  const SkinnedMesh mesh = RandomMesh(50, 3, 4);
  const std::vector<glm::mat4> identity(4, glm::mat4(1.0f));
  const GoldResult r = SkinGold(mesh, identity);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    EXPECT_NEAR(glm::length(r.positions[v] - glm::dvec3(mesh.positions[v])), 0.0, 1e-6);
  }
}

TEST(SkinGold, BlendsTranslationsByWeight) {
  SkinnedMesh mesh;
  mesh.influences = 2;
  mesh.joint_count = 2;
  mesh.positions = {{1, 2, 3}};
  mesh.joints = {0, 1};
  mesh.weights = {0.25f, 0.75f};
  const std::vector<glm::mat4> palette = {glm::translate(glm::mat4(1.0f), {4, 0, 0}),
                                          glm::translate(glm::mat4(1.0f), {0, 8, 0})};
  const GoldResult r = SkinGold(mesh, palette);
  EXPECT_DOUBLE_EQ(r.positions[0].x, 2.0);
  EXPECT_DOUBLE_EQ(r.positions[0].y, 8.0);
  EXPECT_DOUBLE_EQ(r.positions[0].z, 3.0);
}

TEST(SkinGold, NormalsOfARotationAndUniformScaleAreRotatedAndRenormalised) {
  SkinnedMesh mesh;
  mesh.influences = 1;
  mesh.joint_count = 1;
  mesh.positions = {{0, 0, 0}};
  mesh.normals = {{1, 0, 0}};
  mesh.joints = {0};
  mesh.weights = {1.0f};
  const std::vector<glm::mat4> palette = {
      glm::translate(glm::scale(glm::mat4(1.0f), {3, 3, 3}), {5, 5, 5}) *
      glm::rotate(glm::mat4(1.0f), glm::radians(90.0f), {0, 0, 1})};
  const GoldResult r = SkinGold(mesh, palette, true);
  ASSERT_EQ(r.normals.size(), 1u);
  EXPECT_NEAR(r.normals[0].x, 0.0, 1e-7);
  EXPECT_NEAR(r.normals[0].y, 1.0, 1e-7);
}

// Normals follow the inverse transpose of the blended 3x3 (its direction):
// under non-uniform scale, shear, a mirror and a blend of two differently
// scaled joints, against glm's inverse in float64; a singular blend (a joint
// flattened along z) still gives the cofactor's direction. The serial and
// fast CPU skinners agree with the gold. The plain upper 3x3 is 0.32 rad off
// in the first case.
TEST(SkinGold, NormalsFollowTheInverseTransposeUnderScaleShearAndMirror) {
  const glm::vec3 n0 = glm::normalize(glm::vec3(1, 1, 0.5f));
  glm::mat4 shear(1.0f);
  shear[1][0] = 0.5f;  // x += 0.5 y
  shear[2][1] = -0.3f;  // y -= 0.3 z
  const std::vector<std::pair<std::vector<glm::mat4>, std::vector<float>>> cases = {
      {{glm::scale(glm::mat4(1.0f), {2, 1, 1})}, {1.0f}},
      {{shear}, {1.0f}},
      {{glm::scale(glm::mat4(1.0f), {-1, 1, 1})}, {1.0f}},
      {{glm::scale(glm::mat4(1.0f), {1.7f, 1, 0.6f}), glm::rotate(glm::scale(glm::mat4(1.0f), {0.5f, 2, 1}), 0.7f, {0, 0, 1})},
       {0.3f, 0.7f}},
  };
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const auto& [palette, weights] = cases[c];
    SkinnedMesh mesh;
    mesh.influences = static_cast<int>(weights.size());
    mesh.joint_count = static_cast<int>(palette.size());
    mesh.positions = {{0.2f, -0.1f, 0.4f}};
    mesh.normals = {n0};
    mesh.weights = weights;
    for (int i = 0; i < mesh.influences; ++i) mesh.joints.push_back(static_cast<std::uint16_t>(i));
    glm::dmat3 a(0.0);
    for (int i = 0; i < mesh.influences; ++i) a += double(weights[i]) * glm::dmat3(glm::dmat4(palette[i]));
    const glm::dvec3 expected = glm::normalize(glm::transpose(glm::inverse(a)) * glm::dvec3(n0));
    const GoldResult gold = SkinGold(mesh, palette, true);
    ASSERT_EQ(gold.normals.size(), 1u);
    EXPECT_NEAR(glm::length(gold.normals[0] - expected), 0.0, 1e-12) << "case " << c;
    std::vector<glm::vec3> p(1), serial(1), fast(1);
    SkinSerial(mesh, palette, p, serial);
    FastSkinner(mesh, 1).Run(palette, p, fast);
    EXPECT_NEAR(glm::length(glm::dvec3(serial[0]) - expected), 0.0, 1e-6) << "serial, case " << c;
    EXPECT_NEAR(glm::length(glm::dvec3(fast[0]) - expected), 0.0, 1e-6) << "fast, case " << c;
    if (c == 0) {  // what the plain upper 3x3 would give
      const double off = std::acos(glm::dot(glm::normalize(a * glm::dvec3(n0)), expected));
      EXPECT_GT(off, 0.3) << off;
    }
  }
  SkinnedMesh flat;
  flat.influences = 1;
  flat.joint_count = 1;
  flat.positions = {{0, 0, 0}};
  flat.normals = {{0, 0, 1}};
  flat.joints = {0};
  flat.weights = {1.0f};
  const GoldResult r = SkinGold(flat, std::vector<glm::mat4>{glm::scale(glm::mat4(1.0f), {1, 1, 0})}, true);
  EXPECT_NEAR(glm::length(r.normals[0] - glm::dvec3(0, 0, 1)), 0.0, 1e-12) << "a singular blend keeps a direction";
}

// Tangents follow the surface: the blended 3x3 itself, renormalised, their
// handedness kept, and flipped by a mirror (det < 0) so the bitangent
// w * cross(n, t) stays the skinned surface's; gold and serial agree. The
// same cases as the normals above.
TEST(SkinGold, TangentsFollowTheBlendedMatrixAndAMirrorFlipsTheirHandedness) {
  const glm::vec4 t0(glm::normalize(glm::vec3(1.0f, 0.2f, -0.3f)), -1.0f);
  glm::mat4 shear(1.0f);
  shear[1][0] = 0.5f;
  const std::vector<std::pair<glm::mat4, bool>> cases = {
      {glm::scale(glm::mat4(1.0f), {2, 1, 1}), false},
      {shear, false},
      {glm::scale(glm::mat4(1.0f), {-1, 1, 1}), true},
      {glm::rotate(glm::scale(glm::mat4(1.0f), {0.5f, 2, 1}), 0.7f, {0, 0, 1}), false},
  };
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const auto& [m, mirror] = cases[c];
    SkinnedMesh mesh;
    mesh.influences = 1;
    mesh.joint_count = 1;
    mesh.positions = {{0.2f, -0.1f, 0.4f}};
    mesh.tangents = {t0};
    mesh.joints = {0};
    mesh.weights = {1.0f};
    const std::vector<glm::mat4> palette = {m};
    const glm::dvec3 expected = glm::normalize(glm::dmat3(glm::dmat4(m)) * glm::dvec3(t0));
    const GoldResult gold = SkinGold(mesh, palette, false, true);
    ASSERT_EQ(gold.tangents.size(), 1u);
    EXPECT_NEAR(glm::length(glm::dvec3(gold.tangents[0]) - expected), 0.0, 1e-12) << "case " << c;
    EXPECT_EQ(gold.tangents[0].w, mirror ? 1.0 : -1.0) << "case " << c;
    std::vector<glm::vec3> p(1);
    std::vector<glm::vec4> serial(1);
    SkinSerial(mesh, palette, p, {}, serial);
    EXPECT_NEAR(glm::length(glm::dvec3(serial[0]) - expected), 0.0, 1e-6) << "serial, case " << c;
    EXPECT_EQ(serial[0].w, mirror ? 1.0f : -1.0f) << "serial, case " << c;
  }
  SkinnedMesh bad;
  bad.influences = 1;
  bad.joint_count = 1;
  bad.positions = {{0, 0, 0}};
  bad.tangents = {{1, 0, 0, 0.5f}};
  bad.joints = {0};
  bad.weights = {1.0f};
  EXPECT_FALSE(Validate(bad).ok()) << "a handedness other than +-1";
}

// Dual-quaternion skinning's gold: with one influence it is the linear
// gold, rigid or not (scale, shear and a mirror go through the two-phase S);
// at a twisting joint it keeps the volume linear blending loses (the candy
// wrapper); rotations more than 180 degrees apart blend the short way
// (antipodality against the first influence); a singular joint is an error
// naming it.
TEST(SkinGoldDualQuaternion, IsTheLinearGoldForOneInfluenceAndKeepsVolumeWhereItCollapses) {
  glm::mat4 shear(1.0f);
  shear[1][0] = 0.5f;
  const std::vector<glm::mat4> joints = {
      glm::translate(glm::rotate(glm::mat4(1.0f), 0.8f, glm::normalize(glm::vec3(1, 2, 3))), {1, -2, 0.5f}),
      glm::translate(glm::scale(glm::mat4(1.0f), {2, 1, 0.5f}), {0.3f, 0, 0}),
      shear,
      glm::scale(glm::mat4(1.0f), {-1, 1, 1}),
  };
  for (std::size_t j = 0; j < joints.size(); ++j) {
    SkinnedMesh mesh;
    mesh.influences = 1;
    mesh.joint_count = 1;
    mesh.positions = {{0.2f, -0.7f, 0.4f}};
    mesh.normals = {glm::normalize(glm::vec3(1, 1, 0.5f))};
    mesh.tangents = {{glm::normalize(glm::vec3(1, -1, 0)), 1.0f}};
    mesh.joints = {0};
    mesh.weights = {1.0f};
    const std::vector<glm::mat4> palette = {joints[j]};
    const GoldResult lbs = SkinGold(mesh, palette, true, true), dq = SkinGoldDualQuaternion(mesh, palette, true, true);
    EXPECT_NEAR(glm::length(dq.positions[0] - lbs.positions[0]), 0.0, 1e-6) << "joint " << j;
    EXPECT_NEAR(glm::length(dq.normals[0] - lbs.normals[0]), 0.0, 1e-6) << "joint " << j;
    EXPECT_NEAR(glm::length(dq.tangents[0] - lbs.tangents[0]), 0.0, 1e-6) << "joint " << j;
  }
  // A twist of +-90 degrees about x, half and half: linear blending collapses
  // the point onto the axis, dual quaternions keep its distance.
  SkinnedMesh twist;
  twist.influences = 2;
  twist.joint_count = 2;
  twist.positions = {{0.5f, 1.0f, 0.0f}};
  twist.joints = {0, 1};
  twist.weights = {0.5f, 0.5f};
  const std::vector<glm::mat4> twisted = {glm::rotate(glm::mat4(1.0f), glm::radians(90.0f), {1, 0, 0}),
                                          glm::rotate(glm::mat4(1.0f), glm::radians(-90.0f), {1, 0, 0})};
  const glm::dvec3 lbs = SkinGold(twist, twisted).positions[0], dq = SkinGoldDualQuaternion(twist, twisted).positions[0];
  EXPECT_NEAR(glm::length(glm::dvec2(lbs.y, lbs.z)), 0.0, 1e-6) << "linear blending: on the axis";
  EXPECT_NEAR(glm::length(glm::dvec2(dq.y, dq.z)), 1.0, 1e-6) << "dual quaternions: the radius kept";
  EXPECT_NEAR(dq.x, 0.5, 1e-6);
  // 170 and 190 degrees about z: the short way round, through 180.
  const std::vector<glm::mat4> far = {glm::rotate(glm::mat4(1.0f), glm::radians(170.0f), {0, 0, 1}),
                                      glm::rotate(glm::mat4(1.0f), glm::radians(190.0f), {0, 0, 1})};
  twist.positions = {{1.0f, 0.0f, 0.0f}};
  const glm::dvec3 half = SkinGoldDualQuaternion(twist, far).positions[0];
  EXPECT_NEAR(glm::length(half - glm::dvec3(-1, 0, 0)), 0.0, 1e-6) << half.x << " " << half.y;
  const std::vector<glm::mat4> singular = {glm::mat4(1.0f), glm::scale(glm::mat4(1.0f), {1, 1, 0})};
  try {
    (void)SkinGoldDualQuaternion(twist, singular);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("joint 1: not an invertible affine matrix"), std::string::npos) << e.what();
  }
}

TEST(SkinGold, RejectsInvalidMeshAndWrongPaletteSize) {
  SkinnedMesh mesh = RandomMesh(5, 2, 3);
  EXPECT_THROW(SkinGold(mesh, RandomPalette(2, 1)), Error);
  mesh.joints[0] = 7;
  EXPECT_THROW(SkinGold(mesh, RandomPalette(3, 1)), Error);
}

TEST(SkinSerialAndFast, RejectWrongPaletteOrOutputSize) {
  const SkinnedMesh mesh = RandomMesh(5, 2, 3);
  std::vector<glm::vec3> out(5), short_out(4);
  EXPECT_THROW(SkinSerial(mesh, RandomPalette(4, 1), out), Error);
  EXPECT_THROW(SkinSerial(mesh, RandomPalette(3, 1), short_out), Error);
  FastSkinner fast(mesh);
  EXPECT_THROW(fast.Run(RandomPalette(4, 1), out), Error);
  EXPECT_THROW(fast.Run(RandomPalette(3, 1), short_out), Error);
}

TEST(FastSkinner, RejectsAnInvalidMeshAtConstruction) {
  SkinnedMesh mesh = RandomMesh(5, 2, 3);
  mesh.weights[0] = -1.0f;
  EXPECT_THROW(FastSkinner{mesh}, Error);
}

TEST(SkinAgreement, SerialAndFastMatchGoldOnRandomMeshesForEveryInfluenceCount) {
  for (int b = 1; b <= kMaxInfluences; ++b) {
    const SkinnedMesh mesh = RandomMesh(20000 + 17 * b, b, 77, 10 + b, true);
    EXPECT_LT(WorstAgainstGold(mesh, RandomPalette(77, b)), 1e-5) << "B=" << b;
  }
}

TEST(SkinAgreement, FastIsTheSameForOneThreadAndManyThreads) {
  const SkinnedMesh mesh = RandomMesh(70001, 4, 30, 3);
  const auto palette = RandomPalette(30, 3);
  std::vector<glm::vec3> one(mesh.vertex_count()), many(mesh.vertex_count());
  FastSkinner(mesh, 1).Run(palette, one);
  FastSkinner(mesh, 7).Run(palette, many);
  EXPECT_EQ(0, std::memcmp(one.data(), many.data(), one.size() * sizeof(glm::vec3)));
}

TEST(SkinAgreement, SerialAndFastMatchGoldOnSyntheticDatasetsLocalAndRandom) {
  for (const char* key : {"30k-b4-normals", "30k-b2-random", "10k-b1", "5000-b8-bones12-seed3-normals"}) {
    const SkinnedAsset asset = GenerateDataset(ParseDatasetKey(key));
    const auto palette = asset.PaletteAt(0, 0.7);
    EXPECT_LT(WorstAgainstGold(asset.mesh, palette), 1e-5) << key;
  }
}

TEST(SkinAgreement, SerialAndFastMatchGoldOnRealGltfModelsMidAnimation) {
  for (const char* file : {"CesiumMan.gltf", "Fox.gltf", "RiggedSimple.gltf"}) {
    const SkinnedAsset asset = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/" + file).asset;
    ASSERT_FALSE(asset.animations.empty()) << file;
    const AnimationClip& clip = asset.animations[0];
    const auto palette = asset.PaletteAt(0, clip.start + 0.37 * clip.duration());
    EXPECT_LT(WorstAgainstGold(asset.mesh, palette), 1e-5) << file;
  }
}

TEST(CompareToGold, ReportsNonFiniteOutputsAsFailures) {
  const std::vector<glm::dvec3> gold = {{1, 0, 0}, {0, 1, 0}};
  const std::vector<glm::vec3> bad = {{1, 0, 0}, {std::numeric_limits<float>::quiet_NaN(), 1, 0}};
  const GoldComparison c = CompareToGold(gold, bad);
  EXPECT_EQ(c.non_finite, 1u);
  EXPECT_EQ(c.worst_vertex, 1u);
  EXPECT_TRUE(std::isinf(c.max_relative));
}

TEST(CompareToGold, MeasuresErrorRelativeToTheVertexWithAFloorNearTheOrigin) {
  const std::vector<glm::dvec3> gold = {{100, 0, 0}, {0, 0, 0}};
  const std::vector<glm::vec3> actual = {{100.001f, 0, 0}, {0, 0.05f, 0}};
  const GoldComparison c = CompareToGold(gold, actual);
  EXPECT_NEAR(c.max_relative, 0.05 / 0.1, 1e-6);  // floor = 1e-3 * 100
  EXPECT_EQ(c.worst_vertex, 1u);
}

// CompareToGold runs in chunks on a thread pool for large meshes; one pass
// over the vertices, as it was written first, is the reference: the same
// maxima, count and worst vertex (the first non-finite one, else the first of
// the largest error), whatever chunk holds them.
GoldComparison OnePass(std::span<const glm::dvec3> gold, std::span<const glm::vec3> actual) {
  double largest = 0.0;
  for (const glm::dvec3& g : gold) largest = std::max(largest, glm::length(g));
  const double floor = std::max(1e-3 * largest, 1e-30);
  GoldComparison c;
  for (std::size_t v = 0; v < gold.size(); ++v) {
    const glm::dvec3 a(actual[v]);
    if (!std::isfinite(a.x) || !std::isfinite(a.y) || !std::isfinite(a.z)) {
      if (c.non_finite++ == 0) c.worst_vertex = v;
      continue;
    }
    const double abs_err = glm::length(a - gold[v]);
    const double rel = abs_err / std::max(glm::length(gold[v]), floor);
    if (rel > c.max_relative) {
      c.max_relative = rel;
      if (c.non_finite == 0) c.worst_vertex = v;
    }
    c.max_absolute = std::max(c.max_absolute, abs_err);
  }
  if (c.non_finite > 0) c.max_relative = std::numeric_limits<double>::infinity();
  return c;
}

TEST(CompareToGold, InChunksIsOnePassWhereverTheWorstVertexAndTheNonFiniteOnesAre) {
  const std::size_t n = 200003;  // 13 chunks of 16384, the last short
  std::vector<glm::dvec3> gold(n);
  std::vector<glm::vec3> actual(n);
  for (std::size_t v = 0; v < n; ++v) {
    gold[v] = glm::dvec3(std::sin(0.001 * double(v)), std::cos(0.0007 * double(v)), 0.5 + double(v % 97) / 97.0);
    actual[v] = glm::vec3(gold[v]) + glm::vec3(float(v % 13) * 1e-7f, 0.0f, float(v % 7) * -1e-7f);
  }
  const auto expect_same = [&](const char* what) {
    const GoldComparison want = OnePass(gold, actual), got = CompareToGold(gold, actual);
    EXPECT_EQ(got.worst_vertex, want.worst_vertex) << what;
    EXPECT_EQ(got.non_finite, want.non_finite) << what;
    EXPECT_EQ(got.max_relative, want.max_relative) << what;
    EXPECT_EQ(got.max_absolute, want.max_absolute) << what;
  };
  expect_same("small errors everywhere");
  actual[150000].y += 0.25f;  // the largest error, in a late chunk
  actual[150001].y += 0.25f;  // and a tie after it: the first one is named
  expect_same("one large error");
  actual[20000].x += 0.25f;  // the same error, earlier: the tie goes to it
  expect_same("a tie across chunks");
  actual[190000].z = std::numeric_limits<float>::quiet_NaN();
  expect_same("a NaN after the worst vertex");
  actual[70000].x = std::numeric_limits<float>::infinity();
  expect_same("an infinity before it");
  EXPECT_EQ(CompareToGold(gold, actual).worst_vertex, 70000u);
  EXPECT_EQ(CompareToGold(gold, actual).non_finite, 2u);
}

// The gold of a large mesh (computed in chunks on a thread pool) is each
// vertex's own: slices of 50 vertices from several chunks, skinned alone.
TEST(SkinGold, InChunksIsEveryVertexsOwnGold) {
  const SkinnedMesh big = RandomMesh(40000, 4, 30, 11, true);
  const std::vector<glm::mat4> palette = RandomPalette(30, 5);
  const GoldResult all = SkinGold(big, palette, true);
  for (const std::size_t first : {0u, 16383u, 16384u, 39950u}) {
    SkinnedMesh slice = big;
    slice.positions.assign(big.positions.begin() + first, big.positions.begin() + first + 50);
    slice.normals.assign(big.normals.begin() + first, big.normals.begin() + first + 50);
    slice.joints.assign(big.joints.begin() + first * 4, big.joints.begin() + (first + 50) * 4);
    slice.weights.assign(big.weights.begin() + first * 4, big.weights.begin() + (first + 50) * 4);
    const GoldResult alone = SkinGold(slice, palette, true);
    for (std::size_t v = 0; v < 50; ++v) {
      ASSERT_EQ(all.positions[first + v], alone.positions[v]) << first + v;
      ASSERT_EQ(all.normals[first + v], alone.normals[v]) << first + v;
    }
  }
}

// The candy wrapper: linear blending shrinks the middle ring of a tube whose
// joint twists to |cos(angle / 2)| of its radius, dual quaternions keep it.
TEST(CandyWrapper, LinearBlendingCollapsesATwistedJointAndDualQuaternionsKeepItsVolume) {
  const std::vector<CandyWrapperPoint> points = CandyWrapper({0.0, 90.0, 180.0});
  ASSERT_EQ(points.size(), 3u);
  for (const CandyWrapperPoint& p : points) {
    SCOPED_TRACE(p.twist_degrees);
    EXPECT_NEAR(p.linear_radius, std::fabs(std::cos(p.twist_degrees * M_PI / 360.0)), 1e-5);
    EXPECT_NEAR(p.dual_quaternion_radius, 1.0, 1e-5);
    EXPECT_NEAR(p.dual_quaternion_volume, 1.0, 1e-5);
  }
  EXPECT_NEAR(points[0].linear_volume, 1.0, 1e-6);
  EXPECT_LT(points[1].linear_volume, 0.9);
  EXPECT_LT(points[2].linear_volume, points[1].linear_volume);
}

}  // namespace
}  // namespace skintune::internal
