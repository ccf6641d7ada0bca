// Small hand-made meshes shared by the reference tests.
#pragma once

#include <random>

#include "model/mesh.h"

namespace skintune::internal::testing {

// n vertices, b slots, `joints` joints; random positions, joints and weights
// that sum to 1 (normalised in double). Deterministic for a given seed.
inline SkinnedMesh RandomMesh(std::size_t n, int b, int joints, unsigned seed = 1, bool normals = false) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coord(-2.0f, 2.0f);
  std::uniform_real_distribution<float> weight(0.05f, 1.0f);
  std::uniform_int_distribution<int> joint(0, joints - 1);
  SkinnedMesh m;
  m.name = "random";
  m.influences = b;
  m.joint_count = joints;
  for (std::size_t v = 0; v < n; ++v) {
    m.positions.push_back({coord(rng), coord(rng), coord(rng)});
    if (normals) m.normals.push_back(glm::normalize(glm::vec3(coord(rng), coord(rng), coord(rng)) + 1e-3f));
    double sum = 0;
    std::vector<float> w(b);
    for (float& x : w) sum += (x = weight(rng));
    for (int i = 0; i < b; ++i) {
      m.joints.push_back(static_cast<std::uint16_t>(joint(rng)));
      m.weights.push_back(static_cast<float>(w[i] / sum));
    }
  }
  return m;
}

}  // namespace skintune::internal::testing
