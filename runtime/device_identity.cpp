#include "runtime/device_identity.h"

#include <algorithm>
#include <cctype>

#include <nlohmann/json.hpp>

#include "base/error.h"

namespace skintune::internal {

std::string DeviceIdentity::Id() const { return backend + ":" + platform + "/" + name + "/" + driver_version; }

namespace {

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// Platforms whose full name does not contain the name users call them by.
struct PlatformAlias {
  const char* platform;
  const char* short_name;
};
constexpr PlatformAlias kPlatformAliases[] = {{"Portable Computing Language", "PoCL"}};

}  // namespace

std::string PlatformShortName(const std::string& platform) {
  for (const PlatformAlias& a : kPlatformAliases)
    if (platform == a.platform) return a.short_name;
  return "";
}

bool MatchesDevice(const std::string& pattern, const DeviceIdentity& d) {
  const std::string wanted = Lower(pattern);
  for (const std::string& field : {d.Id(), d.vendor, d.type, PlatformShortName(d.platform)})
    if (Lower(field).find(wanted) != std::string::npos) return true;
  return false;
}

void to_json(nlohmann::json& out, const DeviceIdentity& d) {
  out = {{"id", d.Id()},
         {"backend", d.backend},
         {"index", d.index},
         {"platform", d.platform},
         {"vendor", d.vendor},
         {"name", d.name},
         {"driver_version", d.driver_version},
         {"api_version", d.api_version},
         {"type", d.type},
         {"compute_units", d.compute_units},
         {"global_memory_bytes", d.global_memory_bytes},
         {"local_memory_bytes", d.local_memory_bytes},
         {"constant_memory_bytes", d.constant_memory_bytes},
         {"uuid", d.uuid},
         {"pci_bus_id", d.pci_bus_id},
         {"last_level_cache_bytes", d.last_level_cache_bytes},
         {"last_level_cache_source", d.last_level_cache_source},
         {"reported_cache_bytes", d.reported_cache_bytes}};
}

namespace {

template <typename T>
void ReadField(const nlohmann::json& in, const char* name, T& value, bool required) {
  const auto found = in.find(name);
  if (found == in.end()) {
    if (required) throw Error(std::string("device identity: missing '") + name + "'");
    return;
  }
  try {
    value = found->get<T>();
  } catch (const nlohmann::json::exception&) {
    throw Error(std::string("device identity: '") + name + "' has the wrong type (" + found->dump() + ")");
  }
}

}  // namespace

void from_json(const nlohmann::json& in, DeviceIdentity& d) {
  if (!in.is_object()) throw Error("device identity: not a JSON object");
  d = DeviceIdentity{};
  ReadField(in, "backend", d.backend, true);
  ReadField(in, "platform", d.platform, true);
  ReadField(in, "name", d.name, true);
  ReadField(in, "driver_version", d.driver_version, true);
  ReadField(in, "index", d.index, false);
  ReadField(in, "vendor", d.vendor, false);
  ReadField(in, "api_version", d.api_version, false);
  ReadField(in, "type", d.type, false);
  ReadField(in, "compute_units", d.compute_units, false);
  ReadField(in, "global_memory_bytes", d.global_memory_bytes, false);
  ReadField(in, "local_memory_bytes", d.local_memory_bytes, false);
  ReadField(in, "constant_memory_bytes", d.constant_memory_bytes, false);
  ReadField(in, "uuid", d.uuid, false);
  ReadField(in, "pci_bus_id", d.pci_bus_id, false);
  ReadField(in, "last_level_cache_bytes", d.last_level_cache_bytes, false);
  ReadField(in, "last_level_cache_source", d.last_level_cache_source, false);
  ReadField(in, "reported_cache_bytes", d.reported_cache_bytes, false);
}

}  // namespace skintune::internal
