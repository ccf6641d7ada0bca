// The packed normal and tangent formats (docs/VARIANTS.md "Packed normals and
// tangents"): their stated bounds hold and are tight, handedness survives,
// and the words are the documented ones.
#include <cmath>
#include <cstdint>
#include <random>

#include <glm/glm.hpp>
#include <gtest/gtest.h>

#include "generator/packer.h"
#include "generator/variant.h"

namespace skintune::internal {
namespace {

constexpr NormalFormat kPacked[] = {NormalFormat::kOct16, NormalFormat::kSnorm8};

// The largest distance between a direction and its round trip, normals and
// tangents, over random directions and those on the octahedron's folds.
struct Worst {
  double normal = 0.0, tangent = 0.0;
};
Worst RoundTripError(NormalFormat format, int samples) {
  std::mt19937_64 random(20261130);
  std::normal_distribution<double> gauss;
  Worst worst;
  const auto measure = [&](glm::dvec3 d, float w) {
    d = glm::normalize(d);
    const glm::vec3 n(d);
    const glm::vec3 back = UnpackedNormal(format, PackedNormalWord(format, n));
    worst.normal = std::max(worst.normal, glm::length(glm::dvec3(back) - d));
    const glm::vec4 t = UnpackedTangent(format, PackedTangentWord(format, glm::vec4(n, w)));
    worst.tangent = std::max(worst.tangent, glm::length(glm::dvec3(t) - d));
    EXPECT_EQ(t.w, w) << "handedness of (" << d.x << ", " << d.y << ", " << d.z << ")";
  };
  for (int i = 0; i < samples; ++i) measure({gauss(random), gauss(random), gauss(random)}, i % 2 ? 1.0f : -1.0f);
  for (int i = 0; i <= 2000; ++i) {  // the folds: z = 0, x = 0, y = 0, and the poles
    const double a = 2.0 * 3.141592653589793 * i / 2000.0;
    measure({std::cos(a), std::sin(a), 0.0}, 1.0f);
    measure({std::cos(a), std::sin(a), -1e-7}, -1.0f);
    measure({0.0, std::cos(a), std::sin(a)}, 1.0f);
    measure({std::cos(a), 0.0, std::sin(a)}, -1.0f);
  }
  for (const double z : {1.0, -1.0}) measure({0.0, 0.0, z}, 1.0f);
  return worst;
}

TEST(NormalFormat, StatedBoundsHoldAndAreTightWithTheHandednessKept) {
  for (const NormalFormat format : kPacked) {
    const Worst worst = RoundTripError(format, 400000);
    EXPECT_LT(worst.normal, NormalFormatBound(format)) << Name(format);
    EXPECT_LT(worst.tangent, TangentFormatBound(format)) << Name(format);
    // Tight: a bound far above the format's real error would let a wrong kernel verify.
    EXPECT_GT(worst.normal, 0.6 * NormalFormatBound(format)) << Name(format);
    EXPECT_GT(worst.tangent, 0.6 * TangentFormatBound(format)) << Name(format);
  }
  EXPECT_EQ(NormalFormatBound(NormalFormat::kF32), 0.0);
}

TEST(NormalFormat, WordsAreTheDocumentedOnes) {
  // oct16: +z is the centre (0.5, 0.5): 32768 each (floor(0.5 * 65535 + 0.5)).
  EXPECT_EQ(PackedNormalWord(NormalFormat::kOct16, {0, 0, 1}), 32768u | 32768u << 16);
  // +x: (1, 0) -> u = 1, v = 0.5; -z folds to the corner (1, 1).
  EXPECT_EQ(PackedNormalWord(NormalFormat::kOct16, {1, 0, 0}), 65535u | 32768u << 16);
  EXPECT_EQ(PackedNormalWord(NormalFormat::kOct16, {0, 0, -1}), 65535u | 65535u << 16);
  // A tangent's y: +z, w = +1: max(0.5, 1/32767) * 0.5 + 0.5 = 0.75 -> 49151; w = -1: 0.25 -> 16384.
  EXPECT_EQ(PackedTangentWord(NormalFormat::kOct16, {0, 0, 1, 1}), 32768u | 49151u << 16);
  EXPECT_EQ(PackedTangentWord(NormalFormat::kOct16, {0, 0, 1, -1}), 32768u | 16384u << 16);
  // (0, 65535) is written (65535, 65535): -y (u = 0.5 ...) does not reach it, -x with z < 0 folded does.
  // Just off -z towards -x folds to (u, v) = (0, 1), which a +1 tangent would write (0, 65535):
  // written (65535, 65535), the same direction (Godot reserves (0, 65535)).
  EXPECT_EQ(PackedTangentWord(NormalFormat::kOct16, {-1e-6f, 0, -1, 1}), 65535u | 65535u << 16);
  EXPECT_EQ(PackedNormalWord(NormalFormat::kOct16, {-1e-6f, 0, -1}) & 0xffffu, 0u);
  // snorm8: x, y, z, w from the low byte up, 127 for 1, 0x81 for -1.
  EXPECT_EQ(PackedNormalWord(NormalFormat::kSnorm8, {1, 0, 0}), 0x0000007fu);
  EXPECT_EQ(PackedNormalWord(NormalFormat::kSnorm8, {0, -1, 0}), 0x00008100u);
  EXPECT_EQ(PackedTangentWord(NormalFormat::kSnorm8, {0, 0, 1, -1}), 0x817f0000u);
  EXPECT_EQ(PackedNormalWord(NormalFormat::kF32, {1, 0, 0}), 0u);
}

TEST(NormalFormat, TheOutputsOfAPackedVariantAreOneWordAVertex) {
  Variant v;
  v.normals = Normals::kTangents;
  v.normal_format = NormalFormat::kOct16;
  EXPECT_EQ(OutputStrideBytes(v, Output::kPositions), 16u);
  EXPECT_EQ(OutputStrideBytes(v, Output::kNormals), 4u);
  EXPECT_EQ(OutputStrideBytes(v, Output::kTangents), 4u);
  v.normal_format = NormalFormat::kF32;
  v.position = PositionFormat::kFloat3;
  EXPECT_EQ(OutputStrideBytes(v, Output::kNormals), 12u);
  EXPECT_EQ(OutputStrideBytes(v, Output::kTangents), 16u);
}

}  // namespace
}  // namespace skintune::internal
