// skintune: a variant = one point of the kernel tuning space.
//
// Every axis value has one meaning in every language, so the same variant is
// the same algorithm on the same bytes in OpenCL, CUDA and GLSL: that is what
// makes the comparison fair. docs/VARIANTS.md explains each axis and why it
// can matter.
//
// Compact key: the axis values joined by '.', in this canonical order:
//   <lang>.b<B>.<mixed>.<layout>.<position>.<index>.<weight>.<palette>.<storage>
//   .<blend>.v<vertices_per_item><c|s>.wg<wg_size>.<nonormals|normals|tangents>[.morph-<dense|sparse>[-half]]
// e.g. "opencl.b4.padded.soa-split.float4.u16.unorm16.mat3x4.local.matrix.v2c.wg256.nonormals".
// Every token is unique across axes, so ParseVariantKey accepts the tokens in
// any order; omitted axes take their default (Variant{}), so "cuda.b2" is a key.
// The axes, their values and tokens are the table in generator/axes.h.
#pragma once

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/languages.h"  // Lang, the lang axis's enum: one row per language

namespace skintune::internal {

enum class MixedCounts { kPadded, kBucketed };
enum class Layout { kAos, kSoa, kSoaSplit };
enum class PositionFormat { kFloat4, kFloat3 };
enum class IndexFormat { kI32, kU16, kU8 };
enum class WeightFormat { kF32, kUnorm16, kUnorm8 };
// kDualQuaternion: a unit dual quaternion a joint (real then dual part, 2
// float4 rows), read only by Blend::kDualQuaternion.
enum class PaletteFormat { kMat4, kMat3x4, kDualQuaternion };
enum class PaletteStorage { kConstant, kLocal, kGlobal, kImage };
// kMatrix and kPoint are linear blend skinning (the same result, two orders
// of work); kDualQuaternion is dual-quaternion skinning (Kavan et al. 2007),
// a different result: a user's choice, never raced against the linear two
// (docs/VARIANTS.md "Dual quaternions").
enum class Blend { kMatrix, kPoint, kDualQuaternion };
enum class Assignment { kContiguous, kStrided };
// What a variant skins beside positions: nothing, normals, or normals and
// tangents (xyz skinned, w the handedness: docs/VARIANTS.md "Normals and tangents").
enum class Normals { kNone, kNormals, kTangents };
// Whether a variant applies the mesh's morph targets before skinning, and how
// it stores their offsets (docs/VARIANTS.md "Morph targets"): dense (every
// target an offset per vertex) or sparse (per vertex the targets that move
// it), float32 or half (IEEE binary16) offsets.
enum class Morph { kNone, kDense, kSparse, kDenseHalf, kSparseHalf };
// The format the kernel writes skinned normals and tangents in (docs/VARIANTS.md
// "Packed normals and tangents"): float32 (the position format's vector for
// normals, float4 for tangents), octahedral 2 x unorm16 (Godot 4's layout; a
// tangent folds its handedness into y), or 4 x snorm8 (xyz, then 0 for a normal
// and the handedness for a tangent). A user's choice: what the consumer reads.
enum class NormalFormat { kF32, kOct16, kSnorm8 };
// Where an animated scene's palettes come from (docs/ANIMATION.md): uploaded
// by the host each frame, or made on the device by the palette kernel, which
// samples the model's clips (sampled) or interpolates them baked at 30, 60,
// 120 or 240 frames a second (BakeRateOf): each joint's palette entry
// (baked*: one read a joint; a blend of two clips mixed in the model's
// space), or each node's local transform (local*: the hierarchy composed
// each frame; a blend mixed in local space, as sampled clips are;
// BakesLocally), or both (hybrid*: an instance that plays one clip reads
// palette records, one that cross-fades mixes local ones; BakesHybrid), or
// records made into each skin work-group's local copy by the group itself
// (no palette kernel, one launch a frame; FusesPalette; storage local):
// palette records (fused*), local ones, the group walking the hierarchy
// (fusedlocal*), or hybrid ones (fusedhybrid*).
// Otherwise the skin kernel is the same, and the frame runs the palette
// kernel first. A scene's choice (the tuner's "-anim" scenes animate on the
// device): never raced against host.
enum class Animation {
  kHost, kSampled, kBaked30, kBaked60, kBaked120, kBaked240, kLocal30, kLocal60, kLocal120, kLocal240,
  kHybrid30, kHybrid60, kHybrid120, kHybrid240, kFused30, kFused60, kFused120, kFused240,
  kFusedLocal30, kFusedLocal60, kFusedLocal120, kFusedLocal240,
  kFusedHybrid30, kFusedHybrid60, kFusedHybrid120, kFusedHybrid240
};

struct Variant {
  Lang lang = Lang::kOpenCl;
  int influences = 4;                                 // B, 1..8
  MixedCounts mixed = MixedCounts::kPadded;           // meshes whose vertices use fewer than B bones
  Layout layout = Layout::kSoa;
  PositionFormat position = PositionFormat::kFloat4;  // also the format of normals
  IndexFormat index = IndexFormat::kU16;
  WeightFormat weight = WeightFormat::kF32;
  PaletteFormat palette = PaletteFormat::kMat3x4;
  PaletteStorage storage = PaletteStorage::kGlobal;
  Blend blend = Blend::kMatrix;
  int vertices_per_item = 1;                          // 1, 2, 4, 8
  Assignment assignment = Assignment::kContiguous;
  int wg_size = 128;                                  // 32..1024, a multiple of 32
  Normals normals = Normals::kNone;
  Morph morph = Morph::kNone;  // keys leave it out when none
  NormalFormat normal_format = NormalFormat::kF32;  // keys leave it out when f32
  Animation animation = Animation::kHost;           // keys leave it out when host

  std::string Key() const;
  std::size_t Hash() const;  // stable across runs and machines (FNV-1a of Key())
  friend bool operator==(const Variant&, const Variant&) = default;
};

// Whether the variant skins normals (normals or normals + tangents), tangents.
constexpr bool SkinsNormals(const Variant& v) { return v.normals != Normals::kNone; }
constexpr bool SkinsTangents(const Variant& v) { return v.normals == Normals::kTangents; }
// The value that skins normals (and tangents) where asked.
constexpr Normals NormalsFor(bool normals, bool tangents) {
  return tangents ? Normals::kTangents : normals ? Normals::kNormals : Normals::kNone;
}

// Whether the variant applies morph targets; their layout; half offsets.
constexpr bool SkinsMorph(const Variant& v) { return v.morph != Morph::kNone; }
constexpr bool MorphSparse(const Variant& v) { return v.morph == Morph::kSparse || v.morph == Morph::kSparseHalf; }
constexpr bool MorphHalf(const Variant& v) { return v.morph == Morph::kDenseHalf || v.morph == Morph::kSparseHalf; }

// Whether the variant's palettes are made on the device (the palette kernel).
constexpr bool AnimatesOnDevice(Animation a) { return a != Animation::kHost; }
constexpr bool AnimatesOnDevice(const Variant& v) { return AnimatesOnDevice(v.animation); }
// The frames a second its clips are baked at; 0: sampled (or the host's palettes).
constexpr double BakeRateOf(Animation a) {
  switch (a) {
    case Animation::kBaked30: case Animation::kLocal30: case Animation::kHybrid30:
    case Animation::kFused30: case Animation::kFusedLocal30: case Animation::kFusedHybrid30: return 30.0;
    case Animation::kBaked60: case Animation::kLocal60: case Animation::kHybrid60:
    case Animation::kFused60: case Animation::kFusedLocal60: case Animation::kFusedHybrid60: return 60.0;
    case Animation::kBaked120: case Animation::kLocal120: case Animation::kHybrid120:
    case Animation::kFused120: case Animation::kFusedLocal120: case Animation::kFusedHybrid120: return 120.0;
    case Animation::kBaked240: case Animation::kLocal240: case Animation::kHybrid240:
    case Animation::kFused240: case Animation::kFusedLocal240: case Animation::kFusedHybrid240: return 240.0;
    default: return 0.0;
  }
}
// Whether its clips are baked with palette records beside local ones (hybrid*, fusedhybrid*).
constexpr bool BakesHybrid(Animation a) {
  return a == Animation::kHybrid30 || a == Animation::kHybrid60 || a == Animation::kHybrid120 ||
         a == Animation::kHybrid240 || a == Animation::kFusedHybrid30 || a == Animation::kFusedHybrid60 ||
         a == Animation::kFusedHybrid120 || a == Animation::kFusedHybrid240;
}
// Whether each skin work-group makes its palette from its records (fused*,
// fusedlocal*, fusedhybrid*: the skin kernel's ANIM_FUSED,
// generator/palette_kernel.h EmitFused).
constexpr bool FusesPalette(Animation a) {
  return a >= Animation::kFused30 && a <= Animation::kFusedHybrid240;
}
// The shape a fused form takes where nothing chose one (a Skinner's variant
// neither forced nor tuned fused; the tuner's coordinate search starts there
// too, tuner/strategy.h): storage local, 2048 vertices a work-group, 8 an
// item, strided, in groups of 256, a mat4 palette kept as 3x4 rows. Every
// group pays for making its palette, so a fused form wins only in large
// groups: 64 x 25k-b4 on an H200 (2026-11-30), CUDA frames of 66 us in groups
// of 64 one vertex an item, 18.2 us in this shape; and 3x4 rows (the same
// affine matrices) are a quarter fewer bytes for each group to make and read:
// pipelined frames 17.0 / 18.7 / 25.0 / 22.9 us in CUDA / NVIDIA OpenCL / GL
// compute / Vulkan against 18.1 / 19.7 / 26.9-27.8 / 24.9 with mat4 rows
// (2026-12-01; docs/ANIMATION.md "The palette in the skin launch").
inline constexpr int kFusedGroup = 256;
inline constexpr int kFusedVerticesPerGroup = 2048;
constexpr Variant InFusedShape(Variant v) {
  v.storage = PaletteStorage::kLocal;
  v.wg_size = kFusedGroup;
  v.vertices_per_item = kFusedVerticesPerGroup / kFusedGroup;
  v.assignment = Assignment::kStrided;
  if (v.palette == PaletteFormat::kMat4) v.palette = PaletteFormat::kMat3x4;
  return v;
}
// Whether its clips are baked as each node's local transform (local*,
// fusedlocal*, and hybrid*, fusedhybrid*, whose cross-fades mix local records).
constexpr bool BakesLocally(Animation a) {
  return a == Animation::kLocal30 || a == Animation::kLocal60 || a == Animation::kLocal120 ||
         a == Animation::kLocal240 || a == Animation::kFusedLocal30 || a == Animation::kFusedLocal60 ||
         a == Animation::kFusedLocal120 || a == Animation::kFusedLocal240 || BakesHybrid(a);
}

// Whether the variant writes normals and tangents packed (not float32).
constexpr bool PacksNormals(const Variant& v) { return v.normal_format != NormalFormat::kF32; }
// The largest distance between a unit vector and the decoding of its packing
// in `format`, over every direction (tests/generator/normal_format_test.cpp
// searches for it): normals; tangents, whose oct16 y keeps one bit less.
// Verification allows it on top of the tolerance.
// (Largest found over 20 million random directions: oct16 6.5e-5, its
// tangents 1.7e-4, snorm8 6.8e-3; the bounds leave a quarter above that.)
constexpr double NormalFormatBound(NormalFormat format) {
  return format == NormalFormat::kOct16 ? 8e-5 : format == NormalFormat::kSnorm8 ? 8.5e-3 : 0.0;
}
constexpr double TangentFormatBound(NormalFormat format) {
  return format == NormalFormat::kOct16 ? 2.2e-4 : NormalFormatBound(format);
}

// Throws Error("variant 'KEY': unknown token 'X' (...)") etc.
Variant ParseVariantKey(std::string_view key);

void to_json(nlohmann::json& out, const Variant& v);
// Throws Error naming the field for a missing/unknown value.
void from_json(const nlohmann::json& in, Variant& v);

// Variant's fields in declaration order: axis i of the table in
// generator/axes.h reads field i. A field added to Variant stops this
// compiling until it is named here, and then axes.cpp's static_asserts until
// it has its axis.
template <typename T>
  requires std::same_as<std::remove_const_t<T>, Variant>
constexpr auto VariantFields(T& v) {
  auto& [lang, influences, mixed, layout, position, index, weight, palette, storage, blend, vertices_per_item,
         assignment, wg_size, normals, morph, normal_format, animation] = v;
  return std::tie(lang, influences, mixed, layout, position, index, weight, palette, storage, blend,
                  vertices_per_item, assignment, wg_size, normals, morph, normal_format, animation);
}
using VariantFieldRefs = decltype(VariantFields(std::declval<Variant&>()));

// The index of Variant's field of type E (each axis enum types one field), or the field count.
template <typename E>
constexpr std::size_t FieldIndexOf() {
  return []<std::size_t... I>(std::index_sequence<I...>) {
    std::size_t index = sizeof...(I);
    ((std::is_same_v<std::tuple_element_t<I, VariantFieldRefs>, E&> ? (void)(index = I) : (void)0), ...);
    return index;
  }(std::make_index_sequence<std::tuple_size_v<VariantFieldRefs>>{});
}
template <typename E>
concept AxisEnum = std::is_enum_v<E> && FieldIndexOf<E>() < std::tuple_size_v<VariantFieldRefs>;

// The name of value `code` of axis `axis` (generator/axes.cpp).
const char* AxisValueName(std::size_t axis, int code);

// Names of axis values, as used in keys, JSON and configs: Name(Layout::kSoaSplit) is "soa-split".
template <AxisEnum E>
const char* Name(E value) {
  return AxisValueName(FieldIndexOf<E>(), static_cast<int>(value));
}

// Byte sizes of the formats (as stored in device buffers).
std::size_t BytesOf(PositionFormat);
std::size_t BytesOf(IndexFormat);
std::size_t BytesOf(WeightFormat);
std::size_t BytesOf(PaletteFormat);

}  // namespace skintune::internal

template <>
struct std::hash<skintune::internal::Variant> {
  std::size_t operator()(const skintune::internal::Variant& v) const { return v.Hash(); }
};
