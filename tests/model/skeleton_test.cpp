#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include "model/asset.h"
#include "base/error.h"
#include "model/skeleton.h"

namespace skintune::internal {
namespace {

// root -> a -> b, with b's parent stored after it (glTF allows any order).
Skeleton ThreeNodes() {
  Skeleton s;
  s.nodes.resize(3);
  s.nodes[0].name = "root";
  s.nodes[0].rest.translation = {1, 0, 0};
  s.nodes[1].name = "b";
  s.nodes[1].parent = 2;
  s.nodes[1].rest.translation = {0, 0, 3};
  s.nodes[2].name = "a";
  s.nodes[2].parent = 0;
  s.nodes[2].rest.translation = {0, 2, 0};
  s.nodes[2].rest.rotation = glm::angleAxis(glm::radians(90.0), glm::dvec3(0, 0, 1));
  s.joints = {0, 2, 1};
  const std::vector<glm::dmat4> global = s.GlobalTransforms(s.RestPose());
  for (int j : s.joints) s.inverse_bind.push_back(glm::inverse(global[j]));
  return s;
}

// docs/INPUTS.md "Finite outputs": an entry finite in double but not in float (or not at
// all) is an error naming the joint, its node and the element, never a
// palette that skins every vertex to NaN.
TEST(Skeleton, PaletteEntriesBeyondFloatAreAnErrorNamingTheJoint) {
  Skeleton s = ThreeNodes();
  s.nodes[2].rest.scale = {1e300, 1, 1};
  s.inverse_bind[1] = glm::dmat4(1.0);
  std::string message;
  try {
    (void)s.Palette(s.RestPose());
  } catch (const Error& e) {
    message = e.what();
  }
  EXPECT_EQ(message.rfind("joint 1 (nodes[2] ('a')): palette entry [0][", 0), 0u) << message;
  EXPECT_NE(message.find(", beyond float32 (the node's global transform times its inverse bind matrix)"), std::string::npos)
      << message;
  EXPECT_NO_THROW((void)s.PaletteD(s.RestPose()));  // finite in double: the gold may use it
  s.nodes[2].rest.scale = {1e300, 1e300, 1};
  s.nodes[1].rest.scale = {1e300, 1, 1};  // b's global transform overflows double
  EXPECT_THROW((void)s.PaletteD(s.RestPose()), Error);
  // Through the asset, with its source and the pose.
  SkinnedAsset asset;
  asset.source = "model.gltf";
  asset.skeleton = s;
  try {
    (void)asset.PaletteAt(-1, 0.0);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("model.gltf: rest pose: joint ", 0), 0u) << e.what();
  }
}

TEST(Transform, ComposesTranslationRotationScaleInThatOrder) {
  Transform t;
  t.translation = {1, 2, 3};
  t.rotation = glm::angleAxis(glm::radians(90.0), glm::dvec3(0, 0, 1));
  t.scale = {2, 2, 2};
  const glm::dvec4 p = t.ToMatrix() * glm::dvec4(1, 0, 0, 1);
  EXPECT_NEAR(p.x, 1.0, 1e-12);
  EXPECT_NEAR(p.y, 4.0, 1e-12);
  EXPECT_NEAR(p.z, 3.0, 1e-12);
}

TEST(Skeleton, GlobalTransformsFollowParentsStoredInAnyOrder) {
  const Skeleton s = ThreeNodes();
  const auto global = s.GlobalTransforms(s.RestPose());
  const glm::dvec4 origin_b = global[1] * glm::dvec4(0, 0, 0, 1);
  EXPECT_NEAR(origin_b.x, 1.0, 1e-12);
  EXPECT_NEAR(origin_b.y, 2.0, 1e-12);
  EXPECT_NEAR(origin_b.z, 3.0, 1e-12);
}

TEST(Skeleton, RestPosePaletteIsIdentityWhenInverseBindMatchesTheRestPose) {
  const Skeleton s = ThreeNodes();
  for (const glm::dmat4& m : s.PaletteD(s.RestPose())) {
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) EXPECT_NEAR(m[c][r], c == r ? 1.0 : 0.0, 1e-12);
  }
}

TEST(Skeleton, MatrixNodesIgnoreThePose) {
  Skeleton s = ThreeNodes();
  s.nodes[0].has_matrix = true;
  s.nodes[0].matrix = glm::translate(glm::dmat4(1.0), glm::dvec3(0, 0, 9));
  Pose pose = s.RestPose();
  pose[0].translation = {100, 100, 100};
  const auto global = s.GlobalTransforms(pose);
  EXPECT_NEAR(global[0][3].z, 9.0, 1e-12);
  EXPECT_NEAR(global[0][3].x, 0.0, 1e-12);
}

TEST(SkeletonValidate, RejectsNoJoints) {
  Skeleton s = ThreeNodes();
  s.joints.clear();
  s.inverse_bind.clear();
  EXPECT_THROW(s.Validate("x"), Error);
}

TEST(SkeletonValidate, RejectsJointAndInverseBindCountMismatch) {
  Skeleton s = ThreeNodes();
  s.inverse_bind.pop_back();
  EXPECT_THROW(s.Validate("x"), Error);
}

TEST(SkeletonValidate, RejectsParentOutOfRange) {
  Skeleton s = ThreeNodes();
  s.nodes[1].parent = 3;
  EXPECT_THROW(s.Validate("x"), Error);
}

TEST(SkeletonValidate, RejectsACycleNamingTheNode) {
  Skeleton s = ThreeNodes();
  s.nodes[0].parent = 1;
  try {
    s.Validate("rig.gltf");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rig.gltf: nodes[0] ('root'): node hierarchy has a cycle"), std::string::npos)
        << e.what();
  }
}

TEST(SkeletonValidate, RejectsJointReferringToAMissingNode) {
  Skeleton s = ThreeNodes();
  s.joints[2] = 5;
  EXPECT_THROW(s.Validate("x"), Error);
}

TEST(SkeletonValidate, RejectsNonFiniteTransforms) {
  Skeleton s = ThreeNodes();
  s.nodes[2].rest.translation.x = std::nan("");
  EXPECT_THROW(s.Validate("x"), Error);
  Skeleton t = ThreeNodes();
  t.inverse_bind[1][3][0] = INFINITY;
  EXPECT_THROW(t.Validate("x"), Error);
}

TEST(SkinnedAsset, FindsAnimationsByNameOrIndexAndListsThemOtherwise) {
  SkinnedAsset asset;
  asset.source = "fox.gltf";
  asset.animations.resize(2);
  asset.animations[0].name = "Walk";
  asset.animations[1].name = "Run";
  EXPECT_EQ(asset.FindAnimation("Run"), 1);
  EXPECT_EQ(asset.FindAnimation("0"), 0);
  try {
    asset.FindAnimation("Fly");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "fox.gltf: no animation 'Fly' (it has: 0 'Walk', 1 'Run')");
  }
  EXPECT_THROW(asset.FindAnimation("2"), Error);
  EXPECT_THROW(asset.FindAnimation("1x"), Error);
}

}  // namespace
}  // namespace skintune::internal
