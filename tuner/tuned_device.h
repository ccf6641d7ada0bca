// skintune: a device the tuner measures variants on, whatever its API
// ("backend" is the runtime's word for an API: runtime/backends/).
//
// One TunedDevice per device the runtime's discovery finds
// (runtime/backend_table.h: every OpenCL device of every platform, every
// CUDA device, one OpenGL 4.3+ context through EGL, every Vulkan device, the
// cpu device), measuring through the runner driver (runtime/runner.h,
// tuner/runner_device.h). Discovery never fails: an absent API is reported
// as skipped with its reason. A device runs the jobs of
// tuner/measure_job.h; the tuning run reaches it through a child process
// (tuner/worker.h IsolatedDevice).
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/device_identity.h"  // DeviceIdentity, its JSON
#include "tuner/measurement.h"
#include "tuner/timing_options.h"

namespace skintune::internal {

// What a variant is measured on: a dataset key and the mesh/palettes made from it.
struct TuningDataset {
  std::string key;  // model/synthetic.h key, or a glTF path
};

// Whom a compile ahead is for (TunedDevice::CompileAhead): this process,
// which then measures the kernels, or only the program cache, for another
// process to load: a compile helper's, or a later device's worker started
// ahead without the chip's lock (tuner/device_tuning.h PrecompileDevice).
enum class CompileFor { kThisProcess, kTheCache };

class TunedDevice {
 public:
  virtual ~TunedDevice() = default;
  virtual const DeviceIdentity& identity() const = 0;
  virtual DeviceLimits limits() const = 0;
  virtual std::vector<Lang> languages() const = 0;  // opencl | cuda | glsl-compute + glsl-vertex | ...
  // Verifies then times one variant (MeasureJob). Never throws for a
  // kernel's failure: returns a Measurement with the status (invalid,
  // compile_failed, launch_failed, verify_failed). Throws Error only for
  // set-up problems of the device itself.
  virtual Measurement Measure(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options) = 0;
  // The race at the end of a search (RaceJob, docs/TUNING.md "Races and
  // ties"): `variants` (verified before) measured again, interleaved, until
  // their kernel times separate or prove equal. Returns each variant's
  // samples, ms. Throws Error when one cannot be prepared or timed.
  virtual std::vector<std::vector<double>> Race(const std::vector<Variant>& variants, const TuningDataset& dataset,
                                                const TimingOptions& options) = 0;
  // The device's copy bandwidth: the copy kernel (generator/copy_kernel.h)
  // with a source of `bytes`, GB/s (read + written per second).
  virtual double CopyBandwidthGBps(std::size_t bytes) = 0;
  // Compiles the kernels of `variants` (valid ones) ahead of their Measure,
  // in parallel where the API allows it, into the program cache that Measure
  // then loads from. A kernel that fails to compile is left for Measure to
  // record. Returns how many kernels were compiled (or found compiled); a
  // device that cannot compile ahead compiles nothing and returns 0. For
  // the cache only, nothing is built into the runner that measures: no
  // context is chosen (a choice times on the chip) where nothing is timed.
  virtual std::size_t CompileAhead(const std::vector<Variant>& variants, const TuningDataset& dataset,
                                   CompileFor compile_for) = 0;
};

// Whether `device` compiles kernels ahead of their Measure
// (TunedDevice::CompileAhead; runner_device.cpp says why each API and device
// type is in or out).
bool CompilesAhead(const DeviceIdentity& device);

// Whether `device`'s kernels are compiled ahead in processes of their own
// (runner_device.cpp: a driver that compiles one kernel at a time in a
// process, PoCL's and NVIDIA's OpenCL), where the measuring process finds
// them on disk.
bool CompilesAheadInProcesses(const DeviceIdentity& device);
// Whether those processes compile each kernel by running it once (PoCL:
// it compiles again for each work-group size at a kernel's first launch, into
// its own disk cache), rather than by building it into the program cache.
bool CompilesAheadByRunning(const DeviceIdentity& device);

struct Discovery {
  std::vector<std::unique_ptr<TunedDevice>> devices;
  std::vector<std::string> skipped;  // "cuda: skipped: libcuda.so.1 not found (...)"
};

// Every device found, numbered in discovery order.
Discovery DiscoverTunedDevices();

}  // namespace skintune::internal
