// skintune (internal): the host's cores, shared by the tuner's worker
// processes while a CPU device is tuned beside a GPU (tuner/schedule.h tunes
// them at the same time). A CPU device's timed bursts run on those cores, so
// they hold the lock exclusively; a GPU worker holds it shared for each whole
// measurement (packing, gold checks, its bursts, whose driver threads spin on
// a host core while they wait) and for its compiles, and waits while a CPU
// device is timing. A CPU device's host-side work takes no lock. On the H100
// machine the CPU devices' winners were 15-50% slower tuned beside the GPU
// than alone without it; with only the GPUs' host phases locked, PoCL's were
// 6% and the cpu device's still 26% (docs/PERFORMANCE.md, issue 16 item 7).
//
// flock(2) on a file the parent makes (HostLockFile) and names to each worker
// (`tune-worker --host-lock PATH`: UseHostLock); in a process without one,
// every HostLock is a no-op.
#pragma once

#include <string>

namespace skintune::tuner_internal {

// The worker process, once at start: the lock file to use. Throws Error
// naming the file when it cannot be opened.
void UseHostLock(const std::string& path);

class HostLock {
 public:
  enum class Mode { kNone, kShared, kExclusive };
  explicit HostLock(Mode mode);
  ~HostLock() { Release(); }
  HostLock(const HostLock&) = delete;
  HostLock& operator=(const HostLock&) = delete;
  void Release();  // early

 private:
  bool held_ = false;
};

// The lock's mode for host-side work, and for timed bursts, of a device.
HostLock::Mode HostWorkMode(bool cpu_device);
HostLock::Mode TimedMode(bool cpu_device);

// The parent: a new, empty lock file in the temporary directory, removed
// when the object goes; path() is "" when none could be made (then the
// workers run without a lock, as before).
class HostLockFile {
 public:
  HostLockFile();
  ~HostLockFile();
  HostLockFile(const HostLockFile&) = delete;
  HostLockFile& operator=(const HostLockFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace skintune::tuner_internal
