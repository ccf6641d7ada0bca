// The float64 gold of dual-quaternion skinning (Kavan et al. 2007), with the
// two-phase method for joints that scale or shear: each joint's 3x3 A = R S
// (R a rotation, S the rest: scale, shear, a mirror), the rigid part (R, t)
// as a unit dual quaternion. Per vertex, the S are blended linearly and the
// dual quaternions (each made antipodal-consistent with the first
// influence's) blended and normalised: each vertex's map is the affine
// (R_b S_b, t_b), skinned by GoldOfMaps as the linear gold's blended matrix:
//   v' = R_b (S_b v) + t_b,  n' = normalize(N(R_b S_b) n) = normalize(R_b N(S_b) n),
//   t' = R_b S_b t   (N: reference/skinning.h NormalMatrix). For rigid joints S = I and this is
// plain dual-quaternion skinning: no volume lost at twisting joints.
#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtx/dual_quaternion.hpp>
#include <glm/gtx/matrix_decompose.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "base/error.h"
#include "reference/skinning.h"

namespace skintune::internal {

void CheckSkinningArguments(const SkinnedMesh& mesh, std::size_t palette_size, std::size_t out_positions,
                            std::size_t out_normals, const char* who);

namespace {

struct JointParts {
  glm::ddualquat rigid;  // R and t
  glm::dmat3 rest;       // S = R^T A
};

// Throws Error naming the joint for a matrix with no affine decomposition
// (singular, or a projective last row).
std::vector<JointParts> Decompose(std::span<const glm::mat4> palette) {
  std::vector<JointParts> parts;
  for (std::size_t j = 0; j < palette.size(); ++j) {
    const glm::dmat4 m(palette[j]);
    glm::dvec3 scale, translation, skew;
    glm::dquat rotation;
    glm::dvec4 perspective;
    if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0 ||
        !glm::decompose(m, scale, rotation, translation, skew, perspective))
      throw Error("SkinGoldDualQuaternion: joint " + std::to_string(j) +
                  ": not an invertible affine matrix (no rotation and translation to take from it)");
    rotation = glm::normalize(rotation);
    const glm::dmat3 r = glm::mat3_cast(rotation);
    parts.push_back({glm::ddualquat(rotation, glm::dvec3(m[3])), glm::transpose(r) * glm::dmat3(m)});
  }
  return parts;
}

}  // namespace

GoldResult SkinGoldDualQuaternion(const SkinnedMesh& mesh, std::span<const glm::mat4> palette, bool with_normals,
                                  bool with_tangents) {
  // A palette of the wrong size is GoldOfMaps's to name, before any joint is decomposed.
  CheckSkinningArguments(mesh, palette.size(), mesh.vertex_count(), 0, "SkinGoldDualQuaternion");
  const std::vector<JointParts> joints = Decompose(palette);
  const int b = mesh.influences;
  // Each vertex's map: R_b S_b and t_b (the normal matrix of R_b S_b is R_b N(S_b)).
  return GoldOfMaps(mesh, palette.size(), with_normals, with_tangents, "SkinGoldDualQuaternion", [&](std::size_t v) {
    glm::ddualquat blended(glm::dquat(0.0, 0.0, 0.0, 0.0), glm::dquat(0.0, 0.0, 0.0, 0.0));
    glm::dmat3 rest(0.0);
    // Antipodality against the first slot's rotation, whatever its weight
    // (the kernels' rule, docs/VARIANTS.md "Dual quaternions"; exporters put
    // the largest weight first).
    const glm::dquat* pivot = &joints[mesh.joints[v * b]].rigid.real;
    for (int i = 0; i < b; ++i) {
      const double w = mesh.weights[v * b + i];
      if (w == 0.0) continue;
      const JointParts& joint = joints[mesh.joints[v * b + i]];
      const double sign = glm::dot(*pivot, joint.rigid.real) < 0.0 ? -1.0 : 1.0;
      blended.real = blended.real + (sign * w) * joint.rigid.real;
      blended.dual = blended.dual + (sign * w) * joint.rigid.dual;
      rest += w * joint.rest;
    }
    const double length = glm::length(blended.real);
    blended.real = blended.real / length;
    blended.dual = blended.dual / length;
    const glm::dquat t = 2.0 * (blended.dual * glm::conjugate(blended.real));
    glm::dmat4 map(glm::mat3_cast(blended.real) * rest);
    map[3] = glm::dvec4(t.x, t.y, t.z, 1.0);
    return map;
  });
}

}  // namespace skintune::internal
