// skintune: the host lock between the tuner's workers (tuner/host_lock.h).
#include "tuner/host_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <shared_mutex>
#include <string>

#include "base/error.h"
#include "runtime/runner.h"  // TimingLog

namespace skintune::internal::tuner_internal {

namespace {
int lock_fd = -1;  // the worker's host lock file, or -1 (no lock)
// The process's shared holds of lock_fd: its threads (a GPU worker's
// compile threads, one hold per kernel) share one flock, taken by the first
// and released by the last; each passes the gate on its own.
std::mutex shared_mutex;
int shared_holds = 0;
int chip_fd = -1;  // the worker's chip lock file, or -1 (no lock)
// The chip's quiet (ChipQuiet): a race and the process's landings exclude
// each other in the process; its landings share one hold of the quiet byte.
std::shared_mutex quiet_in_process;
std::mutex quiet_holds_mutex;
int quiet_holds = 0;
constexpr off_t kQuietByte = 1;
constexpr off_t kQuietGateByte = 2;

void Use(int& fd_of, const std::string& path, const char* what) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) throw Error(std::string(what) + " '" + path + "': cannot open it (" + std::strerror(errno) + ")");
  if (fd_of >= 0) ::close(fd_of);
  fd_of = fd;
}

// Whether `operation` on `fd` was taken (a lock that cannot be taken costs
// only the measurement's quiet).
bool Take(int fd, int operation) {
  if (fd < 0) return false;
  while (::flock(fd, operation) != 0) {
    if (errno != EINTR) return false;
  }
  return true;
}

// The gate: an open-file-description lock on one byte of the lock file, by
// default the first (independent of the flock on the whole file, Linux
// fcntl(2); ChipQuiet locks bytes 1 and 2 of the chip's file the same way). flock grants
// a shared request while an exclusive one waits, so a CPU device could wait
// for as long as the GPU workers' shared holds overlap; an exclusive request
// holds the gate while it waits and while it holds the lock, and a shared
// request passes the gate before it takes the lock, so it waits behind it.
bool Gate(int fd, short type, off_t byte = 0) {
  if (fd < 0) return false;
  struct flock range {};
  range.l_type = type;
  range.l_whence = SEEK_SET;
  range.l_start = byte;
  range.l_len = 1;
  while (::fcntl(fd, F_OFD_SETLKW, &range) != 0) {
    if (errno != EINTR) return false;
  }
  return true;
}

// A wait for the host lock, named in the timing log (SKINTUNE_TIMING_LOG):
// what a CPU device's timed work lost to the GPU workers' host work, or
// their host work to it; shorter waits are left out.
void LogWait(HostLock::Mode mode, double waited_ms) {
  if (waited_ms < (mode == HostLock::Mode::kExclusive ? 20.0 : 50.0)) return;
  TimingLog([&] {
    char ms[32];
    std::snprintf(ms, sizeof ms, "%.1f ms", waited_ms);
    return std::string(mode == HostLock::Mode::kExclusive ? "host lock: a CPU device's timed work waited "
                                                          : "host lock: a GPU worker's host work waited ") +
           ms + " (pid " + std::to_string(::getpid()) + ")";
  });
}

}  // namespace

void UseHostLock(const std::string& path) { Use(lock_fd, path, "host lock"); }
void UseChipLock(const std::string& path) { Use(chip_fd, path, "chip lock"); }

HostLock::HostLock(Mode mode) {
  if (mode == Mode::kNone || lock_fd < 0) return;
  const auto start = std::chrono::steady_clock::now();
  if (mode == Mode::kExclusive) {
    gate_held_ = Gate(lock_fd, F_WRLCK);
    held_ = Take(lock_fd, LOCK_EX);
  } else {
    const bool gated = Gate(lock_fd, F_RDLCK);
    {
      const std::lock_guard<std::mutex> lock(shared_mutex);
      shared_ = shared_holds > 0 || Take(lock_fd, LOCK_SH);
      if (shared_) ++shared_holds;
    }
    if (gated) (void)Gate(lock_fd, F_UNLCK);
  }
  LogWait(mode, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
}

void HostLock::Release() {
  if (shared_) {
    const std::lock_guard<std::mutex> lock(shared_mutex);
    if (--shared_holds == 0) ::flock(lock_fd, LOCK_UN);
  }
  if (held_) ::flock(lock_fd, LOCK_UN);
  if (gate_held_) (void)Gate(lock_fd, F_UNLCK);
  held_ = gate_held_ = shared_ = false;
}

ChipLock::ChipLock() : held_(Take(chip_fd, LOCK_EX)) {}

ChipLock::~ChipLock() {
  if (held_) ::flock(chip_fd, LOCK_UN);
}

ChipQuiet::ChipQuiet(Mode mode) : mode_(mode) {
  const auto start = std::chrono::steady_clock::now();
  const auto log_wait = [&](const char* who) {
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (ms < 20.0 || chip_fd < 0) return;
    TimingLog([&] {
      char text[32];
      std::snprintf(text, sizeof text, "%.1f ms", ms);
      return std::string("chip quiet: ") + who + " waited " + text + " (pid " + std::to_string(::getpid()) + ")";
    });
  };
  if (mode_ == Mode::kRace) {
    quiet_in_process.lock();
    gate_held_ = Gate(chip_fd, F_WRLCK, kQuietGateByte);
    held_ = Gate(chip_fd, F_WRLCK, kQuietByte);
    log_wait("a race");
    return;
  }
  quiet_in_process.lock_shared();
  const bool gated = Gate(chip_fd, F_RDLCK, kQuietGateByte);  // behind a race that waits
  {
    const std::lock_guard<std::mutex> lock(quiet_holds_mutex);
    shared_ = quiet_holds > 0 || Gate(chip_fd, F_RDLCK, kQuietByte);
    if (shared_) ++quiet_holds;
  }
  if (gated) (void)Gate(chip_fd, F_UNLCK, kQuietGateByte);
  log_wait("an opening, closing or build");
}

ChipQuiet::~ChipQuiet() {
  if (mode_ == Mode::kRace) {
    if (held_) (void)Gate(chip_fd, F_UNLCK, kQuietByte);
    if (gate_held_) (void)Gate(chip_fd, F_UNLCK, kQuietGateByte);
    quiet_in_process.unlock();
    return;
  }
  if (shared_) {
    const std::lock_guard<std::mutex> lock(quiet_holds_mutex);
    if (--quiet_holds == 0) (void)Gate(chip_fd, F_UNLCK, kQuietByte);
  }
  quiet_in_process.unlock_shared();
}

HostLock::Mode HostWorkMode(bool cpu_device) { return cpu_device ? HostLock::Mode::kNone : HostLock::Mode::kShared; }
HostLock::Mode TimedMode(bool cpu_device) { return cpu_device ? HostLock::Mode::kExclusive : HostLock::Mode::kNone; }

HostLockFile::HostLockFile(const char* what) {
  std::error_code error;
  const std::filesystem::path dir = std::filesystem::temp_directory_path(error);
  if (error) return;
  std::string name = (dir / ("skintune-" + std::string(what) + "-XXXXXX")).string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) return;
  ::close(fd);
  path_ = name;
}

HostLockFile::~HostLockFile() {
  if (!path_.empty()) ::unlink(path_.c_str());
}

}  // namespace skintune::internal::tuner_internal
