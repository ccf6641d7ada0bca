// skintune: the packer turns a SkinnedMesh into exactly the buffers a variant
// reads (docs/VARIANTS.md, "Kernel interface"), and the kernel's outputs back
// into the mesh's vertex order.
//
// - Formats: positions/normals float4 (w = 1 / 0) or float3; indices i32/u16/u8;
//   weights f32, or unorm16/unorm8 quantised by the largest-remainder rule of
//   docs/VARIANTS.md (the kernel contract's item 1, exact to the double
//   operation) so that each vertex's quantised weights sum to exactly
//   65535 / 255.
// - Mixed counts: `padded` keeps every vertex with B slots (zero weights,
//   index 0, in unused slots); `bucketed` orders vertices by their non-zero
//   influence count (stable, so vertex order is kept inside a bucket) and
//   packs each bucket with its own count k as B; one launch per bucket.
// - Every buffer is a byte vector whose size is a multiple of 4 (32-bit words).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "generator/emit.h"  // Output, OutputStrideBytes
#include "generator/variant.h"
#include "model/mesh.h"

namespace skintune::internal {

// Bytes of one tangent, input or output, in every position format: x, y, z,
// then w, the handedness (+1 or -1). Variants that skin tangents use the
// float4 position format, so every output of a variant has one stride.
inline constexpr std::size_t kTangentBytes = 16;

// Bytes of one morph-target offset: float32 x, y, z; or IEEE binary16 x, y,
// z and a zero (8 bytes: one aligned load).
inline constexpr std::size_t kMorphF32OffsetBytes = 12;
inline constexpr std::size_t kMorphHalfOffsetBytes = 8;

struct PackedBuffer {
  std::string name;                // "positions", "indices", "weights", "normals", "tangents", "records"
  std::vector<std::uint8_t> bytes;
};

// One launch: `count` vertices starting at `first` in the packed order, with a
// kernel specialised for `influences` (== variant.influences unless bucketed).
struct Launch {
  std::uint32_t first = 0;
  std::uint32_t count = 0;
  int influences = 0;
  std::uint32_t slot_stride = 0;   // S for soa-split (docs/VARIANTS.md: slot arrays 256-byte aligned), else 0
  std::vector<PackedBuffer> inputs;  // in argument order (docs/VARIANTS.md)
};

struct PackedMesh {
  Variant variant;
  std::size_t vertex_count = 0;
  std::vector<Launch> launches;         // one for padded, one per non-empty bucket for bucketed
  std::vector<std::uint32_t> order;     // packed position p holds mesh vertex order[p]
  std::vector<std::uint8_t> palette;    // float4 rows, R = 4 (mat4) or 3 (mat3x4) per joint
  std::size_t palette_joints = 0;
  std::size_t output_stride_bytes = 0;  // bytes per position output vertex (16 for float4, 12 for float3)
  // Morph targets (variants that skin them): their count T, and the weights
  // the mesh is skinned with as the kernel reads them (T float32, every
  // instance's; or K x T, each instance's, where a caller sets them so), bound
  // until a frame's weights replace them (as `palette` is).
  int morph_targets = 0;
  std::vector<std::uint8_t> morph_weights;
};

// Byte offsets of the fields of one `aos` record: the position at 0, the
// `influences` indices, the weights, then the normal and the tangent (where
// the variant skins them), each
// field at its natural alignment (weights: their element size; a float4 normal:
// 16 bytes; a float3 normal: 4), as in the equivalent C struct; the record size
// is rounded up to 16 bytes (float4) or 4 bytes (float3).
// E.g. float4 + b4 u16 + unorm8 = 16 + 8 + 4 -> 32; float3 + b1 u8 + unorm8 ->
// 12 + 1 + 1 -> 16; float3 + b3 u8 + f32 -> 12 + 3 (+1) + 12 -> 28.
struct RecordLayout {
  std::size_t position = 0;  // always 0
  std::size_t indices = 0;
  std::size_t weights = 0;
  std::size_t normal = 0;    // 0 when the variant has no normals
  std::size_t tangent = 0;   // after the normal (4 floats); 0 when the variant has no tangents
  std::size_t size = 0;      // bytes per record (the record stride)
};
RecordLayout AosRecordLayout(const Variant& variant, int influences);

// Slot stride S of `soa-split` for a launch of `count` vertices: `count`
// rounded up so that every slot array of both the index and the weight format
// starts on a 256-byte boundary and S is a multiple of 64: a multiple of 64
// when both formats are 4 bytes, of 128 when the narrower is 2 bytes, of 256
// when it is 1 byte. Kernels compute the same S from n.
std::uint32_t SoaSplitSlotStride(std::uint32_t count, const Variant& variant);

// Throws Error when the variant cannot hold the mesh (influences below the
// mesh's largest count, joints beyond the index format, normals missing).
PackedMesh Pack(const SkinnedMesh& mesh, const Variant& variant);

// Morph weights as the kernel reads them: float32, T per instance.
std::vector<std::uint8_t> PackMorphWeights(std::span<const double> weights);
// The IEEE binary16 bits nearest `value` (ties to even; overflow to
// infinity): a half morph offset's components.
std::uint16_t HalfBits(float value);
float HalfValue(std::uint16_t bits);

// Palette rows in the variant's palette format (call per frame). Throws
// Error (NotRigid) for a dual-quaternion palette with a joint that scales,
// shears or mirrors.
std::vector<std::uint8_t> PackPalette(std::span<const glm::mat4> palette, const Variant& variant);
// Why palette entry `entry` cannot be a dual quaternion ("palette entry 3 is
// not a rigid transform: max |(A^T A - I)_ij| ... ").
std::string NotRigid(const glm::mat4& matrix, std::size_t entry);
// PackPalette's bytes of `matrices` column-major 4x4 float matrices (16
// floats each, as glm::mat4 stores them) written into `out`, which holds
// matrices x PaletteRowBytes(variant) bytes, in one pass (the runtime packs
// straight into its page-locked staging). Returns the index of the first
// matrix with a NaN or infinite element (for the dualquat format also one
// that is not rigid: NotRigid says why), or `matrices` when every element
// is finite. `largest_magnitude`, where given, receives the largest |element|
// of them all (meaningful when every element is finite; 0 for no matrices):
// the runtime's bound on the outputs (runtime/skinner.cpp, the read-back).
//
// `isa` picks the code path: kAuto the best this CPU has (AVX-512: a matrix
// a load, one permute and one masked store; 2.2x the baseline's speed on the
// development machine), the others for tests (PackIsaAvailable says which run here).
enum class PackIsa { kAuto, kBaseline, kAvx512 };
bool PackIsaAvailable(PackIsa isa);
std::size_t PackPaletteInto(const float* column_major, std::size_t matrices, const Variant& variant, std::uint8_t* out,
                            PackIsa isa = PackIsa::kAuto, float* largest_magnitude = nullptr);
// Bytes of one packed matrix: 64 (mat4), 48 (mat3x4) or 32 (dualquat).
std::size_t PaletteMatrixBytes(const Variant& variant);

// Output bytes in packed order (vertex_count x output_stride_bytes) -> one
// glm::vec3 per mesh vertex, in the mesh's order.
std::vector<glm::vec3> Unpack(const PackedMesh& packed, std::span<const std::uint8_t> output);
// The normal output likewise (vertex_count x OutputStrideBytes(variant,
// kNormals)), decoded where the variant packs normals (normal_format).
std::vector<glm::vec3> UnpackNormals(const PackedMesh& packed, std::span<const std::uint8_t> output);
// The tangent output likewise: xyz and the handedness w per mesh vertex.
std::vector<glm::vec4> UnpackTangents(const PackedMesh& packed, std::span<const std::uint8_t> output);
// The packed words of normals and tangents (docs/VARIANTS.md "Packed normals
// and tangents"; the emitted header's PackNormal / PackTangent rule, which the
// kernels run): 0 for NormalFormat::kF32.
std::uint32_t PackedNormalWord(NormalFormat format, const glm::vec3& normal);
std::uint32_t PackedTangentWord(NormalFormat format, const glm::vec4& tangent);
glm::vec3 UnpackedNormal(NormalFormat format, std::uint32_t word);
glm::vec4 UnpackedTangent(NormalFormat format, std::uint32_t word);

// The mesh the kernel really skins: weights after quantisation, as floats, in
// the mesh's vertex order (so the gold can be computed on exactly these
// values); morph offsets as half where the variant stores them so (the
// weights are a frame's input, as the palette is: not the variant's choice).
SkinnedMesh QuantisedMesh(const SkinnedMesh& mesh, const Variant& variant);

// Whether `format` holds the mesh's weights exactly: QuantisedMesh changes
// none of them (always for f32; for unorm8 / unorm16 when every weight is
// k / 255 or k / 65535, as a glTF's normalized WEIGHTS are, and each vertex's
// sum to 1 on that grid). Such a format costs no precision (zero quantisation
// error). Throws Error for an invalid mesh, as QuantisedMesh does.
bool HoldsWeightsExactly(const SkinnedMesh& mesh, WeightFormat format);

}  // namespace skintune::internal
