#include "base/memory_limit.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "base/error.h"

namespace skintune::internal {

namespace {

// MemAvailable in bytes, or 0.
std::uint64_t MemAvailable() {
  std::ifstream in("/proc/meminfo");
  std::string name;
  std::uint64_t kib = 0;
  std::string unit;
  while (in >> name >> kib >> unit) {
    if (name == "MemAvailable:") return kib * 1024;
  }
  return 0;
}

// Bytes mapped by this process now (VmSize), or 0.
std::uint64_t MappedBytes() {
  std::ifstream in("/proc/self/statm");
  std::uint64_t pages = 0;
  if (!(in >> pages)) return 0;
  const long page = ::sysconf(_SC_PAGESIZE);
  return pages * static_cast<std::uint64_t>(page > 0 ? page : 4096);
}

}  // namespace

MemoryAvailable HostMemoryAvailable() {
  MemoryAvailable available;
  available.bytes = MemAvailable();
  if (available.bytes) available.from = "MemAvailable in /proc/meminfo";
  const std::uint64_t mapped = MappedBytes();
  for (const auto& [resource, name] : {std::pair{RLIMIT_AS, "RLIMIT_AS"}, std::pair{RLIMIT_DATA, "RLIMIT_DATA"}}) {
    rlimit limit{};
    if (::getrlimit(resource, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) continue;
    const std::uint64_t left = limit.rlim_cur > mapped ? limit.rlim_cur - mapped : 0;
    if (available.bytes == 0 || left < available.bytes) {
      available.bytes = std::max<std::uint64_t>(left, 1);
      available.from = std::string(name) + " less what is mapped";
    }
  }
  return available;
}

std::uint64_t MeshBytesPerVertex(int influences, bool normals) {
  return 12 + (normals ? 12 : 0) + static_cast<std::uint64_t>(std::max(influences, 0)) * (2 + 4);
}

std::string FormatBytes(std::uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  double value = static_cast<double>(bytes);
  int unit = 0;
  while (value >= 1024.0 && unit < 6) {
    value /= 1024.0;
    ++unit;
  }
  char text[32];
  std::snprintf(text, sizeof text, unit == 0 ? "%.0f %s" : "%.1f %s", value, units[unit]);
  return text;
}

std::string FormatVertexCount(std::uint64_t n) {
  // Round down to 3 significant digits, then write with k/m where exact.
  std::uint64_t scale = 1;
  while (n / scale >= 1000) scale *= 10;
  const std::uint64_t rounded = n / scale * scale;
  if (rounded >= 1000000 && rounded % 1000000 == 0) return std::to_string(rounded / 1000000) + "m";
  if (rounded >= 1000 && rounded % 1000 == 0) return std::to_string(rounded / 1000) + "k";
  return std::to_string(rounded);
}

void CheckMemoryFor(const std::string& what, std::uint64_t vertices, std::uint64_t bytes_per_vertex,
                    const std::string& breakdown, const MemoryAvailable& available) {
  if (available.bytes == 0 || bytes_per_vertex == 0) return;
  const std::uint64_t fit = available.bytes / bytes_per_vertex;
  if (vertices <= fit) return;
  // vertices x bytes_per_vertex may not fit in 64 bits.
  const long double needed = static_cast<long double>(vertices) * static_cast<long double>(bytes_per_vertex);
  const std::string needed_text =
      needed >= 1.8e19L ? "more than 16 EiB" : "about " + FormatBytes(static_cast<std::uint64_t>(needed));
  throw Error(what + ": needs " + needed_text + " of memory (" + std::to_string(vertices) + " vertices x " +
              std::to_string(bytes_per_vertex) + " B: " + breakdown + ") but " + FormatBytes(available.bytes) +
              " are available" + (available.from.empty() ? std::string() : " (" + available.from + ")") +
              ": at most about " + FormatVertexCount(fit) + " vertices fit");
}

}  // namespace skintune::internal
