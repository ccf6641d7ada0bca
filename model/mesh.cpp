#include "model/mesh.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>

#include "base/error.h"

namespace skintune::internal {

int SkinnedMesh::InfluencesOf(std::size_t v) const {
  int count = 0;
  for (int i = 0; i < influences; ++i) count += weights[v * influences + i] != 0.0f ? 1 : 0;
  return count;
}

namespace {

class IssueCollector {
 public:
  explicit IssueCollector(ValidationReport& report, const ValidateOptions& options)
      : report_(report), options_(options) {}
  void Add(MeshProblem problem, std::size_t vertex, int slot, std::string message) {
    ++report_.total_issues;
    if (problem == MeshProblem::kWeightSum) ++report_.weight_sum_issues;
    if (report_.issues.size() < options_.max_issues)
      report_.issues.push_back({problem, vertex, slot, std::move(message)});
  }

 private:
  ValidationReport& report_;
  const ValidateOptions& options_;
};

std::string VertexSlot(std::size_t v, int slot) {
  std::ostringstream s;
  s << "vertex " << v;
  if (slot >= 0) s << " slot " << slot;
  return s.str();
}

bool Finite(const glm::vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// The morph targets' sizes against the mesh, and their finiteness (each
// problem once per stream, naming the first target and vertex).
void CheckMorph(const SkinnedMesh& mesh, IssueCollector& out) {
  const MorphTargets& m = mesh.morph;
  if (m.count() == 0 && m.weights.empty() && m.normals.empty() && m.tangents.empty()) return;
  const std::string where = m.where.empty() ? std::string("morph targets") : m.where;
  const std::size_t n = mesh.vertex_count();
  if (m.count() > static_cast<std::size_t>(kMaxMorphTargets))
    out.Add(MeshProblem::kLengthMismatch, 0, -1,
            where + ": " + std::to_string(m.count()) + " targets, more than the " + std::to_string(kMaxMorphTargets) +
                " a mesh may have");
  if (m.weights.size() != m.count())
    out.Add(MeshProblem::kLengthMismatch, 0, -1,
            where + ": " + std::to_string(m.weights.size()) + " weights for " + std::to_string(m.count()) + " targets");
  for (std::size_t k = 0; k < m.weights.size(); ++k)
    if (!std::isfinite(m.weights[k])) {
      out.Add(MeshProblem::kNonFinitePosition, 0, -1, where + ": weight " + std::to_string(k) + " is not finite");
      break;
    }
  const auto check = [&](const std::vector<std::vector<glm::vec3>>& offsets, const char* what, bool mesh_has) {
    if (offsets.empty()) return;
    if (!mesh_has || offsets.size() != m.count()) {
      out.Add(MeshProblem::kLengthMismatch, 0, -1,
              where + ": " + std::to_string(offsets.size()) + " targets of " + what + " offsets for " +
                  std::to_string(m.count()) + " targets" + (mesh_has ? "" : std::string(" of a mesh without ") + what));
      return;
    }
    for (std::size_t k = 0; k < offsets.size(); ++k) {
      if (offsets[k].size() != n) {
        out.Add(MeshProblem::kLengthMismatch, 0, -1,
                where + ": target " + std::to_string(k) + " has " + std::to_string(offsets[k].size()) + " " + what +
                    " offsets for " + std::to_string(n) + " vertices");
        return;
      }
      for (std::size_t v = 0; v < n; ++v)
        if (!Finite(offsets[k][v])) {
          out.Add(MeshProblem::kNonFinitePosition, v, -1,
                  where + ": target " + std::to_string(k) + " vertex " + std::to_string(v) + ": " + what +
                      " offset is not finite");
          return;
        }
    }
  };
  check(m.positions, "position", true);
  check(m.normals, "normal", mesh.has_normals());
  check(m.tangents, "tangent", mesh.has_tangents());
}

// Mesh-level shape problems; returns false when per-vertex checks cannot run.
bool CheckShape(const SkinnedMesh& mesh, IssueCollector& out) {
  bool per_vertex_ok = true;
  if (mesh.influences < 1 || mesh.influences > kMaxInfluences) {
    out.Add(MeshProblem::kBadInfluenceCount, 0, -1,
            "influences per vertex is " + std::to_string(mesh.influences) + " (allowed 1.." +
                std::to_string(kMaxInfluences) + ")");
    per_vertex_ok = false;
  }
  if (mesh.joint_count <= 0) out.Add(MeshProblem::kNoJoints, 0, -1, "the mesh has no joints");
  if (mesh.vertex_count() == 0) out.Add(MeshProblem::kNoVertices, 0, -1, "the mesh has no vertices");
  const std::size_t n = mesh.vertex_count();
  if (!mesh.normals.empty() && mesh.normals.size() != n) {
    out.Add(MeshProblem::kLengthMismatch, 0, -1,
            std::to_string(mesh.normals.size()) + " normals for " + std::to_string(n) + " vertices");
  }
  if (!mesh.tangents.empty() && mesh.tangents.size() != n) {
    out.Add(MeshProblem::kLengthMismatch, 0, -1,
            std::to_string(mesh.tangents.size()) + " tangents for " + std::to_string(n) + " vertices");
  }
  CheckMorph(mesh, out);
  if (per_vertex_ok) {
    const std::size_t slots = n * static_cast<std::size_t>(mesh.influences);
    for (auto [name, size] : {std::pair{"joint indices", mesh.joints.size()},
                              std::pair{"weights", mesh.weights.size()}}) {
      if (size != slots) {
        std::ostringstream s;
        s << size << " " << name << " for " << n << " vertices x " << mesh.influences
          << " influences (expected " << slots << ")";
        out.Add(MeshProblem::kLengthMismatch, 0, -1, s.str());
        per_vertex_ok = false;
      }
    }
  }
  return per_vertex_ok;
}

void CheckVertex(const SkinnedMesh& mesh, std::size_t v, const ValidateOptions& options,
                 IssueCollector& out) {
  if (!Finite(mesh.positions[v]) || (mesh.has_normals() && mesh.normals.size() == mesh.vertex_count() &&
                                     !Finite(mesh.normals[v]))) {
    out.Add(MeshProblem::kNonFinitePosition, v, -1, VertexSlot(v, -1) + ": position or normal is not finite");
  }
  if (mesh.has_tangents() && mesh.tangents.size() == mesh.vertex_count()) {
    const glm::vec4& t = mesh.tangents[v];
    if (!std::isfinite(t.x) || !std::isfinite(t.y) || !std::isfinite(t.z) || (t.w != 1.0f && t.w != -1.0f))
      out.Add(MeshProblem::kNonFinitePosition, v, -1,
              VertexSlot(v, -1) + ": tangent is not finite or its handedness (w) is not +1 or -1");
  }
  const int b = mesh.influences;
  double sum = 0.0;
  bool weights_ok = true;
  for (int i = 0; i < b; ++i) {
    const float w = mesh.weights[v * b + i];
    const unsigned joint = mesh.joints[v * b + i];
    if (!std::isfinite(w) || w < 0.0f) {
      std::ostringstream s;
      s << VertexSlot(v, i) << ": weight " << w << " is " << (std::isfinite(w) ? "negative" : "not finite");
      out.Add(MeshProblem::kBadWeight, v, i, s.str());
      weights_ok = false;
      continue;
    }
    sum += w;
    if (joint >= static_cast<unsigned>(mesh.joint_count)) {
      out.Add(MeshProblem::kJointOutOfRange, v, i,
              VertexSlot(v, i) + ": joint " + std::to_string(joint) + " out of range (" +
                  std::to_string(mesh.joint_count) + " joints)");
    }
  }
  if (!weights_ok) return;
  if (sum == 0.0) {
    out.Add(MeshProblem::kZeroWeights, v, -1, VertexSlot(v, -1) + ": all weights are zero");
  } else if (std::abs(sum - 1.0) > options.weight_sum_tolerance) {
    std::ostringstream s;
    s << VertexSlot(v, -1) << ": weights sum to " << sum << " (must be 1 within "
      << options.weight_sum_tolerance << "; renormalise explicitly to accept)";
    out.Add(MeshProblem::kWeightSum, v, -1, s.str());
  }
}

}  // namespace

std::string ValidationReport::Summary() const {
  if (ok()) return "valid";
  std::string s = issues.empty() ? std::string("invalid") : issues.front().message;
  if (total_issues > 1) s += " (and " + std::to_string(total_issues - 1) + " more)";
  return s;
}

ValidationReport Validate(const SkinnedMesh& mesh, const ValidateOptions& options) {
  ValidationReport report;
  IssueCollector out(report, options);
  if (!CheckShape(mesh, out)) return report;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) CheckVertex(mesh, v, options, out);
  return report;
}

void ThrowIfInvalid(const SkinnedMesh& mesh, const std::string& context, const ValidateOptions& options) {
  const ValidationReport report = Validate(mesh, options);
  if (!report.ok()) throw Error(context + ": " + report.Summary());
}

RenormalizeReport Renormalize(SkinnedMesh& mesh, double tolerance) {
  ValidateOptions options;
  options.weight_sum_tolerance = tolerance;
  options.max_issues = 1;
  const ValidationReport report = Validate(mesh, options);
  if (report.total_issues != report.weight_sum_issues) {
    throw Error("cannot renormalise: " + report.Summary());
  }
  RenormalizeReport result;
  double worst_distance = -1.0;
  const int b = mesh.influences;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    float* w = &mesh.weights[v * b];
    const double sum = std::accumulate(w, w + b, 0.0);
    if (std::abs(sum - 1.0) <= tolerance) continue;
    ++result.changed_vertices;
    if (std::abs(sum - 1.0) > worst_distance) {
      worst_distance = std::abs(sum - 1.0);
      result.worst_vertex = v;
      result.worst_sum = sum;
    }
    for (int i = 0; i < b; ++i) w[i] = static_cast<float>(w[i] / sum);
  }
  return result;
}

std::size_t CompactInfluences(SkinnedMesh& mesh, int max_influences) {
  if (max_influences < 1 || max_influences > kMaxInfluences) {
    throw Error("CompactInfluences: max_influences " + std::to_string(max_influences) + " outside 1..8");
  }
  const int b = mesh.influences;
  const std::size_t n = mesh.vertex_count();
  if (b < 1 || mesh.joints.size() != n * b || mesh.weights.size() != n * b) {
    throw Error("CompactInfluences: " + Validate(mesh).Summary());
  }
  std::vector<std::pair<float, std::uint16_t>> slots(b);
  int widest = 1;
  std::size_t truncated = 0;
  for (std::size_t v = 0; v < n; ++v) {
    for (int i = 0; i < b; ++i) slots[i] = {mesh.weights[v * b + i], mesh.joints[v * b + i]};
    // Descending weight; ties keep the lower joint first so the order is deterministic.
    std::stable_sort(slots.begin(), slots.end(), [](const auto& a, const auto& c) { return a.first > c.first; });
    int used = 0;
    while (used < b && slots[used].first != 0.0f) ++used;
    if (used > max_influences) {
      ++truncated;
      double kept = 0.0;
      for (int i = 0; i < max_influences; ++i) kept += slots[i].first;
      for (int i = 0; i < b; ++i) slots[i].first = i < max_influences ? float(slots[i].first / kept) : 0.0f;
      used = max_influences;
    }
    widest = std::max(widest, used);
    for (int i = 0; i < b; ++i) {
      mesh.weights[v * b + i] = slots[i].first;
      mesh.joints[v * b + i] = slots[i].first != 0.0f ? slots[i].second : 0;
    }
  }
  if (widest < b) {
    std::vector<std::uint16_t> joints(n * widest);
    std::vector<float> weights(n * widest);
    for (std::size_t v = 0; v < n; ++v) {
      for (int i = 0; i < widest; ++i) {
        joints[v * widest + i] = mesh.joints[v * b + i];
        weights[v * widest + i] = mesh.weights[v * b + i];
      }
    }
    mesh.joints = std::move(joints);
    mesh.weights = std::move(weights);
    mesh.influences = widest;
  }
  return truncated;
}

std::vector<std::size_t> InfluenceHistogram(const SkinnedMesh& mesh) {
  std::vector<std::size_t> histogram(mesh.influences + 1, 0);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) ++histogram[mesh.InfluencesOf(v)];
  return histogram;
}

bool MorphTargets::MovesVertices() const {
  for (std::size_t k = 0; k < count() && k < weights.size(); ++k) {
    if (weights[k] == 0.0) continue;
    for (const auto* stream : {&positions, &normals, &tangents})
      if (k < stream->size())
        for (const glm::vec3& d : (*stream)[k])
          if (d != glm::vec3(0.0f)) return true;
  }
  return false;
}

namespace {
// Sum of w_k * offsets[k][v] in float64, in target order.
glm::dvec3 Offset(const MorphTargets& m, const std::vector<std::vector<glm::vec3>>& offsets, std::size_t v) {
  glm::dvec3 sum(0.0);
  for (std::size_t k = 0; k < offsets.size() && k < m.weights.size(); ++k)
    if (m.weights[k] != 0.0) sum += m.weights[k] * glm::dvec3(offsets[k][v]);
  return sum;
}
}  // namespace

glm::dvec3 MorphedPosition(const SkinnedMesh& mesh, std::size_t v) {
  return glm::dvec3(mesh.positions[v]) + Offset(mesh.morph, mesh.morph.positions, v);
}
glm::dvec3 MorphedNormal(const SkinnedMesh& mesh, std::size_t v) {
  return glm::dvec3(mesh.normals[v]) + Offset(mesh.morph, mesh.morph.normals, v);
}
glm::dvec3 MorphedTangent(const SkinnedMesh& mesh, std::size_t v) {
  return glm::dvec3(glm::vec3(mesh.tangents[v])) + Offset(mesh.morph, mesh.morph.tangents, v);
}

SkinnedMesh MorphApplied(const SkinnedMesh& mesh) {
  SkinnedMesh out = mesh;
  out.morph = MorphTargets{};
  if (!mesh.has_morph()) return out;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    out.positions[v] = glm::vec3(MorphedPosition(mesh, v));
    if (mesh.has_normals()) out.normals[v] = glm::vec3(MorphedNormal(mesh, v));
    if (mesh.has_tangents()) out.tangents[v] = glm::vec4(glm::vec3(MorphedTangent(mesh, v)), mesh.tangents[v].w);
  }
  return out;
}

}  // namespace skintune::internal
