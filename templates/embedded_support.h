// skintune embedded kernels: the hand-written part of the header that
// `skintune emit --db DB.json --device PATTERN --out DIR` generates
// (templates/embedded_support.h in skintune's sources; docs/RUNTIME.md
// "Emitting kernels into other builds").
//
// The generated header holds the winning kernels of a winners database for
// the devices that matched, each specialised for one palette size, with
// everything a program needs to bind and launch them: the kernel text, its
// variant parameters, its argument list, its launch geometry, and helpers that
// pack a mesh and a palette into exactly the bytes the kernel reads. Winners
// tuned on a crowd (K instances of one mesh per launch) are instanced kernels,
// winners tuned on a batch (different meshes packed as one) plain kernels for
// the batch's palette; each kernel says which scene it won on (`shape`,
// `instances`, `meshes`), and FindKernel, FindCrowdKernel and FindBatchKernel
// pick by it. It needs
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
// A crowd of K instances of the mesh in one launch: FindCrowdKernel(lang, 4,
// vertex_count, joint_count, K), the same PackMesh, PackPalette(*k, matrices,
// joint_count, K) with instance i's matrices at matrices + i*joint_count*16,
// one more scalar argument (vertex_count, after first), a second launch
// dimension of K (below), and K*vertex_count output vertices, instance after
// instance. A batch of different meshes in one launch: PackBatch (the meshes
// as one), FindBatchKernel with the batch's totals, PackPalette of every
// mesh's matrices one after another, and the plain launch over the batch.
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
//               bytes (kFloat4) or 4 (kFloat3), then the tangent (when
//               k.tangents: 4 floats) aligned likewise; the record is padded
//               to a multiple of 16 (kFloat4) or 4 (kFloat3) bytes.
//     kSoa      `positions`, `indices` (vertex v's slot i at element v*B+i),
//               `weights` (likewise), `normals` (like positions, when k.normals),
//               `tangents` (4 floats per vertex, when k.tangents).
//     kSoaSplit `positions`, `normals`, `tangents` as kSoa; `indices` and `weights`
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
//   OutputStrideBytes(k) bytes (out_normals: NormalStrideBytes(k);
//   out_tangents: TangentStrideBytes(k); a packed k.normal_format writes one
//   32-bit word a vector, which UnpackNormal / UnpackTangent decode).
// - Crowds (k.instanced, shape "instances"; skintune's docs/VARIANTS.md
//   "Instancing"): the arguments are skin(n, first, vertex_count, ...) with
//   vertex_count = n (GLSL: uniform vertex_count; glsl-vertex has none); the
//   palette buffer holds K palettes, instance i's joint j row r at float4
//   (i*k.joints + j)*R + r (an image over it is k.joints*R*K texels wide);
//   instance i's vertex v is written at element i*n + v (K*n elements). The
//   instance is the launch's second dimension: OpenCL global size
//   (GlobalWorkItems(k, n), K) with local size (k.wg_size, 1), CUDA grid
//   (GlobalWorkItems(k, n) / wg_size, K), glDispatchCompute(groups, K, 1),
//   glsl-vertex glDrawArraysInstanced(GL_POINTS, 0, n, K). A kernel whose
//   palette lives in a compile-time array (CUDA kConstant, GLSL kConstant)
//   holds k.max_instances palettes: a launch skins at most that many; 0 for
//   the others (any K).
// - Batches (shape "batch"; skintune's docs/VARIANTS.md "Batches"): a plain
//   kernel skinning several meshes packed as one (PackBatch): mesh m's
//   vertices follow the earlier meshes' (its outputs at
//   offsets.vertices[m] + v), its joint j is palette entry
//   offsets.joints[m] + j, and every mesh is padded to the batch's B with
//   zero-weight slots naming its own first joint. k.joints holds the
//   meshes' palettes together.
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
#include <utility>
#include <vector>

namespace skintune_kernels {

// The variant axes (skintune's docs/VARIANTS.md "Axes").
enum class Layout { kAos, kSoa, kSoaSplit };
enum class PositionFormat { kFloat4, kFloat3 };   // also the format of normals and outputs
enum class IndexFormat { kI32, kU16, kU8 };        // joint index: 4, 2, 1 bytes
enum class WeightFormat { kF32, kUnorm16, kUnorm8 };
enum class PaletteFormat { kMat4, kMat3x4, kDualquat };  // R = 4, 3 or 2 float4 rows per joint
                                                                // (kDualquat: the kernel blends
                                                                // unit dual quaternions, not matrices)
enum class PaletteStorage { kGlobal, kConstant, kLocal, kImage };
// Morph targets applied before skinning (skintune's docs/VARIANTS.md "Morph
// targets"): none, or their offsets dense or sparse, float32 or half.
enum class Morph { kNone, kDense, kSparse, kDenseHalf, kSparseHalf };
// The format of the skinned normals and tangents (skintune's docs/VARIANTS.md
// "Packed normals and tangents"): kF32 (normals in the position format,
// tangents 4 floats), or one 32-bit word per normal and per tangent:
// kOct16 octahedral 2 x unorm16 (Godot 4's layout), kSnorm8 4 x snorm8.
enum class NormalFormat { kF32, kOct16, kSnorm8 };

// The packed words, by the rule the kernels run (float32 arithmetic, in this
// order; docs/VARIANTS.md gives it step by step). `xyz` is a unit vector (the
// kernels normalise first); a tangent's w is its handedness, +1 or -1 (any
// w >= 0 counts as +1). kF32 has no word: 0.
namespace detail {
inline float SignNotZero(float v) { return v >= 0.0f ? 1.0f : -1.0f; }
// floor(v * scale + 0.5) of v clamped to [lo, 1]: the nearest step (ties up).
inline int Quantise(float v, float lo, float scale) {
  const float c = v < lo ? lo : (v > 1.0f ? 1.0f : v);
  return static_cast<int>(std::floor(c * scale + 0.5f));
}
// The octahedral coordinates of a unit vector, each in [0, 1].
inline void OctahedralOf(const float* xyz, float* uv) {
  const float s = std::fabs(xyz[0]) + std::fabs(xyz[1]) + std::fabs(xyz[2]);
  float u = xyz[0] / s, v = xyz[1] / s;
  if (xyz[2] < 0.0f) {
    const float fu = (1.0f - std::fabs(v)) * SignNotZero(u);
    v = (1.0f - std::fabs(u)) * SignNotZero(v);
    u = fu;
  }
  uv[0] = u * 0.5f + 0.5f;
  uv[1] = v * 0.5f + 0.5f;
}
// The unit vector of octahedral coordinates in [0, 1] (as Godot decodes).
inline void FromOctahedral(float u, float v, float* xyz) {
  float x = u * 2.0f - 1.0f, y = v * 2.0f - 1.0f;
  const float z = 1.0f - std::fabs(x) - std::fabs(y);
  const float t = z < 0.0f ? -z : 0.0f;
  x += x >= 0.0f ? -t : t;
  y += y >= 0.0f ? -t : t;
  const float length = std::sqrt(x * x + y * y + z * z);
  xyz[0] = x / length, xyz[1] = y / length, xyz[2] = z / length;
}
inline std::uint32_t Snorm8Word(const float* v4) {
  std::uint32_t word = 0;
  for (int c = 0; c < 4; ++c)
    word |= (static_cast<std::uint32_t>(Quantise(v4[c], -1.0f, 127.0f)) & 0xffu) << (8 * c);
  return word;
}
inline float Snorm8Value(std::uint32_t word, int c) {
  const float v = static_cast<float>(static_cast<std::int8_t>(static_cast<std::uint8_t>(word >> (8 * c)))) / 127.0f;
  return v < -1.0f ? -1.0f : v;
}
inline void NormaliseXyz(float* xyz) {
  const float length = std::sqrt(xyz[0] * xyz[0] + xyz[1] * xyz[1] + xyz[2] * xyz[2]);
  for (int c = 0; c < 3; ++c) xyz[c] = length > 0.0f ? xyz[c] / length : 0.0f;
}
}  // namespace detail

// A normal's word: kOct16 x = the first octahedral coordinate in the low 16
// bits, y in the high; kSnorm8 x, y, z, 0 from the low byte up.
inline std::uint32_t PackNormal(NormalFormat format, const float* xyz) {
  if (format == NormalFormat::kSnorm8) {
    const float v4[4] = {xyz[0], xyz[1], xyz[2], 0.0f};
    return detail::Snorm8Word(v4);
  }
  if (format != NormalFormat::kOct16) return 0;
  float uv[2];
  detail::OctahedralOf(xyz, uv);
  return static_cast<std::uint32_t>(detail::Quantise(uv[0], 0.0f, 65535.0f)) |
         static_cast<std::uint32_t>(detail::Quantise(uv[1], 0.0f, 65535.0f)) << 16;
}
// A tangent's word: kOct16 as a normal's, but its y coordinate v becomes
// max(v, 1/32767) / 2 + 1/2, then 1 minus that for w < 0 (so a stored y of
// at least 1/2 means +1, and y keeps 15 bits); the word (0, 65535), which
// decodes as (65535, 65535) does, is written as that, as Godot's importer
// writes it. kSnorm8: x, y, z, w from the low byte up.
inline std::uint32_t PackTangent(NormalFormat format, const float* xyzw) {
  if (format == NormalFormat::kSnorm8) return detail::Snorm8Word(xyzw);
  if (format != NormalFormat::kOct16) return 0;
  float uv[2];
  detail::OctahedralOf(xyzw, uv);
  float y = uv[1] < 1.0f / 32767.0f ? 1.0f / 32767.0f : uv[1];
  y = y * 0.5f + 0.5f;
  if (xyzw[3] < 0.0f) y = 1.0f - y;
  std::uint32_t x16 = static_cast<std::uint32_t>(detail::Quantise(uv[0], 0.0f, 65535.0f));
  const std::uint32_t y16 = static_cast<std::uint32_t>(detail::Quantise(y, 0.0f, 65535.0f));
  if (x16 == 0 && y16 == 65535) x16 = 65535;
  return x16 | y16 << 16;
}
// The unit normal of a word (kSnorm8: each byte / 127, at least -1, then
// normalised). kF32: (0, 0, 0).
inline void UnpackNormal(NormalFormat format, std::uint32_t word, float* xyz) {
  xyz[0] = xyz[1] = xyz[2] = 0.0f;
  if (format == NormalFormat::kOct16) {
    detail::FromOctahedral(static_cast<float>(word & 0xffffu) / 65535.0f, static_cast<float>(word >> 16) / 65535.0f,
                           xyz);
  } else if (format == NormalFormat::kSnorm8) {
    for (int c = 0; c < 3; ++c) xyz[c] = detail::Snorm8Value(word, c);
    detail::NormaliseXyz(xyz);
  }
}
// The unit tangent and handedness (+1 / -1) of a word.
inline void UnpackTangent(NormalFormat format, std::uint32_t word, float* xyzw) {
  xyzw[0] = xyzw[1] = xyzw[2] = xyzw[3] = 0.0f;
  if (format == NormalFormat::kOct16) {
    float y = static_cast<float>(word >> 16) / 65535.0f * 2.0f - 1.0f;
    xyzw[3] = y >= 0.0f ? 1.0f : -1.0f;
    y = std::fabs(y);
    detail::FromOctahedral(static_cast<float>(word & 0xffffu) / 65535.0f, y, xyzw);
  } else if (format == NormalFormat::kSnorm8) {
    for (int c = 0; c < 3; ++c) xyzw[c] = detail::Snorm8Value(word, c);
    detail::NormaliseXyz(xyzw);
    xyzw[3] = detail::Snorm8Value(word, 3) >= 0.0f ? 1.0f : -1.0f;
  }
}

// One kernel argument, as the sidecar JSON describes it.
struct Argument {
  const char* name;         // "n", "first", "vertex_count" (instanced), "records", "positions", "indices",
                            // "weights", "normals", "palette", "out_positions", "out_normals"
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
  std::size_t vertices;        // the vertex count of the scene it won on, a crowd's or batch's total
                               // (one kernel per measured count)
  const char* shape;           // the scene it won on: "single" (one mesh), "instances" (a crowd), "batch"
  int instances;               // a crowd's K (1 for the other shapes)
  int meshes;                  // a batch's mesh count (1 for the other shapes)
  bool instanced;              // an instanced kernel (shape "instances"): K instances per launch
  int max_instances;           // instances one launch may skin: 0 = any K; else at most this (compile-time palettes)
  const char* variant;         // variant key (always `padded`: a `bucketed` winner is emitted as its padded twin)
  Layout layout;
  PositionFormat position;
  IndexFormat index;
  WeightFormat weight;
  PaletteFormat palette;
  PaletteStorage storage;
  Morph morph;                 // kNone, or the kernel applies morph targets (FindMorphKernel, PackMorphTargets)
  NormalFormat normal_format;  // how out_normals / out_tangents hold a vector (NormalStrideBytes, UnpackNormal)
  bool point_blend;            // blends transformed points (else blends matrices): no effect on the interface
  bool normals;                // also skins normals: a `normals` input and an `out_normals` output
  bool tangents;               // also skins tangents (with normals): a `tangents` input and an
                               // `out_tangents` output, 4 floats each (x y z, handedness w)
  int vertices_per_item;       // 1, 2, 4, 8
  bool strided;                // item g skins g, g+G, ... (else g*N .. g*N+N-1)
  int wg_size;                 // work-group size (0 for glsl-vertex)
  int joints;                  // palette entries the kernel is specialised for (a crowd's: per instance;
                               // a batch's: its meshes' together)
  int morph_targets;           // morph targets the kernel is specialised for (0 when morph is kNone)
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

// "vertex V slot I" of slot `s` (joints / weights element) of `slots` per vertex.
inline std::string SlotName(std::size_t s, std::size_t slots) {
  return "vertex " + std::to_string(s / slots) + " slot " + std::to_string(s % slots);
}

// Joints a kernel's palette and index format can both hold.
inline std::uint64_t JointLimit(const Kernel& k) {
  const std::uint64_t palette = static_cast<std::uint64_t>(k.joints);
  return IndexCapacity(k.index) < palette ? IndexCapacity(k.index) : palette;
}

// The first of `count` joint indices that is >= `limit`; `count` when none is.
inline std::size_t FirstJointFrom(const std::uint32_t* joints, std::size_t count, std::uint64_t limit) {
  for (std::size_t s = 0; s < count; ++s)
    if (joints[s] >= limit) return s;
  return count;
}

// What is wrong with the weights of n vertices of `slots` each, "" when
// nothing: the contract covers finite, non-negative weights, not all zero
// per vertex (a quantised format divides by their sum).
inline std::string BadWeight(const float* weights, std::size_t n, std::size_t slots) {
  for (std::size_t v = 0; v < n; ++v) {
    bool any = false;
    for (std::size_t i = 0; i < slots; ++i) {
      const float w = weights[v * slots + i];
      if (!(w >= 0.0f) || w > 3.4028234663852886e38f) {
        char text[96];
        std::snprintf(text, sizeof text, "vertex %zu slot %zu: weight %g is %s", v, i, static_cast<double>(w),
                      w < 0.0f ? "negative" : "not finite");
        return text;
      }
      any = any || w > 0.0f;
    }
    if (!any) return "vertex " + std::to_string(v) + ": all weights are zero";
  }
  return "";
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

// What a Find* call asks for: kernels of `lang` whose scene is `shape` (or,
// with single_serves, a single mesh's: skintune's fallback), joints >=
// joint_count addressable by the index format, B >= influences, and at least
// `instances` per launch; `vertices` the scene's total, `count` its instance
// or mesh count.
struct Request {
  const char* lang;
  const char* shape;
  bool single_serves;
  int influences;
  std::size_t vertices;
  int joint_count;
  int count;
  int instances;
  bool dual_quaternions;  // dual-quaternion kernels only (PaletteFormat::kDualquat), else linear ones only
  int morph_targets;      // > 0: kernels specialised for that many morph targets only; 0: kernels without
  NormalFormat normal_format;  // kernels writing normals and tangents in this format only (kF32 unless asked)
};

inline bool Serves(const Kernel& k, const Request& r) {
  const bool shape = std::strcmp(k.shape, r.shape) == 0 || (r.single_serves && std::strcmp(k.shape, "single") == 0);
  return shape && std::strcmp(k.lang, r.lang) == 0 && k.influences >= r.influences && k.joints >= r.joint_count &&
         (k.palette == PaletteFormat::kDualquat) == r.dual_quaternions &&
         (k.morph == Morph::kNone ? r.morph_targets == 0 : k.morph_targets == r.morph_targets) &&
         k.normal_format == r.normal_format &&
         static_cast<std::uint64_t>(r.joint_count) <= IndexCapacity(k.index) &&
         (k.max_instances == 0 || k.max_instances >= r.instances);
}

// Smaller is better: another shape than asked (the single-mesh fallback), B
// above the mesh's, the vertex count's distance, the instance or mesh count's
// (within the shape), then the larger vertex count.
inline bool Better(const Kernel& a, const Kernel& b, const Request& r) {
  const auto rank = [&r](const Kernel& k, double* vertices, double* count) {
    const bool other = std::strcmp(k.shape, r.shape) != 0;
    *vertices = VertexCountDistance(k.vertices, r.vertices);
    const int tuned = std::strcmp(k.shape, "instances") == 0 ? k.instances : k.meshes;
    *count = other ? 1.0 : VertexCountDistance(static_cast<std::size_t>(tuned), static_cast<std::size_t>(r.count));
    return other;
  };
  double av = 0.0, ac = 0.0, bv = 0.0, bc = 0.0;
  const bool a_other = rank(a, &av, &ac), b_other = rank(b, &bv, &bc);
  if (a_other != b_other) return !a_other;
  if (a.influences != b.influences) return a.influences < b.influences;
  if (av != bv) return av < bv;
  if (ac != bc) return ac < bc;
  return a.vertices > b.vertices;
}

inline const Kernel* Find(const Request& r) {
  if (r.lang == nullptr || r.influences < 1 || r.joint_count < 1 || r.count < 1) return nullptr;
  const Kernel* best = nullptr;
  for (int i = 0; i < kKernelCount; ++i) {
    if (Serves(kKernels[i], r) && (best == nullptr || Better(kKernels[i], *best, r))) best = &kKernels[i];
  }
  return best;
}

}  // namespace detail

// The kernel for a mesh of `vertex_count` vertices whose vertices use at most
// `influences` bones and whose palette has `joint_count` joints: among the
// single-mesh kernels (shape "single") of `lang` ("opencl", "cuda",
// "glsl-compute", "glsl-vertex", "vulkan") whose `joints` >= joint_count and
// whose index format can address joint_count joints (u8: 256, u16: 65536),
// the smallest B >= influences wins, then the nearest measured vertex count
// (as a factor; the larger on a tie), then the first in kKernels.
// Kernels of every device of the header take part (check k->device_id, or
// generate one header per device). nullptr if none fits, or for a null `lang`,
// influences < 1 or joint_count < 1. Check k->normals yourself when you skin
// normals. Linear blend skinning kernels only: FindDualQuaternionKernel gives
// the dual-quaternion ones, which compute something else.
inline const Kernel* FindKernel(const char* lang, int influences, std::size_t vertex_count, int joint_count) {
  return detail::Find({lang, "single", false, influences, vertex_count, joint_count, 1, 1, false, 0, NormalFormat::kF32});
}

// FindKernel's rule among the single-mesh kernels that write normals (and
// tangents) packed in `format` (kOct16, kSnorm8: one 32-bit word a vector,
// UnpackNormal / UnpackTangent decode it). The other finders return kF32
// kernels only.
inline const Kernel* FindPackedNormalsKernel(const char* lang, int influences, std::size_t vertex_count,
                                             int joint_count, NormalFormat format) {
  return detail::Find({lang, "single", false, influences, vertex_count, joint_count, 1, 1, false, 0, format});
}

// FindKernel's rule among the single-mesh dual-quaternion kernels
// (PaletteFormat::kDualquat: PackPalette takes rigid matrices only).
inline const Kernel* FindDualQuaternionKernel(const char* lang, int influences, std::size_t vertex_count,
                                              int joint_count) {
  return detail::Find({lang, "single", false, influences, vertex_count, joint_count, 1, 1, true, 0, NormalFormat::kF32});
}

// The kernel for a mesh with `morph_targets` morph targets (one instance, or a
// crowd of `instances`): FindKernel's rule (FindCrowdKernel's for instances >
// 1) among the kernels that apply morph targets and were specialised for
// exactly that many (MORPH_TARGETS is compiled in: `skintune emit --db
// --morph-targets T` specialises the morph winners for your T). The other
// finders never return these. nullptr if none fits, or for morph_targets < 1.
inline const Kernel* FindMorphKernel(const char* lang, int influences, std::size_t vertex_count, int joint_count,
                                     int morph_targets, int instances = 1) {
  if (morph_targets < 1 || instances < 1) return nullptr;
  if (instances == 1)
    return detail::Find(
        {lang, "single", false, influences, vertex_count, joint_count, 1, 1, false, morph_targets, NormalFormat::kF32});
  const std::size_t total = vertex_count * static_cast<std::size_t>(instances);
  return detail::Find(
      {lang, "instances", false, influences, total, joint_count, instances, instances, false, morph_targets,
       NormalFormat::kF32});
}

// The instanced kernel for a crowd of `instances` instances of one mesh of
// `vertex_count` vertices (each instance its own palette of `joint_count`
// joints) in one launch: FindKernel's rule among the crowd kernels (shape
// "instances") that take that many instances per launch (max_instances 0 or
// >= instances), the vertex count compared as the crowd's total
// (instances x vertex_count), then the nearest tuned instance count.
// nullptr if none fits, or for instances < 1 (and as FindKernel).
inline const Kernel* FindCrowdKernel(const char* lang, int influences, std::size_t vertex_count, int joint_count,
                                     int instances) {
  const std::size_t total = vertex_count * static_cast<std::size_t>(instances > 0 ? instances : 0);
  return detail::Find({lang, "instances", false, influences, total, joint_count, instances, instances, false, 0, NormalFormat::kF32});
}

// The kernel for a batch of `meshes` meshes packed as one (PackBatch) of
// `vertex_count` vertices and `joint_count` joints in all (offsets.vertices
// and offsets.joints' last entries), `influences` the largest B of its
// meshes: FindKernel's rule among the batch kernels (shape "batch"), then the
// nearest tuned mesh count; without one, the single-mesh kernel of the
// batch's size (a batch is one mesh to a kernel; skintune's runtime falls
// back the same way). nullptr if none fits, or for meshes < 1 (and as
// FindKernel).
inline const Kernel* FindBatchKernel(const char* lang, int influences, std::size_t vertex_count, int joint_count,
                                     int meshes) {
  return detail::Find({lang, "batch", true, influences, vertex_count, joint_count, meshes, 1, false, 0, NormalFormat::kF32});
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
// Bytes per vertex of out_normals and out_tangents: 4 for a packed
// normal_format (one word: UnpackNormal, UnpackTangent), else
// OutputStrideBytes(k) and 16.
inline std::size_t NormalStrideBytes(const Kernel& k) {
  return k.normal_format == NormalFormat::kF32 ? OutputStrideBytes(k) : 4;
}
inline std::size_t TangentStrideBytes(const Kernel& k) { return k.normal_format == NormalFormat::kF32 ? 16 : 4; }

// The kernel's input buffers. Only the layout's buffers are non-empty: kAos
// `records`; kSoa and kSoaSplit `positions`, `indices`, `weights`, `normals`
// when k.normals and `tangents` when k.tangents. Every size is a multiple of
// 4 bytes (32-bit words).
struct PackedInputs {
  std::vector<std::uint8_t> records, positions, indices, weights, normals, tangents;
  // PackMorphTargets: a morph kernel's morph-target buffers (morph_offsets
  // and morph_targets for the sparse layouts only; morph_normals with
  // k.normals, morph_tangents with k.tangents).
  std::vector<std::uint8_t> morph_offsets, morph_targets, morph_positions, morph_normals, morph_tangents;
};

// Packs a mesh of n vertices into the kernel's input buffers, byte for byte
// as skintune's packer does for the kernel's (padded) variant:
//   positions  3 floats per vertex (x y z); normals likewise, required when
//              k.normals (may be null otherwise, then ignored); tangents 4
//              floats per vertex (x y z, handedness w), required when
//              k.tangents (the overload without them: kernels without tangents);
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
// positions / joints / weights, normals missing when k.normals, tangents
// missing when k.tangents, a negative or
// non-finite weight, a vertex whose weights are all zero, or a joint
// index the index format cannot hold or >= k.joints.
inline bool PackMesh(const Kernel& k, std::size_t n, int influences, const float* positions, const float* normals,
                     const float* tangents, const std::uint32_t* joints, const float* weights, PackedInputs* out,
                     std::string* error) {
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
  if (k.tangents && tangents == nullptr) return fail("the kernel skins tangents but tangents is null");
  const std::size_t slots = static_cast<std::size_t>(influences);
  const std::uint64_t capacity = detail::IndexCapacity(k.index);
  const std::size_t bad = detail::FirstJointFrom(joints, n * slots, detail::JointLimit(k));
  if (bad < n * slots) {
    const std::string where = detail::SlotName(bad, slots) + ": joint " + std::to_string(joints[bad]);
    if (joints[bad] >= capacity)
      return fail(where + " does not fit " + detail::IndexName(k.index) + " indices (at most " +
                  std::to_string(capacity - 1) + ")");
    return fail(where + " out of range (the kernel has " + std::to_string(k.joints) + " joints)");
  }
  const std::string weight_error = detail::BadWeight(weights, n, slots);
  if (!weight_error.empty()) return fail(weight_error);

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
    std::size_t normal_at = 0, tangent_at = 0;
    if (k.normals) {
      normal_at = detail::RoundUp(end, align);
      end = normal_at + pb;
    }
    if (k.tangents) {
      tangent_at = detail::RoundUp(end, align);
      end = tangent_at + 16;
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
      if (k.tangents) detail::PutVector(record + tangent_at, tangents + 4 * v, PositionFormat::kFloat4, tangents[4 * v + 3]);
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
  if (k.tangents) out->tangents.assign(n * 16, 0);
  for (std::size_t v = 0; v < n; ++v) {
    detail::PutVector(out->positions.data() + v * pb, positions + 3 * v, k.position, 1.0f);
    if (k.normals) detail::PutVector(out->normals.data() + v * pb, normals + 3 * v, k.position, 0.0f);
    if (k.tangents)
      detail::PutVector(out->tangents.data() + v * 16, tangents + 4 * v, PositionFormat::kFloat4, tangents[4 * v + 3]);
    gather(v);
    for (std::size_t i = 0; i < b; ++i) {
      const std::size_t e = split ? i * stride + v : v * b + i;
      detail::PutUint(out->indices.data() + e * ib, index_words[i], ib);
      detail::PutUint(out->weights.data() + e * wb, weight_words[i], wb);
    }
  }
  return true;
}

// PackMesh for kernels that skin no tangents (k.tangents false).
inline bool PackMesh(const Kernel& k, std::size_t n, int influences, const float* positions, const float* normals,
                     const std::uint32_t* joints, const float* weights, PackedInputs* out, std::string* error) {
  return PackMesh(k, n, influences, positions, normals, nullptr, joints, weights, out, error);
}

namespace detail {

// The IEEE 754 binary16 bits nearest `value`, ties to even, as a conversion
// of float to half does in hardware (F16C, CUDA, GLSL's packHalf2x16):
// beyond the largest half, infinity; below the smallest subnormal, zero.
inline std::uint16_t HalfBits(float value) {
  const std::uint32_t f = FloatBits(value);
  const std::uint32_t sign = (f >> 16) & 0x8000u;
  const std::uint32_t exponent = (f >> 23) & 0xffu;
  const std::uint32_t mantissa = f & 0x7fffffu;
  if (exponent == 0xffu) return static_cast<std::uint16_t>(sign | 0x7c00u | (mantissa != 0 ? 0x200u : 0u));
  const int e = static_cast<int>(exponent) - 127 + 15;  // the half's biased exponent
  if (e >= 31) return static_cast<std::uint16_t>(sign | 0x7c00u);
  // Normal: 10 of the 23 mantissa bits; subnormal: the 24-bit significand
  // shifted to units of 2^-24. Then round the bits shifted out, ties to even.
  const std::uint32_t significand = e > 0 ? mantissa : (exponent != 0 ? mantissa | 0x800000u : 0u);
  const int shift = e > 0 ? 13 : 14 - e;
  if (shift > 24) return static_cast<std::uint16_t>(sign);
  std::uint32_t half = significand >> shift;
  const std::uint32_t rest = significand & ((1u << shift) - 1u), midpoint = 1u << (shift - 1);
  if (rest > midpoint || (rest == midpoint && (half & 1u) != 0)) ++half;  // a carry may reach the exponent: right
  if (e > 0) half += static_cast<std::uint32_t>(e) << 10;
  return static_cast<std::uint16_t>(sign | half);
}

}  // namespace detail

// Packs a mesh's morph targets into a morph kernel's buffers (k.morph not
// kNone), byte for byte as skintune's packer does (skintune's docs/VARIANTS.md
// "Morph targets"). The offsets are target after target, 3 floats a vertex:
// target t's offset of vertex v at [(t * n + v) * 3]; `normals` (read when
// k.normals) and `tangents` (xyz; read when k.tangents) may be null: zero
// offsets. Dense kernels get every offset; sparse ones, per vertex, an entry
// for each target with a non-zero offset in a stream the kernel reads.
// Half kernels store each component as IEEE binary16 (detail::HalfBits)
// then a zero. The weights are no input of this call: upload `targets`
// float32 weights per instance (instance i's target t at i * targets + t)
// as `morph_weights` each frame. Returns false and sets *error for out ==
// null, a kernel without morph targets, `targets` other than
// k.morph_targets, n == 0, null positions, an offset that is not finite, or
// (half) one that rounds to infinity, naming the target and vertex.
inline bool PackMorphTargets(const Kernel& k, std::size_t n, int targets, const float* positions, const float* normals,
                             const float* tangents, PackedInputs* out, std::string* error) {
  const auto fail = [error, &k](const std::string& message) {
    if (error != nullptr) *error = "PackMorphTargets " + std::string(k.variant) + ": " + message;
    return false;
  };
  if (out == nullptr) return fail("no output (out is null)");
  out->morph_offsets.clear();
  out->morph_targets.clear();
  out->morph_positions.clear();
  out->morph_normals.clear();
  out->morph_tangents.clear();
  if (k.morph == Morph::kNone) return fail("the kernel applies no morph targets");
  if (targets != k.morph_targets)
    return fail(std::to_string(targets) + " morph targets, the kernel is specialised for " +
                std::to_string(k.morph_targets) + " (skintune emit --db --morph-targets)");
  if (n == 0) return fail("no vertices");
  if (positions == nullptr) return fail("positions is null");
  const bool sparse = k.morph == Morph::kSparse || k.morph == Morph::kSparseHalf;
  const bool half = k.morph == Morph::kDenseHalf || k.morph == Morph::kSparseHalf;
  const std::size_t bytes = half ? 8 : 12;
  struct Stream {
    const float* offsets;  // null: zeros
    std::vector<std::uint8_t>* out;
    const char* what;
  };
  std::vector<Stream> streams = {{positions, &out->morph_positions, "position"}};
  if (k.normals) streams.push_back({normals, &out->morph_normals, "normal"});
  if (k.tangents) streams.push_back({tangents, &out->morph_tangents, "tangent"});
  const std::size_t t_count = static_cast<std::size_t>(targets);
  for (const Stream& s : streams) {
    if (s.offsets == nullptr) continue;
    for (std::size_t i = 0; i < t_count * n * 3; ++i) {
      const float c = s.offsets[i];
      const std::string where = "target " + std::to_string(i / 3 / n) + " vertex " + std::to_string(i / 3 % n) +
                                ": " + s.what + " offset component " + std::to_string(c);
      if (!std::isfinite(c)) return fail(where + " is not finite");
      if (half && (detail::HalfBits(c) & 0x7c00u) == 0x7c00u)
        return fail(where + " rounds to infinity as a half (binary16 holds magnitudes below 65520)");
    }
  }
  const auto moves = [&](std::size_t t, std::size_t v) {
    for (const Stream& s : streams)
      if (s.offsets != nullptr)
        for (int c = 0; c < 3; ++c)
          if (s.offsets[(t * n + v) * 3 + static_cast<std::size_t>(c)] != 0.0f) return true;
    return false;
  };
  const auto put = [&](const Stream& s, std::size_t element, std::size_t t, std::size_t v) {
    std::uint8_t* at = s.out->data() + element * bytes;
    for (std::size_t c = 0; c < 3; ++c) {
      const float value = s.offsets != nullptr ? s.offsets[(t * n + v) * 3 + c] : 0.0f;
      if (half) {
        detail::PutUint(at + 2 * c, detail::HalfBits(value), 2);
      } else {
        detail::PutFloat(at + 4 * c, value);
      }
    }
  };
  if (!sparse) {
    for (const Stream& s : streams) {
      s.out->assign(detail::RoundUp(t_count * n * bytes, 4), 0);
      for (std::size_t t = 0; t < t_count; ++t)
        for (std::size_t v = 0; v < n; ++v) put(s, t * n + v, t, v);
    }
    return true;
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> entries;  // (vertex, target)
  out->morph_offsets.assign((n + 1) * 4, 0);
  for (std::size_t v = 0; v < n; ++v) {
    detail::PutUint(out->morph_offsets.data() + 4 * v, static_cast<std::uint32_t>(entries.size()), 4);
    for (std::size_t t = 0; t < t_count; ++t)
      if (moves(t, v)) entries.emplace_back(static_cast<std::uint32_t>(v), static_cast<std::uint32_t>(t));
  }
  detail::PutUint(out->morph_offsets.data() + 4 * n, static_cast<std::uint32_t>(entries.size()), 4);
  const std::size_t elements = entries.empty() ? 1 : entries.size();  // every buffer holds one element at least
  out->morph_targets.assign(elements * 4, 0);
  for (std::size_t e = 0; e < entries.size(); ++e) detail::PutUint(out->morph_targets.data() + 4 * e, entries[e].second, 4);
  for (const Stream& s : streams) {
    s.out->assign(detail::RoundUp(elements * bytes, 4), 0);
    for (std::size_t e = 0; e < entries.size(); ++e) put(s, e, entries[e].second, entries[e].first);
  }
  return true;
}

// One mesh of a batch (PackBatch): its arrays as PackMesh takes a mesh's.
struct BatchMesh {
  std::size_t vertex_count = 0;
  int influences = 0;                     // slots per vertex of `joints` and `weights`
  int joint_count = 0;                    // its own palette's joints: its indices are 0..joint_count-1
  const float* positions = nullptr;       // 3 floats per vertex
  const float* normals = nullptr;         // likewise; required when the kernel skins normals
  const std::uint32_t* joints = nullptr;  // `influences` per vertex
  const float* weights = nullptr;         // `influences` per vertex
};

// Where each mesh lies in a batch: mesh m's vertices from vertices[m] on (its
// outputs too), its joints from palette entry joints[m] on; each list ends
// with the batch's total.
struct BatchOffsets {
  std::vector<std::size_t> vertices;
  std::vector<int> joints;
};

namespace detail {

// The batch as one mesh's arrays.
struct BatchArrays {
  int influences = 0;  // the largest of its meshes'
  std::vector<float> positions, normals, weights;
  std::vector<std::uint32_t> joints;
};

// What is wrong with a mesh of a batch for kernel k, "" when nothing.
inline std::string BadBatchMesh(const Kernel& k, const BatchMesh& mesh) {
  if (mesh.vertex_count == 0) return "no vertices";
  if (mesh.joint_count < 1) return "no joints";
  if (mesh.influences < 1 || mesh.influences > k.influences)
    return "influences " + std::to_string(mesh.influences) + " outside 1.." + std::to_string(k.influences) +
           " (the kernel's B)";
  if (mesh.positions == nullptr || mesh.joints == nullptr || mesh.weights == nullptr)
    return "positions, joints or weights is null";
  if (k.normals && mesh.normals == nullptr) return "the kernel skins normals but normals is null";
  const std::size_t slots = static_cast<std::size_t>(mesh.influences), count = mesh.vertex_count * slots;
  const std::size_t bad = FirstJointFrom(mesh.joints, count, static_cast<std::uint64_t>(mesh.joint_count));
  if (bad < count)
    return SlotName(bad, slots) + ": joint " + std::to_string(mesh.joints[bad]) + " out of range (the mesh has " +
           std::to_string(mesh.joint_count) + " joints)";
  return BadWeight(mesh.weights, mesh.vertex_count, slots);
}

// Appends a mesh whose joints start at palette entry `offset`, its slots
// padded to the batch's B with weight 0 on its own first joint.
inline void AppendMesh(BatchArrays& batch, const BatchMesh& mesh, std::uint32_t offset, bool normals) {
  const std::size_t n = mesh.vertex_count, mb = static_cast<std::size_t>(mesh.influences);
  batch.positions.insert(batch.positions.end(), mesh.positions, mesh.positions + 3 * n);
  if (normals) batch.normals.insert(batch.normals.end(), mesh.normals, mesh.normals + 3 * n);
  for (std::size_t v = 0; v < n; ++v) {
    for (std::size_t i = 0; i < static_cast<std::size_t>(batch.influences); ++i) {
      batch.joints.push_back(offset + (i < mb ? mesh.joints[v * mb + i] : 0u));
      batch.weights.push_back(i < mb ? mesh.weights[v * mb + i] : 0.0f);
    }
  }
}

}  // namespace detail

// Packs `mesh_count` meshes as one mesh for a batch kernel, byte for byte as
// skintune packs a batch (docs/VARIANTS.md "Batches"): the meshes' vertices
// one after another; mesh m's joint j becomes palette entry
// offsets.joints[m] + j, the earlier meshes' joint counts summed; every mesh
// padded to the batch's B (the largest of their influences) with zero-weight
// slots naming its own first joint; then PackMesh. Fills *offsets (when not
// null) with where each mesh lies. Returns false and sets *error (when not
// null), naming the mesh as meshes[m], for out == null, no meshes, a mesh
// without vertices or joints, influences outside 1..k.influences, null
// arrays, missing normals when k.normals, a joint index >= the mesh's
// joint_count, weights PackMesh refuses, or a batch of more joints than
// k.joints or its index format holds.
inline bool PackBatch(const Kernel& k, const BatchMesh* meshes, std::size_t mesh_count, PackedInputs* out,
                      BatchOffsets* offsets, std::string* error) {
  const auto fail = [error, &k](const std::string& message) {
    if (error != nullptr) *error = "PackBatch " + std::string(k.variant) + ": " + message;
    return false;
  };
  if (out == nullptr) return fail("no output (out is null)");
  *out = PackedInputs{};
  if (meshes == nullptr || mesh_count == 0) return fail("no meshes");
  const std::uint64_t limit = detail::JointLimit(k);
  BatchOffsets where{{0}, {0}};
  detail::BatchArrays batch;
  for (std::size_t m = 0; m < mesh_count; ++m) {
    const std::string bad = detail::BadBatchMesh(k, meshes[m]);
    if (!bad.empty()) return fail("meshes[" + std::to_string(m) + "]: " + bad);
    const std::uint64_t joints =
        static_cast<std::uint64_t>(where.joints.back()) + static_cast<std::uint64_t>(meshes[m].joint_count);
    if (joints > limit)
      return fail("meshes[" + std::to_string(m) + "]: the batch's joints reach " + std::to_string(joints) +
                  " with this mesh's, above the " + std::to_string(limit) + " the kernel holds (" +
                  std::to_string(k.joints) + " joints, " + detail::IndexName(k.index) + " indices)");
    where.vertices.push_back(where.vertices.back() + meshes[m].vertex_count);
    where.joints.push_back(static_cast<int>(joints));
    if (meshes[m].influences > batch.influences) batch.influences = meshes[m].influences;
  }
  for (std::size_t m = 0; m < mesh_count; ++m)
    detail::AppendMesh(batch, meshes[m], static_cast<std::uint32_t>(where.joints[m]), k.normals);
  if (!PackMesh(k, where.vertices.back(), batch.influences, batch.positions.data(),
                k.normals ? batch.normals.data() : nullptr, batch.joints.data(), batch.weights.data(), out, error))
    return false;
  if (offsets != nullptr) *offsets = std::move(where);
  return true;
}

// Dual-quaternion kernels (PaletteFormat::kDualquat) take rigid joints
// only: a palette matrix's upper 3x3 A must be a rotation, max |(A^T A - I)_ij|
// at most kRigidTolerance and det A > 0 (skintune's docs/VARIANTS.md "Dual
// quaternions"). A scaled, sheared or mirrored joint is refused, never
// rounded to its rotation.
inline constexpr double kRigidTolerance = 2e-5;

// A palette matrix (16 floats, column-major: element (row r, column c) at
// c*4+r) as the unit dual quaternion the kernels read, 8 floats into `out`:
// the real part q = (x, y, z, w), the rotation of A (Shepperd's method in
// double, normalised), then the dual part 0.5 * (t, 0) * q for the
// translation t = column 3: (0.5 * (q.w t + t x q.xyz), -0.5 * t . q.xyz).
// Row 3 is not read, as the matrix kernels do not read it. Returns false
// (and writes nothing) when the matrix is not finite or not rigid;
// `deviation`, where given, receives max |(A^T A - I)_ij| (infinity when not
// finite, and also when det A <= 0).
inline bool DualQuaternionOf(const float* m, float out[8], double* deviation = nullptr) {
  double a[3][3];  // a[r][c]
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[r][c] = static_cast<double>(m[c * 4 + r]);
  const double t[3] = {static_cast<double>(m[12]), static_cast<double>(m[13]), static_cast<double>(m[14])};
  bool finite = std::isfinite(t[0]) && std::isfinite(t[1]) && std::isfinite(t[2]);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) finite = finite && std::isfinite(a[r][c]);
  double worst = finite ? 0.0 : HUGE_VAL;
  for (int i = 0; finite && i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double g = a[0][i] * a[0][j] + a[1][i] * a[1][j] + a[2][i] * a[2][j];
      worst = std::fmax(worst, std::fabs(g - (i == j ? 1.0 : 0.0)));
    }
  const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                     a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                     a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  if (finite && !(det > 0.0)) worst = HUGE_VAL;
  if (deviation != nullptr) *deviation = worst;
  if (!(worst <= kRigidTolerance)) return false;
  double q[4];  // x, y, z, w
  const double trace = a[0][0] + a[1][1] + a[2][2];
  if (trace > 0.0) {
    const double s = std::sqrt(trace + 1.0) * 2.0;
    q[3] = 0.25 * s, q[0] = (a[2][1] - a[1][2]) / s, q[1] = (a[0][2] - a[2][0]) / s, q[2] = (a[1][0] - a[0][1]) / s;
  } else if (a[0][0] > a[1][1] && a[0][0] > a[2][2]) {
    const double s = std::sqrt(1.0 + a[0][0] - a[1][1] - a[2][2]) * 2.0;
    q[3] = (a[2][1] - a[1][2]) / s, q[0] = 0.25 * s, q[1] = (a[0][1] + a[1][0]) / s, q[2] = (a[0][2] + a[2][0]) / s;
  } else if (a[1][1] > a[2][2]) {
    const double s = std::sqrt(1.0 + a[1][1] - a[0][0] - a[2][2]) * 2.0;
    q[3] = (a[0][2] - a[2][0]) / s, q[0] = (a[0][1] + a[1][0]) / s, q[1] = 0.25 * s, q[2] = (a[1][2] + a[2][1]) / s;
  } else {
    const double s = std::sqrt(1.0 + a[2][2] - a[0][0] - a[1][1]) * 2.0;
    q[3] = (a[1][0] - a[0][1]) / s, q[0] = (a[0][2] + a[2][0]) / s, q[1] = (a[1][2] + a[2][1]) / s, q[2] = 0.25 * s;
  }
  const double length = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (double& x : q) x /= length;
  const double d[4] = {0.5 * (q[3] * t[0] + t[1] * q[2] - t[2] * q[1]),
                       0.5 * (q[3] * t[1] + t[2] * q[0] - t[0] * q[2]),
                       0.5 * (q[3] * t[2] + t[0] * q[1] - t[1] * q[0]),
                       -0.5 * (t[0] * q[0] + t[1] * q[1] + t[2] * q[2])};
  // + 0.0: no negative zeros (a joint without translation packs as the identity padding does).
  for (int i = 0; i < 4; ++i) out[i] = static_cast<float>(q[i] + 0.0), out[4 + i] = static_cast<float>(d[i] + 0.0);
  return true;
}

namespace detail {

// One palette's rows at `at`: `joint_count` column-major matrices as `rows`
// float4 rows each, then identities up to `joints` entries.
inline float* PutPalette(const float* matrices, int joint_count, int joints, std::size_t rows, float* at) {
  for (int j = 0; j < joints; ++j) {
    for (std::size_t r = 0; r < rows; ++r) {
      for (std::size_t c = 0; c < 4; ++c, ++at) {
        *at = j < joint_count ? matrices[static_cast<std::size_t>(j) * 16 + c * 4 + r] : (c == r ? 1.0f : 0.0f);
      }
    }
  }
  return at;
}

}  // namespace detail

// The palette buffer in the kernel's format, as floats (upload them as they
// are): `joint_count` matrices, each 16 floats column-major (glm's layout:
// element (row r, column c) at c*4+r), become R = 4 (kMat4) or 3 (kMat3x4)
// float4 rows per joint, joint j row r at float4 j*R+r, followed by identity
// matrices up to k.joints entries (the kernel is specialised for k.joints:
// the buffer always holds k.joints*R*4 floats). A crowd kernel (k.instanced)
// takes `instances` K palettes in one buffer: instance i's joint_count
// matrices at matrices + i*joint_count*16, packed from float4 i*k.joints*R on
// (K*k.joints*R*4 floats). A batch's palette is its meshes' matrices one
// after another (mesh m's at joint offsets.joints[m]), joint_count their total.
// Empty for joint_count < 0, joint_count > k.joints, null matrices with
// joint_count > 0, instances < 1, instances > 1 for a kernel that is not
// instanced, or more instances than k.max_instances (when it is not 0).
inline std::vector<float> PackPalette(const Kernel& k, const float* matrices, int joint_count, int instances = 1) {
  if (joint_count < 0 || joint_count > k.joints || (matrices == nullptr && joint_count > 0) || instances < 1 ||
      (instances > 1 && !k.instanced) || (k.max_instances > 0 && instances > k.max_instances))
    return {};
  if (k.palette == PaletteFormat::kDualquat) {
    // 2 rows a joint (DualQuaternionOf); empty when a matrix is not rigid.
    std::vector<float> out(static_cast<std::size_t>(instances) * static_cast<std::size_t>(k.joints) * 8, 0.0f);
    for (std::size_t i = 0; i < static_cast<std::size_t>(instances); ++i)
      for (std::size_t j = 0; j < static_cast<std::size_t>(k.joints); ++j) {
        float* at = out.data() + (i * static_cast<std::size_t>(k.joints) + j) * 8;
        if (j >= static_cast<std::size_t>(joint_count)) {
          at[3] = 1.0f;  // the identity: real part (0, 0, 0, 1), dual part 0
        } else if (!DualQuaternionOf(matrices + (i * static_cast<std::size_t>(joint_count) + j) * 16, at)) {
          return {};
        }
      }
    return out;
  }
  const std::size_t rows = k.palette == PaletteFormat::kMat4 ? 4 : 3;
  const std::size_t per_instance = static_cast<std::size_t>(joint_count) * 16;
  std::vector<float> out(static_cast<std::size_t>(instances) * static_cast<std::size_t>(k.joints) * rows * 4, 0.0f);
  float* at = out.data();
  for (std::size_t i = 0; i < static_cast<std::size_t>(instances); ++i)
    at = detail::PutPalette(joint_count > 0 ? matrices + i * per_instance : nullptr, joint_count, k.joints, rows, at);
  return out;
}

// The output buffer (n vertices of OutputStrideBytes(k) bytes, as read back
// from out_positions, or out_normals of a kF32 kernel) -> 3 floats per vertex
// into xyz (3*n floats), in the mesh's order.
inline void UnpackPositions(const Kernel& k, const void* output, std::size_t n, float* xyz) {
  const std::size_t stride = OutputStrideBytes(k);
  const auto* bytes = static_cast<const unsigned char*>(output);
  for (std::size_t v = 0; v < n; ++v) std::memcpy(xyz + 3 * v, bytes + v * stride, 3 * sizeof(float));
}
// out_normals (n vertices of NormalStrideBytes(k) bytes) -> 3 floats per
// vertex, decoded where k.normal_format packs them.
inline void UnpackNormals(const Kernel& k, const void* output, std::size_t n, float* xyz) {
  if (k.normal_format == NormalFormat::kF32) return UnpackPositions(k, output, n, xyz);
  const auto* bytes = static_cast<const unsigned char*>(output);
  for (std::size_t v = 0; v < n; ++v) {
    std::uint32_t word;
    std::memcpy(&word, bytes + 4 * v, 4);
    UnpackNormal(k.normal_format, word, xyz + 3 * v);
  }
}
// out_tangents (n vertices of TangentStrideBytes(k) bytes) -> 4 floats per
// vertex (x y z, handedness w), decoded where k.normal_format packs them.
inline void UnpackTangents(const Kernel& k, const void* output, std::size_t n, float* xyzw) {
  const auto* bytes = static_cast<const unsigned char*>(output);
  for (std::size_t v = 0; v < n; ++v) {
    if (k.normal_format == NormalFormat::kF32) {
      std::memcpy(xyzw + 4 * v, bytes + 16 * v, 4 * sizeof(float));
      continue;
    }
    std::uint32_t word;
    std::memcpy(&word, bytes + 4 * v, 4);
    UnpackTangent(k.normal_format, word, xyzw + 4 * v);
  }
}

}  // namespace skintune_kernels
