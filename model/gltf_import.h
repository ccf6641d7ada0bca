// skintune: glTF 2.0 (.gltf / .glb) import of a skinned mesh, its skin and its
// animations, through tinygltf (Debian's libtinygltf-dev).
//
// What is read: the first skinned mesh (a node with both `mesh` and `skin`),
// or the one named in GltfImportOptions::mesh (node name or mesh name); every
// triangle primitive of that mesh, concatenated in order: POSITION, NORMAL
// (when every primitive has it), all JOINTS_n / WEIGHTS_n sets (joints:
// UNSIGNED_BYTE or UNSIGNED_SHORT; weights: FLOAT, or normalized UNSIGNED_BYTE
// / UNSIGNED_SHORT), sparse accessors included. Influences are compacted
// (CompactInfluences) so mesh.influences is the largest per-vertex count.
// The skin's joints and inverseBindMatrices (identity when absent), the whole
// node hierarchy, and every animation's translation/rotation/scale channels
// (morph-target `weights` channels are ignored).
//
// Errors: every malformed input throws Error whose message starts with the
// file name and names the offending element (accessor, bufferView, buffer,
// primitive, skin, node, animation channel/sampler), e.g. missing accessor,
// wrong component or element type, accessor outside its buffer (truncated
// buffer), joint index outside the skin, negative/NaN/all-zero weights, not a
// glTF file at all.
//
// Weights whose sum is not 1 (kWeightSumTolerance): with strict = false they
// are renormalised and ONE warning is added to GltfImportResult::warnings
// (how many vertices, the worst one and its sum); with strict = true the
// import fails naming the first such vertex.
#pragma once

#include <string>
#include <vector>

#include "model/asset.h"

namespace skintune::internal {

struct GltfImportOptions {
  std::string mesh;     // node or mesh name; empty = first skinned mesh
  bool strict = false;  // reject weights that do not sum to 1
  bool normals = true;  // import NORMAL when present
  // Import TANGENT (and the morph targets' TANGENT offsets): every triangle
  // primitive must have it, each handedness +1 or -1 (an error names the
  // first primitive without it, or the vertex).
  bool tangents = false;
  // Import TANGENT where every triangle primitive has it and normals are
  // imported; a mesh without it is imported without tangents, not refused.
  bool tangents_when_present = false;
};

struct GltfImportResult {
  SkinnedAsset asset;
  std::vector<std::string> warnings;  // complete lines, already prefixed with the file name
};

GltfImportResult ImportGltf(const std::string& path, const GltfImportOptions& options = {});

}  // namespace skintune::internal
