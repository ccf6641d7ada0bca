// The table of APIs (runtime/backend_table.h). A new API adds its entry
// function here, in skintune::Backend order.
#include "runtime/backend_table.h"

#include <exception>

#include "base/error.h"
#include "runtime/physical_device.h"

namespace skintune::internal {

// Each defined in its folder: runtime/backends/<api>/<api>_backend.cpp.
BackendEntry OpenClEntry();
BackendEntry CudaEntry();
BackendEntry GlEntry();
BackendEntry VulkanEntry();
BackendEntry CpuEntry();

const std::vector<BackendEntry>& Backends() {
  static const std::vector<BackendEntry> table = {OpenClEntry(), CudaEntry(), GlEntry(), VulkanEntry(), CpuEntry()};
  return table;
}

const BackendEntry* FindBackend(std::string_view name) {
  for (const BackendEntry& b : Backends())
    if (name == b.name) return &b;
  return nullptr;
}

namespace {

void ResolveCaches(std::vector<FoundDevice>& devices) {
  std::vector<CacheReport> reports;
  for (FoundDevice& d : devices) {
    DeviceIdentity& i = d.identity;
    i.reported_cache_bytes = i.last_level_cache_bytes;  // what the API's discovery said
    reports.push_back({i.backend, i.type, i.name, i.uuid, i.pci_bus_id, i.reported_cache_bytes, i.global_memory_bytes});
  }
  const std::vector<CacheFigure> figures = ResolveLastLevelCaches(reports, HostLastLevelCacheBytes());
  for (std::size_t k = 0; k < devices.size(); ++k) {
    devices[k].identity.last_level_cache_bytes = figures[k].bytes;
    devices[k].identity.last_level_cache_source = figures[k].bytes ? figures[k].source : "unknown";
  }
}

}  // namespace

Discovered DiscoverDevices(const char* only) {
  Discovered found;
  for (const BackendEntry& b : Backends()) {
    if (only && std::string_view(only) != b.name) continue;
    try {
      b.discover(found);
    } catch (const std::exception& e) {
      found.skipped.push_back(std::string(b.name) + ": skipped: " + e.what());
    }
  }
  ResolveCaches(found.devices);
  return found;
}

std::string JoinedBackendNames(bool titles) {
  return OneOf(Backends(), [titles](const BackendEntry& b) { return std::string(titles ? b.title : b.name); });
}

std::vector<std::string> LanguageNames() {
  std::vector<std::string> names;
  for (const BackendEntry& b : Backends())
    for (const Lang lang : b.languages) names.push_back(Name(lang));
  return names;
}

}  // namespace skintune::internal
