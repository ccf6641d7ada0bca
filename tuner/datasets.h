// skintune (internal to tuner/): the data sets a tuned device measures on,
// made once per key: the scene, its golds, its frames' palettes and its
// packings (generator/packer.h), and the kernels a variant emits for it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "generator/variant.h"
#include "model/asset.h"
#include "model/scene.h"
#include "reference/skinning.h"

namespace skintune::internal::tuner_internal {

// The scenes a tuned device measures on, made once per key (model/scene.h): a
// synthetic dataset key or a glTF path (.gltf / .glb), K instances of one
// ("25k-b4-x64"), or a batch ("a.gltf+25k-b2", "mix1600k-b4"), with, per
// weight format and normals, the float64 gold of the verification frame and,
// per normals, the gold of the unquantised source. Golds hold the whole
// scene's output in the kernel's order: instance after instance, or mesh after
// mesh of a batch; each part (an instance, a batch's mesh) is compared on its own.
class DatasetCache {
 public:
  // A part of a scene's output, verified against its own gold.
  struct Part {
    std::string name;         // "" (one mesh), "instance 3", "meshes[2] (Fox.gltf)"
    std::size_t first = 0;    // its first vertex in the scene's output
    std::size_t count = 0;    // its vertices
    double diagonal = 0.0;    // BoundingBoxDiagonal of its rest positions
  };
  // What a gold depends on: the weight format (-1: the source's weights), the
  // normals, whether it skins with dual quaternions (SkinGoldDualQuaternion)
  // or linear blending (SkinGold), and whether the morph offsets are halves
  // (QuantisedMesh rounds them; never for the source).
  // An animated scene's gold also depends on the palettes its form makes:
  // the baked forms' own (their code), the sampled and host forms the float64 ones (0).
  using GoldKey = std::tuple<int, Normals, bool, bool, int>;
  struct Entry {
    SkinnedScene scene;
    // The verification frame's palette as the kernel reads it: instance
    // after instance (K x joints), a batch's meshes one after another.
    std::vector<glm::mat4> verification_palette;
    bool rigid_joints = false;  // AllRigid(verification_palette): dual quaternions may skin it
    std::vector<Part> parts;
    std::map<GoldKey, GoldResult> gold;                   // (weight format, normals, dual quaternions, half offsets)
    std::map<GoldKey, GoldResult> source_gold;            // (-1, normals, dual quaternions, false)
    std::map<GoldKey, double> quantisation;               // as gold: gold vs source gold, / diagonal
    std::map<int, std::vector<std::vector<glm::mat4>>> frames;  // ScenePalettes by count
    // An animated scene ("-anim", docs/ANIMATION.md): the verification frame's
    // K instances (CrowdStates; verification_palette is their float64
    // palettes), the model's clips packed per form, and the verification
    // palettes each baked form makes (the palette kernel's algorithm).
    std::vector<AnimInstance> verification_states;
    std::map<Animation, PackedAnimation> animations;
    std::map<Animation, std::vector<glm::mat4>> baked_palettes;
    // The last few packings (PackingKey, its packed mesh), newest last.
    std::vector<std::pair<std::string, PackedMesh>> packings;
    const SkinnedMesh& mesh() const { return scene.mesh(); }
    int instances() const { return scene.spec.instances; }
  };
  // Throws Error for a malformed key or a glTF file that cannot be imported.
  Entry& Get(const std::string& key);
  // The gold of `variant`'s quantised mesh at the verification frame.
  const GoldResult& Gold(Entry& entry, const Variant& variant);
  // The gold of the unquantised source mesh (the weights as the dataset has them).
  const GoldResult& SourceGold(Entry& entry, const Variant& variant);
  // The largest over the parts of MaxDistance(Gold, SourceGold) of the
  // positions / the part's diagonal: what `variant`'s weight format alone
  // moves them, relative (0 when it holds the weights exactly).
  double QuantisationError(Entry& entry, const Variant& variant);
  // The model's clips packed for `form` (PackForm: sampled, or baked at
  // BakeRateOf(form) in its space), made once per form. Throws Error for a
  // scene that is not animated, or the packer's errors.
  const PackedAnimation& Clips(Entry& entry, Animation form);
  // The verification frame's palettes as `variant`'s form makes them: the
  // float64 sampled ones, or a baked form's (RunPaletteKernel on its frames).
  std::span<const glm::mat4> VerificationPalette(Entry& entry, const Variant& variant);
  // ScenePalettes(entry.scene, count), made once per count.
  const std::vector<std::vector<glm::mat4>>& Frames(Entry& entry, int count);
  // Pack(entry.mesh(), variant), reused from a variant of the same packing
  // (PackingKey): the variants of one packing differ in their kernels only.
  // The cached packing itself, its `variant` set to `variant`, not a copy (a
  // 6400k-vertex packing is ~200 MB: copying it cost 85 ms a measurement,
  // and compile-ahead packs every variant it announces): valid, and of
  // `variant`, until the next call. Throws Error (naming `variant`) when it
  // cannot be packed.
  const PackedMesh& Packed(Entry& entry, const Variant& variant);

 private:
  std::map<std::string, std::unique_ptr<Entry>> entries_;
};

// `abs` / `diagonal`: an error relative to a part's size; for a part of one
// point (diagonal 0) any error is all of it.
double Relative(double abs, double diagonal);

// `count` palettes of the asset's first animation at evenly spaced times
// (frame k at start + duration * (k + 0.5) / count); the rest pose, repeated,
// when the asset has no animation.
std::vector<std::vector<glm::mat4>> FramePalettes(const SkinnedAsset& asset, int count);
// Whether every palette entry of the scene's verification frame (ScenePalettes
// count 1) is rigid, so dual quaternions may skin it (ProblemShape::rigid_joints;
// a later frame that is not fails its variant's measurement, naming the joint).
bool PalettesRigid(const SkinnedScene& scene);
// Whether every matrix has a dual quaternion (skintune_kernels::DualQuaternionOf).
bool AllRigid(std::span<const glm::mat4> palette);
// An animated scene's K instances of input set `set` (the verification's:
// kVerificationSet): instance k plays clip (set x K + k) mod C of the model's
// C clips at its own phase of it (golden-ratio steps), so every set is a
// different frame of the crowd; in a "-animblend" scene every third
// cross-fades to the next clip at weight 0.35 (two-clip blends, as crowds in
// transition play them).
inline constexpr int kVerificationSet = 1 << 20;
std::vector<AnimInstance> CrowdStates(const SkinnedScene& scene, int set);
// The float64 palettes of `states` (SkinnedAsset::BlendedPoseAt per instance), instance after instance.
std::vector<glm::mat4> CrowdPalettes(const SkinnedScene& scene, std::span<const AnimInstance> states);
// `count` frames of a scene, each as the kernel reads it: one mesh's
// FramePalettes; K instances: K different frames (set s, instance k: frame
// s x K + k of count x K); a batch: each mesh's frame s, one after another.
std::vector<std::vector<glm::mat4>> ScenePalettes(const SkinnedScene& scene, int count);

// `variant`'s key with every axis the packer does not read (generator/packer.h)
// set to one value: the variants with one packing key have the same packed
// bytes. An axis not listed here counts as one that changes them.
std::string PackingKey(Variant variant);

// The variant packed for the scene's mesh (DatasetCache::Packed: valid until
// the next packing) and its kernels, one per launch (instanced for K
// instances). Throws Error when it cannot be packed or emitted.
const PackedMesh& PackScene(DatasetCache& datasets, DatasetCache::Entry& entry, const Variant& variant,
                            std::vector<KernelSource>& kernels);

// The bytes one frame of `packed` moves (inputs, outputs, palette) for K
// `instances`: what K copies of the mesh would move (an instanced kernel
// may find its one mesh in cache; the same-size copy is that of the scene's
// total bytes).
std::uint64_t FrameBytes(const PackedMesh& packed, int instances);
// The least of those bytes the frame can move: the launches' inputs (the
// one mesh every instance reads) once, each instance's outputs and palette.
// FrameBytes for one instance.
std::uint64_t FloorBytes(const PackedMesh& packed, int instances);
// `sets` frames' palettes of the scene, packed as `variant` reads them.
std::vector<std::vector<std::uint8_t>> TimedPalettes(DatasetCache& datasets, DatasetCache::Entry& data,
                                                     const Variant& variant, int sets);

}  // namespace skintune::internal::tuner_internal
