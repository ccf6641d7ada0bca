// skintune: the palette kernel, animation that lives on the device.
//
// A model's animation is packed once (generator/clip_packer.h) into the flat
// buffers below; each frame the kernel turns every instance's (clip, time,
// second clip, blend weight) into its bone palette: it samples the clips'
// channels (glTF 2.0 STEP, LINEAR, CUBICSPLINE, as model/animation.cpp does),
// blends the two clips in local space, composes each joint's global transform
// through the node hierarchy and applies the inverse bind matrix. The output
// is the `mat3x4` palette the skin kernels read (docs/VARIANTS.md), K
// instances' palettes one after another, so a skin kernel can read it as it is.
//
// This file holds the layout (docs/ANIMATION.md is its byte-level
// description) and the CPU device's kernel, in float32 as a GPU computes it;
// templates/palette.cl is the same algorithm for OpenCL.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace skintune::internal {

enum class AnimInterpolation : std::uint32_t { kStep = 0, kLinear = 1, kCubicSpline = 2 };
enum class AnimPath : std::uint32_t { kTranslation = 0, kRotation = 1, kScale = 2 };
inline constexpr std::uint32_t kAnimPaths = 3;
// As a clip index: no clip, the skeleton's rest pose. Clip indices are 16-bit
// (AnimInstance), so at most kAnimMaxClips clips are packed.
inline constexpr std::uint16_t kAnimRestPose = 0xffff;
inline constexpr std::uint32_t kAnimMaxClips = 0xffff;
// The device kernels sample every node of an instance into local memory
// (templates/palette.cl, ANIM_MAX_NODES: 512 x 48 bytes, 24 KiB, within every
// API's guaranteed minimum), so a packed animation has at most this many nodes.
inline constexpr std::size_t kAnimMaxNodes = 512;
// Float4 rows per joint of the output palette (`mat3x4`).
inline constexpr std::size_t kAnimPaletteRows = 3;

// Buffer elements, each the bytes one element of a device buffer holds (all
// 32-bit little-endian words; a std::vector of them is the buffer).
//
// `nodes`: one per node, in the skeleton's node order.
struct AnimNodeRecord {
  std::int32_t parent = -1;  // -1 for a root
  std::uint32_t fixed = 0;   // 1: a glTF `matrix` node (never animated), rows = that matrix
  std::uint32_t reserved[2] = {0, 0};
  // fixed 0: the rest TRS: translation (x, y, z, 0), rotation (x, y, z, w)
  // normalised, scale (x, y, z, 0). fixed 1: the matrix's three rows.
  float rows[3][4] = {};
};
// `channels`: one per (clip, node, path), at (clip * node_count + node) * 3 + path.
struct AnimChannelHeader {
  std::uint32_t interpolation = 0;  // AnimInterpolation
  std::uint32_t key_count = 0;      // 0: the clip does not animate it (the rest value holds)
  std::uint32_t time_offset = 0;    // index of its first key in `times`
  std::uint32_t value_offset = 0;   // index of its first value in `values` (float4s)
};
// `joints`: one per joint of the skin.
struct AnimJointRecord {
  std::int32_t node = 0;  // the joint's node
  std::uint32_t reserved[3] = {0, 0, 0};
  float inverse_bind[3][4] = {};  // rows of the affine inverse bind matrix
};
// `instances`: one per instance, 16 bytes: two clips, each at its own time,
// blended in local space.
struct AnimInstance {
  std::uint16_t clip = 0;               // packed clip index, or kAnimRestPose
  std::uint16_t clip2 = kAnimRestPose;  // second clip, or kAnimRestPose; read only when weight != 0
  float time = 0.0f;                    // seconds of `clip` (its own key times; clamped to its first and last key)
  float time2 = 0.0f;                   // seconds of `clip2`
  float weight = 0.0f;                  // clip2's blend weight in [0, 1]: local = lerp(clip's, clip2's, weight)
};
static_assert(sizeof(AnimNodeRecord) == 64 && sizeof(AnimChannelHeader) == 16 && sizeof(AnimJointRecord) == 64 &&
              sizeof(AnimInstance) == 16);

// Baked clips (docs/ANIMATION.md "Baked clips"): each clip's palettes
// pre-sampled at evenly spaced frames, so that the kernel reads two records
// a joint instead of sampling channels and walking the hierarchy. Buffer
// `frames`: one record per (frame, joint), at float4 R * (f * joints + j),
// of the joint's skinning transform M (global x inverse bind) split as
// Shoemake and Duff's polar decomposition M = T(t) R(q) S, q a unit
// rotation and S symmetric:
//   R = 2 (a similarity: S = s I): (q.x, q.y, q.z, q.w), (t.x, t.y, t.z, s);
//   R = 4 (any affine M): q, (t.x, t.y, t.z, 0), (S00, S11, S22, S01),
//       (S02, S12, 0, 0).
// Frame 0 is the rest pose; clip c's F frames follow at its first frame,
// frame k at start + k (end - start) / (F - 1). Its entry of `clips` is then
// (start, end, F, first frame), the last two as uint32 bits.
inline constexpr std::uint32_t kBakedRowsSimilar = 2;
inline constexpr std::uint32_t kBakedRowsAffine = 4;
// Clips baked in local space (docs/ANIMATION.md "Baked in local space"): one
// record per (frame, node), at float4 R * (f * nodes + n), of the node's
// local transform T(t) R(q) S(s) at the frame, so that a blend of two clips
// mixes each node's local transform (as sampled clips do) and the kernel
// composes the hierarchy as the sampled one does, without searching keys:
//   R = 2 (every node's scale uniform, s within 1e-5 of each axis's):
//       q, (t.x, t.y, t.z, s);
//   R = 3: q, (t.x, t.y, t.z, 0), (s.x, s.y, s.z, 0).
// A fixed-matrix node's records are the identity (its matrix is in
// `nodes`); frames and `clips` as for palette records.
inline constexpr std::uint32_t kBakedRowsLocalScaled = 3;

// The packed animation as the kernel reads it: views of the buffers.
struct AnimationView {
  std::uint32_t clip_count = 0;
  std::span<const AnimNodeRecord> nodes;
  std::span<const AnimChannelHeader> channels;  // clip_count * nodes * 3
  std::span<const float> times;
  std::span<const float> values;  // 4 floats per value
  std::span<const AnimJointRecord> joints;
  // `clips`: clip_count x 4 floats, clip c's time range (start, end, 0, 0):
  // where AdvanceAnimInstances loops its clock. Baked: (start, end, frame
  // count, first frame), the last two uint32 bits.
  std::span<const float> clip_ranges;
  // Baked clips' `frames` (baked_rows float4s a record: kBakedRowsSimilar
  // or kBakedRowsAffine); empty: the clips are sampled from nodes, channels,
  // times and values. Baked, those four are not read (nor uploaded): joints
  // gives the joint count.
  std::span<const float> frames;
  std::uint32_t baked_rows = 0;
  // Baked in local space: records per (frame, node) (kBakedRowsSimilar or
  // kBakedRowsLocalScaled), read with nodes and joints; channels, times and
  // values are not.
  bool baked_local = false;
  // Local records with palette records beside them (BakeSpace::kHybrid,
  // docs/ANIMATION.md "Hybrid records"): the same frames' palette records
  // (steady_rows float4s a record, kBakedRowsSimilar or kBakedRowsAffine;
  // one per (frame, joint), laid out as `frames` is for palette records),
  // which an instance that plays one clip (weight 0) reads instead of
  // walking the hierarchy; a cross-fading one mixes the local records.
  // Empty: none.
  std::span<const float> steady;
  std::uint32_t steady_rows = 0;

  bool baked() const { return !frames.empty(); }
  // What a baked frame holds a record of: joints, or nodes (local space).
  std::size_t baked_items() const { return baked_local ? nodes.size() : joints.size(); }
};

// Throws Error naming the element for buffers an outside program could have
// packed wrong: a channel table not of clip_count * nodes * 3 headers, an
// interpolation outside 0..2, keys beyond `times` or values beyond `values`
// (CUBICSPLINE: 3 values per key), keys not strictly increasing or not
// finite, a parent or joint node out of range, a cycle, no joints.
void ValidateAnimation(const AnimationView& animation);
// Baked (frames not empty): throws Error naming the element for a `frames`
// buffer not of whole records for the joints (local space: the nodes, whose
// hierarchy is checked as ValidateAnimation checks it), a clip's frames beyond it or
// fewer than 1 (2 for a clip of some duration), a record not finite or with
// a rotation not of unit length within 1e-3; `steady` records beside records
// not in local space, or not of as many frames, or as `frames` is checked.
// Sampled: as ValidateAnimation.
void ValidateBakedAnimation(const AnimationView& animation);
// A hybrid animation's steady records seen as palette records: frames =
// steady, baked_rows = steady_rows, not local, no steady records of its own.
AnimationView SteadyView(const AnimationView& animation);
// Throws Error("instances[I]: ...") for a clip or clip2 (when weight != 0)
// neither below clip_count nor kAnimRestPose, a time, time2 or weight that
// is not finite, a weight outside [0, 1].
void ValidateAnimInstances(const AnimationView& animation, std::span<const AnimInstance> instances);

// Time t moved into clip c's range [start, end], looping: start + (t - start)
// modulo (end - start), the device kernels' formula (templates/palette.cl
// anim_loop_time); a clip of no duration gives its start.
float AnimLoopTime(float t, float start, float end);
// Every state's clock advanced by `delta` seconds (time on clip, time2 on
// clip2), each looping in its clip's range; the rest pose and a clip beyond
// clip_count keep theirs. What the device kernels do to the states they keep
// on the device (docs/ANIMATION.md "`states`").
void AdvanceAnimInstances(const AnimationView& animation, std::span<AnimInstance> states, float delta);

// Writes instances.size() * joints * `rows` float4 rows to `palette`
// (a baked animation: from its frames, templates/palette.cl's baked algorithm;
// hybrid: an instance of weight 0 from the steady records, as palette records):
// instance i's joint j row r at float4 (i * joints + j) * rows + r; rows 3
// (mat3x4) or 4 (mat4: a fourth row 0 0 0 1), else Error. Validates the instances
// (ValidateAnimInstances, cheap); the animation must have passed
// ValidateAnimation once (PackAnimation's has), which this does not repeat
// per frame.
void RunPaletteKernel(const AnimationView& animation, std::span<const AnimInstance> instances, float* palette,
                      int rows = static_cast<int>(kAnimPaletteRows));

}  // namespace skintune::internal
