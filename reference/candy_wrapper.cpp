#include "reference/candy_wrapper.h"

#include <cmath>
#include <numbers>

#include <glm/gtc/matrix_transform.hpp>

#include "reference/skinning.h"

namespace skintune::internal {

namespace {

constexpr int kRingVertices = 32;
constexpr int kRings = 41;  // x = 0, 0.05, ..., 2
constexpr double kRadius = 0.25;

double RingX(int ring) { return 2.0 * ring / (kRings - 1); }

// Each ring's mean distance from the x axis in `positions`, over the rest radius.
std::vector<double> RingRadii(const std::vector<glm::dvec3>& positions) {
  std::vector<double> radii(kRings, 0.0);
  for (int ring = 0; ring < kRings; ++ring) {
    for (int k = 0; k < kRingVertices; ++k) {
      const glm::dvec3& p = positions[static_cast<std::size_t>(ring * kRingVertices + k)];
      radii[static_cast<std::size_t>(ring)] += std::hypot(p.y, p.z) / kRadius / kRingVertices;
    }
  }
  return radii;
}

// The blend region's volume, from the rings' areas (radius squared), over the rest volume.
double BlendVolume(const std::vector<double>& radii) {
  double volume = 0.0, rest = 0.0;
  for (int ring = 0; ring < kRings; ++ring) {
    const double x = RingX(ring);
    if (x < 0.5 - 1e-9 || x > 1.5 + 1e-9) continue;
    volume += radii[static_cast<std::size_t>(ring)] * radii[static_cast<std::size_t>(ring)];
    rest += 1.0;
  }
  return volume / rest;
}

}  // namespace

SkinnedMesh CandyWrapperMesh() {
  SkinnedMesh mesh;
  mesh.name = "candy wrapper";
  mesh.influences = 2;
  mesh.joint_count = 2;
  for (int ring = 0; ring < kRings; ++ring) {
    const double x = RingX(ring);
    const auto w1 = static_cast<float>(std::fmin(1.0, std::fmax(0.0, x - 0.5)));
    for (int k = 0; k < kRingVertices; ++k) {
      const double phi = 2.0 * std::numbers::pi * k / kRingVertices;
      mesh.positions.emplace_back(x, kRadius * std::cos(phi), kRadius * std::sin(phi));
      mesh.joints.insert(mesh.joints.end(), {0, 1});
      mesh.weights.insert(mesh.weights.end(), {1.0f - w1, w1});
    }
  }
  return mesh;
}

std::vector<CandyWrapperPoint> CandyWrapper(const std::vector<double>& twist_degrees) {
  const SkinnedMesh mesh = CandyWrapperMesh();
  std::vector<CandyWrapperPoint> points;
  for (const double degrees : twist_degrees) {
    const std::vector<glm::mat4> palette = {
        glm::mat4(1.0f),
        glm::rotate(glm::mat4(1.0f), static_cast<float>(degrees * std::numbers::pi / 180.0), glm::vec3(1, 0, 0))};
    const std::vector<double> linear = RingRadii(SkinGold(mesh, palette).positions);
    const std::vector<double> dq = RingRadii(SkinGoldDualQuaternion(mesh, palette).positions);
    const std::size_t middle = kRings / 2;
    points.push_back({degrees, linear[middle], dq[middle], BlendVolume(linear), BlendVolume(dq)});
  }
  return points;
}

}  // namespace skintune::internal
