// skintune: the skinned mesh (offline data model) and its validation.
//
// A SkinnedMesh holds rest (bind-pose) positions, optional normals, and for
// every vertex `influences` (B, 1..8) slots of (joint index, weight), stored
// interleaved per vertex: slot i of vertex v is at [v * influences + i].
// Vertices that need fewer than B bones have zero weights in their trailing
// slots (their joint index is then 0 and ignored). This is the layout of the
// paper's serial baseline (array of structures).
//
// The palette (one 4x4 affine matrix per joint, already multiplied by the
// inverse bind matrix) is not part of the mesh: it changes every frame.
//
// Nothing in skintune silently fixes bad data: Validate() reports every
// problem; Renormalize() is the one explicit fix, and says what it changed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace skintune::internal {

inline constexpr int kMaxInfluences = 8;
// |sum(weights) - 1| allowed per vertex. float32 weights that were normalised
// in float32 are within ~1e-6; glTF unorm8 weights that sum to 255 are exact;
// 1e-3 leaves room for weights written with a few decimals in text formats.
inline constexpr double kWeightSumTolerance = 1e-3;
// The most vertices a mesh may have: kernels index vertices with uint32 (K
// instances x vertices too) and a .stv file counts them in a uint32: 2^32 - 1.
inline constexpr std::uint64_t kMaxVertexCount = 0xffffffffull;
// The most morph targets a mesh may have (a face rig has tens to a hundred or so).
inline constexpr int kMaxMorphTargets = 256;

// The mesh's morph targets (glTF `targets`): per target, a position (and
// normal, tangent xyz) offset per vertex, zero where a primitive has none;
// applied before skinning at `weights`: p = p0 + sum_k w_k dp_k (normals and
// tangents likewise, renormalised after skinning). Kernels whose variant
// skins morph targets read them; everything else must refuse a mesh whose
// targets move vertices (MovesVertices).
struct MorphTargets {
  std::vector<std::vector<glm::vec3>> positions;  // [target][vertex]
  std::vector<std::vector<glm::vec3>> normals;    // [target][vertex]; empty without normals
  std::vector<std::vector<glm::vec3>> tangents;   // [target][vertex] (xyz offsets); empty without tangents
  // The weights the mesh is skinned with (glTF: the node's, else the mesh's,
  // else 0; an animation frame's once sampled). One per target.
  std::vector<double> weights;
  std::string where;  // e.g. "meshes[0].primitives[0].targets"
  std::size_t count() const { return positions.size(); }
  // Whether some target with a non-zero weight has a non-zero offset.
  bool MovesVertices() const;
};

struct SkinnedMesh {
  std::string name;
  int influences = 0;                  // B: slots per vertex, 1..kMaxInfluences
  int joint_count = 0;                 // palette size the joint indices refer to
  std::vector<glm::vec3> positions;    // rest pose, one per vertex
  std::vector<glm::vec3> normals;      // empty, or one per vertex
  // Empty, or one per vertex: xyz a unit tangent, w its handedness (+1 or
  // -1: the bitangent is w * cross(normal, tangent), glTF's TANGENT).
  std::vector<glm::vec4> tangents;
  std::vector<std::uint16_t> joints;   // vertex_count() * influences
  std::vector<float> weights;          // vertex_count() * influences
  MorphTargets morph;                  // none, or applied before skinning (see MorphTargets)

  std::size_t vertex_count() const { return positions.size(); }
  bool has_normals() const { return !normals.empty(); }
  bool has_tangents() const { return !tangents.empty(); }
  bool has_morph() const { return morph.count() > 0; }
  // Number of slots of vertex v with a non-zero weight.
  int InfluencesOf(std::size_t v) const;
};

enum class MeshProblem {
  kBadInfluenceCount,   // influences outside 1..kMaxInfluences
  kNoJoints,            // joint_count == 0
  kNoVertices,          // empty mesh
  kLengthMismatch,      // normals/tangents/joints/weights/morph arrays do not match the vertex count
  kNonFinitePosition,   // NaN or infinite position, normal, tangent, morph offset or weight, or a handedness not +-1
  kJointOutOfRange,     // joint index >= joint_count (any slot: kernels read every slot)
  kBadWeight,           // negative or NaN/infinite weight
  kZeroWeights,         // every weight of a vertex is zero (cannot be renormalised)
  kWeightSum,           // |sum - 1| > tolerance (renormalisable)
};

struct MeshIssue {
  MeshProblem problem;
  std::size_t vertex = 0;  // vertex concerned (0 for mesh-level problems)
  int slot = -1;           // influence slot concerned, or -1
  std::string message;     // complete, e.g. "vertex 12 slot 3: joint 80 out of range (77 joints)"
};

struct ValidateOptions {
  double weight_sum_tolerance = kWeightSumTolerance;
  // Stop after this many issues (a bad file can have millions). Counting goes on.
  std::size_t max_issues = 20;
};

struct ValidationReport {
  std::vector<MeshIssue> issues;  // at most max_issues, in vertex order
  std::size_t total_issues = 0;   // all problems found
  std::size_t weight_sum_issues = 0;  // of which kWeightSum (renormalisable)
  bool ok() const { return total_issues == 0; }
  // Only weight-sum problems: Renormalize() would make the mesh valid.
  bool renormalisable() const { return total_issues > 0 && total_issues == weight_sum_issues; }
  // One line: the first issue plus "(and N more)".
  std::string Summary() const;
};

ValidationReport Validate(const SkinnedMesh& mesh, const ValidateOptions& options = {});

// Throws Error("<context>: <summary>") unless the mesh is valid.
void ThrowIfInvalid(const SkinnedMesh& mesh, const std::string& context,
                    const ValidateOptions& options = {});

struct RenormalizeReport {
  std::size_t changed_vertices = 0;  // vertices whose sum was outside tolerance
  std::size_t worst_vertex = 0;      // the vertex whose sum was furthest from 1
  double worst_sum = 1.0;            // its sum before renormalisation
};

// Divides the weights of every vertex whose sum is outside `tolerance` by that
// sum. Throws Error if any vertex has a negative/NaN weight or all-zero weights:
// those cannot be renormalised.
RenormalizeReport Renormalize(SkinnedMesh& mesh, double tolerance = kWeightSumTolerance);

// Sorts each vertex's slots by descending weight and drops trailing all-zero
// slots mesh-wide, so `influences` becomes the largest per-vertex count (>= 1).
// When a vertex has more than `max_influences` non-zero weights, the smallest
// are dropped and the rest renormalised; the count of such vertices is returned.
std::size_t CompactInfluences(SkinnedMesh& mesh, int max_influences = kMaxInfluences);

// `mesh` with its morph targets applied at their weights, in float64 then
// rounded once to float32, and no targets left (the mesh itself where it has
// none).
SkinnedMesh MorphApplied(const SkinnedMesh& mesh);
// The float64 morphed position / normal / tangent xyz of vertex v (the
// gold's source: the offsets at the targets' weights, summed in target order).
glm::dvec3 MorphedPosition(const SkinnedMesh& mesh, std::size_t v);
glm::dvec3 MorphedNormal(const SkinnedMesh& mesh, std::size_t v);
glm::dvec3 MorphedTangent(const SkinnedMesh& mesh, std::size_t v);

// Histogram: result[k] = number of vertices with k non-zero weights (k = 0..influences).
std::vector<std::size_t> InfluenceHistogram(const SkinnedMesh& mesh);

}  // namespace skintune::internal
