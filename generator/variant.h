// skintune: a variant = one point of the kernel tuning space.
//
// Every axis value has one meaning in every language, so the same variant is
// the same algorithm on the same bytes in OpenCL, CUDA and GLSL: that is what
// makes the comparison fair. docs/VARIANTS.md explains each axis and why it
// can matter.
//
// Compact key: the axis values joined by '.', in this canonical order:
//   <lang>.b<B>.<mixed>.<layout>.<position>.<index>.<weight>.<palette>.<storage>
//   .<blend>.v<vertices_per_item><c|s>.wg<wg_size>.<normals>
// e.g. "opencl.b4.padded.soa-split.float4.u16.unorm16.mat3x4.local.matrix.v2c.wg256.nonormals".
// Every token is unique across axes, so ParseVariantKey accepts the tokens in
// any order; omitted axes take their default (Variant{}), so "cuda.b2" is a key.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace skintune {

enum class Lang { kOpenCl, kCuda, kGlslCompute, kGlslVertex };
enum class MixedCounts { kPadded, kBucketed };
enum class Layout { kAos, kSoa, kSoaSplit };
enum class PositionFormat { kFloat4, kFloat3 };
enum class IndexFormat { kI32, kU16, kU8 };
enum class WeightFormat { kF32, kUnorm16, kUnorm8 };
enum class PaletteFormat { kMat4, kMat3x4 };
enum class PaletteStorage { kConstant, kLocal, kGlobal, kImage };
enum class Blend { kMatrix, kPoint };
enum class Assignment { kContiguous, kStrided };

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
  bool normals = false;

  std::string Key() const;
  std::size_t Hash() const;  // stable across runs and machines (FNV-1a of Key())
  friend bool operator==(const Variant&, const Variant&) = default;
};

// Throws Error("variant 'KEY': unknown token 'X' (...)") etc.
Variant ParseVariantKey(std::string_view key);

void to_json(nlohmann::json& out, const Variant& v);
// Throws Error naming the field for a missing/unknown value.
void from_json(const nlohmann::json& in, Variant& v);

// Names of axis values, as used in keys, JSON and configs.
const char* Name(Lang);
const char* Name(MixedCounts);
const char* Name(Layout);
const char* Name(PositionFormat);
const char* Name(IndexFormat);
const char* Name(WeightFormat);
const char* Name(PaletteFormat);
const char* Name(PaletteStorage);
const char* Name(Blend);
const char* Name(Assignment);

// Byte sizes of the formats (as stored in device buffers).
std::size_t BytesOf(PositionFormat);
std::size_t BytesOf(IndexFormat);
std::size_t BytesOf(WeightFormat);
std::size_t BytesOf(PaletteFormat);

}  // namespace skintune

template <>
struct std::hash<skintune::Variant> {
  std::size_t operator()(const skintune::Variant& v) const { return v.Hash(); }
};
