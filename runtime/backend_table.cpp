// The table of APIs (runtime/backend_table.h). A new API adds its entry
// function here, in skintune::Backend order.
#include "runtime/backend_table.h"

#include <exception>

namespace skintune {

// Each defined in its folder: runtime/backends/<api>/<api>_backend.cpp.
BackendEntry OpenClEntry();
BackendEntry CudaEntry();
BackendEntry GlEntry();
BackendEntry VulkanEntry();

const std::vector<BackendEntry>& Backends() {
  static const std::vector<BackendEntry> table = {OpenClEntry(), CudaEntry(), GlEntry(), VulkanEntry()};
  return table;
}

const BackendEntry* FindBackend(std::string_view name) {
  for (const BackendEntry& b : Backends())
    if (name == b.name) return &b;
  return nullptr;
}

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
  return found;
}

std::string JoinedBackendNames(bool titles) {
  const std::vector<BackendEntry>& table = Backends();
  std::string out;
  for (std::size_t i = 0; i < table.size(); ++i) {
    if (i > 0) out += i + 1 == table.size() ? " or " : ", ";
    out += titles ? table[i].title : table[i].name;
  }
  return out;
}

std::vector<std::string> LanguageNames() {
  std::vector<std::string> names;
  for (const BackendEntry& b : Backends())
    for (const Lang lang : b.languages) names.push_back(Name(lang));
  return names;
}

}  // namespace skintune
