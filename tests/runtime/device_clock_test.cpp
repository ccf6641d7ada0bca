// The GPU clock reader (runtime/device_clock.h) against a stand-in NVML
// (fake_nvml.cpp, named by SKINTUNE_NVML_LIBRARY): which devices it opens,
// how it finds the GPU, and what it reads. NVML is loaded once per process:
// each test runs in a process of its own (gtest_discover_tests).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <thread>
#include <vector>
#include <string>

#include "runtime/backend_table.h"
#include "runtime/device_clock.h"

namespace skintune::internal {
namespace {

DeviceIdentity NvidiaGpu() {
  DeviceIdentity d;
  d.backend = "vulkan";
  d.vendor = "NVIDIA";
  d.name = "NVIDIA H200";
  d.type = "gpu";
  d.uuid = "0123456789abcdef0123456789abcdef";
  return d;
}

class DeviceClockTest : public ::testing::Test {
 protected:
  void SetUp() override {
    setenv("SKINTUNE_NVML_LIBRARY", SKINTUNE_FAKE_NVML, 1);
    unsetenv("SKINTUNE_FAKE_NVML_MHZ");
    unsetenv("SKINTUNE_FAKE_NVML_INIT_FAILS");
  }
};

TEST(DeviceClockNames, NvmlNamesAUuidInGroupsOf8_4_4_4_12) {
  EXPECT_EQ(NvmlUuid("0123456789abcdef0123456789abcdef"), "GPU-01234567-89ab-cdef-0123-456789abcdef");
  EXPECT_EQ(NvmlUuid(""), "");
  EXPECT_EQ(NvmlUuid("0123456789abcdef0123456789abcde"), "") << "31 digits";
  EXPECT_EQ(NvmlUuid("0123456789abcdef0123456789abcdeg"), "") << "not hex";
}

TEST_F(DeviceClockTest, ReadsTheSmClockOfTheGpuWithTheApisUuid) {
  std::string why;
  const std::unique_ptr<DeviceClock> clock = DeviceClock::Open(NvidiaGpu(), &why);
  ASSERT_TRUE(clock) << why;
  EXPECT_EQ(clock->SmMhz(), 1980u);
  EXPECT_EQ(clock->MaxSmMhz(), 1980u);
  setenv("SKINTUNE_FAKE_NVML_MHZ", "1110", 1);
  EXPECT_EQ(clock->SmMhz(), 1110u) << "read at each call, not once";
  setenv("SKINTUNE_FAKE_NVML_MHZ", "0", 1);
  EXPECT_EQ(clock->SmMhz(), std::nullopt) << "a clock of 0 is no answer";
}

TEST_F(DeviceClockTest, FindsTheGpuByItsPciBusIdWhereTheApiGaveNoUuid) {
  DeviceIdentity gl = NvidiaGpu();
  gl.backend = "gl";
  gl.vendor = "NVIDIA Corporation";
  gl.uuid = "";
  gl.pci_bus_id = "0000:41:00.0";
  std::string why;
  const std::unique_ptr<DeviceClock> clock = DeviceClock::Open(gl, &why);
  ASSERT_TRUE(clock) << why;
  EXPECT_EQ(clock->SmMhz(), 1980u);
}

TEST_F(DeviceClockTest, OpensNothingForCpusOtherVendorsUnknownGpusOrWithoutNvml) {
  std::string why;
  DeviceIdentity cpu = NvidiaGpu();
  cpu.type = "cpu";
  EXPECT_FALSE(DeviceClock::Open(cpu, &why));
  EXPECT_EQ(why, "a CPU device");

  DeviceIdentity amd = NvidiaGpu();
  amd.vendor = "AMD";
  amd.name = "Radeon";
  EXPECT_FALSE(DeviceClock::Open(amd, &why));
  EXPECT_EQ(why, "not an NVIDIA GPU");

  DeviceIdentity anonymous = NvidiaGpu();
  anonymous.uuid = "";
  EXPECT_FALSE(DeviceClock::Open(anonymous, &why));
  EXPECT_EQ(why, "its API gave neither a UUID nor a PCI bus id");

  DeviceIdentity other = NvidiaGpu();
  other.uuid = "ffffffffffffffffffffffffffffffff";
  EXPECT_FALSE(DeviceClock::Open(other, &why));
  EXPECT_EQ(why, "NVML does not know the GPU (GPU-ffffffff-ffff-ffff-ffff-ffffffffffff)");
}

TEST_F(DeviceClockTest, SaysWhyWhenNvmlIsMissing) {
  setenv("SKINTUNE_NVML_LIBRARY", "libskintune-no-such-nvml.so", 1);
  std::string why;
  EXPECT_FALSE(DeviceClock::Open(NvidiaGpu(), &why));
  EXPECT_EQ(why, "NVML not found (libskintune-no-such-nvml.so)");
}

TEST_F(DeviceClockTest, SaysWhyWhenNvmlDoesNotStart) {
  setenv("SKINTUNE_FAKE_NVML_INIT_FAILS", "1", 1);
  std::string why;
  EXPECT_FALSE(DeviceClock::Open(NvidiaGpu(), &why));
  EXPECT_EQ(why, "nvmlInit_v2 failed (999)");
}

// On a GPU machine with NVIDIA's driver: with the hold, the SM clock of an
// idle GPU stays within the clock guard's tolerance of its boost (without
// it NVIDIA's driver lowers it within milliseconds when no CUDA context
// exists: 345 MHz on an H200). The real NVML reads it.
TEST(ClockHold, KeepsAnIdleNvidiaGpuAtItsClockUnderLoad) {
  std::vector<DeviceIdentity> gpus;
  for (const FoundDevice& found : DiscoverDevices("cuda").devices) gpus.push_back(found.identity);
  if (gpus.empty()) GTEST_SKIP() << "no CUDA GPU on this machine";
  std::string why;
  const std::unique_ptr<DeviceClock> clock = DeviceClock::Open(gpus.front(), &why);
  if (!clock) GTEST_SKIP() << "the GPU's clock cannot be read here: " << why;
  const std::unique_ptr<ClockHold> hold = ClockHold::ForDevices(gpus, &why);
  ASSERT_TRUE(hold) << why;
  EXPECT_GE(hold->held(), 1u);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // idle: the driver would lower the clock by now
  const std::optional<unsigned> mhz = clock->SmMhz(), boost = clock->MaxSmMhz();
  ASSERT_TRUE(mhz && boost);
  EXPECT_GE(static_cast<double>(*mhz), 0.97 * *boost) << "SM clock " << *mhz << " MHz of " << *boost << " with the hold";
}

TEST(ClockHold, HoldsNothingWithoutAnNvidiaGpu) {
  DeviceIdentity cpu;
  cpu.type = "cpu";
  cpu.vendor = "GenuineIntel";
  DeviceIdentity amd;
  amd.type = "gpu";
  amd.vendor = "AMD";
  std::string why;
  EXPECT_FALSE(ClockHold::ForDevices({cpu, amd}, &why));
  EXPECT_EQ(why, "no NVIDIA GPU among the devices");
}

}  // namespace
}  // namespace skintune::internal
