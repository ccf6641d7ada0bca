// skintune devices: every OpenCL platform and device on this machine, then
// every device of every API skintune runs on (runtime/backend_table.h), by
// the id the tuner and the runtime use, or why an API has none.
#include <iomanip>
#include <iostream>

#include <nlohmann/json.hpp>

#include "runtime/backend_table.h"
#include "runtime/backends/opencl/opencl_devices.h"
#include "tools/commands.h"

namespace skintune::internal::tools {

namespace {

std::string Bytes(std::uint64_t bytes) {
  std::ostringstream s;
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double value = static_cast<double>(bytes);
  int unit = 0;
  while (value >= 1024.0 && unit < 4) {
    value /= 1024.0;
    ++unit;
  }
  s << std::setprecision(value < 10 ? 3 : 4) << value << " " << units[unit];
  return s.str();
}

void PrintText(const OpenClInventory& inventory) {
  if (inventory.devices.empty()) {
    std::cout << "OpenCL: skipped: " << (inventory.status.empty() ? "no devices" : inventory.status) << "\n";
  }
  int last_platform = -1;
  for (const OpenClDeviceInfo& d : inventory.devices) {
    if (d.platform_index != last_platform) {
      last_platform = d.platform_index;
      std::cout << "OpenCL platform " << d.platform_index << ": " << d.platform_name << " (" << d.platform_vendor
                << ", " << d.platform_version << ")\n";
    }
    std::cout << "  device " << d.platform_index << "." << d.device_index << ": " << d.name << "\n"
              << "    vendor " << d.vendor << ", type " << d.type << ", driver " << d.driver_version << ", "
              << d.device_version << "\n"
              << "    " << d.compute_units << " compute units at " << d.max_clock_mhz << " MHz, global memory "
              << Bytes(d.global_memory_bytes) << ", local memory " << Bytes(d.local_memory_bytes)
              << ", constant buffer " << Bytes(d.constant_buffer_bytes) << ", max work-group "
              << d.max_work_group_size << ", images " << (d.image_support ? "yes" : "no") << "\n";
  }
  for (const std::string& w : inventory.warnings) std::cout << "  warning: " << w << "\n";
}

std::string Languages(const std::string& backend) {
  std::string out;
  for (const Lang lang : FindBackend(backend)->languages) out += (out.empty() ? "" : ", ") + std::string(Name(lang));
  return out;
}

void PrintText(const Discovered& found) {
  std::cout << "Devices (" << JoinedBackendNames(true) << "):\n";
  for (const FoundDevice& d : found.devices) {
    const DeviceIdentity& i = d.identity;
    std::cout << "  " << i.Id() << " (" << i.type << "): " << Languages(i.backend) << "\n";
    if (!i.uuid.empty() || !i.pci_bus_id.empty())
      std::cout << "    chip" << (i.uuid.empty() ? "" : " UUID " + i.uuid) << (i.pci_bus_id.empty() ? "" : " PCI " + i.pci_bus_id)
                << "\n";
    std::cout << "    last-level cache for timing: "
              << (i.last_level_cache_bytes ? std::to_string(i.last_level_cache_bytes >> 10) + " KiB (" +
                                                 i.last_level_cache_source + ")"
                                           : std::string("unknown (64 MiB assumed)"))
              << "\n";
  }
  for (const std::string& s : found.skipped) std::cout << "  " << s << "\n";
}

nlohmann::json Json(const Discovered& found) {
  nlohmann::json devices = nlohmann::json::array();
  for (const FoundDevice& d : found.devices) devices.push_back(d.identity);
  return {{"devices", devices}, {"skipped", found.skipped}};
}

}  // namespace

Command RegisterDevices(CLI::App& app) {
  auto* sub = app.add_subcommand("devices", "list every OpenCL platform and device, and every device skintune runs on");
  auto json = std::make_shared<bool>(false);
  sub->add_flag("--json", *json, "print JSON instead of text");
  return {sub, [json] {
            const OpenClInventory inventory = EnumerateOpenCl();
            const Discovered found = DiscoverDevices();
            if (*json) {
              nlohmann::json out = {{"opencl",
                                     {{"platform_count", inventory.platform_count},
                                      {"status", inventory.status.empty() ? "ok" : "skipped: " + inventory.status},
                                      {"devices", inventory.devices},
                                      {"warnings", inventory.warnings}}},
                                    {"skintune", Json(found)}};
              std::cout << out.dump(2) << "\n";
            } else {
              PrintText(inventory);
              PrintText(found);
            }
            return 0;
          }};
}

}  // namespace skintune::internal::tools
