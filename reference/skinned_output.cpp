// skintune: finiteness of palettes and skinned output (reference/skinning.h).
//
// A NaN or infinite output is never written, read back or compared as if it
// were a result: it is an error that names where it came from.
#include <cmath>
#include <cstdio>

#include "base/error.h"
#include "reference/skinning.h"

namespace skintune::internal {

namespace {

std::string Number(double v) {
  char text[40];
  std::snprintf(text, sizeof text, "%.9g", v);
  return text;
}

std::string Vector(const glm::vec3& v) { return "(" + Number(v.x) + ", " + Number(v.y) + ", " + Number(v.z) + ")"; }

bool Finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// "joints 3, 5 with weights 0.75, 0.25" of vertex v (its non-zero slots).
std::string Influences(const SkinnedMesh& mesh, std::size_t v) {
  if (mesh.influences <= 0 || mesh.joints.size() < (v + 1) * mesh.influences ||
      mesh.weights.size() < (v + 1) * mesh.influences)
    return "";
  std::string joints, weights;
  for (int i = 0; i < mesh.influences; ++i) {
    const std::size_t slot = v * static_cast<std::size_t>(mesh.influences) + static_cast<std::size_t>(i);
    if (mesh.weights[slot] == 0.0f) continue;
    joints += (joints.empty() ? "" : ", ") + std::to_string(mesh.joints[slot]);
    weights += (weights.empty() ? "" : ", ") + Number(mesh.weights[slot]);
  }
  return joints.empty() ? "" : " (joints " + joints + " with weights " + weights + ")";
}

}  // namespace

std::size_t FirstNonFinite(std::span<const glm::vec3> values) {
  for (std::size_t v = 0; v < values.size(); ++v)
    if (!Finite(values[v])) return v;
  return values.size();
}

std::size_t FirstNonFinite(std::span<const glm::vec4> values) {
  for (std::size_t v = 0; v < values.size(); ++v)
    if (!Finite(glm::vec3(values[v])) || !std::isfinite(values[v].w)) return v;
  return values.size();
}

void CheckPaletteFinite(std::span<const glm::mat4> palette, const std::string& context) {
  for (std::size_t j = 0; j < palette.size(); ++j)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!std::isfinite(palette[j][c][r]))
          throw Error(context + ": palette matrix " + std::to_string(j) + " element [" + std::to_string(c) + "][" +
                      std::to_string(r) + "] is " + Number(palette[j][c][r]) + ": a palette entry must be finite");
}

void CheckSkinnedOutput(const SkinnedMesh& mesh, std::span<const glm::vec3> positions,
                        std::span<const glm::vec3> normals, const std::string& context) {
  for (const auto& [values, what] : {std::pair{positions, "position"}, std::pair{normals, "normal"}}) {
    const std::size_t v = FirstNonFinite(values);
    if (v == values.size()) continue;
    throw Error(context + ": skinned " + what + " of vertex " + std::to_string(v) + " is " + Vector(values[v]) +
                ", not finite" + Influences(mesh, v) +
                ": its palette entries times its rest " + what + " overflow float32; nothing written");
  }
}

}  // namespace skintune::internal
