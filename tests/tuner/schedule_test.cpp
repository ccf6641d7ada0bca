// Which devices a tuning run measures at the same time (tuner/schedule.h).
#include "tuner/schedule.h"

#include <gtest/gtest.h>

namespace skintune::internal {
namespace {

DeviceIdentity Device(const std::string& backend, const std::string& type, const std::string& uuid = "",
                      const std::string& pci = "") {
  DeviceIdentity d;
  d.backend = backend;
  d.type = type;
  d.name = backend + " " + type;
  d.uuid = uuid;
  d.pci_bus_id = pci;
  return d;
}

using Groups = std::vector<std::vector<std::size_t>>;

TEST(Schedule, ACpuDeviceRunsBesideTheGpuWhoseApisStayOneAfterAnother) {
  // The H100 machine: PoCL, then NVIDIA's OpenCL (PCI only), CUDA (UUID and PCI), GL (UUID).
  const std::vector<DeviceIdentity> devices = {Device("opencl", "cpu"), Device("opencl", "gpu", "", "0000:1a:00.0"),
                                               Device("cuda", "gpu", "ab", "0000:1a:00.0"), Device("gl", "gpu", "ab")};
  EXPECT_EQ(IndependentGroups(devices), (Groups{{0}, {1, 2, 3}}));
}

TEST(Schedule, TwoCpuDevicesAreNeverTunedAtOnce) {
  // This machine: PoCL and llvmpipe both run on the host's cores.
  EXPECT_EQ(IndependentGroups({Device("opencl", "cpu"), Device("gl", "CPU")}), (Groups{{0, 1}}));
}

TEST(Schedule, TwoGpusAreApartOnlyWhenTheirIdentitiesSaySo) {
  // Two chips by UUID, each seen by two APIs, listed interleaved.
  EXPECT_EQ(IndependentGroups({Device("cuda", "gpu", "aa"), Device("cuda", "gpu", "bb"), Device("gl", "gpu", "bb"),
                               Device("gl", "gpu", "aa")}),
            (Groups{{0, 3}, {1, 2}}));
  // By PCI bus id when there are not two UUIDs.
  EXPECT_EQ(IndependentGroups({Device("opencl", "gpu", "", "0000:01:00.0"), Device("opencl", "gpu", "", "0000:02:00.0")}),
            (Groups{{0}, {1}}));
  // A GPU that tells neither may be either chip: one group with both.
  EXPECT_EQ(IndependentGroups({Device("cuda", "gpu", "aa"), Device("cuda", "gpu", "bb"), Device("gl", "gpu")}),
            (Groups{{0, 1, 2}}));
  // A UUID beside a PCI bus id cannot be compared.
  EXPECT_TRUE(MayShareHardware(Device("cuda", "gpu", "aa"), Device("opencl", "gpu", "", "0000:01:00.0")));
  EXPECT_FALSE(MayShareHardware(Device("opencl", "cpu"), Device("cuda", "gpu", "aa")));
  EXPECT_TRUE(IndependentGroups({}).empty());
}

}  // namespace
}  // namespace skintune::internal
