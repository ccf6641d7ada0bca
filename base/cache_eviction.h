// skintune: evicting bytes from every cache of the host, for a kernel time
// that starts clean and cold (docs/TUNING.md "Kernel time") on a device whose
// memory is the host's: skintune's cpu device, and PoCL through a native
// kernel queued before each sample.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace skintune::internal {

// Writes back and invalidates every cache line of `buffers` in every cache of
// the coherence domain, the shared last-level cache and other cores' caches
// included (clflushopt where the CPU has it, else clflush), and waits until
// that is done (mfence, once), so the next read of them comes from memory.
// Unlike a flush by reading other data, it is exact whatever the cache's
// size, and it costs one instruction per 64 bytes of the kernel's own data.
// A no-op on a CPU without these instructions.
void EvictFromCaches(std::span<const std::span<const std::uint8_t>> buffers);

class ThreadPool;
// The same, the lines spread over `pool`'s threads in pieces of
// kEvictionPieceBytes (EvictionPieces), each thread waiting for its own
// flushes: one thread evicts a 100k-vertex frame's 5 MB in 0.25-0.4 ms, 2-5
// times the cpu device's kernel on a 16-thread host, and took seconds of a
// tuning run in its cold samples and its copy probe's 1.2 GB (an H200
// machine's host, 300 MiB of L3, 2026-12-02). One thread where the buffers
// make fewer than two pieces.
void EvictFromCaches(std::span<const std::span<const std::uint8_t>> buffers, ThreadPool& pool);

inline constexpr std::size_t kEvictionPieceBytes = std::size_t{256} << 10;

// `buffers` cut at every multiple of `piece` bytes from each one's start
// (the last piece of each holds its end): every byte in exactly one piece.
std::vector<std::span<const std::uint8_t>> EvictionPieces(std::span<const std::span<const std::uint8_t>> buffers,
                                                          std::size_t piece);

}  // namespace skintune::internal
