// skintune: evicting bytes from every cache of the host, for a kernel time
// that starts clean and cold (docs/TUNING.md "Kernel time") on a device whose
// memory is the host's: skintune's cpu device, and PoCL through a native
// kernel queued before each sample.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace skintune::internal {

// Writes back and invalidates every cache line of `buffers` in every cache of
// the coherence domain, the shared last-level cache and other cores' caches
// included (clflushopt where the CPU has it, else clflush), and waits until
// that is done (mfence, once), so the next read of them comes from memory.
// Unlike a flush by reading other data, it is exact whatever the cache's
// size, and it costs one instruction per 64 bytes of the kernel's own data.
// A no-op on a CPU without these instructions.
void EvictFromCaches(std::span<const std::span<const std::uint8_t>> buffers);

}  // namespace skintune::internal
