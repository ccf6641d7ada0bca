// skintune: CPU linear blend skinning, three ways.
//
//   v' = sum_i w_i * M[d_i] * v            (positions)
//   n' = normalize(N(A) * n), A = upper3x3(sum_i w_i * M[d_i])   (normals)
//
// N(A) is the normal matrix, the inverse transpose of A up to its positive
// length: sign(det A) * cofactor(A) (NormalMatrix below). The plain upper
// 3x3 turns a normal off its surface under non-uniform scale or shear: up to
// 0.41 rad on a joint scaled (1.7, 1, 0.6). The cofactor needs no inverse,
// so a singular A (a blend that flattens the surface) still gives a
// direction; the sign keeps a mirrored surface's normal on its side, as the
// inverse transpose does.
//   t' = (normalize(A * t.xyz), t.w * sign(det A))   (tangents: they follow the
//        surface, so the plain 3x3; a mirror flips the handedness)
//
// - SkinGold:   float64 throughout; the reference every correctness check uses.
//               (SkinGoldDualQuaternion: the same for dual-quaternion skinning.)
// - SkinSerial: the paper's serial baseline: float32, one thread, a plain loop
//               over the mesh's array-of-structures data (blend the matrices,
//               then transform). The denominator of every speedup.
// - FastSkinner: the honest CPU competitor: structure-of-arrays copy of the
//               mesh made once, the CPU kernel family's kernel for its
//               influence count (cpu_kernels/cpu_kernels.h: AVX-512 / AVX2 /
//               baseline tables chosen at run time, streaming stores), all
//               cores through a persistent thread pool.
//
// Morph targets: the golds skin the mesh with its morph targets applied at
// their weights in float64 (MorphedPosition, model/mesh.h), as the kernels of
// variants that skin morph targets do before skinning.
//
// Preconditions: palette.size() == mesh.joint_count and output spans of
// vertex_count() elements (violations throw Error). SkinGold and FastSkinner's
// constructor also Validate() the mesh and throw on any problem; SkinSerial,
// being the timed baseline, checks only array sizes: validate the mesh once
// before calling it per frame. Normals are skinned only when the mesh has them
// and an output span for them is given.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "model/mesh.h"

namespace skintune::internal {

// sign(det a) * cofactor(a) for a glm 3x3 (float or double): its columns are
// the cross products of a's columns c1 x c2, c2 x c0, c0 x c1, and det a =
// c0 . (c1 x c2); +1 where det a is 0.
template <typename M3>
M3 NormalMatrix(const M3& a) {
  const M3 cofactor(glm::cross(a[1], a[2]), glm::cross(a[2], a[0]), glm::cross(a[0], a[1]));
  return glm::dot(a[0], cofactor[0]) < 0 ? -cofactor : cofactor;
}

struct GoldResult {
  std::vector<glm::dvec3> positions;
  std::vector<glm::dvec3> normals;   // empty unless requested and present
  std::vector<glm::dvec4> tangents;  // empty unless requested and present
};

GoldResult SkinGold(const SkinnedMesh& mesh, std::span<const glm::mat4> palette,
                    bool with_normals = false, bool with_tangents = false);

// The gold's outputs from each vertex's affine map (SkinGold's blended matrix,
// SkinGoldDualQuaternion's R_b S_b and t_b): positions by the map, normals by
// its 3x3's NormalMatrix, tangents by its 3x3 (a mirror flipping their
// handedness). Validates the mesh and the palette's size as `who`.
GoldResult GoldOfMaps(const SkinnedMesh& mesh, std::size_t palette_size, bool with_normals, bool with_tangents,
                      const char* who, const std::function<glm::dmat4(std::size_t)>& map_of);

// The float64 gold of dual-quaternion skinning (reference/skin_dual_quaternion.cpp):
// the joints' rotations and translations blended as unit dual quaternions
// (antipodality against the first influence), their scale and shear (A = R S)
// blended linearly first (Kavan et al.'s two-phase method). Throws Error
// naming a joint whose matrix is not an invertible affine map.
GoldResult SkinGoldDualQuaternion(const SkinnedMesh& mesh, std::span<const glm::mat4> palette,
                                  bool with_normals = false, bool with_tangents = false);

// Throws Error("<who>: <where>: the morph targets move vertices ...") for a
// mesh whose morph targets move it (MorphTargets::MovesVertices): SkinSerial
// and FastSkinner skin the mesh as it is; apply the targets first
// (MorphApplied). The golds apply them.
void RequireNoMorph(const SkinnedMesh& mesh, const char* who);

// Tangents are skinned when the mesh has them and out_tangents is given.
void SkinSerial(const SkinnedMesh& mesh, std::span<const glm::mat4> palette,
                std::span<glm::vec3> out_positions, std::span<glm::vec3> out_normals = {},
                std::span<glm::vec4> out_tangents = {});

class FastSkinner {
 public:
  // threads = 0: std::thread::hardware_concurrency().
  explicit FastSkinner(const SkinnedMesh& mesh, unsigned threads = 0);
  ~FastSkinner();
  FastSkinner(const FastSkinner&) = delete;
  FastSkinner& operator=(const FastSkinner&) = delete;

  void Run(std::span<const glm::mat4> palette, std::span<glm::vec3> out_positions,
           std::span<glm::vec3> out_normals = {});

  unsigned threads() const;
  std::size_t vertex_count() const;
  int influences() const;
  // Bytes one Run() must move through memory: SoA inputs read + outputs written
  // (positions; normals too when `with_normals`), excluding the palette.
  std::size_t BytesPerRun(bool with_normals) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Error of `actual` against the gold, per vertex: |a - g| / max(|g|, floor),
// where floor = 1e-3 * (largest |g| of the mesh), so vertices near the origin
// do not inflate it. Also the largest absolute error and its vertex.
struct GoldComparison {
  double max_relative = 0.0;
  double max_absolute = 0.0;
  std::size_t worst_vertex = 0;
  std::size_t non_finite = 0;  // NaN/inf outputs (count as failures)
  std::size_t wrong_handedness = 0;  // tangents whose w differs from the gold's (count as failures)
};

GoldComparison CompareToGold(std::span<const glm::dvec3> gold, std::span<const glm::vec3> actual);
// Tangents: xyz as CompareToGold does, and each w (the handedness, +-1)
// exactly; worst_vertex is the first wrong w where there is one.
GoldComparison CompareTangentsToGold(std::span<const glm::dvec4> gold, std::span<const glm::vec4> actual);

// The largest Euclidean distance between a[v] and b[v] (two golds: what a
// weight quantisation moves the result). Throws Error for different sizes.
double MaxDistance(std::span<const glm::dvec3> a, std::span<const glm::dvec3> b);

// The diagonal of the axis-aligned bounding box of `points` (0 for none):
// the mesh's scale, which errors "relative to the diagonal" divide by.
double BoundingBoxDiagonal(std::span<const glm::vec3> points);

// Finiteness (reference/skinned_output.cpp): a NaN or infinite palette entry
// or output is an error naming its origin, never a result.
//
// The first vector with a NaN or infinite component, or values.size().
std::size_t FirstNonFinite(std::span<const glm::vec3> values);
std::size_t FirstNonFinite(std::span<const glm::vec4> values);  // tangents: w too
// Throws Error("<context>: palette matrix J element [c][r] is nan: ...") for
// the first element that is not finite (a palette from outside: an engine's,
// a file's; Skeleton::Palette checks its own with the joint's node).
void CheckPaletteFinite(std::span<const glm::mat4> palette, const std::string& context);
// Throws Error("<context>: skinned position of vertex V is (x, y, z), not
// finite (joints ... with weights ...): ...") for the first non-finite
// position, then normal. Every writer of skinned output calls it first.
void CheckSkinnedOutput(const SkinnedMesh& mesh, std::span<const glm::vec3> positions,
                        std::span<const glm::vec3> normals, const std::string& context);

}  // namespace skintune::internal
