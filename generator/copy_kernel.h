// skintune: the copy kernel every measurement is judged against, as the
// runner driver runs it: an ordinary kernel over an ordinary packed mesh.
//
// "As fast as a copy of the same bytes" is the ceiling of a memory-bound
// kernel, so every measurement is timed next to a copy moving the bytes its
// frame moves, by the same method (the same input-set rotation, the same
// launch-gap-free bursts: docs/TUNING.md "Same-size copy"). The copy is made
// of the driver's own parts: a KernelSource with the scalars `n` and `first`,
// the input buffer `copy_in` and the output `out_positions` (16-byte items),
// and a PackedMesh of one launch whose "vertices" are those items, so every
// API plans, binds and times it as it does a skinning kernel.
#pragma once

#include <cstddef>
#include <cstdint>

#include "generator/emit.h"
#include "generator/packer.h"

namespace skintune::internal {

// Work items of 256; a work item copies 2, 4 or 8 items (strided) when one
// item each would take more than kCopyMaxGroups work-groups (GL's minimum
// GL_MAX_COMPUTE_WORK_GROUP_COUNT).
inline constexpr int kCopyWorkGroup = 256;
inline constexpr std::size_t kCopyMaxGroups = 65535;

struct CopyKernel {
  PackedMesh mesh;      // one launch of `items` "vertices" of 16 bytes, no palette use
  KernelSource kernel;  // the language's copy_template (generator/languages.h), entry point "skintune_copy" (GLSL: "main")
  std::size_t items = 0;
};

// The copy moving `bytes` per frame (read + written: items = bytes / 32, at
// least 1) in `lang`'s API: the language table's copy_template, emitted as its
// copy_lang (glsl-vertex's copy is the GLSL compute one: both run on GL). Throws Error for more items than 8 per work item of
// kCopyMaxGroups groups take (a source over 2 GiB).
CopyKernel EmitCopy(Lang lang, std::size_t bytes);

// The flush that runs before every kernel-time sample (docs/TUNING.md
// "Kernel time"): the copy kernel of `read_bytes` of input with
// SKINTUNE_FLUSH defined, which reads every item and writes none (no item of
// the copy's input has all four words 0xffffffff, the only value it would
// write). Run over at least twice the last-level cache (FlushBytes), it
// leaves the cache holding clean lines of its own input: the next kernel
// finds none of its data there and has no dirty line of another's to write
// back, the state Nsight Compute's default cache control (--cache-control
// all) leaves before each kernel it profiles.
CopyKernel EmitFlush(Lang lang, std::size_t read_bytes);
// The flush's input for a device whose last-level cache holds `llc_bytes`
// (0: unknown, kUnknownCacheBytes assumed): twice the cache, at least 8 MiB;
// for a CPU device (`cpu`) at most kCpuFlushCapBytes. A CPU's last-level
// cache as sysfs reports it is the socket's, shared with cores the device
// does not time (300 MiB on this project's 2-core and 16-core machines,
// November 2026): no affordable flush empties it (600 MiB before every sample
// took ~60 ms a sample on 2 cores and made CPU tuning ten times slower). 32 MiB
// is 8 times the 2-core machine's L2 (4 MiB) and 6 times the largest mesh the
// default run tunes (100k-b4's 5 MB); on llvmpipe, whose flush runs at a few
// GB/s, 64 MiB made a GL variant's kernel time 1.7 times as long to sample.
// Where such a flush is read (GL and Vulkan on the host's CPU), a kernel
// time is therefore cold in the cores' caches, not necessarily in the whole
// socket's L3; PoCL and skintune's cpu device evict the frame's own lines
// instead, which is exact (docs/TUNING.md).
std::size_t FlushBytes(std::uint64_t llc_bytes, bool cpu = false);
inline constexpr std::uint64_t kUnknownCacheBytes = 64ull << 20;
inline constexpr std::uint64_t kCpuFlushCapBytes = 32ull << 20;

// The bytes one frame of `copy` moves: 32 per item (16 read, 16 written).
inline std::size_t CopyBytes(const CopyKernel& copy) { return copy.items * 32; }

}  // namespace skintune::internal
