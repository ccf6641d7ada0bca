// skintune: a TunedDevice measured in a child process, so that a kernel that
// hangs or crashes the driver costs one variant, never the tuning run.
//
// The child is `<skintune> tune-worker --device-index N --device-id ID`
// (RunTuneWorker in tune.h). Protocol, one JSON object per line each way:
//
//   child -> parent, once at start:  {"ready": true, "device_id": "<DeviceIdentity::Id()>"}
//                                    or {"error": "<why the device cannot be used>"}
//   parent -> child, a variant:      {"variant": {...}, "dataset": "<key or glTF path>",
//                                     "timing": {every field of TimingOptions (ToJson)}}
//   child -> parent:                 the Measurement (to_json), or {"error": "<set-up problem>"}
//   parent -> child, a copy kernel:  {"copy_bandwidth": <bytes>}
//   child -> parent:                 {"copy_bandwidth_gbps": <GB/s>} or {"copy_bandwidth_error": "..."}
//   parent -> child, a race:         {"race": [variant, ...], "dataset": "<key or glTF path>", "timing": {...}}
//   child -> parent:                 {"race": [[ms, ...], ...]} (each variant's samples) or {"race_error": "..."}
//   parent -> child, compile ahead:  {"compile_ahead": [variant, ...], "dataset": "<key or glTF path>",
//                                     "for": "this process" | "the cache"}
//   child -> parent:                 {"compiled": <kernels compiled or found compiled>}
//
// The child writes its protocol lines on its original stdout and sends
// anything libraries print on stdout to stderr; the parent keeps the last
// lines of the child's stderr for failure details. The child exits at end of
// input; it is killed (SIGKILL) when its parent dies (PR_SET_PDEATHSIG).
//
// Per request the parent waits at most the variant time limit (poll on the
// pipe). No answer in time: the child is killed, the variant is recorded as
// timeout ("no result within S s") and a fresh child serves the next request.
// The child died (end of its output): the variant is recorded as
// launch_failed ("worker process died: signal N (name)" or "... exit code N"),
// and a fresh child serves the next request.
#pragma once

#include <sys/types.h>

#include <optional>
#include <string>
#include <vector>

#include "base/error.h"
#include "tuner/measurement.h"
#include "tuner/timing_options.h"
#include "tuner/tuned_device.h"

namespace skintune::internal {

// The device cannot be used: its worker does not start, names another device,
// or reports a set-up problem of the device. The tuning run goes on without it.
class WorkerError : public Error {
 public:
  using Error::Error;
};

// The process environment as it was at start-up, before any library could
// change it; workers are started with it (see worker.cpp for why).
const std::vector<std::string>& StartupEnvironment();

// The arguments a worker for `device` is started with after `tune-worker`
// (RunTuneWorker, tune.h): its id and index, the locks when given, its own
// API as the only one to discover (`--discover-only`), and the cache figure
// the parent resolved across every API's view of the chip (`--cache-bytes`,
// `--cache-source`), which the worker gives its device in place of what its
// one API says: NVIDIA's OpenCL says 4.3 MB of an H100's 50 MiB L2, GL nothing
// (runtime/physical_device.h). Every API's discovery took a worker 150-230
// ms on an idle H200 machine's host, a median of 690-870 ms beside a tuning
// run (0.76-0.99 s in a GPU API's worker), 18-23 s of CPU a run across its
// ~30 workers, and the cpu device starts one for each race's second leg
// (2026-12-02).
std::vector<std::string> WorkerArguments(const DeviceIdentity& device, const std::string& host_lock,
                                         const std::string& chip_lock);

class IsolatedDevice {
 public:
  // `executable`: the skintune binary. `identity`: the device as the parent
  // discovered it (the child finds it by its id; its index is a hint). The child is
  // started on the first request.
  IsolatedDevice(std::string executable, DeviceIdentity identity, double variant_timeout_s);
  ~IsolatedDevice();
  IsolatedDevice(const IsolatedDevice&) = delete;
  IsolatedDevice& operator=(const IsolatedDevice&) = delete;

  const DeviceIdentity& identity() const { return identity_; }

  // Always returns a Measurement of the variant (device_id, dataset, variant,
  // generator version and timestamp filled in), whatever the child did; an
  // answer with impossible figures (ImpossibleFigures: a time of 0, NaN...)
  // is recorded as launch_failed. A child that lost its device (a GL context
  // the driver reset) exits after its answer, and the variant is measured
  // once more in a fresh child (the detail says so). Throws WorkerError when
  // the device cannot be used at all.
  Measurement Measure(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options);

  // Has the child compile the kernels of `variants` ahead of their Measure
  // (TunedDevice::CompileAhead), waiting at most the variant time limit per
  // variant. Returns the kernels compiled; anything that goes wrong (a hang,
  // a crash, a set-up problem) costs only the head start: it returns 0, and
  // each variant's Measure compiles, and records the failure, as without it.
  std::size_t CompileAhead(const std::vector<Variant>& variants, const TuningDataset& dataset,
                           CompileFor compile_for = CompileFor::kThisProcess);

  // The race of `variants` (TunedDevice::Race) in the child, waiting at most the
  // variant time limit per variant: each variant's samples, or nullopt with
  // the reason in `why_not` (a failed race costs the run only its
  // judgement: the winners are then judged on the search's own intervals).
  std::optional<std::vector<std::vector<double>>> Race(const std::vector<Variant>& variants, const TuningDataset& dataset,
                                                        const TimingOptions& options, std::string* why_not = nullptr);

  // The device's copy bandwidth, or nullopt with the reason in `why_not`.
  // Throws WorkerError when the device cannot be used at all.
  std::optional<double> CopyBandwidthGBps(std::size_t bytes, std::string* why_not = nullptr);

  int starts() const { return starts_; }  // child processes started so far

  // Ends the child (if one runs); the next request starts a fresh one, with
  // its own memory placement and threads (a race's second leg on a CPU).
  void Restart() { Stop(); }

  // Ends the child's input: it returns and exits on its own, and is reaped
  // when this is destroyed (or restarted). Processes ended so exit side by
  // side, where stopping each in turn waits for one exit after another.
  void EndInput();

  // The host lock every worker started from now on shares (tuner/host_lock.h).
  void UseHostLock(std::string path) { host_lock_ = std::move(path); }
  // The chip lock every worker started from now on takes (tuner/host_lock.h ChipLock).
  void UseChipLock(std::string path) { chip_lock_ = std::move(path); }

 private:
  enum class ReadResult { kLine, kTimeout, kEnd };
  // One request to the worker; *lost: the worker lost its device and exited.
  Measurement MeasureOnce(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options, bool* lost);
  void Start();
  void Spawn();                      // the child process, its pipes connected
  void AwaitGreeting();              // its {"ready": ...} line, for this device
  void Stop();                       // end of input, then SIGKILL if it lingers
  void Kill();                       // SIGKILL and reap
  std::string Reap(bool block);      // waits for the child; "signal N (name)" / "exit code N"
  bool Send(const std::string& line);
  // Sends `request` (to a fresh child once more when the first one is gone)
  // and reads one answer line within `timeout_s`; false with `why` when the
  // child died or timed out (killed then), as the copy and the race report it.
  bool Exchange(const std::string& request, double timeout_s, std::string& line, std::string& why);
  ReadResult ReadLine(double timeout_s, std::string& line);
  std::string StderrTail() const;    // the child's last stderr line, or empty
  std::string DeathDetail();         // after the end of the child's output
  // The reaped child died of a signal from outside (kInterruptedDetail), not of its own fault or ours.
  bool KilledFromOutside() const;
  bool Stopped() const;              // the running child is stopped (SIGSTOP, a debugger)

  std::string executable_;
  std::string host_lock_;  // "" = none
  std::string chip_lock_;  // "" = none
  DeviceIdentity identity_;
  double variant_timeout_s_;
  pid_t pid_ = -1;
  int to_child_ = -1;
  int from_child_ = -1;
  int child_stderr_ = -1;
  std::string out_buffer_;
  std::string err_tail_;
  int starts_ = 0;
  int reaped_status_ = 0;    // the last reaped child's wait status
  bool killed_here_ = false;  // that child got its SIGKILL from us
};

}  // namespace skintune::internal
