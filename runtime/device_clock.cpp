#include "runtime/device_clock.h"

#include <algorithm>
#include <cctype>
#include <vector>

#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/cuda/nvml.h"
#include "runtime/physical_device.h"  // UuidHex

namespace skintune::internal {

namespace {

class NvmlClock final : public DeviceClock {
 public:
  NvmlClock(const nvml::Api& api, nvml::Device device) : api_(api), device_(device) {}
  std::optional<unsigned> SmMhz() override { return Read(api_.clock); }
  std::optional<unsigned> MaxSmMhz() override { return Read(api_.max_clock); }

 private:
  std::optional<unsigned> Read(nvml::Return (*fn)(nvml::Device, int, unsigned*)) const {
    unsigned mhz = 0;
    if (fn(device_, nvml::kClockSm, &mhz) != 0 || mhz == 0) return std::nullopt;
    return mhz;
  }
  const nvml::Api& api_;
  nvml::Device device_;
};

bool Contains(std::string text, const std::string& lower_word) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text.find(lower_word) != std::string::npos;
}

bool IsCpu(const DeviceIdentity& d) { return Contains(d.type, "cpu"); }
bool IsNvidia(const DeviceIdentity& d) { return Contains(d.vendor, "nvidia") || Contains(d.name, "nvidia"); }

}  // namespace

std::string NvmlUuid(const std::string& hex32) {
  if (hex32.size() != 32 || !std::all_of(hex32.begin(), hex32.end(), [](unsigned char c) { return std::isxdigit(c); }))
    return "";
  return "GPU-" + hex32.substr(0, 8) + "-" + hex32.substr(8, 4) + "-" + hex32.substr(12, 4) + "-" +
         hex32.substr(16, 4) + "-" + hex32.substr(20);
}

std::unique_ptr<DeviceClock> DeviceClock::Open(const DeviceIdentity& device, std::string* why) {
  const auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return std::unique_ptr<DeviceClock>();
  };
  if (IsCpu(device)) return fail("a CPU device");
  if (!IsNvidia(device)) return fail("not an NVIDIA GPU");
  const std::string uuid = NvmlUuid(device.uuid);
  if (uuid.empty() && device.pci_bus_id.empty()) return fail("its API gave neither a UUID nor a PCI bus id");
  std::string missing;
  const nvml::Api* api = nvml::Library(&missing);
  if (!api) return fail(missing);
  if (!api->by_uuid || !api->by_pci_bus_id || !api->clock || !api->max_clock)
    return fail("NVML lacks a function skintune uses");
  nvml::Device handle = nullptr;
  if (!uuid.empty() && api->by_uuid(uuid.c_str(), &handle) == 0 && handle)
    return std::make_unique<NvmlClock>(*api, handle);
  if (!device.pci_bus_id.empty() && api->by_pci_bus_id(device.pci_bus_id.c_str(), &handle) == 0 && handle)
    return std::make_unique<NvmlClock>(*api, handle);
  return fail("NVML does not know the GPU (" + (uuid.empty() ? device.pci_bus_id : uuid) + ")");
}

ClockHold::~ClockHold() {
  if (const cuda::DriverApi* api = cuda::Driver())
    for (const int device : held_) (void)api->cuDevicePrimaryCtxRelease(device);
}

std::unique_ptr<ClockHold> ClockHold::ForDevices(const std::vector<DeviceIdentity>& devices, std::string* why) {
  const auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return std::unique_ptr<ClockHold>();
  };
  std::vector<std::string> uuids;
  bool any = false, without_uuid = false;
  for (const DeviceIdentity& d : devices) {
    if (IsCpu(d) || !IsNvidia(d)) continue;
    any = true;
    if (d.uuid.empty()) without_uuid = true;
    else uuids.push_back(d.uuid);
  }
  if (!any) return fail("no NVIDIA GPU among the devices");
  std::string missing;
  const cuda::DriverApi* api = cuda::Driver(&missing);
  if (!api) return fail("no CUDA driver: " + missing);
  int count = 0;
  if (api->cuDeviceGetCount(&count) != cuda::kSuccess) return fail("cuDeviceGetCount failed");
  std::unique_ptr<ClockHold> hold(new ClockHold);
  constexpr int kAttributeComputeMode = 20;  // CU_DEVICE_ATTRIBUTE_COMPUTE_MODE; 0 = CU_COMPUTEMODE_DEFAULT
  for (int ordinal = 0; ordinal < count; ++ordinal) {
    cuda::Device device = 0;
    if (api->cuDeviceGet(&device, ordinal) != cuda::kSuccess) continue;
    unsigned char bytes[16] = {};
    const std::string uuid = api->cuDeviceGetUuid(bytes, device) == cuda::kSuccess ? UuidHex(bytes) : "";
    if (!without_uuid && std::find(uuids.begin(), uuids.end(), uuid) == uuids.end()) continue;
    int mode = -1;
    if (api->cuDeviceGetAttribute(&mode, kAttributeComputeMode, device) != cuda::kSuccess || mode != 0) continue;
    cuda::Context context = nullptr;
    if (api->cuDevicePrimaryCtxRetain(&context, device) == cuda::kSuccess) hold->held_.push_back(device);
  }
  if (hold->held_.empty()) return fail("no NVIDIA GPU of the devices could be held (CUDA sees none, or each is in an exclusive compute mode)");
  return hold;
}

}  // namespace skintune::internal
