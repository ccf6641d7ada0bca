// Which devices a tuning run measures at the same time (tuner/schedule.h).
#include "tuner/schedule.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "base/error.h"

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

TEST(Schedule, GroupsRunSideBySideUnlessAskedOneAfterAnotherAndACpuBesideAGpuSharesTheHost) {
  const std::vector<DeviceIdentity> devices = {Device("cuda", "gpu", "aa"), Device("opencl", "cpu"),
                                               Device("gl", "gpu", "aa")};
  const Schedule parallel = ScheduleDevices(devices, true);
  EXPECT_EQ(parallel.groups, (Groups{{0, 2}, {1}}));
  EXPECT_TRUE(parallel.shares_host);
  const Schedule serial = ScheduleDevices(devices, false);
  EXPECT_EQ(serial.groups, (Groups{{0, 1, 2}}));
  EXPECT_FALSE(serial.shares_host);  // nothing runs beside the CPU device
  EXPECT_FALSE(ScheduleDevices({Device("cuda", "gpu", "aa"), Device("cuda", "gpu", "bb")}, true).shares_host);
}

// One GPU's APIs share its chip: tuned at the same time, each holding the
// chip's lock for its work on it, unless a CPU device is tuned beside them
// (their host work would hold up its timing). A lone GPU and every group of
// a run asked for one device after another do not.
TEST(Schedule, OneGpusApisShareItsChipWhenNoCpuDeviceIsTunedBeside) {
  const std::vector<DeviceIdentity> gpus = {Device("cuda", "gpu", "aa"), Device("gl", "gpu", "aa"),
                                            Device("vulkan", "gpu", "bb")};
  const Schedule alone = ScheduleDevices(gpus, true);
  EXPECT_EQ(alone.groups, (Groups{{0, 1}, {2}}));
  EXPECT_EQ(alone.shares_chip, (std::vector<bool>{true, false}));
  EXPECT_EQ(ScheduleDevices(gpus, false).shares_chip, (std::vector<bool>{false}));
  std::vector<DeviceIdentity> with_cpu = gpus;
  with_cpu.push_back(Device("opencl", "cpu"));
  const Schedule beside = ScheduleDevices(with_cpu, true);
  EXPECT_EQ(beside.groups, (Groups{{0, 1}, {2}, {3}}));
  EXPECT_TRUE(beside.shares_host);
  EXPECT_EQ(beside.shares_chip, (std::vector<bool>{false, false, false}));
}

// A group that shares a chip runs its devices at the same time (each on a
// thread of its own, none waiting for another to end), nothing beside it
// preparing later devices, and its first error is rethrown at the end.
TEST(Schedule, AGroupSharingAChipRunsItsDevicesAtOnce) {
  Schedule schedule;
  schedule.groups = {{0, 1, 2}, {3}};
  schedule.shares_chip = {true, false};
  std::atomic<int> inside{0}, most{0}, ahead_calls{0};
  std::atomic<int> runs{0};
  EXPECT_THROW(RunSchedule(
                   schedule,
                   [&](std::size_t d) {
                     ++runs;
                     if (d == 3) return;
                     const int now = ++inside;
                     for (int seen = most.load(); now > seen && !most.compare_exchange_weak(seen, now);) {}
                     // Each device waits (up to 2 s) until all three are inside: only at once can they all be.
                     const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
                     while (most.load() < 3 && std::chrono::steady_clock::now() < until) std::this_thread::yield();
                     --inside;
                     if (d == 1) throw Error("device 1 failed");
                   },
                   [&](const std::vector<std::size_t>&, const std::atomic<std::size_t>&) { ++ahead_calls; }),
               Error);
  EXPECT_EQ(runs.load(), 4);
  EXPECT_EQ(most.load(), 3) << "the chip's devices ran one after another";
  EXPECT_EQ(ahead_calls.load(), 0);
}

TEST(Schedule, EveryDeviceRunsOnceInItsGroupsOrderBesideWhatPreparesTheLaterOnes) {
  Schedule schedule;
  schedule.groups = {{0, 2, 3}, {1}};
  std::mutex mutex;
  std::vector<std::size_t> order_of_first;  // the first group's devices, in the order they ran
  std::vector<std::size_t> ran;
  std::vector<std::size_t> reached_seen;
  RunSchedule(
      schedule,
      [&](std::size_t d) {
        const std::lock_guard<std::mutex> lock(mutex);
        ran.push_back(d);
        if (d != 1) order_of_first.push_back(d);
      },
      [&](const std::vector<std::size_t>& group, const std::atomic<std::size_t>& reached) {
        EXPECT_EQ(group, (std::vector<std::size_t>{0, 2, 3}));  // only beside a group of several devices
        while (reached.load() < group.size()) std::this_thread::yield();
        const std::lock_guard<std::mutex> lock(mutex);
        reached_seen.push_back(reached.load());
      });
  std::sort(ran.begin(), ran.end());
  EXPECT_EQ(ran, (std::vector<std::size_t>{0, 1, 2, 3}));
  EXPECT_EQ(order_of_first, (std::vector<std::size_t>{0, 2, 3}));
  EXPECT_EQ(reached_seen, (std::vector<std::size_t>{3}));
}

TEST(Schedule, AGroupsErrorIsRethrownOnceEveryGroupHasRun) {
  Schedule schedule;
  schedule.groups = {{0}, {1}};
  std::atomic<int> runs{0};
  EXPECT_THROW(RunSchedule(
                   schedule,
                   [&](std::size_t d) {
                     ++runs;
                     if (d == 1) throw Error("device 1 failed");
                   },
                   {}),
               Error);
  EXPECT_EQ(runs.load(), 2);
}

}  // namespace
}  // namespace skintune::internal
