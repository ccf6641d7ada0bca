#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "base/error.h"
#include "model/mesh.h"
#include "test_meshes.h"

namespace skintune::internal {
namespace {

using testing::RandomMesh;

MeshProblem FirstProblem(const SkinnedMesh& m) {
  const ValidationReport r = Validate(m);
  EXPECT_FALSE(r.ok());
  return r.issues.empty() ? MeshProblem::kBadInfluenceCount : r.issues.front().problem;
}

TEST(MeshValidate, AcceptsAWellFormedMesh) {
  const ValidationReport r = Validate(RandomMesh(100, 4, 10, 1, true));
  EXPECT_TRUE(r.ok()) << r.Summary();
}

TEST(MeshValidate, RejectsInfluenceCountOutsideOneToEight) {
  SkinnedMesh m = RandomMesh(4, 2, 3);
  m.influences = 0;
  EXPECT_EQ(FirstProblem(m), MeshProblem::kBadInfluenceCount);
  m.influences = 9;
  EXPECT_EQ(FirstProblem(m), MeshProblem::kBadInfluenceCount);
}

TEST(MeshValidate, RejectsZeroJoints) {
  SkinnedMesh m = RandomMesh(4, 1, 3);
  m.joint_count = 0;
  EXPECT_EQ(FirstProblem(m), MeshProblem::kNoJoints);
}

TEST(MeshValidate, RejectsAnEmptyMesh) {
  SkinnedMesh m = RandomMesh(0, 1, 3);
  EXPECT_EQ(FirstProblem(m), MeshProblem::kNoVertices);
}

TEST(MeshValidate, RejectsMismatchedArrayLengths) {
  SkinnedMesh m = RandomMesh(4, 2, 3);
  m.weights.pop_back();
  EXPECT_EQ(FirstProblem(m), MeshProblem::kLengthMismatch);
  EXPECT_NE(Validate(m).Summary().find("7 weights for 4 vertices x 2 influences"), std::string::npos)
      << Validate(m).Summary();
  SkinnedMesh n = RandomMesh(4, 2, 3, 1, true);
  n.normals.pop_back();
  EXPECT_EQ(FirstProblem(n), MeshProblem::kLengthMismatch);
  SkinnedMesh j = RandomMesh(4, 2, 3);
  j.joints.push_back(0);
  EXPECT_EQ(FirstProblem(j), MeshProblem::kLengthMismatch);
}

TEST(MeshValidate, RejectsJointIndexOutOfRangeNamingVertexAndSlot) {
  SkinnedMesh m = RandomMesh(10, 3, 5);
  m.joints[7 * 3 + 2] = 5;
  const ValidationReport r = Validate(m);
  ASSERT_EQ(r.total_issues, 1u);
  EXPECT_EQ(r.issues[0].problem, MeshProblem::kJointOutOfRange);
  EXPECT_EQ(r.issues[0].vertex, 7u);
  EXPECT_EQ(r.issues[0].slot, 2);
  EXPECT_EQ(r.issues[0].message, "vertex 7 slot 2: joint 5 out of range (5 joints)");
}

TEST(MeshValidate, RejectsNegativeWeight) {
  SkinnedMesh m = RandomMesh(10, 2, 5);
  m.weights[3 * 2 + 1] = -0.25f;
  EXPECT_EQ(FirstProblem(m), MeshProblem::kBadWeight);
  EXPECT_NE(Validate(m).Summary().find("vertex 3 slot 1: weight -0.25 is negative"), std::string::npos);
}

TEST(MeshValidate, RejectsNaNAndInfiniteWeight) {
  SkinnedMesh m = RandomMesh(10, 2, 5);
  m.weights[4] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(FirstProblem(m), MeshProblem::kBadWeight);
  EXPECT_NE(Validate(m).Summary().find("is not finite"), std::string::npos);
  m.weights[4] = std::numeric_limits<float>::infinity();
  EXPECT_EQ(FirstProblem(m), MeshProblem::kBadWeight);
}

TEST(MeshValidate, RejectsAllZeroWeights) {
  SkinnedMesh m = RandomMesh(10, 2, 5);
  m.weights[6] = m.weights[7] = 0.0f;
  EXPECT_EQ(FirstProblem(m), MeshProblem::kZeroWeights);
}

TEST(MeshValidate, RejectsWeightsNotSummingToOneOutsideTolerance) {
  SkinnedMesh m = RandomMesh(10, 2, 5);
  m.weights[8] *= 0.5f;  // vertex 4
  const ValidationReport r = Validate(m);
  EXPECT_EQ(r.issues.at(0).problem, MeshProblem::kWeightSum);
  EXPECT_EQ(r.issues.at(0).vertex, 4u);
  EXPECT_TRUE(r.renormalisable());
}

TEST(MeshValidate, AcceptsWeightSumWithinTheStatedTolerance) {
  SkinnedMesh m = RandomMesh(10, 2, 5);
  m.weights[0] += static_cast<float>(kWeightSumTolerance * 0.5);
  EXPECT_TRUE(Validate(m).ok());
  m.weights[0] += static_cast<float>(kWeightSumTolerance);
  EXPECT_FALSE(Validate(m).ok());
}

TEST(MeshValidate, RejectsNonFinitePosition) {
  SkinnedMesh m = RandomMesh(10, 2, 5);
  m.positions[9].y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(FirstProblem(m), MeshProblem::kNonFinitePosition);
}

TEST(MeshValidate, CountsEveryIssueButKeepsAtMostMaxIssues) {
  SkinnedMesh m = RandomMesh(100, 1, 5);
  for (auto& w : m.weights) w = 0.5f;
  ValidateOptions o;
  o.max_issues = 3;
  const ValidationReport r = Validate(m, o);
  EXPECT_EQ(r.total_issues, 100u);
  EXPECT_EQ(r.issues.size(), 3u);
  EXPECT_NE(r.Summary().find("(and 99 more)"), std::string::npos);
}

TEST(MeshValidate, ThrowIfInvalidPrefixesTheContext) {
  SkinnedMesh m = RandomMesh(2, 1, 1);
  m.joints[1] = 3;
  try {
    ThrowIfInvalid(m, "model.gltf");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "model.gltf: vertex 1 slot 0: joint 3 out of range (1 joints)");
  }
}

TEST(MeshRenormalize, FixesSumsAndReportsTheWorstVertex) {
  SkinnedMesh m = RandomMesh(10, 2, 5);
  m.weights[2 * 2] *= 0.9f;
  m.weights[6 * 2] *= 0.2f;
  const RenormalizeReport r = Renormalize(m);
  EXPECT_EQ(r.changed_vertices, 2u);
  EXPECT_EQ(r.worst_vertex, 6u);
  EXPECT_LT(r.worst_sum, 0.9);
  EXPECT_TRUE(Validate(m).ok());
  EXPECT_NEAR(m.weights[12] + m.weights[13], 1.0f, 1e-6);
}

TEST(MeshRenormalize, RefusesAllZeroNegativeOrNaNWeights) {
  SkinnedMesh zero = RandomMesh(4, 2, 5);
  zero.weights[0] = zero.weights[1] = 0.0f;
  EXPECT_THROW(Renormalize(zero), Error);
  SkinnedMesh negative = RandomMesh(4, 2, 5);
  negative.weights[3] = -1.0f;
  EXPECT_THROW(Renormalize(negative), Error);
  SkinnedMesh nan = RandomMesh(4, 2, 5);
  nan.weights[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(Renormalize(nan), Error);
}

TEST(MeshCompactInfluences, SortsSlotsByWeightAndDropsEmptyTrailingSlots) {
  SkinnedMesh m;
  m.influences = 4;
  m.joint_count = 9;
  m.positions = {{0, 0, 0}, {1, 1, 1}};
  m.joints = {1, 2, 3, 4, /**/ 5, 6, 7, 8};
  m.weights = {0.25f, 0.0f, 0.75f, 0.0f, /**/ 1.0f, 0.0f, 0.0f, 0.0f};
  EXPECT_EQ(CompactInfluences(m), 0u);
  EXPECT_EQ(m.influences, 2);
  EXPECT_EQ(m.joints, (std::vector<std::uint16_t>{3, 1, 5, 0}));
  EXPECT_EQ(m.weights, (std::vector<float>{0.75f, 0.25f, 1.0f, 0.0f}));
}

TEST(MeshCompactInfluences, KeepsTheLargestWeightsWhenMoreThanTheMaximum) {
  SkinnedMesh m;
  m.influences = 3;
  m.joint_count = 3;
  m.positions = {{0, 0, 0}};
  m.joints = {0, 1, 2};
  m.weights = {0.2f, 0.5f, 0.3f};
  EXPECT_EQ(CompactInfluences(m, 2), 1u);
  EXPECT_EQ(m.influences, 2);
  EXPECT_EQ(m.joints, (std::vector<std::uint16_t>{1, 2}));
  EXPECT_NEAR(m.weights[0], 0.625f, 1e-6);
  EXPECT_NEAR(m.weights[1], 0.375f, 1e-6);
}

TEST(MeshInfluenceHistogram, CountsNonZeroWeightsPerVertex) {
  SkinnedMesh m;
  m.influences = 2;
  m.joint_count = 2;
  m.positions = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  m.joints = {0, 1, 0, 0, 1, 0};
  m.weights = {0.5f, 0.5f, 1.0f, 0.0f, 1.0f, 0.0f};
  EXPECT_EQ(InfluenceHistogram(m), (std::vector<std::size_t>{0, 2, 1}));
}

}  // namespace
}  // namespace skintune::internal
