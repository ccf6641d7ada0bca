// skintune: one tuning measurement (a variant on a device and dataset) and
// the append-only cache that makes a tuning run resumable.
//
// Every variant ends with exactly one MeasureStatus. A time counts only when the
// variant's output passed verification against the float64 gold on that
// device (status ok). Every verified measurement also states its error
// against the unquantised source mesh (SourceError); a variant whose weight
// format costs more than the run's budget is too_imprecise: verified and
// timed, recorded, never the winner (docs/TUNING.md "Precision").
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/variant.h"
#include "base/error.h"
#include "runtime/source_error.h"
#include "tuner/race_record.h"

namespace skintune::internal {

// Now, UTC, ISO 8601 ("2026-11-22T13:39:17Z"): when a measurement or a report was made.
std::string UtcTimestamp();

// The statuses, in the order kAllMeasureStatuses lists them (Name() and the
// JSON schemas must name each: a forgotten one fails a static_assert or
// Measurement.SchemasListEveryStatus).
enum class MeasureStatus { kOk, kInvalid, kCompileFailed, kLaunchFailed, kVerifyFailed, kTimeout, kTooImprecise };
inline constexpr MeasureStatus kAllMeasureStatuses[] = {
    MeasureStatus::kOk,           MeasureStatus::kInvalid, MeasureStatus::kCompileFailed, MeasureStatus::kLaunchFailed,
    MeasureStatus::kVerifyFailed, MeasureStatus::kTimeout, MeasureStatus::kTooImprecise};
const char* Name(MeasureStatus);
// Whether a measurement of this status was verified and timed (ok, too_imprecise).
constexpr bool IsTimed(MeasureStatus s) { return s == MeasureStatus::kOk || s == MeasureStatus::kTooImprecise; }
MeasureStatus MeasureStatusFromName(const std::string& name);  // throws Error for an unknown name

// How times are measured (docs/TUNING.md "Timing"). Part of every cache key,
// so a change of method measures everything again instead of mixing figures:
// 1: each frame timed alone by the device's timers (CUDA events around each
//    launch, counting launch processing), input sets sized from the cache the
//    API reports; 2: launch-gap-free bursts, input sets sized from the
//    physical chip's cache, a same-size copy timed beside every measurement;
// 3: an even number of input sets (so CUDA's and OpenCL's two lanes never
//    read one set at once), warm-up bursts long enough to raise a GPU's
//    clock and ended only when the clock probe is back up (runtime/runner.cpp);
// 4: burst lengths are powers of two (0.71 to 1.41 x burst_ms), so the same-size
//    copy is timed once per length; a device busy within 10 ms is not warmed
//    again, and one still warm by the probe gets one 4 ms burst.
// 5: two figures named for what they measure. The kernel time ranks: each
//    sample is one frame's launches, each timed alone by the device's own
//    record of the kernel (OpenCL profiling, CUPTI, GL timer queries, Vulkan
//    timestamps), after a flush that leaves the last-level cache holding
//    only clean lines of other data (Nsight Compute's default state);
//    samples are taken until the median's 95% interval is tight or a cap.
//    The frame time is the host's wall time per frame of frames issued back
//    to back as a Skinner issues them. Bursts timed as a whole are gone: at
//    the sizes engines skin they timed how fast the host issued launches.
// 6: the cpu device chooses its threads and chunks per variant and frame
//    shape, on frames timed as the kernel time times them (cold), where 5
//    chose once per variant: a schedule chosen for 100k vertices ran a
//    5k-vertex crowd on one thread, 5x slower. The other devices' method is
//    that of 5.
// 7: on a GPU whose driver tells its SM clock (NVIDIA's, through NVML), each
//    batch of samples is taken at the clock the GPU runs at under load,
//    warmed back before it and taken again when the clock fell during it
//    (tuner/clock_guard.h); the clock is recorded (timing.sm_clock_mhz).
//    Version 6's GL and Vulkan batches on the H200 ran at 630-1500 MHz
//    instead of 1980 in parts of a run. Other devices time as in 6.
// 8: every cold frame (flush, then the frame's launches) is queued whole and
//    waited for before the next, so it starts on an idle device, as Nsight
//    Compute replays a kernel; CUDA's run on the Skinner's stream, with
//    CUPTI's first launches untimed; the frame time is taken before the
//    kernel time. Version 7's back-to-back frames started a kernel after the
//    flush 1 us later in every other frame on an H200, and a median of a
//    batch fell on either side as that share moved (4.2-5.0 us for one
//    100k-vertex CUDA kernel); each CUDA batch's first sample counted the
//    host's 0.15-2.5 ms.
// 9: CUDA and OpenCL on a GPU measure on the quickest of several contexts of
//    their own (ten and six), by their launch start (tuner/runner_device.h
//    OpenMeasuringRunner), where 8 used the one a runner opened (CUDA's
//    primary context): the device's start of a launch after the flush is the
//    context's, and one 100k-vertex CUDA kernel read 4.06-4.10 us on some
//    contexts and 4.19-4.26 on others, steady within each (an H200,
//    2026-12-01), so a run's CUDA rows moved together by that step; NVIDIA's
//    OpenCL contexts differed as much. Other devices time as in 8.
// 10: on the host's CPU (PoCL's, skintune's cpu device) each kernel-time
//    sample is the quickest of three cold frames spread over its batch
//    (TimingOptions::host_frames_per_sample), and the cpu device chooses a
//    variant's schedule by its quickest frame, not its median: three cold
//    runs of 9 on an H200 machine's 16-thread host (2026-12-02) put one
//    variant's 100k-vertex frames at 62-70 us and at 130-160 us within one
//    race, as neighbours' threads hit some of them, and its figure 1.2-2.1x
//    apart between runs. A GPU's samples are those of 9.
// 11: Vulkan records a cold frame into sixteen command buffers taken in turn,
//    where 10 reused the one retired last: on NVIDIA's driver a launch's
//    stamped time depends steadily on the command buffer it is recorded into
//    (one 100k-vertex kernel 4.13-4.42 us by command buffer, an H200,
//    2026-12-02), so a measurement carried its command buffer's level and a
//    run's Vulkan winners moved 3-7% from one process to the next. Other
//    devices time as in 10.
// 12: OpenCL times each launch of a cold frame to the START of a marker
//    queued after it, the launch itself without an event, where 11 read the
//    launch's own END: on NVIDIA's driver the launch's event cost the device
//    1.3-1.5 us beside the kernel (a 100k-vertex kernel 6.59 us to its END,
//    5.25 to the marker's START, CUDA's twin 4.10; an H200, 2026-12-03).
//    Other APIs time as in 11.
// 13: OpenCL starts each launch's time at the END of a marker queued before
//    it (after the flush, or after the launch before), where 12 started at
//    the flush's END or the marker's START: a marker's own 0.6-0.96 us was in
//    every launch after a frame's first (bucketed meshes, animated frames;
//    an H200, 2026-12-03). And on a GPU the flush runs once per launch of
//    the frame, so that the device is not idle waiting for the host to
//    queue the launches: a bucketed frame of four launches read 24-41.5 us
//    with one flush, 17.7-17.9 with four (Vulkan's twin 17.1). Other APIs
//    time as in 12.
inline constexpr int kTimingVersion = 13;

// The largest verification tolerance a config may set (timing.tolerance:
// the largest relative error against the gold of the quantised mesh): float32
// kernels agree with it within ~5e-7 (docs/TUNING.md "Precision"), so more
// would let a wrong kernel pass. A timed record claiming more is impossible.
inline constexpr double kMaxTolerance = 1e-3;

struct Timing {
  // The kernel time (docs/TUNING.md "Kernel time"), ms.
  double median_ms = 0.0;  // the median of the samples
  double min_ms = 0.0;     // the fastest sample
  double max_ms = 0.0;     // the slowest
  int warmup = 0;          // untimed cold frames before the samples
  int repetitions = 0;     // samples taken
  int input_sets = 0;      // distinct input sets rotated between samples
  // Frames per frame-time run (frame_ms; before timing version 5: per burst).
  int burst_frames = 0;
  double footprint_bytes = 0.0;  // input_sets x the bytes of one set
  double copy_ms = 0.0;    // the same-size copy's kernel time, the same method (0: not measured)
  int version = kTimingVersion;
  double low_ms = 0.0;     // the median's 95% interval (order statistics); both 0: not recorded
  double high_ms = 0.0;
  bool tight = false;      // the interval met the stop rule (not stopped by a cap)
  std::string clock;       // what timed each launch (DeviceApi::kernel_clock)
  double flush_bytes = 0;  // what the flush before each sample read, or the frame's own bytes where the device evicts them (0: none)
  double sm_clock_mhz = 0; // the lowest SM clock read around the samples kept (tuner/clock_guard.h; 0: not read)
  std::string schedule;    // how the device ran the samples where it chooses that itself (the cpu device's threads and chunk; "": elsewhere)
  std::string context;     // how the runner's context was chosen among several (timing version 9; "": the one it opened)
  // The context's launch start: a 4 KiB copy's kernel time, taken as
  // median_ms is (tuner/runner_device.h LaunchStartProbe), ms; 0: not probed
  // (the host's CPU, older records). median_ms less it is the kernel's time
  // beyond the smallest launch, comparable across APIs (docs/TUNING.md).
  double launch_start_ms = 0.0;
  // The frame time (docs/TUNING.md "Frame time"): host ms per frame of
  // `burst_frames` frames issued back to back as a Skinner issues them (0: not measured).
  double frame_ms = 0.0;
  // An animated scene's (animation sampled or baked): the palette kernel's own
  // time, the median of each sample's first launch, ms; part of median_ms (0: none).
  double palette_kernel_ms = 0.0;
};

// A baked variant's clip (generator/clip_packer.h BakedClipInfo): its frames,
// their bytes on the device, and the largest distance between a vertex
// skinned by its baked palettes and by the float64 sampled ones, relative to
// the mesh's bounding-box diagonal.
struct BakedClipRecord {
  std::string name;
  double frames = 0.0;
  double bytes = 0.0;
  double max_error = 0.0;
};

struct Measurement {
  std::string device_id;          // DeviceIdentity::Id() (includes the driver version)
  std::string dataset;            // dataset key (model/synthetic.h) or glTF file name
  Variant variant;
  MeasureStatus status = MeasureStatus::kOk;
  std::string detail;             // invalid: the constraint and its message; compile_failed: the first
                                  // lines of the build log; launch/verify failures: the error; timeout: the limit
  Timing timing;                  // status ok only
  double bytes_per_frame = 0.0;   // bytes the variant's format must move per frame (inputs + outputs)
  // The least of them the frame can move: an instanced launch's one mesh is
  // read once (FloorBytes), so K instances may run faster than K copies'
  // bytes allow. What the ceiling against the copy judges (RejectOverCeiling);
  // 0 in records written before it: bytes_per_frame.
  double least_bytes_per_frame = 0.0;
  double gbps = 0.0;              // bytes_per_frame / median time (status ok only)
  double x_copy = 0.0;            // median time / the same-size copy's (timing.copy_ms); 0: no copy time
  double max_relative_error = 0.0;  // against the gold of the quantised mesh (ok, too_imprecise, verify_failed);
                                    // packed normals and tangents (normal_format) count in source_error only
  SourceError source_error;         // against the unquantised source (ok and too_imprecise)
  std::vector<BakedClipRecord> baked_clips;  // a baked variant's clips, verified or not (empty: none)
  std::string generator_version;
  std::string timestamp;          // UTC, ISO 8601

  // The cache key: device identity (with driver), generator version, timing
  // version, dataset, variant.
  std::string CacheKey() const;
};

// What makes a measurement impossible (runtime/recorded_time.h), or "" when
// it is possible. Only a status-ok measurement's figures are ever used (a
// failed one is never ranked), so only those are checked: a possible time
// (median, min, max), bytes per frame, GB/s consistent with them, at least one
// repetition, warm-up >= 0, at least one input set, bursts of at least one
// frame (0 only in timing version 1), a finite footprint >= 0, and a finite
// relative error from 0 to kMaxTolerance; too_imprecise ones (timed too)
// likewise, and a known SourceError must be possible (ImpossibleSourceError);
// where a copy time is given, a possible one with x_copy = median / copy_ms.
std::string ImpossibleFigures(const Measurement& m);

// The start of the detail of a failure that says nothing about the variant:
// its worker was killed by a signal the tuner did not send (SIGKILL, SIGTERM,
// SIGINT, SIGHUP, SIGQUIT: a user, the OOM killer, a shutdown) or was
// stopped until its time ran out.
inline constexpr const char* kInterruptedDetail = "interrupted: ";

// Why a cached record of this run's cache key is measured again instead of
// reused ("" when it is reused): a timed record without a source error (older
// than that measurement), or with a relative error over this run's
// `tolerance`; a failure that was interrupted (kInterruptedDetail).
std::string MeasuredAgainOnResume(const Measurement& m, double tolerance);

// Applies the budget to a timed measurement: status ok when it is
// WithinBudget (its quantisation error within `max_error`, its whole error
// within that and the kernel's rounding allowance), too_imprecise (with the
// figures in `detail`) when over; other statuses, and measurements with no known error, are left
// as they are. Symmetric, so a cached record is judged by the current run's budget.
void ApplyBudget(Measurement& m, double max_error);

// Thrown by from_json for a well-formed measurement with impossible figures.
class ImpossibleMeasurement : public Error {
 public:
  using Error::Error;
};

void to_json(nlohmann::json& out, const Measurement& m);
// Throws Error("measurement: ...") naming the field for a malformed
// measurement (a status-ok one without "timing" included), and
// ImpossibleMeasurement("measurement: impossible figures: ...") for one that
// ImpossibleFigures rejects: no reader (cache, report, replay, worker answer)
// can take an impossible time.
void from_json(const nlohmann::json& in, Measurement& m);

// Append-only JSON-lines file of measurements. Each Append writes one complete
// line with a single write() on an O_APPEND descriptor and fsyncs it, so a run
// killed at any moment leaves every finished measurement on disk; a torn last
// line (killed mid-write) is ignored and cut off when the file is reopened.
class MeasurementCache {
 public:
  // Opens (creating) the file. Throws Error naming the file when it cannot
  // be read, created or written, or when a complete line is malformed or
  // impossible ("<path>:<line>: ..."); the file is then left as it was.
  explicit MeasurementCache(const std::string& path);
  ~MeasurementCache();
  MeasurementCache(const MeasurementCache&) = delete;
  MeasurementCache& operator=(const MeasurementCache&) = delete;

  const Measurement* Find(const std::string& cache_key) const;
  void Append(const Measurement& m);
  // A race is kept beside the measurements, on a line of its own
  // ({"race_key": ..., "race": ...}), under a key that names everything its
  // verdicts depend on (RaceCacheKey, tuner/race.h): a run whose candidates
  // were all cached finds it and does not race them again.
  const RaceRecord* FindRace(const std::string& race_key) const;
  void AppendRace(const std::string& race_key, const RaceRecord& race);
  const std::vector<Measurement>& all() const { return measurements_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
  std::vector<Measurement> measurements_;
  std::map<std::string, std::size_t> index_;
  std::map<std::string, RaceRecord> races_;

  void AppendLine(const std::string& line, const char* what);
  // The opened file, locked, whole (its size checked against the input limit).
  std::string ReadLocked();
  // Every complete line of `data`; a torn last line is cut off the file.
  void Load(const std::string& data);
  // One line (number `line_number`): a race or a measurement; the later record of a key wins.
  void LoadLine(const std::string& line, std::size_t line_number);
  // Keeps `m` under its cache key, replacing an earlier record of it.
  void Keep(Measurement m);
};

}  // namespace skintune::internal
