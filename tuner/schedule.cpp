#include "tuner/schedule.h"

#include <algorithm>
#include <cctype>
#include <exception>
#include <numeric>
#include <string>
#include <thread>

namespace skintune::internal {

bool IsHostCpu(const DeviceIdentity& d) {
  std::string type = d.type;
  std::transform(type.begin(), type.end(), type.begin(), [](unsigned char c) { return std::tolower(c); });
  return type.find("cpu") != std::string::npos;
}

bool IsSoftwareRasterizer(const DeviceIdentity& d) {
  return IsHostCpu(d) && (d.backend == "gl" || d.backend == "vulkan");
}

bool MayShareHardware(const DeviceIdentity& a, const DeviceIdentity& b) {
  if (IsHostCpu(a) || IsHostCpu(b)) return IsHostCpu(a) && IsHostCpu(b);
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

Schedule ScheduleDevices(const std::vector<DeviceIdentity>& devices, bool parallel) {
  Schedule schedule;
  schedule.groups = IndependentGroups(devices);
  if (!parallel && schedule.groups.size() > 1) {
    std::vector<std::size_t> all;
    for (const auto& g : schedule.groups) all.insert(all.end(), g.begin(), g.end());
    std::sort(all.begin(), all.end());
    schedule.groups = {all};
  }
  const auto is_cpu = [&](std::size_t i) { return IsHostCpu(devices[i]); };
  for (const auto& g : schedule.groups)
    schedule.shares_host = schedule.shares_host || (schedule.groups.size() > 1 && std::any_of(g.begin(), g.end(), is_cpu));
  for (const auto& g : schedule.groups)
    schedule.shares_chip.push_back(parallel && !schedule.shares_host && g.size() > 1 &&
                                   std::none_of(g.begin(), g.end(), is_cpu));
  return schedule;
}

void RunSchedule(const Schedule& schedule, const std::function<void(std::size_t device)>& tune, const GroupAhead& ahead) {
  const auto& groups = schedule.groups;
  std::vector<std::exception_ptr> errors(groups.size());
  auto run_group = [&](std::size_t g) {
    if (g < schedule.shares_chip.size() && schedule.shares_chip[g]) {
      // Every device at once; the first error of any of them is the group's.
      std::vector<std::exception_ptr> device_errors(groups[g].size());
      auto run_device = [&](std::size_t k) {
        try {
          tune(groups[g][k]);
        } catch (...) {
          device_errors[k] = std::current_exception();
        }
      };
      std::vector<std::thread> devices;
      for (std::size_t k = 1; k < groups[g].size(); ++k) devices.emplace_back(run_device, k);
      if (!groups[g].empty()) run_device(0);
      for (std::thread& t : devices) t.join();
      for (const std::exception_ptr& e : device_errors)
        if (e && !errors[g]) errors[g] = e;
      return;
    }
    std::atomic<std::size_t> reached{0};
    std::thread beside;
    try {
      if (ahead && groups[g].size() > 1) beside = std::thread(ahead, std::cref(groups[g]), std::cref(reached));
      for (std::size_t k = 0; k < groups[g].size(); ++k) {
        reached = k;
        tune(groups[g][k]);
      }
    } catch (...) {
      errors[g] = std::current_exception();
    }
    reached = groups[g].size();
    if (beside.joinable()) beside.join();
  };
  std::vector<std::thread> threads;
  for (std::size_t g = 1; g < groups.size(); ++g) threads.emplace_back(run_group, g);
  if (!groups.empty()) run_group(0);
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace skintune::internal
