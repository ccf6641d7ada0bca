// skintune: scenes: what one launch skins. A scene is one mesh, K instances
// of one mesh (a crowd of one character, each instance with its own palette:
// the instanced kernels, docs/VARIANTS.md "Instancing"), or a batch of
// different meshes (a crowd of different characters) packed as ONE mesh:
//
//   - the meshes' vertices one after another (mesh m's first vertex at the
//     sum of the earlier meshes' vertex counts);
//   - each joint index offset into one concatenated palette (mesh m's joint j
//     is palette entry joint_offset[m] + j, joint_offset[m] the sum of the
//     earlier meshes' joint counts);
//   - every mesh padded to the batch's B (the largest B of its meshes) with
//     zero-weight slots that name the mesh's own first joint.
//
// So every variant of every language skins a batch with no kernel change; a
// vertex reads only its own mesh's joints, so the batch's float64 gold is the
// meshes' golds one after another (checked per mesh).
//
// Scene keys (the tuner's datasets, docs/DATA.md):
//   <dataset>              one mesh: a synthetic key (model/synthetic.h) or a glTF path
//   <dataset>-x<K>         K >= 2 instances of it, e.g. "25k-b4-x64"
//   <scene>-anim           a scene of one mesh or its instances animated on the device: each
//                          instance plays one of the model's clips at its own time, and the
//                          palette kernel makes the palettes (docs/ANIMATION.md), e.g.
//                          "25k-b4-x64-anim"; the model must have animation clips
//   <scene>-animblend      the same, every third instance cross-fading two clips at weight 0.35
//   <m1>+<m2>+...          a batch of the meshes m1, m2, ... (synthetic keys, glTF paths, mixes)
//   mix<N>-b<B>[-seed<S>]  a batch of seeded synthetic meshes of 5k..100k vertices, N vertices in
//                          all, each with its own influence count 1..B (every one of them
//                          present), bone count 20..77 and seed, e.g. "mix1600k-b4"
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "model/asset.h"

namespace skintune::internal {

// A batch mix's mesh sizes (vertices): seeded uniform in this range; the last
// mesh takes what is left (at least kMixMinVertices, so it may be larger).
inline constexpr std::size_t kMixMinVertices = 5000;
inline constexpr std::size_t kMixMaxVertices = 100000;

struct SceneSpec {
  std::string key;
  // The meshes of the scene: dataset keys or glTF paths; one unless a batch
  // (a mix expands to its synthetic keys here).
  std::vector<std::string> meshes;
  int instances = 1;   // > 1: instances of meshes[0] (never with a batch)
  bool batch = false;  // meshes[] packed as one mesh (ConcatenateMeshes)
  bool animated = false;  // "-anim", "-animblend": the palettes made on the device from the model's clips
  bool blended = false;   // "-animblend": every third instance cross-fades two clips
};

// Throws Error("scene 'KEY': ...") for a malformed key (an empty '+' member,
// a batch member with instances, K < 2 or above 65536, a bad mix); a member's
// synthetic key is checked by ParseDatasetKey (its message names the member).
SceneSpec ParseSceneKey(const std::string& key);
// Whether `key` names a glTF file (.gltf / .glb, any case).
bool IsGltfFile(const std::string& key);

// ConcatenateMeshes's result: the batch as one mesh and where each mesh lies in it.
struct MeshBatch {
  SkinnedMesh mesh;                          // influences: the largest of the meshes'
  std::vector<std::size_t> vertex_offsets;   // per mesh, then the total vertex count
  std::vector<int> joint_offsets;            // per mesh, then the total joint count
};

// The meshes as one (the top of this file). Throws Error naming the mesh by
// index ("meshes[2]: no vertices") for an empty list, a mesh without vertices
// or joints, and a total of joints above 65536 (SkinnedMesh stores joint
// indices in 16 bits). The meshes must be valid (Validate); normals are kept
// when every mesh has them, else none are.
MeshBatch ConcatenateMeshes(std::span<const SkinnedMesh* const> meshes);

// A loaded scene: its meshes and the mesh the kernels skin (meshes[0]'s for
// one mesh or instances; the concatenation for a batch).
struct SkinnedScene {
  SceneSpec spec;
  // Per mesh of spec.meshes: its skeleton and animations. Its mesh is moved
  // into `batch` (left empty: a 1600k scene is not held twice).
  std::vector<SkinnedAsset> assets;
  MeshBatch batch;                   // a batch's concatenation; else meshes[0]'s mesh, offsets {0, n} / {0, J}
  const SkinnedMesh& mesh() const { return batch.mesh; }
  std::size_t total_vertices() const { return batch.mesh.vertex_count() * static_cast<std::size_t>(spec.instances); }
};

// Generates or imports every mesh (GenerateDataset, ImportGltf, whose
// renormalisation warnings are not reported here) and concatenates a batch.
// Errors name the scene and the mesh ("scene 'a+b': meshes[1] 'b': ...").
SkinnedScene LoadScene(const SceneSpec& spec);

}  // namespace skintune::internal
