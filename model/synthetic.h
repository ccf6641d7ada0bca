// skintune: seeded synthetic skinned characters, reproducing the set-up of the
// paper ("GPGPU Acceleration for Skeletal Animation"): any vertex count (the
// paper's 25k, 100k, 400k, 1600k), 77 bones, B influences per vertex.
//
// The rig is a limb hierarchy (a spine with a head, arms with hands and
// fingers, legs with feet: 77 bones by default, any count >= 1 allowed). The
// skin is a set of tubes around the bones; vertices are emitted tube by tube,
// ring by ring, so neighbouring vertices in memory are neighbours on the
// surface and share bones, as on a real character. With `locality` each vertex
// binds to its B nearest bones (distance to the bone segment) with weights
// falling off with distance; with `random_bones` the B indices are uniformly
// random distinct bones (the worst case for caches and constant memory).
// Weights are positive and sum to 1 (normalised in double, stored as float).
//
// The animation is one clip of `frames` keys at 30 fps: every joint rotates
// smoothly (sinusoids of seeded amplitude and phase, up to ~35 degrees), so
// palettes differ every frame. Every joint also scales non-uniformly, so
// the palettes are general affine maps; -rigid leaves the scaling out
// (rotations and translations only: what dual-quaternion skinning takes).
//
// A dataset is named by a compact key, parsed by ParseDatasetKey:
//   <vertices>-b<influences>[-bones<N>][-random][-seed<S>][-rigid][-morph<T>][-normals|-tangents]
// where <vertices> is a count with an optional k/m suffix (1000 / 1000000),
// e.g. "100k-b2", "1600k-b4-random", "5000-b8-bones12-seed3-normals".
// -tangents gives normals and tangents: each vertex's tangent runs along its
// bone, with handedness +1 and -1 in turn around each ring.
// -morph<T> adds T morph targets (1..64), applied at seeded default weights
// (the last of two or more at 0): target 0 moves every vertex, target k >= 1
// one contiguous region of n / (2T) vertices (a patch of the surface: the
// vertices run tube by tube), by up to 2% of the mesh's extent, with
// normal and tangent offsets where the mesh has them.
// "default" means "100k-b2" (the data set of the paper's Fig. 1).
#pragma once

#include <cstdint>
#include <string>

#include "model/asset.h"

namespace skintune::internal {

struct DatasetSpec {
  std::size_t vertices = 100000;
  int influences = 2;
  int bones = 77;
  bool random_bones = false;  // false: bone locality; true: uniformly random indices
  std::uint64_t seed = 1;
  bool normals = false;
  bool tangents = false;      // also tangents (then normals too)
  bool rigid = false;         // the animation rotates and translates only (no scale channels)
  int morph_targets = 0;      // -morph<T>: morph targets (0: none)
  int frames = 60;            // keys of the generated animation clip (30 fps)

  // Throws Error naming the bad field (vertices 0 or above kMaxVertexCount,
  // influences outside 1..8, bones 0 or > 65535, influences > bones, frames < 1).
  void Validate() const;
  std::string Key() const;    // inverse of ParseDatasetKey
};

// Throws Error("dataset 'KEY': ...") for a malformed key.
DatasetSpec ParseDatasetKey(const std::string& key);

// The bytes GenerateDataset allocates per vertex (the mesh's arrays).
std::uint64_t DatasetBytesPerVertex(const DatasetSpec& spec);

// Deterministic: the same spec gives bit-identical output on every machine.
// Throws Error("dataset 'KEY': needs about ... at most about N vertices fit")
// before allocating anything when the mesh does not fit in the memory this
// process may still take (base/memory_limit.h).
SkinnedAsset GenerateDataset(const DatasetSpec& spec);

}  // namespace skintune::internal
