#include <gtest/gtest.h>

#include <algorithm>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "runtime/backends/opencl/opencl_devices.h"

namespace skintune::internal {
namespace {

TEST(OpenClDevices, EveryEnumeratedDeviceHasAnIdentityAndLimits) {
  const OpenClInventory inventory = EnumerateOpenCl();
  if (inventory.devices.empty()) {
    EXPECT_FALSE(inventory.status.empty()) << "no devices but no reason given";
  }
  for (const OpenClDeviceInfo& d : inventory.devices) {
    EXPECT_FALSE(d.name.empty());
    EXPECT_FALSE(d.platform_name.empty());
    EXPECT_FALSE(d.driver_version.empty());
    EXPECT_GT(d.compute_units, 0u);
    EXPECT_GT(d.global_memory_bytes, 0u);
    EXPECT_GT(d.max_work_group_size, 0u);
    EXPECT_GT(d.constant_buffer_bytes, 0u);
    const nlohmann::json j = d;
    EXPECT_EQ(j.at("name"), d.name);
  }
}

TEST(OpenClDevices, PoclIsFoundWhereItsIcdIsRegistered) {
  // CI installs pocl-opencl-icd through scripts/bootstrap: it must be seen.
  if (!std::filesystem::exists("/etc/OpenCL/vendors/pocl.icd")) {
    GTEST_SKIP() << "PoCL's ICD file /etc/OpenCL/vendors/pocl.icd is not installed on this machine";
  }
  const OpenClInventory inventory = EnumerateOpenCl();
  bool found = false;
  for (const OpenClDeviceInfo& d : inventory.devices) found |= d.platform_name == "Portable Computing Language";
  EXPECT_TRUE(found) << inventory.status;
}

// The one --device rule (tune, variants, emit --db, Device::Open).
TEST(MatchesDevice, IdVendorTypeAndPlatformShortNameCaseInsensitive) {
  DeviceIdentity d;
  d.backend = "opencl";
  d.platform = "Portable Computing Language";
  d.vendor = "AuthenticAMD";
  d.name = "pthread-skylake-avx512-AMD EPYC";
  d.driver_version = "3.1+debian";
  d.api_version = "OpenCL 3.0 PoCL HSTR";  // not part of the rule: a database does not record it
  d.type = "cpu";
  for (const char* yes : {"", "pocl", "POCL", "portable computing", "opencl:", "opencl:Portable", "skylake",
                          "3.1+debian", "authenticamd", "cpu", "/3.1"})
    EXPECT_TRUE(MatchesDevice(yes, d)) << yes;
  for (const char* no : {"cuda", "gl:", "gpu", "HSTR", "nvidia"}) EXPECT_FALSE(MatchesDevice(no, d)) << no;
  EXPECT_EQ(PlatformShortName("Portable Computing Language"), "PoCL");
  EXPECT_EQ(PlatformShortName("NVIDIA CUDA"), "");
  // MatchDevices (skintune variants) follows the same rule.
  const OpenClInventory inventory = EnumerateOpenCl();
  for (const OpenClDeviceInfo& device : inventory.devices) {
    const DeviceIdentity identity = IdentityOf(device);
    for (const std::string& pattern : {std::string("pocl"), identity.name, identity.vendor}) {
      const std::vector<OpenClDeviceInfo> matched = MatchDevices(inventory, pattern);
      const bool listed = std::any_of(matched.begin(), matched.end(), [&](const OpenClDeviceInfo& m) {
        return m.platform_index == device.platform_index && m.device_index == device.device_index;
      });
      EXPECT_EQ(listed, MatchesDevice(pattern, identity)) << pattern;
    }
  }
}

}  // namespace
}  // namespace skintune::internal
