// skintune: a device the tuner can measure variants on, whatever its API.
//
// One Backend per device the runtime's discovery finds (runtime/backend_table.h:
// every OpenCL device of every platform, every CUDA device (driver API +
// NVRTC loaded at run time), one OpenGL 4.3+ context through EGL
// (glsl-compute and glsl-vertex)), measuring through the runner driver
// (runtime/runner.h). Discovery never fails: an absent API is reported as
// skipped with its reason.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/device_identity.h"  // DeviceIdentity, its JSON
#include "tuner/measurement.h"
#include "tuner/statistics.h"

namespace skintune::internal {

struct TimingOptions {
  int warmup = 3;        // untimed frames before the kernel-time samples and before the frame time
  // The frame time (docs/TUNING.md "Frame time"): `repetitions` runs of
  // back-to-back frames, each of as many frames as take about burst_ms.
  int repetitions = 10;
  // Input sets rotated between kernel-time samples (each also starts from
  // the flushed cache, so none finds its inputs there).
  int max_input_sets = 8;
  double tolerance = 1e-5;  // max relative error against the gold
  double burst_ms = 2.0;
  // The kernel time's samples (docs/TUNING.md "Kernel time"): until the 95%
  // interval of the median is tight, or a cap (tuner/statistics.h).
  StopRule stop;
  // The race at the end of each search: up to `race` leading candidates
  // measured again, interleaved, until they separate by more than
  // `tie_margin` or prove equal within it (0: no race). 5%: on an H200
  // (November 2026) the same winner's kernel time moved 4-6% between two
  // cold runs at 100k vertices while each run's own interval was +-1%, so a
  // margin narrower than the run-to-run shift let noise pick the winner.
  int race = 8;
  double tie_margin = 0.05;
  // The tie margin on a device that is the host's CPU (PoCL's, skintune's
  // cpu device), whose times move between runs far more than a GPU's: on the
  // H200 machine's 16-thread host (November 2026) three cold runs' winner
  // times differed by up to 1.27x, and two variants 10-30% apart in one run's
  // race swapped places in the next.
  double host_tie_margin = 0.25;
  // The margin a race and the search use on a device (host_tie_margin on a CPU).
  double MarginFor(const DeviceIdentity& device) const;
};

// The config's and the worker protocol's "timing" object: every field of
// TimingOptions, each optional in a config (its default), all written by
// ToJson. Throws Error("<where>.<field>: ...") for an unknown field or a
// value of the wrong type, and UsageError naming the field for an impossible
// stop rule or race (BadStopRule; race < 0; a tie margin outside (0, 0.5]).
TimingOptions TimingOptionsFromJson(const nlohmann::json& in, const std::string& where);
nlohmann::json ToJson(const TimingOptions& t);

// What a variant is measured on: a dataset key and the mesh/palettes made from it.
struct TuningDataset {
  std::string key;  // model/synthetic.h key, or a glTF path
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual const DeviceIdentity& identity() const = 0;
  virtual DeviceLimits limits() const = 0;
  virtual std::vector<Lang> languages() const = 0;  // opencl | cuda | glsl-compute + glsl-vertex
  // Verifies then times one (valid) variant. Never throws for a kernel's
  // failure: returns a Measurement with the status (compile_failed,
  // launch_failed, verify_failed). Throws Error only for set-up problems of
  // the device itself.
  virtual Measurement Measure(const Variant& variant, const TuningDataset& dataset,
                              const TimingOptions& options) = 0;
  // The race at the end of a search (docs/TUNING.md "Races and ties"):
  // `variants` (verified before) measured again, interleaved, until their
  // kernel times separate or prove equal (tuner_internal::RaceWith).
  // Returns each variant's samples, ms. Throws Error when one cannot be
  // prepared or timed.
  virtual std::vector<std::vector<double>> Race(const std::vector<Variant>& variants, const TuningDataset& dataset,
                                                const TimingOptions& options) = 0;
  // The device's copy bandwidth: the copy kernel (generator/copy_kernel.h)
  // with a source of `bytes`, GB/s (read + written per second).
  virtual double CopyBandwidthGBps(std::size_t bytes) = 0;
  // Compiles the kernels of `variants` (valid ones) ahead of their Measure,
  // in parallel where the API allows it, into the program cache that Measure
  // then loads from. A kernel that fails to compile is left for Measure to
  // record. Returns how many kernels were compiled (or found compiled); a
  // backend that cannot compile ahead compiles nothing and returns 0.
  virtual std::size_t CompileAhead(const std::vector<Variant>& variants, const TuningDataset& dataset) = 0;
};

// Whether `device` compiles kernels ahead of their Measure
// (Backend::CompileAhead; device_backend.cpp says why each API and device
// type is in or out).
bool CompilesAhead(const DeviceIdentity& device);

struct Discovery {
  std::vector<std::unique_ptr<Backend>> backends;
  std::vector<std::string> skipped;  // "cuda: skipped: libcuda.so.1 not found (...)"
};

Discovery DiscoverBackends();

// Test hook (for the tuner's failure tests, never set in normal use): when
// $SKINTUNE_INJECT_FAULT is "<variant key>=<kind>", every backend's Measure of
// that exact variant fails as the kind says (kInjectedFaultKinds):
//   compile  its kernel fails to compile;
//   wrong    its kernel writes wrong results (one vertex off);
//   hang     its kernel loops forever;
//   crash    the (worker) process aborts;
//   lost     the device is lost in this process, as when a driver resets a GL
//            context: this Measure and every later one in the same process
//            fail with "<API> lost: ..." (DeviceLostIn).
inline constexpr const char* kInjectedFaultKinds[] = {"compile", "wrong", "hang", "crash", "lost"};
struct InjectedFault {
  std::string variant_key;
  std::string kind;  // one of kInjectedFaultKinds, or empty
};
InjectedFault InjectedFaultFromEnvironment();

}  // namespace skintune::internal
