// skintune (internal): which API devices are one chip, and that chip's real
// last-level cache, for the timing residency rule (docs/TUNING.md "Residency").
//
// The tuner rotates among input sets whose footprint is at least twice the
// last-level cache, so no timed frame finds its inputs in cache. Each API
// reports that cache its own way, and not all of them tell the truth: NVIDIA's
// OpenCL says CL_DEVICE_GLOBAL_MEM_CACHE_SIZE is 4.3 MB on an H100 whose L2 is
// 50 MB (CUDA's CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE), and GL says nothing. So the
// same GPU seen through CUDA, OpenCL, GL (and Vulkan) is matched as one chip by
// its UUID or PCI bus id, and every API's device takes the largest credible
// figure any of them gives, or the known size of the chip, or for a CPU device
// (PoCL, llvmpipe) the host's last-level cache. Each figure says where it came
// from; the report records it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace skintune::internal {

// What one API says about one device.
struct CacheReport {
  std::string backend;             // "opencl", "cuda", "gl", ...
  std::string type;                // "gpu", "cpu", ...
  std::string name;                // the API's device name
  std::string uuid;                // 32 lower-case hex digits, "" when the API does not say
  std::string pci_bus_id;          // "dddd:bb:dd.f" lower-case, "" when the API does not say
  std::uint64_t reported_llc = 0;  // the API's last-level cache figure, 0 = none
  std::uint64_t memory_bytes = 0;  // global memory: a cache figure above it is not credible
};

struct CacheFigure {
  std::uint64_t bytes = 0;  // 0 only when nothing at all is known
  std::string source;       // e.g. "cuda CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE of the same chip (UUID ...)"
};

// The cache figure of every device of `devices`, in their order: the largest
// credible figure among the devices that are the same chip (same UUID, else
// same PCI bus id; every "cpu" device is the host), the chip's known size by
// name (KnownLastLevelCacheBytes), and for "cpu" devices `host_llc_bytes`.
// A figure of 0 or above the device's memory is not credible.
std::vector<CacheFigure> ResolveLastLevelCaches(const std::vector<CacheReport>& devices,
                                                std::uint64_t host_llc_bytes);

// The known last-level cache of a chip by its marketing name (a substring
// match on a short table of datasheet figures), 0 when not known.
std::uint64_t KnownLastLevelCacheBytes(const std::string& device_name);

// This machine's last-level cache: the largest cache of cpu0 in sysfs, else
// sysconf's largest level, 0 when unknown.
std::uint64_t HostLastLevelCacheBytes();

// A 16-byte UUID as 32 lower-case hex digits ("" for all zero bytes: not an identity).
std::string UuidHex(const unsigned char* bytes16);

}  // namespace skintune::internal
