// skintune (internal): who a device is, one type for the runtime and the
// tuner. Discovery (runtime/backend_table.h) fills it once per device from
// the API's own answers (each backend folder: IdentityOf); the tuner records
// it in reports and the runtime matches winners databases on it, so both
// agree on the id "<backend>:<platform>/<name>/<driver_version>". The public
// skintune::DeviceInfo is made from it (runtime/device.h PublicInfo).
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json_fwd.hpp>

namespace skintune::internal {

struct DeviceIdentity {
  std::string backend;          // BackendEntry::name: "opencl", "cuda", "gl"
  int index = 0;                // position in discovery order (for --device and the worker)
  std::string platform;         // OpenCL platform name; "CUDA"; EGL platform for GL
  std::string vendor;
  std::string name;             // device name / GL_RENDERER
  std::string driver_version;
  std::string api_version;      // OpenCL device version; CUDA compute capability; GL_VERSION
  std::string type;             // "gpu", "cpu", ...
  std::uint32_t compute_units = 0;
  std::uint64_t global_memory_bytes = 0;
  std::uint64_t local_memory_bytes = 0;
  std::uint64_t constant_memory_bytes = 0;
  std::string uuid;             // the chip's UUID, 32 hex digits, where the API says ("" otherwise)
  std::string pci_bus_id;       // "dddd:bb:dd.f", where the API says ("" otherwise)
  // The last-level cache the rotation rule uses (docs/TUNING.md
  // "Residency"): the physical chip's, matched across every API discovery
  // found (runtime/physical_device.h); 0 = unknown (then it assumes 64 MiB).
  std::uint64_t last_level_cache_bytes = 0;
  std::string last_level_cache_source;       // where that figure came from
  std::uint64_t reported_cache_bytes = 0;    // what this API itself says (0: nothing)

  // Stable across runs and machines with the same device and driver:
  // "<backend>:<platform>/<name>/<driver_version>".
  std::string Id() const;
};

// The one rule of every `--device PATTERN` and Device::Open (tune, variants,
// emit --db, the runtime): the device matches when PATTERN, case-insensitive,
// is a substring of its id "<backend>:<platform>/<name>/<driver_version>", its
// vendor or type, or its platform's short name (PlatformShortName: "PoCL"
// for "Portable Computing Language"). "" matches every device. Only the fields
// a winners database records take part, so a pattern that picks a device when
// tuning picks its entries in the database.
bool MatchesDevice(const std::string& pattern, const DeviceIdentity& device);
// The name a platform goes by where its full name says otherwise ("PoCL" for
// "Portable Computing Language"), or "".
std::string PlatformShortName(const std::string& platform);

// Every field, and "id". Reading needs backend, platform, name and
// driver_version; throws Error naming a missing field or one of the wrong type.
void to_json(nlohmann::json& out, const DeviceIdentity& d);
void from_json(const nlohmann::json& in, DeviceIdentity& d);

}  // namespace skintune::internal
