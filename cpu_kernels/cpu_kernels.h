// skintune: the fast CPU path's kernels, a small family of specialisations.
//
// ozz-animation's skinning is the model: one function template instantiated
// per influence count B = 1..8 (and here per index format, weight format,
// palette rows and blend), selected through one table declared once (MakeTable in
// cpu_kernels.inc, laid out by cpu_kernel_table.h). Each kernel reads STRIDED streams, so the same code reads
// the bytes every GPU variant reads (generator/packer.h): slot arrays
// (soa-split: vertex stride = one element, slot stride = S elements),
// per-vertex runs (soa) and packed records (aos: vertex stride = the record).
//
// - Index formats u32 / u16 / u8 and weight formats f32 / unorm16 / unorm8
//   are decoded as the GPU kernels decode them (unorm: raw / 65535, raw / 255).
// - Palette rows 4 (mat4: blend 16 floats in one 16-float vector) or 3
//   (mat3x4: blend 12 floats, an 8- and a 4-float vector), from the packer's
//   float4 rows (PackPalette) reordered per frame into CpuPalette; or 2 (a
//   unit dual quaternion a joint, dual-quaternion skinning only: blend 8
//   floats, each joint's on the side of the first influence's, normalise,
//   and take the blend's rigid map as the blended matrix, as the GPU
//   templates' BLEND 2 does).
// - Streaming (non-temporal) stores: outputs written 4 vertices at a time
//   with 16-byte MOVNTPS, which skip the read-for-ownership of the output
//   lines (a plain store reads each output line before writing it: 1.25x the
//   output bytes for a 12-byte float3 output). Runtime flag; measured in
//   docs/PERFORMANCE.md.
// - Each kernel runs one of four loops chosen once per call (normals or not,
//   3 or 4 output floats), so the vertex loop tests nothing per vertex; the
//   influences are decoded a 64-vertex block at a time into palette offsets
//   and float weights (unorm decoded there, not per vertex), and a position
//   is loaded as 16 bytes straight into a register (the range's last vertex,
//   whose 16 bytes could leave its stream, from a padded copy).
// - Each table is compiled three times, for AVX-512, AVX2 and a baseline,
//   in slices of one influence count each (cpu_kernels_slice.cpp, 24
//   objects; a build for this machine only, SKINTUNE_CPU_ISAS=native, compiles
//   the one its CPU runs); CpuKernelIsa() says which table this CPU runs.
//
// Threads and chunking are not fixed: RunCpuKernel takes a CpuSchedule, and
// FastestCandidate times the candidates on the caller's own frames.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace skintune::internal {

class ThreadPool;

enum class CpuIndex { kU32, kU16, kU8 };                // element bytes 4, 2, 1
enum class CpuWeight { kF32, kUnorm16, kUnorm8 };       // element bytes 4, 2, 1
inline constexpr int kCpuMaxInfluences = 8;

// Which specialisation: B, formats, palette rows, blend. The table holds
// linear blending (matrix or point) with palette rows 4 and 3, and
// dual-quaternion blending with palette rows 2 only.
struct CpuKernelKey {
  int influences = 4;  // 1..8
  CpuIndex index = CpuIndex::kU16;
  CpuWeight weight = CpuWeight::kF32;
  int palette_rows = 4;  // 4: mat4, 3: mat3x4, 2: a unit dual quaternion (dual_quaternion only)
  bool point_blend = false;  // false: blend the matrices, then transform; true: transform per bone, blend points
  // Dual-quaternion skinning (palette_rows 2, point_blend false): a result of
  // its own, not another order of the linear blend's work.
  bool dual_quaternion = false;
};
// "b4.u16.f32.mat4.matrix", "b4.u16.f32.mat3x4.point", "b4.u16.f32.dualquat.dq"
std::string CpuKernelName(const CpuKernelKey& key);

// The palette in the kernels' form: per joint one 64-byte-aligned block of 16
// floats, column-major (mat4: 4 columns of 4; mat3x4: 4 columns of 3, packed
// in the first 12 floats); a dual quaternion as its two rows, the real part
// (x, y, z, w) then the dual part, in the first 8 floats.
struct alignas(64) CpuJoint {
  float f[16];
};
struct CpuPalette {
  int rows = 4;
  std::vector<CpuJoint> joints;
};
// From PackPalette's bytes: float4 rows, `rows` (4, 3 or 2) per joint, joint
// after joint. Throws Error when the size is not a multiple of a joint's rows.
void LoadCpuPalette(std::span<const std::uint8_t> packed_rows, int rows, CpuPalette& out);

// Where a kernel reads and writes, in bytes. Vertex v's slot i is at
// `base + v * stride + i * slot`; positions and normals are x, y, z floats at
// `base + v * stride`. Outputs are `output_floats` (3 or 4; w = 1 for
// positions, 0 for normals) floats per vertex from vertex 0 of the range;
// tangents 4 floats in and out.
struct CpuStreams {
  const std::uint8_t* positions = nullptr;
  std::size_t position_stride = 0;
  const std::uint8_t* normals = nullptr;  // null: positions only
  std::size_t normal_stride = 0;
  const std::uint8_t* indices = nullptr;
  std::size_t index_stride = 0, index_slot = 0;
  const std::uint8_t* weights = nullptr;
  std::size_t weight_stride = 0, weight_slot = 0;
  float* out_positions = nullptr;
  float* out_normals = nullptr;  // skinned normals (normalised) when `normals` and this are set
  // Tangents (read only with normals): 4 floats (xyz, handedness w) at
  // `tangents + v * tangent_stride`, written as 4 floats per vertex (xyz
  // normalised, w flipped where the blended matrix mirrors).
  const std::uint8_t* tangents = nullptr;
  std::size_t tangent_stride = 0;
  float* out_tangents = nullptr;
  int output_floats = 3;
  bool stream_stores = false;  // non-temporal stores (16-byte aligned outputs; others store plainly)
};

// Skins vertices [begin, end) of `s` with `palette` (joint indices are not
// checked: the caller's mesh is validated).
using CpuKernelFn = void (*)(const CpuStreams& s, const CpuPalette& palette, std::size_t begin, std::size_t end);

// The kernel for `key` on this CPU; throws Error("cpu kernel: ...") for a key
// outside the table (B outside 1..8, rows not 4, 3 or 2, rows 2 without
// dual_quaternion or dual_quaternion with other rows or with point_blend).
CpuKernelFn FindCpuKernel(const CpuKernelKey& key);
// The instruction set of the tables FindCpuKernel returns: "avx512", "avx2" or
// "baseline", the fastest this CPU runs of those the build holds
// (SKINTUNE_CPU_ISAS); "none" when it runs none of them (then FindCpuKernel
// throws Error naming the tables built).
const char* CpuKernelIsa();
// The tables this build holds, the fastest first (SKINTUNE_CPU_ISAS).
std::vector<std::string> CpuKernelIsasBuilt();
// Every key of the table, in table order (B, index, weight, then rows and
// blend: mat4 matrix, mat4 point, mat3x4 matrix, mat3x4 point, dualquat dq): for tests.
std::vector<CpuKernelKey> AllCpuKernelKeys();

// Threads and chunk size of one frame.
struct CpuSchedule {
  unsigned threads = 1;     // >= 1
  std::size_t chunk = 0;    // vertices per chunk, a multiple of 64 (> 0)
};
// "2 threads x 16384-vertex chunks"
std::string Describe(const CpuSchedule& schedule);
// The candidates for `vertices` on up to `max_threads` threads (0: every
// logical CPU): 1, 2, 4, ... and max_threads threads, each with chunks of
// 4k, 16k and 64k vertices and one chunk per thread (those <= vertices only,
// and at least one).
std::vector<CpuSchedule> CpuScheduleCandidates(std::size_t vertices, unsigned max_threads = 0);
// The index of the candidate (0..candidates-1) whose `frame_ms(i)` (the
// quickest of `samples` calls after one untimed call) is the smallest, the
// calls made in rounds of one per candidate: how schedules and streaming
// stores are chosen on the caller's own frames. The quickest, as the tuner's
// kernel-time sample on the host's CPU is the quickest of its frames
// (TimingOptions::host_frames_per_sample): a median of three picked a
// schedule by which of its frames a neighbour's thread happened to hit. A
// candidate whose first sample took more than kFastestCandidateCut times the quickest first sample
// is left out of the later rounds: on a 16-thread host the 40 candidates of a
// 100k-vertex frame took a fresh process 150-250 ms a variant, most of it on
// one and two threads, 8-16 times slower than the winners (an H200 machine's
// host, 2026-12-02). With `warm_group`, the untimed call is made for the
// first candidate of each group only (what it warms is the group's: a thread
// count's pool, the frame's pages). Throws Error for no candidates.
inline constexpr double kFastestCandidateCut = 3.0;
std::size_t FastestCandidate(std::size_t candidates, const std::function<double(std::size_t)>& frame_ms,
                             int samples = 3, const std::function<std::size_t(std::size_t)>& warm_group = nullptr);

// Runs `kernel` over `count` vertices on `pool` (whose size() is the thread
// count) in chunks of `chunk` vertices. Throws Error for chunk 0.
void RunCpuKernel(CpuKernelFn kernel, const CpuStreams& s, const CpuPalette& palette, std::size_t count,
                  ThreadPool& pool, std::size_t chunk);

// Thread pools by thread count, made on first use (one loop at a time).
// Their workers poll for kCpuPoolSpin after a loop before they sleep: the
// kernels at the sizes engines skin take tens of microseconds on many cores
// (100k vertices, 16 threads: ~60 us on the H200 machine's host), and the
// loops of a frame (one per instance, one per mesh) follow each other
// closely, where waking 15 sleeping threads took about as long as the work.
inline constexpr std::chrono::microseconds kCpuPoolSpin{50};
class CpuPools {
 public:
  CpuPools();
  ~CpuPools();
  ThreadPool& Get(unsigned threads);

 private:
  std::vector<std::unique_ptr<ThreadPool>> pools_;  // [threads - 1]
};

}  // namespace skintune::internal
