// The cpu device in the backend table (runtime/backend_table.h): the host's
// CPU running the fast path's kernels (cpu_runner.h), one device per machine.
#include <fstream>
#include <memory>
#include <thread>

#include <unistd.h>

#include "generator/emit.h"  // kGeneratorVersion
#include "runtime/backend_table.h"
#include "runtime/backends/cpu/cpu_runner.h"
#include "runtime/skinner.h"

namespace skintune::internal {

namespace {

// "model name" and "vendor_id" of /proc/cpuinfo ("" where absent).
std::string CpuInfoField(const std::string& field) {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field, 0) != 0) continue;
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::size_t start = line.find_first_not_of(" \t", colon + 1);
    return start == std::string::npos ? "" : line.substr(start);
  }
  return "";
}

void Discover(Discovered& out) {
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  FoundDevice found;
  DeviceIdentity& d = found.identity;
  d.backend = "cpu";
  d.platform = "skintune";
  d.vendor = CpuInfoField("vendor_id");
  d.name = CpuInfoField("model name");
  if (d.name.empty()) d.name = "host CPU";
  // The kernels are skintune's own: the generator version and the
  // instruction set of the table this CPU runs identify them.
  d.driver_version = std::string(kGeneratorVersion) + " " + CpuKernelIsa();
  d.api_version = CpuKernelIsa();
  d.type = "cpu";
  d.compute_units = threads;
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  d.global_memory_bytes = pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page) : 0;
  // The palette is host memory: no constant, local or image storage.
  found.limits.max_wg_size = 0;
  found.limits.local_memory_bytes = 0;
  found.limits.constant_memory_bytes = 0;
  found.limits.uniform_block_bytes = 0;
  found.limits.image_support = false;
  found.limits.image_buffer_max_texels = 0;
  found.open = []() -> std::unique_ptr<Runner> { return std::make_unique<CpuRunner>(); };
  out.devices.push_back(std::move(found));
}

// Last of all: a GPU's API first, and PoCL (3) before it for OpenBest, as
// before the cpu device existed (docs/RUNTIME.md).
int Preference(const DeviceIdentity&) { return 6; }

}  // namespace

BackendEntry CpuEntry() { return {"cpu", "CPU", {Lang::kCpu}, Discover, Preference, MakeRunnerSkinner}; }

}  // namespace skintune::internal
