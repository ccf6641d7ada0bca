// The float64 gold: the reference every kernel variant is checked against.
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include "base/error.h"
#include "reference/skinning.h"
#include "base/thread_pool.h"

namespace skintune::internal {

namespace {
// Vertices per chunk of the gold and its comparisons on the reference pool.
constexpr std::size_t kGoldGrain = 16384;
}  // namespace

void CheckSkinningArguments(const SkinnedMesh& mesh, std::size_t palette_size, std::size_t out_positions,
                            std::size_t out_normals, const char* who) {
  if (palette_size != static_cast<std::size_t>(mesh.joint_count)) {
    throw Error(std::string(who) + ": palette has " + std::to_string(palette_size) + " matrices, mesh has " +
                std::to_string(mesh.joint_count) + " joints");
  }
  const std::size_t n = mesh.vertex_count();
  if (out_positions != n || (out_normals != 0 && out_normals != n)) {
    throw Error(std::string(who) + ": output spans must hold " + std::to_string(n) + " vertices");
  }
  const std::size_t slots = n * static_cast<std::size_t>(std::max(mesh.influences, 0));
  if (mesh.influences < 1 || mesh.influences > kMaxInfluences || mesh.joints.size() != slots ||
      mesh.weights.size() != slots || (mesh.has_normals() && mesh.normals.size() != n)) {
    throw Error(std::string(who) + ": malformed mesh: " + Validate(mesh).Summary());
  }
}

void RequireNoMorph(const SkinnedMesh& mesh, const char* who) {
  if (!mesh.morph.MovesVertices()) return;
  throw Error(std::string(who) + ": " + (mesh.morph.where.empty() ? "the morph targets" : mesh.morph.where) +
              ": the morph targets move vertices, which " + who + " does not apply: apply them first (MorphApplied)");
}

GoldResult GoldOfMaps(const SkinnedMesh& mesh, std::size_t palette_size, bool with_normals, bool with_tangents,
                      const char* who, const std::function<glm::dmat4(std::size_t)>& map_of) {
  ThrowIfInvalid(mesh, who);
  CheckSkinningArguments(mesh, palette_size, mesh.vertex_count(), 0, who);
  with_normals = with_normals && mesh.has_normals();
  with_tangents = with_tangents && mesh.has_tangents();
  const std::size_t n = mesh.vertex_count();
  GoldResult result;
  result.positions.resize(n);
  if (with_normals) result.normals.resize(n);
  if (with_tangents) result.tangents.resize(n);
  ParallelChunks(n, kGoldGrain, [&](std::size_t first, std::size_t last) {
    for (std::size_t v = first; v < last; ++v) {
      const glm::dmat4 map = map_of(v);
      const glm::dmat3 a(map);
      result.positions[v] = glm::dvec3(map * glm::dvec4(MorphedPosition(mesh, v), 1.0));
      if (with_normals) {
        const glm::dvec3 n3 = NormalMatrix(a) * MorphedNormal(mesh, v);
        const double len = glm::length(n3);
        result.normals[v] = len > 0.0 ? n3 / len : n3;
      }
      if (with_tangents) {
        const glm::dvec3 t3 = a * MorphedTangent(mesh, v);
        const double len = glm::length(t3);
        const double handedness = glm::determinant(a) < 0.0 ? -mesh.tangents[v].w : mesh.tangents[v].w;
        result.tangents[v] = glm::dvec4(len > 0.0 ? t3 / len : t3, handedness);
      }
    }
  });
  return result;
}

GoldResult SkinGold(const SkinnedMesh& mesh, std::span<const glm::mat4> palette, bool with_normals,
                    bool with_tangents) {
  const int b = mesh.influences;
  return GoldOfMaps(mesh, palette.size(), with_normals, with_tangents, "SkinGold", [&](std::size_t v) {
    glm::dmat4 blended(0.0);
    for (int i = 0; i < b; ++i) {
      const double w = mesh.weights[v * b + i];
      if (w != 0.0) blended += w * glm::dmat4(palette[mesh.joints[v * b + i]]);
    }
    return blended;
  });
}

GoldComparison CompareToGold(std::span<const glm::dvec3> gold, std::span<const glm::vec3> actual) {
  if (gold.size() != actual.size()) {
    throw Error("CompareToGold: " + std::to_string(actual.size()) + " values against a gold of " +
                std::to_string(gold.size()));
  }
  // Per chunk, then merged in chunk order: the same result as one pass (the
  // first non-finite vertex, else the first vertex of the largest error).
  const std::size_t n = gold.size();
  const std::size_t chunks = (n + kGoldGrain - 1) / kGoldGrain;
  std::vector<double> largest_of(chunks, 0.0);
  ParallelChunks(n, kGoldGrain, [&](std::size_t first, std::size_t last) {
    double largest = 0.0;
    for (std::size_t v = first; v < last; ++v) largest = std::max(largest, glm::length(gold[v]));
    largest_of[first / kGoldGrain] = largest;
  });
  const double largest = chunks ? *std::max_element(largest_of.begin(), largest_of.end()) : 0.0;
  const double floor = std::max(1e-3 * largest, 1e-30);
  std::vector<GoldComparison> of(chunks);
  ParallelChunks(n, kGoldGrain, [&](std::size_t first, std::size_t last) {
    GoldComparison& c = of[first / kGoldGrain];
    c.worst_vertex = first;
    for (std::size_t v = first; v < last; ++v) {
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
  });
  GoldComparison c;
  for (const GoldComparison& part : of) {
    if (part.non_finite > 0 && c.non_finite == 0) c.worst_vertex = part.worst_vertex;
    if (c.non_finite == 0 && part.non_finite == 0 && part.max_relative > c.max_relative) c.worst_vertex = part.worst_vertex;
    c.non_finite += part.non_finite;
    c.max_relative = std::max(c.max_relative, part.max_relative);
    c.max_absolute = std::max(c.max_absolute, part.max_absolute);
  }
  if (c.non_finite > 0) c.max_relative = std::numeric_limits<double>::infinity();
  return c;
}

GoldComparison CompareTangentsToGold(std::span<const glm::dvec4> gold, std::span<const glm::vec4> actual) {
  if (gold.size() != actual.size()) {
    throw Error("CompareTangentsToGold: " + std::to_string(actual.size()) + " values against a gold of " +
                std::to_string(gold.size()));
  }
  std::vector<glm::dvec3> gold_xyz(gold.size());
  std::vector<glm::vec3> actual_xyz(actual.size());
  for (std::size_t v = 0; v < gold.size(); ++v) gold_xyz[v] = glm::dvec3(gold[v]), actual_xyz[v] = glm::vec3(actual[v]);
  GoldComparison c = CompareToGold(gold_xyz, actual_xyz);
  for (std::size_t v = 0; v < gold.size(); ++v) {
    if (static_cast<double>(actual[v].w) == gold[v].w) continue;
    if (c.wrong_handedness++ == 0 && c.non_finite == 0) c.worst_vertex = v;
  }
  return c;
}

double MaxDistance(std::span<const glm::dvec3> a, std::span<const glm::dvec3> b) {
  if (a.size() != b.size())
    throw Error("MaxDistance: " + std::to_string(a.size()) + " values against " + std::to_string(b.size()));
  double largest = 0.0;
  for (std::size_t v = 0; v < a.size(); ++v) largest = std::max(largest, glm::length(a[v] - b[v]));
  return largest;
}

double BoundingBoxDiagonal(std::span<const glm::vec3> points) {
  if (points.empty()) return 0.0;
  glm::dvec3 lo(points.front()), hi(points.front());
  for (const glm::vec3& p : points) {
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  return glm::length(hi - lo);
}

}  // namespace skintune::internal
