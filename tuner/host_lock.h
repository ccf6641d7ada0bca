// skintune (internal): the host's cores, shared by the tuner's worker
// processes while a CPU device is tuned beside a GPU (tuner/schedule.h tunes
// them at the same time). A CPU device's timed bursts run on those cores, so
// they hold the lock exclusively; a GPU worker's bulk host work (compiles, a
// runner's opening) holds it shared, and waits while a CPU device is timing.
// A GPU's own bursts are timed by the device and take no lock, and neither
// does a GPU measurement's or race's own host work (packing, gold checks,
// the verification's read-back; tuner/measure_job.cpp): mostly one thread, on
// a core its process keeps busy anyway (the driver's waits on the device poll
// through its timed bursts, unlocked); the comparisons with the gold
// (reference/skinning.h CompareToGold) spread over every core for a moment,
// which a CPU device's samples ride out as the quickest of three frames
// (TimingOptions::host_frames_per_sample). Its wait held the chip (its lock comes
// first) while the CPU device timed: on the H200 machine (2026-12-02) the
// measuring workers of a cold run's four GPU APIs waited 15-20 s of its
// 66-68 s so, the chip idle; unlocked, the chip's turns of three cold runs
// ended at 52.7-63.4 s on another and named the same winner in all 42 rows,
// the host's CPU devices' winners as unsteady across runs as before (none of
// the cpu device's six within 3% either way). On the H100 machine the CPU
// devices' winners were 15-50% slower tuned beside the GPU than alone; with
// the lock PoCL's are within 6% (median), the cpu device's still 10-26%
// slower (its kernels spread over every core, so a host thread the GPU's
// driver keeps busy, even while it waits on the device, delays them).
// Locking the GPUs' bursts too cost a default run 5-12 s on the H200 machine
// and named the same winner in all three cold runs in 37 rows of 42 against
// 40 without (2026-11-29); locking the GPUs' whole measurements made a run
// take more than 160 s instead of 101 s on the H100 (docs/PERFORMANCE.md
// "The cost of a tuning run").
// `--one-device-at-a-time` gives the cpu device's figures undisturbed.
//
// An exclusive request is not starved by shared holds that overlap one
// another (a GPU's compiles ahead beside another API's host work): it closes
// a gate that later shared requests wait at (host_lock.cpp). Shared holds
// may be taken by several threads of one process at once (a GPU worker's
// compile threads hold it per kernel), so that one waits for the work under
// way, not for a batch.
//
// flock(2) on a file the parent makes (HostLockFile) and names to each worker
// (`tune-worker --host-lock PATH`: UseHostLock); in a process without one,
// every HostLock is a no-op.
#pragma once

#include <string>

namespace skintune::internal::tuner_internal {

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
  void Release();  // early, e.g. before a GPU's timed bursts

 private:
  bool held_ = false;        // an exclusive hold
  bool gate_held_ = false;   // an exclusive holder's gate (host_lock.cpp Gate)
  bool shared_ = false;      // one of the process's shared holds (host_lock.cpp)
};

// The lock's mode for a device's bulk host work (compiles, a runner's
// opening) and for its timed bursts; a measurement's own host work takes none.
HostLock::Mode HostWorkMode(bool cpu_device);
HostLock::Mode TimedMode(bool cpu_device);

// The chip lock: one GPU seen through several APIs (OpenCL, CUDA, GL,
// Vulkan), their devices tuned at the same time or one after another
// (tuner/schedule.h), each API's worker holding the chip alone for whatever
// runs on it: a whole measurement (uploads, the verification launch, the
// kernel's, frame's and copy's samples), a race, the copy bandwidth, a
// context's choice (one after another, a later API's worker started ahead
// chooses between the measuring API's jobs). What runs on the host meanwhile
// (compiles ahead, worker start-up, the parent's bookkeeping) overlaps the
// other APIs' work on the chip. flock(2) on a file the parent makes per
// chip (HostLockFile) and names to each of that chip's workers
// (`tune-worker --chip-lock PATH`: UseChipLock); in a process without one,
// every ChipLock is a no-op. Taken before the host lock, never after it.
void UseChipLock(const std::string& path);
class ChipLock {
 public:
  ChipLock();
  ~ChipLock();
  ChipLock(const ChipLock&) = delete;
  ChipLock& operator=(const ChipLock&) = delete;

 private:
  bool held_ = false;
};

// The chip's quiet: a race's rounds (tuner/measure_job.cpp RaceJob), whose
// samples decide a row's winner and its time, run while no process of the
// chip's workers lands untimed work on the chip: a context's opening or
// closing, or a program's build ahead of its measurement (device memory
// allocated and freed, code loaded). Those run outside the chip's lock, beside
// another API's timing, and move its kernel times: on an H200 (2026-12-03,
// driver 580.159.04) one NVIDIA OpenCL kernel read 5.95 us alone and 6.21-6.27
// beside another process allocating and freeing 256 MiB in a loop (+4.5%),
// 5.95-6.05 beside one loading and unloading a module; NVIDIA OpenCL tuned alone
// kept its six winners within 2.1% over three cold runs without compiling
// ahead and within 3.8% with it, and within 3.9-5.8% (two of six within 3%)
// beside the other APIs' workers. A race holds the quiet exclusively (kRace),
// each such opening, closing or build shared (kLanding): builds wait only for
// the races, a few tenths of a second each, not for the search's measurements.
//
// Byte-range locks (Linux open-file-description locks) on the chip's lock
// file, independent of ChipLock's flock: byte 1 the quiet, byte 2 a gate that
// a waiting race closes, so that overlapping builds do not starve it (as
// HostLock's gate). A process's threads share one hold of byte 1 (its compile
// threads build at once), and a race and a landing in one process exclude
// each other in the process first. Order: ChipLock, then ChipQuiet, then
// HostLock; a kLanding hold never takes the chip's lock (a race holding it
// would wait for that hold). In a process without a chip lock, a no-op
// across processes.
class ChipQuiet {
 public:
  enum class Mode { kRace, kLanding };
  explicit ChipQuiet(Mode mode);
  ~ChipQuiet();
  ChipQuiet(const ChipQuiet&) = delete;
  ChipQuiet& operator=(const ChipQuiet&) = delete;

 private:
  Mode mode_;
  bool held_ = false;       // kRace: byte 1 and the gate, exclusively
  bool gate_held_ = false;
  bool shared_ = false;     // kLanding: one of the process's holds of byte 1
};

// The parent: a new, empty lock file (the host's or a chip's) in the temporary directory, removed
// when the object goes; path() is "" when none could be made (then the
// workers run without a lock, as before).
class HostLockFile {
 public:
  explicit HostLockFile(const char* what = "host");  // the file's name says whose
  ~HostLockFile();
  HostLockFile(const HostLockFile&) = delete;
  HostLockFile& operator=(const HostLockFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace skintune::internal::tuner_internal
