#include "runtime/backends/cuda/nvml.h"

#include <dlfcn.h>

#include <cstdlib>
#include <mutex>
#include <vector>

namespace skintune::internal::nvml {

namespace {

struct Loaded {
  Api api{};
  bool ok = false;
  std::string why;  // why not
};

std::vector<std::string> Candidates() {
  if (const char* forced = std::getenv("SKINTUNE_NVML_LIBRARY"); forced && *forced) return {forced};
  return {"libnvidia-ml.so.1"};
}

template <typename F>
void Resolve(void* library, const char* name, F& pointer) {
  pointer = reinterpret_cast<F>(dlsym(library, name));
}

Loaded Load() {
  Loaded l;
  void* library = nullptr;
  std::string tried;
  for (const std::string& name : Candidates()) {
    library = dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (library) break;
    tried += (tried.empty() ? "" : ", ") + name;
  }
  if (!library) {
    l.why = "NVML not found (" + tried + ")";
    return l;
  }
  Resolve(library, "nvmlInit_v2", l.api.init);
  Resolve(library, "nvmlDeviceGetHandleByUUID", l.api.by_uuid);
  Resolve(library, "nvmlDeviceGetHandleByPciBusId_v2", l.api.by_pci_bus_id);
  Resolve(library, "nvmlDeviceGetClockInfo", l.api.clock);
  Resolve(library, "nvmlDeviceGetMaxClockInfo", l.api.max_clock);
  Resolve(library, "nvmlSystemGetDriverVersion", l.api.driver_version);
  if (!l.api.init) {
    l.why = "NVML lacks nvmlInit_v2";
    return l;
  }
  if (const Return r = l.api.init(); r != 0) {
    l.why = "nvmlInit_v2 failed (" + std::to_string(r) + ")";
    return l;
  }
  l.ok = true;
  return l;  // never unloaded or shut down: handles live as long as the process
}

}  // namespace

const Api* Library(std::string* why) {
  static std::once_flag once;
  static Loaded loaded;
  std::call_once(once, [] { loaded = Load(); });
  if (!loaded.ok && why) *why = loaded.why;
  return loaded.ok ? &loaded.api : nullptr;
}

}  // namespace skintune::internal::nvml
