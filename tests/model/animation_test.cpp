// AnimationClip: interpolation (STEP / LINEAR / CUBICSPLINE), clamping,
// shortest-path slerp, range, and validation failures.
#include <cmath>
#include <limits>
#include <string>

#include <glm/gtc/quaternion.hpp>
#include <gtest/gtest.h>

#include "model/animation.h"
#include "base/error.h"

namespace skintune::internal {
namespace {

constexpr double kPi = 3.14159265358979323846;

Channel MakeChannel(ChannelPath path, Interpolation interpolation, std::vector<float> times,
                    std::vector<glm::dvec4> values, int node = 0) {
  Channel c;
  c.node = node;
  c.path = path;
  c.interpolation = interpolation;
  c.times = std::move(times);
  c.values = std::move(values);
  return c;
}

AnimationClip OneChannel(Channel c) {
  AnimationClip clip;
  clip.name = "test";
  clip.channels.push_back(std::move(c));
  clip.UpdateRange();
  return clip;
}

Pose SampleAt(const AnimationClip& clip, double t, std::size_t nodes = 1) {
  Pose pose(nodes);
  clip.Sample(t, pose);
  return pose;
}

// (x, y, z, w) of a rotation of `angle` about the z axis.
glm::dvec4 AboutZ(double angle) { return {0.0, 0.0, std::sin(angle / 2), std::cos(angle / 2)}; }

// Angle of the rotation about z, from a quaternion that rotates about z only.
double AngleAboutZ(const glm::dquat& q) { return 2.0 * std::atan2(q.z, q.w); }

AnimationClip Translation(Interpolation interpolation) {
  return OneChannel(MakeChannel(ChannelPath::kTranslation, interpolation, {1.0f, 2.0f, 4.0f},
                                {{0, 0, 0, 0}, {10, 20, 30, 0}, {30, 0, -10, 0}}));
}

// ---------------------------------------------------------------- interpolation

TEST(AnimationSample, StepHoldsTheValueOfThePreviousKey) {
  const AnimationClip clip = Translation(Interpolation::kStep);
  EXPECT_EQ(SampleAt(clip, 1.0)[0].translation, glm::dvec3(0, 0, 0));
  EXPECT_EQ(SampleAt(clip, 1.99)[0].translation, glm::dvec3(0, 0, 0));
  EXPECT_EQ(SampleAt(clip, 2.0)[0].translation, glm::dvec3(10, 20, 30));
  EXPECT_EQ(SampleAt(clip, 3.9)[0].translation, glm::dvec3(10, 20, 30));
}

TEST(AnimationSample, LinearInterpolatesTranslationBetweenKeys) {
  const AnimationClip clip = Translation(Interpolation::kLinear);
  const glm::dvec3 mid = SampleAt(clip, 1.5)[0].translation;
  EXPECT_NEAR(mid.x, 5.0, 1e-12);
  EXPECT_NEAR(mid.y, 10.0, 1e-12);
  EXPECT_NEAR(mid.z, 15.0, 1e-12);
  const glm::dvec3 quarter = SampleAt(clip, 2.5)[0].translation;  // 1/4 of the way from key 1 to key 2
  EXPECT_NEAR(quarter.x, 15.0, 1e-12);
  EXPECT_NEAR(quarter.y, 15.0, 1e-12);
  EXPECT_NEAR(quarter.z, 20.0, 1e-12);
}

TEST(AnimationSample, LinearInterpolatesScale) {
  const AnimationClip clip = OneChannel(
      MakeChannel(ChannelPath::kScale, Interpolation::kLinear, {0.0f, 1.0f}, {{1, 1, 1, 0}, {3, 2, 1, 0}}));
  const glm::dvec3 s = SampleAt(clip, 0.25)[0].scale;
  EXPECT_NEAR(s.x, 1.5, 1e-12);
  EXPECT_NEAR(s.y, 1.25, 1e-12);
  EXPECT_NEAR(s.z, 1.0, 1e-12);
}

TEST(AnimationSample, LinearRotationIsSlerpNotLerp) {
  const AnimationClip clip = OneChannel(MakeChannel(ChannelPath::kRotation, Interpolation::kLinear,
                                                    {0.0f, 1.0f}, {AboutZ(0.0), AboutZ(kPi / 2)}));
  // Slerp has constant angular speed: a quarter of the time is a quarter of the angle
  // (normalised lerp would give atan(...) != 22.5 degrees).
  const glm::dquat q = SampleAt(clip, 0.25)[0].rotation;
  EXPECT_NEAR(AngleAboutZ(q), kPi / 8, 1e-9);
  EXPECT_NEAR(glm::length(q), 1.0, 1e-12);
}

TEST(AnimationSample, SlerpTakesTheShortestPath) {
  // -q is the same rotation as q: interpolating 0 -> (-AboutZ(90 deg)) must still
  // pass through 45 degrees, not swing the long way round.
  const AnimationClip clip = OneChannel(MakeChannel(ChannelPath::kRotation, Interpolation::kLinear,
                                                    {0.0f, 1.0f}, {AboutZ(0.0), -AboutZ(kPi / 2)}));
  glm::dquat q = SampleAt(clip, 0.5)[0].rotation;
  if (q.w < 0) q = -q;
  EXPECT_NEAR(AngleAboutZ(q), kPi / 4, 1e-9);
}

TEST(AnimationSample, RotationValuesAreReadAsXyzw) {
  const AnimationClip clip =
      OneChannel(MakeChannel(ChannelPath::kRotation, Interpolation::kStep, {0.0f}, {AboutZ(kPi / 2)}));
  const glm::dquat q = SampleAt(clip, 0.0)[0].rotation;
  EXPECT_NEAR(q.w, std::cos(kPi / 4), 1e-12);
  EXPECT_NEAR(q.z, std::sin(kPi / 4), 1e-12);
  EXPECT_NEAR(q.x, 0.0, 1e-12);
  EXPECT_NEAR(q.y, 0.0, 1e-12);
}

TEST(AnimationSample, RotationsAreNormalised) {
  const AnimationClip clip = OneChannel(
      MakeChannel(ChannelPath::kRotation, Interpolation::kStep, {0.0f, 1.0f}, {{0, 0, 0, 2}, {0, 0, 3, 0}}));
  EXPECT_NEAR(glm::length(SampleAt(clip, 0.5)[0].rotation), 1.0, 1e-12);
  EXPECT_NEAR(SampleAt(clip, 0.5)[0].rotation.w, 1.0, 1e-12);
  EXPECT_NEAR(SampleAt(clip, 1.0)[0].rotation.z, 1.0, 1e-12);
}

// CUBICSPLINE values: (in-tangent, value, out-tangent) per key.
AnimationClip Cubic(double out_tangent0, double in_tangent1, float t1) {
  return OneChannel(MakeChannel(ChannelPath::kTranslation, Interpolation::kCubicSpline, {0.0f, t1},
                                {{9, 9, 9, 0},
                                 {0, 0, 0, 0},
                                 {out_tangent0, 0, 0, 0},
                                 {in_tangent1, 0, 0, 0},
                                 {1, 0, 0, 0},
                                 {9, 9, 9, 0}}));
}

TEST(AnimationSample, CubicSplineWithZeroTangentsIsTheHermiteBasis) {
  const AnimationClip clip = Cubic(0.0, 0.0, 1.0f);
  for (double u : {0.0, 0.25, 0.5, 0.75, 1.0}) {
    EXPECT_NEAR(SampleAt(clip, u)[0].translation.x, 3 * u * u - 2 * u * u * u, 1e-12) << "u = " << u;
  }
}

TEST(AnimationSample, CubicSplineTangentsAreScaledByTheKeyInterval) {
  // Keys 2 s apart, out-tangent 1 (units per second) at key 0, all else 0 except p1 = 1:
  // p(u) = h01(u) * 1 + h10(u) * 2 * 1.
  const AnimationClip clip = Cubic(1.0, 0.0, 2.0f);
  const double u = 0.5;
  const double expected = (-2 * u * u * u + 3 * u * u) + (u * u * u - 2 * u * u + u) * 2.0;
  EXPECT_NEAR(SampleAt(clip, 1.0)[0].translation.x, expected, 1e-12);
  // In-tangent of key 1: h11(u) * interval * m1.
  const AnimationClip in = Cubic(0.0, 1.0, 2.0f);
  EXPECT_NEAR(SampleAt(in, 1.0)[0].translation.x, (-2 * u * u * u + 3 * u * u) + (u * u * u - u * u) * 2.0,
              1e-12);
}

TEST(AnimationSample, CubicSplineAtAndBeyondKeysReturnsTheValueNotATangent) {
  const AnimationClip clip = Cubic(5.0, 5.0, 1.0f);
  EXPECT_EQ(SampleAt(clip, 0.0)[0].translation, glm::dvec3(0, 0, 0));
  EXPECT_EQ(SampleAt(clip, -3.0)[0].translation, glm::dvec3(0, 0, 0));
  EXPECT_EQ(SampleAt(clip, 1.0)[0].translation, glm::dvec3(1, 0, 0));
  EXPECT_EQ(SampleAt(clip, 7.0)[0].translation, glm::dvec3(1, 0, 0));
}

TEST(AnimationSample, CubicSplineRotationIsNormalised) {
  const AnimationClip clip = OneChannel(
      MakeChannel(ChannelPath::kRotation, Interpolation::kCubicSpline, {0.0f, 1.0f},
                  {{0, 0, 0, 0}, AboutZ(0.0), {0, 0, 0, 0}, {0, 0, 0, 0}, AboutZ(kPi / 2), {0, 0, 0, 0}}));
  EXPECT_NEAR(glm::length(SampleAt(clip, 0.3)[0].rotation), 1.0, 1e-12);
}

// ---------------------------------------------------------------- clamping, single keys, targets

TEST(AnimationSample, ClampsToTheFirstKeyBeforeTheRange) {
  const AnimationClip clip = Translation(Interpolation::kLinear);
  EXPECT_EQ(SampleAt(clip, 0.0)[0].translation, glm::dvec3(0, 0, 0));
  EXPECT_EQ(SampleAt(clip, -100.0)[0].translation, glm::dvec3(0, 0, 0));
}

TEST(AnimationSample, ClampsToTheLastKeyAfterTheRange) {
  const AnimationClip clip = Translation(Interpolation::kLinear);
  EXPECT_EQ(SampleAt(clip, 4.0)[0].translation, glm::dvec3(30, 0, -10));
  EXPECT_EQ(SampleAt(clip, 100.0)[0].translation, glm::dvec3(30, 0, -10));
}

TEST(AnimationSample, SingleKeyChannelIsConstant) {
  for (Interpolation interpolation : {Interpolation::kStep, Interpolation::kLinear}) {
    const AnimationClip clip =
        OneChannel(MakeChannel(ChannelPath::kTranslation, interpolation, {0.5f}, {{1, 2, 3, 0}}));
    for (double t : {-1.0, 0.5, 9.0}) EXPECT_EQ(SampleAt(clip, t)[0].translation, glm::dvec3(1, 2, 3));
  }
  const AnimationClip cubic = OneChannel(MakeChannel(ChannelPath::kTranslation, Interpolation::kCubicSpline,
                                                     {0.5f}, {{7, 7, 7, 0}, {1, 2, 3, 0}, {7, 7, 7, 0}}));
  EXPECT_EQ(SampleAt(cubic, 3.0)[0].translation, glm::dvec3(1, 2, 3));
}

TEST(AnimationSample, OnlyTheAnimatedComponentOfTheTargetNodeChanges) {
  const AnimationClip clip = OneChannel(MakeChannel(ChannelPath::kTranslation, Interpolation::kLinear,
                                                    {0.0f, 1.0f}, {{0, 0, 0, 0}, {2, 2, 2, 0}}, 1));
  Pose pose(3);
  pose[1].rotation = glm::dquat(0.0, 1.0, 0.0, 0.0);
  pose[1].scale = glm::dvec3(2.0);
  clip.Sample(0.5, pose);
  EXPECT_EQ(pose[1].translation, glm::dvec3(1, 1, 1));
  EXPECT_EQ(pose[1].rotation, glm::dquat(0.0, 1.0, 0.0, 0.0));
  EXPECT_EQ(pose[1].scale, glm::dvec3(2.0));
  EXPECT_EQ(pose[0].translation, glm::dvec3(0.0));
  EXPECT_EQ(pose[2].translation, glm::dvec3(0.0));
}

TEST(AnimationSample, ChannelOutsideThePoseThrows) {
  const AnimationClip clip =
      OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kStep, {0.0f}, {{1, 1, 1, 0}}, 5));
  Pose pose(2);
  EXPECT_THROW(clip.Sample(0.0, pose), Error);
}

// ---------------------------------------------------------------- range

TEST(AnimationRange, SpansTheKeysOfAllChannels) {
  AnimationClip clip;
  clip.channels.push_back(
      MakeChannel(ChannelPath::kScale, Interpolation::kStep, {0.5f, 1.0f}, {{1, 1, 1, 0}, {1, 1, 1, 0}}));
  clip.channels.push_back(MakeChannel(ChannelPath::kTranslation, Interpolation::kStep, {0.25f, 0.75f},
                                      {glm::dvec4(0.0), glm::dvec4(0.0)}));
  clip.channels.push_back(
      MakeChannel(ChannelPath::kTranslation, Interpolation::kStep, {2.0f}, {glm::dvec4(0.0)}));
  clip.UpdateRange();
  EXPECT_DOUBLE_EQ(clip.start, 0.25);
  EXPECT_DOUBLE_EQ(clip.end, 2.0);
  EXPECT_DOUBLE_EQ(clip.duration(), 1.75);
}

TEST(AnimationRange, ClipWithoutChannelsHasAnEmptyRange) {
  AnimationClip clip;
  clip.start = 3.0;
  clip.end = 4.0;
  clip.UpdateRange();
  EXPECT_EQ(clip.start, 0.0);
  EXPECT_EQ(clip.end, 0.0);
}

// ---------------------------------------------------------------- validation

void ExpectInvalid(const AnimationClip& clip, const std::string& fragment, int nodes = 4) {
  try {
    clip.Validate(nodes, "model.gltf: animations[0]");
    FAIL() << "no error; expected one containing '" << fragment << "'";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("model.gltf: animations[0]", 0), 0u) << message;
    EXPECT_NE(message.find(fragment), std::string::npos) << message;
  }
}

TEST(AnimationValidate, AcceptsAWellFormedClip) {
  EXPECT_NO_THROW(Translation(Interpolation::kLinear).Validate(1, "x"));
  EXPECT_NO_THROW(Cubic(1.0, 2.0, 1.0f).Validate(1, "x"));
}

TEST(AnimationValidate, RejectsNodeOutOfRange) {
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kStep, {0.0f}, {{1, 1, 1, 0}}, 4)),
                "node 4 out of range (4 nodes)");
}

TEST(AnimationValidate, RejectsNegativeNode) {
  ExpectInvalid(
      OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kStep, {0.0f}, {{1, 1, 1, 0}}, -1)),
      "node -1 out of range");
}

TEST(AnimationValidate, RejectsChannelWithoutKeys) {
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kLinear, {}, {})), "no keys");
}

TEST(AnimationValidate, RejectsRepeatedKeyTime) {
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kLinear, {0.0f, 1.0f, 1.0f},
                                       {{1, 1, 1, 0}, {1, 1, 1, 0}, {1, 1, 1, 0}})),
                "not strictly increasing: key 2");
}

TEST(AnimationValidate, RejectsDecreasingKeyTimes) {
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kLinear, {1.0f, 0.5f},
                                       {{1, 1, 1, 0}, {1, 1, 1, 0}})),
                "not strictly increasing: key 1");
}

TEST(AnimationValidate, RejectsNonFiniteKeyTime) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kLinear, {0.0f, nan},
                                       {{1, 1, 1, 0}, {1, 1, 1, 0}})),
                "time of key 1 is not finite");
}

TEST(AnimationValidate, RejectsValueCountNotMatchingKeyCount) {
  ExpectInvalid(
      OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kLinear, {0.0f, 1.0f}, {{1, 1, 1, 0}})),
      "1 values for 2 keys (expected 2)");
}

TEST(AnimationValidate, RejectsCubicSplineWithoutThreeValuesPerKey) {
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kScale, Interpolation::kCubicSpline, {0.0f, 1.0f},
                                       {{1, 1, 1, 0}, {1, 1, 1, 0}})),
                "2 values for 2 keys (expected 6)");
}

TEST(AnimationValidate, RejectsNonFiniteValue) {
  const double inf = std::numeric_limits<double>::infinity();
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kTranslation, Interpolation::kLinear, {0.0f, 1.0f},
                                       {{0, 0, 0, 0}, {0, inf, 0, 0}})),
                "value 1 is not finite");
}

TEST(AnimationValidate, RejectsZeroQuaternion) {
  ExpectInvalid(OneChannel(MakeChannel(ChannelPath::kRotation, Interpolation::kLinear, {0.0f, 1.0f},
                                       {{0, 0, 0, 1}, {0, 0, 0, 0}})),
                "rotation of key 1 is the zero quaternion");
}

TEST(AnimationValidate, NamesTheOffendingChannel) {
  AnimationClip clip = Translation(Interpolation::kLinear);
  clip.channels.push_back(MakeChannel(ChannelPath::kRotation, Interpolation::kLinear, {}, {}, 2));
  ExpectInvalid(clip, "channels[1] (node 2 rotation): no keys");
}

// ---------------------------------------------------------------- morph weights

// A weights channel sets the weights of its four targets from first_target
// on, by any interpolation (component-wise, tangents for CUBICSPLINE scaled
// by the key interval), and leaves the pose alone; targets beyond the
// weights given are ignored, others keep their value.
TEST(AnimationMorphWeights, EveryInterpolationSetsItsFourTargetsAndNotThePose) {
  AnimationClip clip = OneChannel(MakeChannel(ChannelPath::kWeights, Interpolation::kStep, {0.0f, 1.0f},
                                              {{0.1, 0.2, 0.3, 0.4}, {0.9, 0.8, 0.7, 0.6}}));
  clip.channels[0].first_target = 2;
  std::vector<double> w = {5.0, 6.0, 0.0, 0.0, 0.0};  // targets 0-4: the channel drives 2-5 (5 absent)
  clip.SampleMorphWeights(0.99, w);
  EXPECT_EQ(w, (std::vector<double>{5.0, 6.0, 0.1, 0.2, 0.3}));
  clip.SampleMorphWeights(1.0, w);
  EXPECT_EQ(w, (std::vector<double>{5.0, 6.0, 0.9, 0.8, 0.7}));
  const Pose pose = SampleAt(clip, 0.5);
  EXPECT_EQ(pose[0].translation, Transform{}.translation) << "a weights channel moves no node";
  EXPECT_EQ(pose[0].scale, Transform{}.scale);

  const AnimationClip linear = OneChannel(MakeChannel(ChannelPath::kWeights, Interpolation::kLinear, {0.0f, 2.0f},
                                                      {{0.0, 1.0, 0.0, 0.0}, {1.0, 0.0, 0.0, 0.0}}));
  std::vector<double> two(2, 0.0);
  linear.SampleMorphWeights(0.5, two);
  EXPECT_DOUBLE_EQ(two[0], 0.25);
  EXPECT_DOUBLE_EQ(two[1], 0.75);

  // CUBICSPLINE: in-tangent, value, out-tangent per key; zero tangents give
  // the Hermite basis 3u^2 - 2u^3 between the values; an out-tangent adds
  // (u^3 - 2u^2 + u) x tangent x interval.
  const AnimationClip cubic = OneChannel(MakeChannel(
      ChannelPath::kWeights, Interpolation::kCubicSpline, {0.0f, 2.0f},
      {{0, 0, 0, 0}, {0.0, 0.0, 0, 0}, {0.0, 1.0, 0, 0}, {0, 0, 0, 0}, {1.0, 0.0, 0, 0}, {0, 0, 0, 0}}));
  cubic.SampleMorphWeights(1.0, two);  // u = 0.5
  EXPECT_NEAR(two[0], 0.5, 1e-12);
  EXPECT_NEAR(two[1], (0.125 - 0.5 + 0.5) * 1.0 * 2.0, 1e-12);
}

}  // namespace
}  // namespace skintune::internal
