// skintune: the palette kernel of a packed animation, as the runner driver
// runs it (docs/ANIMATION.md): an ordinary KernelSource whose arguments are
// the animation's buffers, the per-frame `instances` and the palette it
// writes, launched as one instanced launch of one work-group per instance.
//
// The kernel is specialised per model, as the skin kernel is per mesh: the
// node, joint and clip counts and the palette's rows per joint are defines
// (ANIM_NODE_COUNT, ANIM_JOINT_COUNT, ANIM_CLIP_COUNT, ANIM_PALETTE_ROWS), so
// it takes no scalars and every API binds it as it binds any kernel's buffers.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "cpu_kernels/palette_kernel.h"
#include "generator/emit.h"

namespace skintune::internal {

// The palette kernel's work-group (templates/palette.cl ANIM_GROUP), one per
// instance: 3 x `nodes` rounded up to a multiple of 32, from 64 to 256, so
// that every (node, path) is sampled in one round where it fits (64 x 25k-b4
// with the 77-joint rig on an H200, 2026-11-29: 6.2 us a launch in groups of
// 256 against 9.0 in groups of 128), and small rigs' crowds keep their
// occupancy (1024 x CesiumMan: 9.6 us in groups of 256 against 8.2 in 128).
inline constexpr int kAnimMaxGroup = 256;
constexpr int AnimGroupFor(std::size_t nodes) {
  const std::size_t tasks = (3 * nodes + 31) / 32 * 32;
  return static_cast<int>(tasks < 64 ? 64 : tasks > kAnimMaxGroup ? kAnimMaxGroup : tasks);
}

// A baked animation's kernel (AnimationView::baked) has no hierarchy to walk:
// an item per joint, the group the joints rounded up to 32, from 32 to 256.
constexpr int AnimBakedGroupFor(std::size_t joints) {
  const std::size_t items = (joints + 31) / 32 * 32;
  return static_cast<int>(items < 32 ? 32 : items > kAnimMaxGroup ? kAnimMaxGroup : items);
}

// The kernel's arguments, in order: the buffers it reads, the palette it
// writes, the clips' time ranges, the instances' states it keeps on the device
// (read and written), and the frame's two scalars: `delta` (f32, seconds) and
// `fresh` (u32: 1 takes the states from `instances`, the frame's upload; 0
// advances the kept ones by delta). docs/ANIMATION.md has every byte.
inline constexpr const char* kAnimInputs[] = {"nodes", "channels", "times", "values", "joints", "instances"};
// A baked animation's kernel takes `frames` (AnimationView::frames),
// instances, out_palette, clips, states, delta and fresh, in that order; one
// baked in local space nodes, frames, joints, then the same (it walks the
// hierarchy: its group, one item per node, is AnimBakedGroupFor(nodes)).
// Hybrid records (AnimationView::steady) add `steady` after frames, and the
// define ANIM_STEADY, the float4s a steady record (0: none).
inline constexpr const char* kAnimFrames = "frames";
inline constexpr const char* kAnimSteady = "steady";
inline constexpr const char* kAnimOutput = "out_palette";
inline constexpr const char* kAnimClips = "clips";
inline constexpr const char* kAnimStates = "states";
inline constexpr const char* kAnimDelta = "delta";
inline constexpr const char* kAnimFresh = "fresh";

// The bytes of `animation`'s buffer that the palette kernel's argument
// `name` binds: nodes, channels, times, values, joints, clips, frames or steady;
// empty for the per-frame `instances`, the kept `states` and the palette it
// writes, which are the caller's (Runner::Animate), and for other names.
std::span<const std::uint8_t> AnimationBufferBytes(const AnimationView& animation, std::string_view name);

struct PaletteKernel {
  KernelSource kernel;  // the language's palette_template in its copy_lang (glsl-vertex: glsl-compute)
  Variant variant;      // what an API reads of a launch's variant: its language, global storage
  // No palette kernel runs: each skin launch makes its palette (EmitFused of
  // the set's skin kernels, Runner::Animate; a fused* variant, FusesPalette).
  bool fused = false;
};

// The palette kernel of `animation` in `lang`'s API writing `palette_rows`
// float4 rows per joint (3: mat3x4, 4: mat4 with a last row 0 0 0 1; a skin
// variant's PaletteRows). Launch it with LaunchSpec count kernel.launch.wg_size (AnimGroupFor) and
// instances K (instanced): one work-group per instance. A baked `animation`
// gets the baked kernel (define ANIM_BAKED: BakedDefine). Throws Error for rows
// other than 3 or 4, no joints or nodes, more nodes than kAnimMaxNodes.
PaletteKernel EmitPalette(Lang lang, const AnimationView& animation, int palette_rows);

// The scalar a fused skin kernel takes last (EmitFused): f32 seconds since
// the instances' upload, added to their clocks as AdvanceAnimInstances does.
inline constexpr const char* kAnimElapsed = "elapsed";

// A skin kernel of storage local that makes its instance's palette itself
// (docs/ANIMATION.md "The palette in the skin launch"): `skin` (Emit's, of
// the animation's joints) specialised again with ANIM_FUSED 1, the
// animation's ANIM_BAKED, ANIM_JOINT_COUNT and ANIM_CLIP_COUNT, and the skin
// kernel's work-group as ANIM_GROUP; its `palette` argument replaced by the
// records and `instances` and `clips` (their bytes: AnimationBufferBytes,
// instances K AnimInstance records) and the scalar kAnimElapsed appended.
// Palette records (BakeSpace kPalette): `frames`. Local records (kLocal):
// `nodes`, `frames`, `joints`, and ANIM_NODE_COUNT, ANIM_JUMPS: each
// work-group walks the hierarchy in its local memory as the palette kernel
// does. Hybrid records (kHybrid): `steady` after `frames`, and ANIM_STEADY.
// Nothing but the outputs is written, so any number of launches and frames
// may read the same instances. Throws Error for sampled clips, a skin kernel
// not of local storage, without a work-group or that blends dual
// quaternions, joint counts that differ, or more nodes than kAnimMaxNodes.
KernelSource EmitFused(const KernelSource& skin, const AnimationView& animation);

// The hierarchy kernels' rounds of pointer jumping (ANIM_JUMPS,
// templates/palette.cl): ceil(log2(depth + 1)) for the deepest node's
// ancestors, so that the 2^rounds-th ancestor of every node is past its root.
int AnimJumpRounds(std::span<const AnimNodeRecord> nodes);

// The kernel's ANIM_BAKED (templates/skin_params.h): 0 sampled; palette
// records of 2 (1) or 4 (2) float4s; local records of 2 (3) or 3 (4).
int BakedDefine(const AnimationView& animation);
// What an ANIM_BAKED value says of the records (a runner that reads a
// built kernel's defines: the cpu device): BakedDefine's inverse.
struct BakedForm {
  bool baked = false, local = false;
  std::uint32_t rows = 0;  // AnimationView::baked_rows
};
BakedForm BakedFormOf(long long define);

}  // namespace skintune::internal
