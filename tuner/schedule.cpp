#include "tuner/schedule.h"

#include <algorithm>
#include <cctype>
#include <numeric>
#include <string>

namespace skintune::internal {

namespace {

bool IsCpu(const DeviceIdentity& d) {
  std::string type = d.type;
  std::transform(type.begin(), type.end(), type.begin(), [](unsigned char c) { return std::tolower(c); });
  return type.find("cpu") != std::string::npos;
}

}  // namespace

bool MayShareHardware(const DeviceIdentity& a, const DeviceIdentity& b) {
  if (IsCpu(a) || IsCpu(b)) return IsCpu(a) && IsCpu(b);
  if (!a.uuid.empty() && !b.uuid.empty()) return a.uuid == b.uuid;
  if (!a.pci_bus_id.empty() && !b.pci_bus_id.empty()) return a.pci_bus_id == b.pci_bus_id;
  return true;
}

std::vector<std::vector<std::size_t>> IndependentGroups(const std::vector<DeviceIdentity>& devices) {
  // Connected components of "may share", each labelled by its first device.
  std::vector<std::size_t> group(devices.size());
  std::iota(group.begin(), group.end(), std::size_t{0});
  for (std::size_t i = 0; i < devices.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (group[i] == group[j] || !MayShareHardware(devices[i], devices[j])) continue;
      const std::size_t from = std::max(group[i], group[j]), to = std::min(group[i], group[j]);
      for (std::size_t& g : group)
        if (g == from) g = to;
    }
  }
  std::vector<std::vector<std::size_t>> groups;
  std::vector<std::size_t> labels;
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const auto at = std::find(labels.begin(), labels.end(), group[i]);
    if (at == labels.end()) {
      labels.push_back(group[i]);
      groups.push_back({i});
    } else {
      groups[static_cast<std::size_t>(at - labels.begin())].push_back(i);
    }
  }
  return groups;
}

}  // namespace skintune::internal
