#include <gtest/gtest.h>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "runtime/backends/opencl/opencl_devices.h"

namespace skintune {
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

}  // namespace
}  // namespace skintune
