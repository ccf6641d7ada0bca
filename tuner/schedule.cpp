#include "tuner/schedule.h"

#include <algorithm>
#include <cctype>

namespace skintune {

std::string HardwareOf(const DeviceIdentity& device) {
  std::string type = device.type;
  std::transform(type.begin(), type.end(), type.begin(), [](unsigned char c) { return std::tolower(c); });
  return type.find("cpu") != std::string::npos ? "host" : "gpu";
}

std::vector<std::vector<std::size_t>> IndependentGroups(const std::vector<DeviceIdentity>& devices) {
  std::vector<std::string> keys;
  std::vector<std::vector<std::size_t>> groups;
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const std::string key = HardwareOf(devices[i]);
    const auto at = std::find(keys.begin(), keys.end(), key);
    if (at == keys.end()) {
      keys.push_back(key);
      groups.push_back({i});
    } else {
      groups[static_cast<std::size_t>(at - keys.begin())].push_back(i);
    }
  }
  return groups;
}

}  // namespace skintune
