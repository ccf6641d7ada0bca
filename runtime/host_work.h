// The Skinner's host work of a read-back, spread over the host's cores: the
// scan and the copy out of page-locked memory (ReadPositions / ReadNormals).
//
// A host thread of the GPU machines moves about 5 GB/s, so a read-back of
// 1.6M vertices runs on one process-wide pool of up to 16 threads, whose idle
// workers poll for the next loop for a short while (the copy follows the scan
// within microseconds) instead of sleeping.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>

#include "generator/variant.h"
#include "model/mesh.h"

namespace skintune::internal {

// body(begin, end) over [0, count) in chunks of `grain` on the runtime's host
// pool when count > grain; otherwise (and when another thread is using the
// pool) on the calling thread, chunk by chunk in order.
void ForChunks(std::size_t count, std::size_t grain, const std::function<void(std::size_t, std::size_t)>& body);

// How long a thread that serves a frame loop (the palette crew's helpers, the
// submit thread) polls for its next piece of work before it sleeps: longer
// than a frame that waits for the device (SetPalette + Skin + Finish, ~50 us
// on the H200 machine), so the next frame finds it awake; a game's frame of
// milliseconds lets it sleep.
inline constexpr std::chrono::microseconds kFramePoll{500};

// How long a Vulkan wait for the device (Finish, a palette buffer's fence, a
// read-back's) polls the fence before it sleeps in vkWaitForFences: NVIDIA's
// driver wakes a thread sleeping there about 27 us after the fence signals,
// more than a crowd's kernel (docs/PERFORMANCE.md "The frame loop"). CUDA's,
// NVIDIA's OpenCL's and GL's waits return as promptly on their own (polling
// glClientWaitSync or clGetEventInfo first changed no GL or OpenCL frame). A
// wait longer than this (a large read-back, a device far behind) sleeps after
// it, and a wait for a CPU device (lavapipe) sleeps at once.
inline constexpr std::chrono::microseconds kDeviceWaitPoll{1000};

// PackPaletteInto (generator/packer.h) spread over the runtime's palette crew:
// half the host's cores, 2 to 8 threads (the caller's and helpers that poll
// for kFramePoll after each packing, so a frame loop's next SetPalette finds
// them awake), each packing the same run of at least kPaletteGrain whole
// matrices every call (its input's lines stay in its core's cache; the caller
// takes the run of a helper that does not come in time). A second caller at
// the same time packs alone. One core stores ~25-30 GB/s into page-locked
// memory on the GPU machines' hosts, so 64 x 77 mat3x4 (236 KB) cost it 7-15
// us a frame, about the crowd kernel's time (H100 and H200 machines, 2026-11).
// `max_threads` (SkinnerOptions::palette_threads): 0, the whole crew; 1, the
// calling thread alone (the crew is not started); else at most that many.
// Returns what PackPaletteInto does for the whole palette: the first
// non-finite matrix (or `matrices`), and the largest |element|.
std::size_t PackPaletteOnPool(const float* column_major, std::size_t matrices, const Variant& variant,
                              std::uint8_t* out, float* largest_magnitude, unsigned max_threads = 0);
inline constexpr std::size_t kPaletteGrain = 512;
// The palette crew's most threads (SkinnerOptions' kMaxPaletteThreads).
inline constexpr unsigned kMaxPaletteLanes = 8;

// Whether every 32-bit word of `bytes` is a finite float (exponent bits not all set).
bool AllFinite(std::span<const std::uint8_t> bytes);

// Whether a read-back of `bytes` into the caller's array should use
// non-temporal stores: from 3/4 of the host's last-level cache on, as glibc's
// memcpy decides (below it the array stays in cache for the caller, who reads
// it next; above it, streaming saves the read for ownership of every line).
bool StreamingWrite(std::size_t bytes);

// Copies vertices [begin, end) of `packed` (stride 12 or 16 bytes, float3 at
// the start of each, in mesh order) to out[3 * v ...]: when `streaming`, with
// non-temporal stores followed by a store fence.
void CopyFloat3(const std::uint8_t* packed, std::size_t stride, float* out, std::size_t begin, std::size_t end,
                bool streaming);

// The bytes of each chunk when `bytes` are read back in at most `max_chunks`
// chunks of whole multiples of `chunk_bytes` (at least one of them): the
// APIs whose reads cost much host time each to queue (NVIDIA's OpenCL) or
// carry a fence each (GL) read in few chunks, the host grains within them.
std::size_t ChunkCovering(std::size_t bytes, std::size_t chunk_bytes, std::size_t max_chunks);

// CopyFloat3 and AllFinite in one pass: block by block, each block of
// `packed` scanned and then copied while it is in the cache. Stops before
// the first block holding a NaN or infinite word and returns false (the
// blocks before it are copied, that one and the rest are not); true when
// every word of [begin, end) is finite and copied.
bool CopyFloat3Finite(const std::uint8_t* packed, std::size_t stride, float* out, std::size_t begin, std::size_t end,
                      bool streaming);

// The read-back's overflow bound (Skinner::ReadPositions): every position
// output's |component| is at most OutputBound(mesh) x the palette's largest
// |element|. x' = sum_i w_i (M_i (x, y, z, 1)) has at most 4 terms of
// |w_i| |M_i[r][c]| |p_c| per influence; the weight sum is the mesh's
// largest plus one per influence (the formats' rounding; a unorm weight is
// at most 1 anyway), the position's the largest |component|, at least 1 (the
// translation column). Normals have no such bound: they are normalised.
double OutputBound(const SkinnedMesh& mesh);
// Whether outputs of that bound, skinned with a palette whose largest
// |element| is `magnitude`, cannot overflow float32: the product at most a
// 1024th of float32's largest, ample for the kernels' rounding (each partial
// sum is within a few ulp of the exact one's bound).
bool CannotOverflow(double output_bound, float magnitude);

}  // namespace skintune::internal
