// The host lock between the tuner's workers (tuner/host_lock.h): a GPU
// worker's host work waits while a CPU device's worker is timing, and a
// process without a lock file never waits.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <thread>

#include "base/error.h"
#include "tuner/host_lock.h"

namespace skintune::internal::tuner_internal {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

TEST(HostLock, HostWorkWaitsWhileACpuDeviceTimesInAnotherProcess) {
  const HostLockFile file;
  ASSERT_FALSE(file.path().empty());
  EXPECT_TRUE(std::filesystem::exists(file.path()));
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // the CPU device's worker: its timed bursts, 300 ms
    UseHostLock(file.path());
    {
      const HostLock timed(TimedMode(/*cpu_device=*/true));
      const char byte = 1;
      if (::write(ready[1], &byte, 1) != 1) ::_exit(2);
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
    ::_exit(0);
  }
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);  // the child holds it now
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
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  ::close(ready[0]);
  ::close(ready[1]);
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
