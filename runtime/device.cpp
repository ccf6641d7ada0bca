// The public Device (skintune/skintune.h): discovery and opening over the
// backend table (runtime/backend_table.h). Adopting handles the caller
// already has is each API's: runtime/backends/<api>/<api>_backend.cpp.
#include "runtime/device.h"

#include <algorithm>
#include <cctype>
#include <utility>

#include "runtime/api_errors.h"

namespace skintune::internal {

namespace {

int Preference(const FoundDevice& d) { return FindBackend(d.identity.backend)->preference(d.identity); }

Device Opened(const FoundDevice& found, const DeviceOptions& options) {
  return MakeDevice(options, found.identity, found.limits, found.open());
}

std::string Names(const std::vector<FoundDevice>& devices) {
  std::string out;
  for (const FoundDevice& d : devices) out += (out.empty() ? "" : ", ") + d.identity.Id();
  return out.empty() ? "none found" : out;
}

}  // namespace

DeviceInfo PublicInfo(const DeviceIdentity& identity) {
  DeviceInfo i;
  const std::vector<BackendEntry>& table = Backends();
  const BackendEntry* entry = FindBackend(identity.backend);
  i.backend = static_cast<Backend>(entry ? entry - table.data() : 0);
  i.id = identity.Id();
  i.platform = identity.platform;
  i.vendor = identity.vendor;
  i.name = identity.name;
  i.driver_version = identity.driver_version;
  i.type = identity.type;
  return i;
}

Device MakeDevice(const DeviceOptions& options, const DeviceIdentity& identity, const DeviceLimits& limits,
                  std::unique_ptr<Runner> runner, bool gl_sharing) {
  auto state = std::make_shared<DeviceState>(options);
  state->info = PublicInfo(identity);
  state->backend = FindBackend(identity.backend);
  state->langs = state->backend->languages;
  state->limits = limits;
  state->runner = std::move(runner);
  state->gl_sharing = gl_sharing;
  state->runner->UseProgramCache(&state->cache, state->info.id);
  state->info.submit_thread = options.submit_thread && state->runner->UseSubmitThread();
  return DeviceAccess::Make(std::move(state));
}

Device DeviceAccess::Make(std::shared_ptr<DeviceState> state) {
  Device device;
  device.impl_ = std::make_unique<Device::Impl>();
  device.impl_->state = std::move(state);
  return device;
}

const std::shared_ptr<DeviceState>* DeviceAccess::State(const Device& device) {
  return device.impl_ ? &device.impl_->state : nullptr;
}

}  // namespace skintune::internal

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

Device::Device() = default;
Device::~Device() = default;
Device::Device(Device&&) noexcept = default;
Device& Device::operator=(Device&&) noexcept = default;

const DeviceInfo& Device::info() const {
  static const DeviceInfo none;
  return impl_ ? impl_->state->info : none;
}

ProgramCacheStats Device::cache_stats() const {
  if (!impl_) return {};
  const ProgramCacheCounters& c = impl_->state->cache.counters();
  return {c.builds, c.disk_hits, c.memory_hits};
}

bool Device::has_gl_sharing() const { return impl_ && impl_->state->gl_sharing; }

std::vector<DeviceInfo> Device::List() {
  std::vector<DeviceInfo> out;
  try {
    for (const FoundDevice& d : DiscoverDevices().devices) out.push_back(PublicInfo(d.identity));
  } catch (...) {
    // Discovery reports absent backends by leaving them out; it never fails.
  }
  return out;
}

Result<Device> Device::OpenBest(const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    std::vector<FoundDevice> devices = DiscoverDevices().devices;
    if (devices.empty())
      FailWith(ErrorCode::kNotFound,
               "Device::OpenBest: no " + JoinedBackendNames(true) + " device on this machine");
    std::stable_sort(devices.begin(), devices.end(),
                     [](const FoundDevice& a, const FoundDevice& b) { return Preference(a) < Preference(b); });
    std::string failures;
    for (const FoundDevice& d : devices) {
      try {
        return Opened(d, options);
      } catch (const Error& e) {
        failures += std::string(failures.empty() ? "" : "; ") + d.identity.Id() + ": " + e.what();
      }
    }
    FailWith(ErrorCode::kDeviceError, "Device::OpenBest: no device could be opened: " + failures);
  });
}

Result<Device> Device::Open(const std::string& pattern, const Backend* backend, const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    const std::vector<FoundDevice> devices = DiscoverDevices(backend ? BackendName(*backend) : nullptr).devices;
    for (const FoundDevice& d : devices)
      if (MatchesDevice(pattern, d.identity)) return Opened(d, options);
    FailWith(ErrorCode::kNotFound, "Device::Open: no " + (backend ? std::string(BackendName(*backend)) + " " : "") +
                                       "device matches '" + pattern + "' (devices: " + Names(devices) + ")");
  });
}

}  // namespace skintune
