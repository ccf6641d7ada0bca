// skintune: the clip packer turns a model's skeleton, skin and animation
// clips into the flat buffers the palette kernel reads
// (cpu_kernels/palette_kernel.h; every byte in docs/ANIMATION.md), once per
// model, so that each frame uploads only 16 bytes per instance instead of
// its palette. packer.h does the same for meshes.
//
// What is packed: per node its parent and rest TRS (or its fixed matrix);
// per (clip, node, path) a channel header; the key times and float4 values
// of every translation, rotation and scale channel of the chosen clips; per
// joint its node and inverse bind matrix (3x4). What is not: `weights`
// channels (morph target weights move vertices before skinning, not bones;
// PackedAnimation::not_packed names each one left out).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "cpu_kernels/palette_kernel.h"
#include "generator/variant.h"
#include "model/asset.h"

namespace skintune::internal {

// Limits beyond which a packing is refused (Error naming the element): nodes
// as the device kernels' local memory holds them (kAnimMaxNodes,
// cpu_kernels/palette_kernel.h), joints as a batch's palette indices allow,
// clips as AnimInstance's 16-bit clip index allows, and 32-bit offsets.
inline constexpr std::size_t kAnimMaxJoints = 65536;
inline constexpr std::size_t kAnimMaxHeaders = std::size_t{1} << 26;  // clips x nodes x 3 (1 GiB of headers)
inline constexpr std::size_t kAnimMaxKeys = 0x7fffffff;               // times, and float4 values, in all

// Baking (BakeAnimation): the rate's range, and the frames' size limit.
inline constexpr double kAnimMaxBakeRate = 1000.0;                     // frames a second
inline constexpr std::size_t kMaxBakedFloats = std::size_t{1} << 28;  // 1 GiB of frames

// What baking a clip cost and lost: its frames, their bytes on the device,
// and the largest distance between a vertex of the mesh skinned by the baked
// palette (interpolated as the kernels do) and by the float64 sampled one,
// at the frames and at 1/4, 1/2 and 3/4 between them, relative to the mesh's
// bounding-box diagonal (NaN for a mesh of no extent: nothing to measure on).
struct BakedClipInfo {
  std::string name;  // "animations[0] 'Walk'"
  std::uint32_t frames = 0;
  std::size_t bytes = 0;
  double max_error = 0.0;
};

struct PackedAnimation {
  std::string source;                       // the asset's, for messages
  std::vector<int> clips;                   // packed clip c is asset.animations[clips[c]]
  std::vector<AnimNodeRecord> nodes;        // buffer `nodes`
  std::vector<AnimChannelHeader> channels;  // buffer `channels`: clips x nodes x 3
  std::vector<float> times;                 // buffer `times`
  std::vector<float> values;                // buffer `values`: 4 floats per value
  std::vector<AnimJointRecord> joints;      // buffer `joints`
  std::vector<float> clip_ranges;           // buffer `clips`: per clip start, end, 0, 0 (AdvanceAnimInstances)
                                            // (baked: start, end, frames, first frame)
  std::vector<float> frames;                // buffer `frames` of baked clips (empty: sampled)
  std::uint32_t baked_rows = 0;             // float4s a baked record: kBakedRowsSimilar, kBakedRowsAffine
                                            // (kBakedRowsLocalScaled in local space)
  bool baked_local = false;                 // records of nodes' local transforms (BakeSpace::kLocal, kHybrid)
  std::vector<float> steady;                // buffer `steady` (BakeSpace::kHybrid): the frames' palette records
  std::uint32_t steady_rows = 0;            // float4s a steady record (kBakedRowsSimilar, kBakedRowsAffine)
  std::vector<BakedClipInfo> baked;         // per packed clip, when baked
  double bake_rate = 0.0;                   // frames a second asked for (0: sampled)
  // Each channel left out and why ("animations[0] 'Wave': channels[3]
  // (weights of node 2): morph target weights are not part of the palette").
  std::vector<std::string> not_packed;

  AnimationView View() const;
  std::size_t Bytes() const;  // of the buffers the kernel reads (baked: frames and clips)
};

// Packs `clips` (indices into asset.animations; packed clip c is clips[c]).
// Throws Error("<source>: ...") naming the element for: a clip index out of
// range, more than kAnimMaxClips clips, an invalid skeleton or clip
// (Skeleton::Validate, AnimationClip::Validate), counts beyond the limits
// above, two channels of a clip on the same node and path (glTF forbids it),
// a channel on a node with a fixed matrix (glTF forbids it; the gold ignores
// it), an inverse bind or fixed matrix whose last row is not 0 0 0 1 (the
// palette is 3x4), or a value beyond float32's range.
PackedAnimation PackAnimation(const SkinnedAsset& asset, std::span<const int> clips);
// Every clip of the asset, in order.
PackedAnimation PackAnimation(const SkinnedAsset& asset);

// What a baked record holds (docs/ANIMATION.md "Baked clips"): each joint's
// palette entry (the kernel reads one record a joint and frame, and mixes a
// blend of two clips in the model's space), or each node's local transform
// (the kernel composes the hierarchy, as for sampled clips, and mixes a blend
// in each node's local space, as sampled clips do), or both (hybrid: an
// instance that plays one clip reads palette records, one that cross-fades
// mixes local ones; docs/ANIMATION.md "Hybrid records").
enum class BakeSpace { kPalette, kLocal, kHybrid };

// Every clip of `clips` baked (docs/ANIMATION.md "Baked clips"): its
// palettes sampled in float64 (SkinnedAsset::PoseAt, Skeleton::PaletteD) at
// F = ceil(duration x rate) + 1 evenly spaced frames (1 for a clip of no
// duration), each joint's transform split by its polar decomposition into a
// unit rotation, a symmetric stretch and a translation, with the rest pose
// as frame 0: records of 2 float4s where every transform of every frame is a
// similarity (the stretch s I to float32's precision), else of 4. nodes and
// joints are packed as PackAnimation packs them, channels, times and values
// not. In BakeSpace::kLocal, each node's local TRS at those frames instead
// (records of 2 float4s where every scale is uniform, else 3), nodes and
// joints packed for the kernel's walk. In BakeSpace::kHybrid, the local
// records with the palette records of the same frames as `steady`; each
// clip's bytes are both's, its error the larger of both's. Throws Error("<source>: ...") for a
// rate not in (0, kAnimMaxBakeRate], more than kMaxBakedFloats floats of
// frames, a singular joint transform, and what PackAnimation throws for.
PackedAnimation BakeAnimation(const SkinnedAsset& asset, std::span<const int> clips, double rate,
                              BakeSpace space = BakeSpace::kPalette);
PackedAnimation BakeAnimation(const SkinnedAsset& asset, double rate,
                              BakeSpace space = BakeSpace::kPalette);  // every clip, in order

// Every clip packed in a variant's form of animation on the device: sampled
// (PackAnimation), or baked at its rate in its space (BakeRateOf,
// BakesLocally, BakesHybrid). Throws Error for Animation::kHost (nothing to pack).
PackedAnimation PackForm(const SkinnedAsset& asset, Animation form);

// The bytes of one buffer of a PackedAnimation (or of instances), as uploaded.
template <typename T>
std::span<const std::uint8_t> BufferBytes(const std::vector<T>& buffer) {
  return {reinterpret_cast<const std::uint8_t*>(buffer.data()), buffer.size() * sizeof(T)};
}

}  // namespace skintune::internal
