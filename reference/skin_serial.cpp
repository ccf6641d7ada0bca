// The paper's serial CPU baseline: float32, one thread, the straightforward
// loop over array-of-structures data. Kept deliberately plain: it is the
// denominator of every speedup skintune reports, as in the paper.
#include "base/error.h"
#include "reference/skinning.h"

namespace skintune::internal {

void CheckSkinningArguments(const SkinnedMesh& mesh, std::size_t palette_size, std::size_t out_positions,
                            std::size_t out_normals, const char* who);

void SkinSerial(const SkinnedMesh& mesh, std::span<const glm::mat4> palette, std::span<glm::vec3> out_positions,
                std::span<glm::vec3> out_normals, std::span<glm::vec4> out_tangents) {
  CheckSkinningArguments(mesh, palette.size(), out_positions.size(), out_normals.size(), "SkinSerial");
  RequireNoMorph(mesh, "SkinSerial");
  const bool with_normals = mesh.has_normals() && !out_normals.empty();
  const bool with_tangents = mesh.has_tangents() && !out_tangents.empty();
  if (with_tangents && (mesh.tangents.size() != mesh.vertex_count() || out_tangents.size() != mesh.vertex_count()))
    throw Error("SkinSerial: tangents and their output must hold " + std::to_string(mesh.vertex_count()) + " vertices");
  const std::size_t n = mesh.vertex_count();
  const int b = mesh.influences;
  for (std::size_t v = 0; v < n; ++v) {
    glm::mat4 blended(0.0f);
    for (int i = 0; i < b; ++i) blended += mesh.weights[v * b + i] * palette[mesh.joints[v * b + i]];
    out_positions[v] = glm::vec3(blended * glm::vec4(mesh.positions[v], 1.0f));
    if (with_normals) out_normals[v] = glm::normalize(NormalMatrix(glm::mat3(blended)) * mesh.normals[v]);
    if (with_tangents) {
      const glm::mat3 a(blended);
      const float w = glm::determinant(a) < 0.0f ? -mesh.tangents[v].w : mesh.tangents[v].w;
      out_tangents[v] = glm::vec4(glm::normalize(a * glm::vec3(mesh.tangents[v])), w);
    }
  }
}

}  // namespace skintune::internal
