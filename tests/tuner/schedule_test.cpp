// Which devices a tuning run measures at the same time (tuner/schedule.h).
#include "tuner/schedule.h"

#include <gtest/gtest.h>

namespace skintune {
namespace {

DeviceIdentity Device(const std::string& backend, const std::string& type, const std::string& name) {
  DeviceIdentity d;
  d.backend = backend;
  d.type = type;
  d.name = name;
  return d;
}

TEST(Schedule, CpuDevicesShareTheHostAndGpusAreOneChip) {
  // The H100 machine: PoCL, NVIDIA's OpenCL, CUDA, GL on the GPU.
  const std::vector<DeviceIdentity> devices = {
      Device("opencl", "cpu", "pthread-sapphirerapids"), Device("opencl", "gpu", "NVIDIA H100 80GB HBM3"),
      Device("cuda", "gpu", "NVIDIA H100 80GB HBM3"), Device("gl", "gpu", "NVIDIA H100 80GB HBM3/PCIe/SSE2")};
  EXPECT_EQ(IndependentGroups(devices), (std::vector<std::vector<std::size_t>>{{0}, {1, 2, 3}}));
  EXPECT_EQ(HardwareOf(devices[0]), "host");
  EXPECT_EQ(HardwareOf(devices[3]), "gpu");
}

TEST(Schedule, TwoCpuDevicesAreNeverTunedAtOnce) {
  // This machine: PoCL and llvmpipe both run on the host's cores.
  const std::vector<DeviceIdentity> devices = {Device("opencl", "cpu", "pthread"), Device("gl", "CPU", "llvmpipe")};
  EXPECT_EQ(IndependentGroups(devices), (std::vector<std::vector<std::size_t>>{{0, 1}}));
}

TEST(Schedule, GroupsKeepTheDevicesOrder) {
  const std::vector<DeviceIdentity> devices = {Device("cuda", "gpu", "A"), Device("opencl", "cpu", "pocl"),
                                               Device("opencl", "gpu", "A"), Device("gl", "cpu", "llvmpipe")};
  EXPECT_EQ(IndependentGroups(devices), (std::vector<std::vector<std::size_t>>{{0, 2}, {1, 3}}));
  EXPECT_TRUE(IndependentGroups({}).empty());
}

}  // namespace
}  // namespace skintune
