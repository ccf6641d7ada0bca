// The host lock between the tuner's workers (tuner/host_lock.h): a GPU
// worker's host work waits while a CPU device's worker is timing, a waiting
// CPU device is not passed by later host work, and a process without a lock
// file never waits.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <thread>

#include "base/error.h"
#include "tuner/host_lock.h"
#include "tests/tuner/lock_holder.h"

namespace skintune::internal::tuner_internal {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

using Holder = skintune::internal::testing::LockHolder;

TEST(HostLock, HostWorkWaitsWhileACpuDeviceTimesInAnotherProcess) {
  const HostLockFile file;
  ASSERT_FALSE(file.path().empty());
  EXPECT_TRUE(std::filesystem::exists(file.path()));
  Holder cpu_device([&] {  // the CPU device's worker, in its timed bursts
    UseHostLock(file.path());
    new HostLock(TimedMode(/*cpu_device=*/true));  // held until the process ends
  });
  UseHostLock(file.path());
  const Clock::time_point start = Clock::now();
  {
    const HostLock host_work(HostWorkMode(/*cpu_device=*/false));
    EXPECT_GE(MsSince(start), 200.0) << "a GPU's host work ran while the CPU device was timing";
  }
  // A GPU's own bursts take no lock, nor does a CPU device's host work.
  const Clock::time_point again = Clock::now();
  { const HostLock gpu_timed(TimedMode(false)), cpu_work(HostWorkMode(true)); }
  EXPECT_LT(MsSince(again), 50.0);
  cpu_device.Join();
}

// A CPU device that asks for the cores while a GPU's work holds them shared
// gets them before any shared request made after its own: GPU workers whose
// holds overlap one another cannot keep it waiting for the whole run.
TEST(HostLock, ACpuDeviceWaitsOnlyForTheSharedHoldsTakenBeforeItAsked) {
  const HostLockFile file;
  ASSERT_FALSE(file.path().empty());
  Holder gpu_work([&] {  // a GPU worker's host work, held 300 ms
    UseHostLock(file.path());
    new HostLock(HostWorkMode(/*cpu_device=*/false));
  });
  const Clock::time_point start = Clock::now();
  const pid_t cpu_device = ::fork();  // asks now, holds it 300 ms once given
  if (cpu_device == 0) {
    UseHostLock(file.path());
    { const HostLock timed(TimedMode(/*cpu_device=*/true)); std::this_thread::sleep_for(std::chrono::milliseconds(300)); }
    ::_exit(0);
  }
  ASSERT_GT(cpu_device, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the CPU device is waiting by now
  UseHostLock(file.path());
  double got_after = 0;
  {
    const HostLock gpu_work_later(HostWorkMode(/*cpu_device=*/false));
    got_after = MsSince(start);
  }
  // The first hold ends at ~300 ms, the CPU device's at ~600 ms; without the
  // gate this shared request would be granted at once, beside the first.
  EXPECT_GE(got_after, 500.0) << "a later shared request went ahead of the waiting CPU device";
  int status = 0;
  ASSERT_EQ(::waitpid(cpu_device, &status, 0), cpu_device);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  gpu_work.Join();
}

// One worker's threads hold the host lock shared each for its own work (a
// GPU worker's compile threads, a hold per kernel): one thread's release
// leaves the others' holds in place, a CPU device asking meanwhile gets the
// lock when the last of them ends, and a thread asking after it waits for it.
TEST(HostLock, AWorkersThreadsEachHoldItSharedUntilTheLastOfThemEnds) {
  const HostLockFile file;
  ASSERT_FALSE(file.path().empty());
  UseHostLock(file.path());
  const Clock::time_point start = Clock::now();
  const auto hold = [](int from_ms, int to_ms, const Clock::time_point t0) {
    std::this_thread::sleep_until(t0 + std::chrono::milliseconds(from_ms));
    const HostLock held(HostWorkMode(/*cpu_device=*/false));
    std::this_thread::sleep_until(t0 + std::chrono::milliseconds(to_ms));
  };
  std::thread long_build(hold, 0, 400, start);   // a kernel building until ~400 ms
  std::thread short_build(hold, 20, 100, start);  // one that ends at ~100 ms
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const pid_t cpu_device = ::fork();  // asks at ~50 ms, holds it 300 ms once given
  if (cpu_device == 0) {
    UseHostLock(file.path());
    const HostLock timed(TimedMode(/*cpu_device=*/true));
    const bool waited_for_the_long_build = MsSince(start) >= 350.0;
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    ::_exit(waited_for_the_long_build ? 0 : 1);
  }
  ASSERT_GT(cpu_device, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // ~150 ms: the short build has ended
  double got_after = 0;
  {
    const HostLock later_build(HostWorkMode(/*cpu_device=*/false));
    got_after = MsSince(start);
  }
  long_build.join();
  short_build.join();
  int status = 0;
  ASSERT_EQ(::waitpid(cpu_device, &status, 0), cpu_device);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << "the CPU device got the lock while a thread of the worker still held it shared";
  // The long build ends at ~400 ms, the CPU device's hold at ~700 ms.
  EXPECT_GE(got_after, 650.0) << "a thread asking after the CPU device went ahead of it";
}

// The chip lock: while one API's worker holds the chip (a measurement on
// it), another API's worker of the same chip waits for it; a process
// without a chip lock file never waits.
TEST(ChipLock, AnotherApisWorkOnTheChipWaitsWhileOneHoldsIt) {
  const HostLockFile file("chip");
  ASSERT_FALSE(file.path().empty());
  EXPECT_NE(file.path().find("skintune-chip-"), std::string::npos) << file.path();
  {
    const Clock::time_point start = Clock::now();
    const ChipLock none;  // no file named yet: a no-op
    EXPECT_LT(MsSince(start), 50.0);
  }
  Holder other_api([&] {  // one API's worker, in a measurement on the chip
    UseChipLock(file.path());
    new ChipLock;  // held until the process ends
  });
  UseChipLock(file.path());
  const Clock::time_point start = Clock::now();
  { const ChipLock chip; EXPECT_GE(MsSince(start), 200.0) << "two APIs' work was on the chip at once"; }
  other_api.Join();
  EXPECT_THROW(UseChipLock("/nonexistent-dir/skintune-chip-lock"), Error);
}

// The chip's quiet: a race waits while another process lands untimed work
// on the chip (a context's opening or closing, a build ahead), and such work
// waits while a race runs; the chip's lock, which a measurement holds, does
// not stop that work.
TEST(ChipQuiet, ARaceAndAnotherProcesssLandingsWaitForEachOther) {
  const HostLockFile file("chip");
  ASSERT_FALSE(file.path().empty());
  Holder builder([&] {  // another API's worker building ahead, 300 ms
    UseChipLock(file.path());
    new ChipQuiet(ChipQuiet::Mode::kLanding);
  });
  UseChipLock(file.path());
  Clock::time_point start = Clock::now();
  { const ChipQuiet race(ChipQuiet::Mode::kRace); EXPECT_GE(MsSince(start), 200.0) << "a race ran beside a build"; }
  builder.Join();
  Holder racer([&] {
    UseChipLock(file.path());
    new ChipQuiet(ChipQuiet::Mode::kRace);
  });
  start = Clock::now();
  { const ChipQuiet landing(ChipQuiet::Mode::kLanding); EXPECT_GE(MsSince(start), 200.0) << "a build ran beside a race"; }
  racer.Join();
  Holder measuring([&] {  // a measurement holds the chip: builds go on beside it
    UseChipLock(file.path());
    new ChipLock;
  });
  start = Clock::now();
  { const ChipQuiet landing(ChipQuiet::Mode::kLanding); EXPECT_LT(MsSince(start), 100.0) << "a build waited for a measurement"; }
  measuring.Join();
}

// A race that asks while builds hold the quiet gets it before any build
// asked after it (builds that overlap one another cannot keep it waiting),
// and one process's threads share one hold: the race waits for the last.
TEST(ChipQuiet, ARaceWaitsOnlyForTheBuildsUnderWayWhenItAsked) {
  const HostLockFile file("chip");
  ASSERT_FALSE(file.path().empty());
  UseChipLock(file.path());
  const Clock::time_point start = Clock::now();
  const auto build = [](int from_ms, int to_ms, const Clock::time_point t0) {
    std::this_thread::sleep_until(t0 + std::chrono::milliseconds(from_ms));
    const ChipQuiet landing(ChipQuiet::Mode::kLanding);
    std::this_thread::sleep_until(t0 + std::chrono::milliseconds(to_ms));
  };
  // Forked before the builds start: a child forked while its parent's threads
  // hold the quiet would inherit their in-process hold.
  const pid_t racer = ::fork();  // asks at ~50 ms, races 300 ms once given
  if (racer == 0) {
    UseChipLock(file.path());
    std::this_thread::sleep_until(start + std::chrono::milliseconds(50));
    const ChipQuiet race(ChipQuiet::Mode::kRace);
    const bool waited_for_the_long_build = MsSince(start) >= 350.0;
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    ::_exit(waited_for_the_long_build ? 0 : 1);
  }
  ASSERT_GT(racer, 0);
  std::thread long_build(build, 0, 400, start);   // a compile thread's kernel until ~400 ms
  std::thread short_build(build, 20, 100, start);  // another's, ending at ~100 ms
  std::this_thread::sleep_until(start + std::chrono::milliseconds(150));  // the race is waiting

  double got_after = 0;
  {
    const ChipQuiet later_build(ChipQuiet::Mode::kLanding);
    got_after = MsSince(start);
  }
  long_build.join();
  short_build.join();
  int status = 0;
  ASSERT_EQ(::waitpid(racer, &status, 0), racer);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the race ran while a thread still built";
  EXPECT_GE(got_after, 650.0) << "a build asking after the race went ahead of it";
}

// In one process too: a race waits for its own process's builds.
TEST(ChipQuiet, ARaceWaitsForItsOwnProcesssBuilds) {
  const HostLockFile file("chip");
  ASSERT_FALSE(file.path().empty());
  UseChipLock(file.path());
  const Clock::time_point start = Clock::now();
  std::thread build([&] {
    const ChipQuiet landing(ChipQuiet::Mode::kLanding);
    std::this_thread::sleep_until(start + std::chrono::milliseconds(300));
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  { const ChipQuiet race(ChipQuiet::Mode::kRace); EXPECT_GE(MsSince(start), 250.0) << "a race ran beside its own build"; }
  build.join();
}

TEST(HostLock, AMissingLockFileIsOneErrorNamingIt) {
  try {
    UseHostLock("/nonexistent-dir/skintune-host-lock");
    FAIL() << "opened a lock file in a missing directory";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/skintune-host-lock"), std::string::npos) << e.what();
  }
}

TEST(HostLock, TheParentsFileGoesWithIt) {
  std::string path;
  {
    const HostLockFile file;
    path = file.path();
    ASSERT_TRUE(std::filesystem::exists(path));
  }
  EXPECT_FALSE(std::filesystem::exists(path));
}

}  // namespace
}  // namespace skintune::internal::tuner_internal
