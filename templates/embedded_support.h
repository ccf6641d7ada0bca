// skintune embedded kernels: the hand-written part of the header that
// `skintune emit --db DB.json --device PATTERN --out DIR` generates
// (templates/embedded_support.h in skintune's sources; docs/RUNTIME.md
// "Emitting kernels into other builds").
//
// The generated header holds the winning kernels of a winners database for
// the devices that matched, each specialised for one palette size, with
// everything a program needs to bind and launch them: the kernel text, its
// variant parameters, its argument list, its launch geometry, and helpers that
// pack a mesh and a palette into exactly the bytes the kernel reads. It needs
// only the C++17 standard library: no skintune library, no OpenCL, CUDA or GL
// header. The generator replaces the namespace `skintune_kernels` below by the
// one asked for (--namespace) and the placeholder kernel table by the real one
// (templates/embedded_support.h alone compiles, with an empty table).
//
// Typical use:
//
//   #include "skintune_kernels.h"
//   const skintune_kernels::Kernel* k = skintune_kernels::FindKernel("opencl", 4, vertex_count, joint_count);
//   skintune_kernels::PackedInputs in;
//   std::string error;
//   if (!k || !skintune_kernels::PackMesh(*k, vertex_count, 4, positions, nullptr, joints, weights, &in, &error))
//     ...;
//   // build k->source (entry point k->entry_point), upload in.positions / in.indices / in.weights (or
//   // in.records), then per frame:
//   std::vector<float> palette = skintune_kernels::PackPalette(*k, matrices, joint_count);
//   // bind the arguments in the order of k->arguments (n, first = 0, inputs, palette, outputs) and
//   // launch skintune_kernels::GlobalWorkItems(*k, vertex_count) work items in groups of k->wg_size;
//   skintune_kernels::UnpackPositions(*k, output_bytes, vertex_count, xyz);
//
// The kernel interface (skintune's docs/VARIANTS.md "Kernel interface"):
//
// - Every buffer is an array of 32-bit words; narrower formats are packed
//   little-endian into words. Positions, normals and outputs use the kernel's
//   `position` format: kFloat4 = 4 floats per vertex (w = 1 for positions,
//   0 for normals), kFloat3 = 3 packed floats.
// - Inputs per layout (PackMesh fills exactly these):
//     kAos      `records`: one record per vertex: the position at byte 0, the
//               B indices right after it, the B weights aligned to their
//               element size, then the normal (when k.normals) aligned to 16
//               bytes (kFloat4) or 4 (kFloat3); the record is padded to a
//               multiple of 16 (kFloat4) or 4 (kFloat3) bytes.
//     kSoa      `positions`, `indices` (vertex v's slot i at element v*B+i),
//               `weights` (likewise), `normals` (like positions, when k.normals).
//     kSoaSplit `positions`, `normals` as kSoa; `indices` and `weights`
//               slot-major: element i*S+v with S = SlotStride(k, n), so every
//               slot's array starts on a 256-byte boundary.
//   B is k.influences; vertices with fewer influences have index 0 weight 0
//   in their unused slots. Quantised weights (kUnorm16 / kUnorm8) sum to
//   exactly 65535 / 255 per vertex.
// - The palette: k.joints entries (the kernel is specialised for that many:
//   bind a buffer of exactly k.joints entries, PackPalette pads with identity
//   matrices), each entry the R float4 *rows* of its matrix, R = 4 (kMat4) or
//   3 (kMat3x4: the affine 0 0 0 1 row is not stored); joint j row r at float4
//   j*R+r. kImage storage reads it as an image / texture over that buffer
//   (OpenCL image1d_buffer_t; CUDA texture object, linear, CU_AD_FORMAT_FLOAT,
//   4 channels, point filtering; GLSL samplerBuffer). CUDA kConstant storage
//   reads the module's __constant__ symbol `skintune_palette` (fill it with
//   cuModuleGetGlobal + a copy before the launch; the palette argument is still
//   passed, not read).
// - Arguments: k.arguments in kernel argument order, the same list as the
//   sidecar JSON `<variant>.json` that skintune writes beside the kernel file:
//   OpenCL / CUDA `skin(uint n, uint first, <inputs>, palette, <outputs>)`,
//   inputs `records` (aos) or `positions, indices, weights` then `normals`
//   (when k.normals), outputs `out_positions` then `out_normals`. GLSL:
//   scalars are uniforms of the same name; buffers and the palette take the
//   bindings 0, 1, 2, ... in argument order; glsl-vertex captures its outputs
//   with transform feedback (separate attributes: varying `out_position` into
//   feedback buffer 0, `out_normal` into 1) instead of storage buffers.
// - Outputs: vertex v is written at element first + v, so pass first = 0 when
//   one launch skins the whole mesh (it always does here: every kernel of this
//   header is `padded`, in mesh order). Output buffers hold n elements of
//   OutputStrideBytes(k) bytes.
// - Launch: GlobalWorkItems(k, n) work items (ceil(n / vertices_per_item)
//   rounded up to a multiple of wg_size) in work-groups of k.wg_size; OpenCL
//   global size = that, CUDA grid = that / wg_size blocks of wg_size threads,
//   glDispatchCompute(that / wg_size, 1, 1). glsl-vertex (wg_size 0): draw n
//   points, glDrawArrays(GL_POINTS, 0, n), with rasterisation discarded. The
//   rule in words: k.launch_rule.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace skintune_kernels {

// The variant axes (skintune's docs/VARIANTS.md "Axes").
enum class Layout { kAos, kSoa, kSoaSplit };
enum class PositionFormat { kFloat4, kFloat3 };   // also the format of normals and outputs
enum class IndexFormat { kI32, kU16, kU8 };        // joint index: 4, 2, 1 bytes
enum class WeightFormat { kF32, kUnorm16, kUnorm8 };
enum class PaletteFormat { kMat4, kMat3x4 };       // R = 4 or 3 float4 rows per joint
enum class PaletteStorage { kGlobal, kConstant, kLocal, kImage };

// One kernel argument, as the sidecar JSON describes it.
struct Argument {
  const char* name;         // "n", "first", "records", "positions", "indices", "weights", "normals",
                            // "palette", "out_positions", "out_normals"
  const char* format;       // "u32", "float4", "float3", "i32", "u16", "u8", "f32", "unorm16", "unorm8",
                            // "record", "float4 rows"
  unsigned element_bytes;   // one element of `format` (a whole record for "record")
  unsigned stride_bytes;    // between consecutive vertices (palette: between joints; 0 for scalars)
  const char* indexing;     // where vertex v's data is: "v", "v*B+i", "i*S+v", "first+v", "j*R+r" ("" for scalars)
  bool output;              // written by the kernel
  bool scalar;              // a 32-bit scalar (GLSL: a uniform)
  bool image;               // the palette as an image / texture (kImage storage)
};

// One winning kernel: which device and problem it won on, its parameters, its
// text and its interface.
struct Kernel {
  // The device it won on (skintune device id "<backend>:<platform>/<name>/<driver_version>" and its parts).
  const char* device_id;
  const char* platform;
  const char* vendor;          // "" when the database does not say
  const char* device_name;
  const char* driver_version;
  const char* device_type;     // "gpu", "cpu", ...; "" when the database does not say
  const char* lang;            // "opencl", "cuda", "glsl-compute", "glsl-vertex", "vulkan"
  int influences;              // B the kernel is specialised for
  const char* vertex_bucket;   // "25k" | "100k" | "400k" | "1600k": the bucket of `vertices`
  std::size_t vertices;        // the vertex count of the mesh it won on (one kernel per measured count)
  const char* variant;         // variant key (always `padded`: a `bucketed` winner is emitted as its padded twin)
  Layout layout;
  PositionFormat position;
  IndexFormat index;
  WeightFormat weight;
  PaletteFormat palette;
  PaletteStorage storage;
  bool point_blend;            // blends transformed points (else blends matrices): no effect on the interface
  bool normals;                // also skins normals: a `normals` input and an `out_normals` output
  int vertices_per_item;       // 1, 2, 4, 8
  bool strided;                // item g skins g, g+G, ... (else g*N .. g*N+N-1)
  int wg_size;                 // work-group size (0 for glsl-vertex)
  int joints;                  // palette entries the kernel is specialised for
  const char* entry_point;     // "skin" (OpenCL, CUDA) / "main" (GLSL)
  const char* source;          // the whole kernel text, NUL-terminated
  const char* source_hash;     // FNV-1a 64 of `source`, 16 hex digits (skintune's program cache key)
  const std::uint32_t* spirv;  // vulkan: `source` compiled to SPIR-V (vkCreateShaderModule's pCode); else null
  std::size_t spirv_words;     // its length in 32-bit words (codeSize = 4 x this); 0 without SPIR-V
  const Argument* arguments;   // in kernel argument order, as in the sidecar
  int argument_count;
  const char* launch_rule;     // the launch geometry in words
  double median_ms;            // the winning time, on `dataset`
  double gbps;
  double copy_fraction;        // gbps / the device's copy bandwidth (0 when unknown)
  const char* dataset;
};

// skintune:kernel-table-begin
// The generator replaces this placeholder, from the marker above to the one
// below, by the kernel table:
//   inline constexpr double kMaxError = <--max-error>;
//   inline constexpr int kKernelCount = <count>;
//   inline constexpr Kernel kKernels[kKernelCount] = {...};
// (inline variables: one object however many translation units include it).
// kMaxError is the error budget the kernels were chosen under (skintune emit
// --db --max-error, default 1e-4), relative to the tuning mesh's bounding-box
// diagonal: of each winner's precision classes (weight formats) the fastest
// whose quantisation costs at most this much; f32 costs nothing.
inline constexpr double kMaxError = 0.0;
inline constexpr int kKernelCount = 0;
inline constexpr const Kernel* kKernels = nullptr;
// skintune:kernel-table-end

namespace detail {

// How far a kernel measured on `measured` vertices is from a mesh of `mesh`: a
// factor, max/min (25k is as far from 50k as 1600k from 3200k).
inline double VertexCountDistance(std::size_t measured, std::size_t mesh) {
  const double a = static_cast<double>(measured > 0 ? measured : 1);
  const double b = static_cast<double>(mesh > 0 ? mesh : 1);
  return a > b ? a / b : b / a;
}

inline std::uint64_t IndexCapacity(IndexFormat f) {  // joints the format can address
  return f == IndexFormat::kU8 ? 256u : f == IndexFormat::kU16 ? 65536u : 0x80000000u;
}

inline std::size_t IndexBytes(IndexFormat f) { return f == IndexFormat::kU8 ? 1 : f == IndexFormat::kU16 ? 2 : 4; }
inline std::size_t WeightBytes(WeightFormat f) {
  return f == WeightFormat::kUnorm8 ? 1 : f == WeightFormat::kUnorm16 ? 2 : 4;
}
inline std::size_t VectorBytes(PositionFormat f) { return f == PositionFormat::kFloat4 ? 16 : 12; }
inline std::size_t RoundUp(std::size_t x, std::size_t multiple) { return (x + multiple - 1) / multiple * multiple; }

inline const char* IndexName(IndexFormat f) {
  return f == IndexFormat::kU8 ? "u8" : f == IndexFormat::kU16 ? "u16" : "i32";
}

inline void PutUint(std::uint8_t* at, std::uint32_t value, std::size_t bytes) {
  for (std::size_t b = 0; b < bytes; ++b) at[b] = static_cast<std::uint8_t>(value >> (8 * b));
}

inline std::uint32_t FloatBits(float value) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  return bits;
}

inline void PutFloat(std::uint8_t* at, float value) { PutUint(at, FloatBits(value), 4); }

// xyz, then w for float4 (1 for positions, 0 for normals).
inline void PutVector(std::uint8_t* at, const float* xyz, PositionFormat format, float w) {
  PutFloat(at, xyz[0]);
  PutFloat(at + 4, xyz[1]);
  PutFloat(at + 8, xyz[2]);
  if (format == PositionFormat::kFloat4) PutFloat(at + 12, w);
}

// skintune's quantisation of one vertex's weights w_0 .. w_(B-1) (B =
// `slots`) to integers q_0 .. q_(B-1) summing to exactly M = `max` (65535 or
// 255). The weights must be finite and non-negative, and not all zero
// (PackMesh refuses others). The rule (skintune's docs/VARIANTS.md, the
// kernel contract's item 1, in the same words):
// In IEEE 754 double precision (binary64), each operation rounded to nearest, ties to even:
// 1. s = ((w_0 + w_1) + w_2) + ... + w_(B-1): the float32 weights converted to double (exactly)
//    and added in slot order.
// 2. t_i = (w_i / s) x M: the quotient rounded to double, then the product rounded to double.
// 3. q_i = floor(t_i) and r_i = t_i - q_i (exact in double).
// 4. D = M - (q_0 + ... + q_(B-1)): the quanta still missing, at most the number of non-zero
//    weights.
// 5. The D slots of non-zero weight with the largest r_i get one quantum more each; of equal r_i
//    the earlier slot (smaller i) comes first. A zero weight stays 0.
inline void QuantiseVertex(const float* w, int slots, std::uint32_t max, std::uint32_t* q) {
  double s = 0.0;
  for (int i = 0; i < slots; ++i) s += static_cast<double>(w[i]);
  double r[8] = {};
  std::uint32_t sum = 0;
  for (int i = 0; i < slots; ++i) {
    const double t = static_cast<double>(w[i]) / s * static_cast<double>(max);
    const double whole = std::floor(t);
    q[i] = static_cast<std::uint32_t>(whole);
    r[i] = w[i] > 0.0f ? t - whole : -1.0;  // -1: a zero weight gets no quantum
    sum += q[i];
  }
  for (std::uint32_t missing = max - sum; missing > 0; --missing) {
    int best = 0;
    for (int i = 1; i < slots; ++i) best = r[i] > r[best] ? i : best;  // strictly larger: the earlier on a tie
    if (r[best] < 0.0) break;  // unreachable for valid weights: D never exceeds the non-zero ones
    ++q[best];
    r[best] = -1.0;  // one quantum per slot
  }
}

}  // namespace detail

// The kernel for a mesh of `vertex_count` vertices whose vertices use at most
// `influences` bones and whose palette has `joint_count` joints: among the
// kernels of `lang` ("opencl", "cuda", "glsl-compute", "glsl-vertex") whose
// `joints` >= joint_count and whose index format can address joint_count
// joints (u8: 256, u16: 65536), the smallest B >= influences wins, then the
// nearest measured vertex count (as a factor; the larger on a tie), then the
// first in kKernels.
// Kernels of every device of the header take part (check k->device_id, or
// generate one header per device). nullptr if none fits, or for a null `lang`,
// influences < 1 or joint_count < 1. Check k->normals yourself when you skin
// normals.
inline const Kernel* FindKernel(const char* lang, int influences, std::size_t vertex_count, int joint_count) {
  if (lang == nullptr || influences < 1 || joint_count < 1) return nullptr;
  const Kernel* best = nullptr;
  double best_distance = 0.0;
  for (int i = 0; i < kKernelCount; ++i) {
    const Kernel& k = kKernels[i];
    if (std::strcmp(k.lang, lang) != 0 || k.influences < influences || k.joints < joint_count ||
        static_cast<std::uint64_t>(joint_count) > detail::IndexCapacity(k.index))
      continue;
    const double distance = detail::VertexCountDistance(k.vertices, vertex_count);
    if (best == nullptr || k.influences < best->influences ||
        (k.influences == best->influences &&
         (distance < best_distance || (distance == best_distance && k.vertices > best->vertices)))) {
      best = &k;
      best_distance = distance;
    }
  }
  return best;
}

// Work items for a launch of n vertices: ceil(n / vertices_per_item) rounded
// up to a multiple of wg_size (glsl-vertex, wg_size 0: n, the points drawn).
inline std::size_t GlobalWorkItems(const Kernel& k, std::size_t n) {
  const std::size_t per_item = static_cast<std::size_t>(k.vertices_per_item > 1 ? k.vertices_per_item : 1);
  const std::size_t wg = static_cast<std::size_t>(k.wg_size > 1 ? k.wg_size : 1);
  return detail::RoundUp((n + per_item - 1) / per_item, wg);
}

// The slot stride S of kSoaSplit for n vertices: n (at least 1) rounded up to a
// multiple of 64 when both the index and the weight format are 4 bytes, of 128
// when the narrower is 2 bytes, of 256 when it is 1 byte, so every slot array
// starts on a 256-byte boundary (the kernel derives the same S from n). 0 for
// the other layouts.
inline std::size_t SlotStride(const Kernel& k, std::size_t n) {
  if (k.layout != Layout::kSoaSplit) return 0;
  const std::size_t ib = detail::IndexBytes(k.index), wb = detail::WeightBytes(k.weight);
  const std::size_t narrowest = ib < wb ? ib : wb;
  const std::size_t multiple = 256 / narrowest > 64 ? 256 / narrowest : 64;
  return detail::RoundUp(n > 0 ? n : 1, multiple);
}

// Bytes per output vertex (and per position / normal input): 16 for kFloat4, 12 for kFloat3.
inline std::size_t OutputStrideBytes(const Kernel& k) { return detail::VectorBytes(k.position); }

// The kernel's input buffers. Only the layout's buffers are non-empty: kAos
// `records`; kSoa and kSoaSplit `positions`, `indices`, `weights`, and
// `normals` when k.normals. Every size is a multiple of 4 bytes (32-bit words).
struct PackedInputs {
  std::vector<std::uint8_t> records, positions, indices, weights, normals;
};

// Packs a mesh of n vertices into the kernel's input buffers, byte for byte
// as skintune's packer does for the kernel's (padded) variant:
//   positions  3 floats per vertex (x y z); normals likewise, required when
//              k.normals (may be null otherwise, then ignored);
//   joints     `influences` joint indices per vertex (slot i of vertex v at
//              v*influences+i), each < k.joints and addressable by k.index;
//   weights    `influences` weights per vertex, same order; kF32 stores them
//              as given, kUnorm16 / kUnorm8 quantise each vertex's weights
//              by QuantiseVertex's rule so they sum to exactly 65535 / 255;
//              zero weights stay 0. Every weight finite and >= 0, and not
//              all of a vertex's zero.
// influences may be below k.influences: the unused slots get index 0 and
// weight 0. Returns false and sets *error (when error is not null) for
// out == null, n == 0 or n >= 2^32, influences outside 1..k.influences, null
// positions / joints / weights, normals missing when k.normals, a negative or
// non-finite weight, a vertex whose weights are all zero, or a joint
// index the index format cannot hold or >= k.joints.
inline bool PackMesh(const Kernel& k, std::size_t n, int influences, const float* positions, const float* normals,
                     const std::uint32_t* joints, const float* weights, PackedInputs* out, std::string* error) {
  const auto fail = [error, &k](const std::string& message) {
    if (error != nullptr) *error = "PackMesh " + std::string(k.variant) + ": " + message;
    return false;
  };
  if (out == nullptr) return fail("no output (out is null)");
  *out = PackedInputs{};
  if (n == 0) return fail("no vertices");
  if (n > 0xffffffffu) return fail(std::to_string(n) + " vertices do not fit 32-bit vertex indices");
  if (influences < 1 || influences > k.influences)
    return fail("influences " + std::to_string(influences) + " outside 1.." + std::to_string(k.influences) +
                " (the kernel's B)");
  if (positions == nullptr) return fail("positions is null");
  if (joints == nullptr) return fail("joints is null");
  if (weights == nullptr) return fail("weights is null");
  if (k.normals && normals == nullptr) return fail("the kernel skins normals but normals is null");
  const std::size_t slots = static_cast<std::size_t>(influences);
  const std::uint64_t capacity = detail::IndexCapacity(k.index);
  for (std::size_t s = 0; s < n * slots; ++s) {
    if (joints[s] < capacity && joints[s] < static_cast<std::uint32_t>(k.joints)) continue;
    const std::string where = "vertex " + std::to_string(s / slots) + " slot " + std::to_string(s % slots) +
                              ": joint " + std::to_string(joints[s]);
    if (joints[s] >= capacity)
      return fail(where + " does not fit " + detail::IndexName(k.index) + " indices (at most " +
                  std::to_string(capacity - 1) + ")");
    return fail(where + " out of range (the kernel has " + std::to_string(k.joints) + " joints)");
  }
  // The weights the contract covers: finite, non-negative, not all zero per
  // vertex (a quantised format divides by their sum).
  for (std::size_t v = 0; v < n; ++v) {
    bool any = false;
    for (std::size_t i = 0; i < slots; ++i) {
      const float w = weights[v * slots + i];
      if (!(w >= 0.0f) || w > 3.4028234663852886e38f) {
        char text[96];
        std::snprintf(text, sizeof text, "vertex %zu slot %zu: weight %g is %s", v, i, static_cast<double>(w),
                      w < 0.0f ? "negative" : "not finite");
        return fail(text);
      }
      any = any || w > 0.0f;
    }
    if (!any) return fail("vertex " + std::to_string(v) + ": all weights are zero");
  }

  const std::size_t b = static_cast<std::size_t>(k.influences);
  const std::size_t pb = detail::VectorBytes(k.position);
  const std::size_t ib = detail::IndexBytes(k.index);
  const std::size_t wb = detail::WeightBytes(k.weight);
  // The 32-bit value of every slot: index and weight word (float bits or quantised integer).
  std::uint32_t index_words[8] = {};
  std::uint32_t weight_words[8] = {};
  const auto gather = [&](std::size_t v) {
    for (std::size_t i = 0; i < b; ++i) index_words[i] = weight_words[i] = 0;
    const float* w = weights + v * slots;
    if (k.weight == WeightFormat::kF32) {
      for (std::size_t i = 0; i < slots; ++i) weight_words[i] = detail::FloatBits(w[i]);
    } else {
      detail::QuantiseVertex(w, influences, k.weight == WeightFormat::kUnorm16 ? 65535u : 255u, weight_words);
    }
    for (std::size_t i = 0; i < slots; ++i) index_words[i] = joints[v * slots + i];
  };

  if (k.layout == Layout::kAos) {
    const std::size_t align = k.position == PositionFormat::kFloat4 ? 16 : 4;
    const std::size_t index_at = pb;
    const std::size_t weight_at = detail::RoundUp(index_at + b * ib, wb);
    std::size_t end = weight_at + b * wb;
    std::size_t normal_at = 0;
    if (k.normals) {
      normal_at = detail::RoundUp(end, align);
      end = normal_at + pb;
    }
    const std::size_t size = detail::RoundUp(end, align);
    out->records.assign(n * size, 0);
    for (std::size_t v = 0; v < n; ++v) {
      std::uint8_t* record = out->records.data() + v * size;
      detail::PutVector(record, positions + 3 * v, k.position, 1.0f);
      gather(v);
      for (std::size_t i = 0; i < b; ++i) {
        detail::PutUint(record + index_at + i * ib, index_words[i], ib);
        detail::PutUint(record + weight_at + i * wb, weight_words[i], wb);
      }
      if (k.normals) detail::PutVector(record + normal_at, normals + 3 * v, k.position, 0.0f);
    }
    return true;
  }

  const bool split = k.layout == Layout::kSoaSplit;
  const std::size_t stride = SlotStride(k, n);
  const std::size_t elements = split ? b * stride : b * n;
  out->positions.assign(n * pb, 0);
  out->indices.assign(detail::RoundUp(elements * ib, 4), 0);
  out->weights.assign(detail::RoundUp(elements * wb, 4), 0);
  if (k.normals) out->normals.assign(n * pb, 0);
  for (std::size_t v = 0; v < n; ++v) {
    detail::PutVector(out->positions.data() + v * pb, positions + 3 * v, k.position, 1.0f);
    if (k.normals) detail::PutVector(out->normals.data() + v * pb, normals + 3 * v, k.position, 0.0f);
    gather(v);
    for (std::size_t i = 0; i < b; ++i) {
      const std::size_t e = split ? i * stride + v : v * b + i;
      detail::PutUint(out->indices.data() + e * ib, index_words[i], ib);
      detail::PutUint(out->weights.data() + e * wb, weight_words[i], wb);
    }
  }
  return true;
}

// The palette buffer in the kernel's format, as floats (upload them as they
// are): `joint_count` matrices, each 16 floats column-major (glm's layout:
// element (row r, column c) at c*4+r), become R = 4 (kMat4) or 3 (kMat3x4)
// float4 rows per joint, joint j row r at float4 j*R+r, followed by identity
// matrices up to k.joints entries (the kernel is specialised for k.joints:
// the buffer always holds k.joints*R*4 floats). Empty for joint_count < 0,
// joint_count > k.joints, or null matrices with joint_count > 0.
inline std::vector<float> PackPalette(const Kernel& k, const float* matrices, int joint_count) {
  if (joint_count < 0 || joint_count > k.joints || (matrices == nullptr && joint_count > 0)) return {};
  const std::size_t rows = k.palette == PaletteFormat::kMat4 ? 4 : 3;
  std::vector<float> out(static_cast<std::size_t>(k.joints) * rows * 4, 0.0f);
  float* at = out.data();
  for (int j = 0; j < k.joints; ++j) {
    for (std::size_t r = 0; r < rows; ++r) {
      for (std::size_t c = 0; c < 4; ++c, ++at) {
        *at = j < joint_count ? matrices[static_cast<std::size_t>(j) * 16 + c * 4 + r] : (c == r ? 1.0f : 0.0f);
      }
    }
  }
  return out;
}

// The output buffer (n vertices of OutputStrideBytes(k) bytes, as read back
// from out_positions or out_normals) -> 3 floats per vertex into xyz (3*n
// floats), in the mesh's order.
inline void UnpackPositions(const Kernel& k, const void* output, std::size_t n, float* xyz) {
  const std::size_t stride = OutputStrideBytes(k);
  const auto* bytes = static_cast<const unsigned char*>(output);
  for (std::size_t v = 0; v < n; ++v) std::memcpy(xyz + 3 * v, bytes + v * stride, 3 * sizeof(float));
}

}  // namespace skintune_kernels
