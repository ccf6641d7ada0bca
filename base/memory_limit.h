// skintune: sizes are checked against the memory they need before anything
// is allocated (docs/INPUTS.md, "Limits").
//
// A dataset key is a few characters for any number of vertices; without a
// check, "100000m-b8" ends in std::bad_alloc and "300m-b8" first takes
// gigabytes. Each command estimates what it needs per vertex (the mesh, its
// reference output, ...) and calls CheckMemoryFor before generating or
// loading anything; the message says what would fit.
#pragma once

#include <cstdint>
#include <string>

namespace skintune::internal {

// Memory that may still be allocated somewhere, and where the figure comes
// from (said in errors).
struct MemoryAvailable {
  std::uint64_t bytes = 0;  // 0: unknown (then nothing is refused)
  std::string from;         // "MemAvailable", "RLIMIT_AS", "device 'opencl: ...' global memory"
};

// What this process may still allocate: the smallest of the machine's
// available memory (MemAvailable in /proc/meminfo) and what the address-space
// and data-segment limits (RLIMIT_AS, RLIMIT_DATA) leave beyond what is
// mapped now.
MemoryAvailable HostMemoryAvailable();

// Bytes of a SkinnedMesh per vertex: position, normal, B joint indices and weights.
std::uint64_t MeshBytesPerVertex(int influences, bool normals);

// Throws Error("<what>: needs about 29.1 GiB of memory (N vertices x B B:
// <breakdown>) but 21.3 GiB are available (<from>): at most about 210m
// vertices fit") when vertices x bytes_per_vertex exceeds what is available.
// `breakdown` says what the bytes are for ("mesh 60 B + skinning 36 B per
// vertex").
void CheckMemoryFor(const std::string& what, std::uint64_t vertices, std::uint64_t bytes_per_vertex,
                    const std::string& breakdown, const MemoryAvailable& available);

// "1.5 GiB", "640 MiB", "12 KiB", "100 B".
std::string FormatBytes(std::uint64_t bytes);
// "210m", "17800k", "1234": a vertex count rounded down to 3 significant digits,
// written as a dataset key can take it (k and m suffixes, no decimals).
std::string FormatVertexCount(std::uint64_t vertices);

}  // namespace skintune::internal
