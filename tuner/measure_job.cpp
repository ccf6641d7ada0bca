// skintune: the measurement job and the race job (tuner/measure_job.h).
#include "tuner/measure_job.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <sstream>
#include <utility>

#include "base/error.h"
#include "model/scene.h"
#include "tuner/host_lock.h"
#include "tuner/schedule.h"  // IsHostCpu

namespace skintune::internal::tuner_internal {

int InputSetsFor(std::uint64_t last_level_cache_bytes, std::uint64_t bytes_per_set, int max_input_sets) {
  const std::uint64_t llc = last_level_cache_bytes ? last_level_cache_bytes : kUnknownLastLevelCacheBytes;
  const int most = std::max(max_input_sets, 1);
  if (bytes_per_set == 0) return most;
  const std::uint64_t wanted = (2 * llc + bytes_per_set - 1) / bytes_per_set;
  int sets = static_cast<int>(std::clamp<std::uint64_t>(wanted, 1, static_cast<std::uint64_t>(most)));
  // Even: CUDA's and OpenCL's two lanes take frames in turn, frame f set
  // f % sets, so each lane keeps to sets of its own parity and the lanes,
  // which may drift apart within a burst, never read one set at once (with
  // 3 sets NVIDIA's OpenCL timed a 43 MB copy at 3.7 TB/s, over HBM3's peak).
  if (sets > 1 && sets % 2 == 1) sets = sets + 1 <= most ? sets + 1 : sets - 1;
  return sets;
}

namespace {

// Timing options a measurement can work with (MeasureJob::Validate).
bool TimingCanWork(const TimingOptions& options) {
  return options.tolerance > 0.0 && options.tolerance <= kMaxTolerance && options.burst_ms > 0.0 &&
         BadStopRule(options.stop, "timing.").empty();
}

std::string Scientific(double value) {
  std::ostringstream out;
  out.precision(2);
  out << std::scientific << value;
  return out.str();
}

// "positions: max relative error 3.1e-02 at vertex 17" or the non-finite count;
// empty when within tolerance.
std::string Disagreement(const char* what, const GoldComparison& c, double tolerance) {
  if (c.non_finite > 0)
    return std::string(what) + ": " + std::to_string(c.non_finite) + " non-finite vertices, the first at vertex " +
           std::to_string(c.worst_vertex);
  if (c.wrong_handedness > 0)
    return std::string(what) + ": " + std::to_string(c.wrong_handedness) +
           " with the wrong handedness (w), the first at vertex " + std::to_string(c.worst_vertex);
  if (c.max_relative > tolerance)
    return std::string(what) + ": max relative error " + Scientific(c.max_relative) + " at vertex " +
           std::to_string(c.worst_vertex) + " (tolerance " + Scientific(tolerance) + ")";
  return "";
}

// The outputs of K instances (packed order, instance after instance) as
// one vec3 per vertex in the mesh's order, instance after instance.
template <typename Vector>
std::vector<Vector> UnpackInstancesBy(const PackedMesh& packed, std::span<const std::uint8_t> output, int instances,
                                      Output which,
                                      std::vector<Vector> (*unpack)(const PackedMesh&, std::span<const std::uint8_t>)) {
  if (instances == 1) return unpack(packed, output);
  const std::size_t bytes = packed.vertex_count * OutputStrideBytes(packed.variant, which);
  if (output.size() != bytes * static_cast<std::size_t>(instances))
    throw Error("UnpackInstances: " + std::to_string(output.size()) + " output bytes for " + std::to_string(instances) +
                " instances of " + std::to_string(bytes));
  std::vector<Vector> all;
  for (int i = 0; i < instances; ++i) {
    const std::vector<Vector> one = unpack(packed, output.subspan(static_cast<std::size_t>(i) * bytes, bytes));
    all.insert(all.end(), one.begin(), one.end());
  }
  return all;
}

std::string DatasetName(const std::string& key) {
  return IsGltfFile(key) ? std::filesystem::path(key).filename().string() : key;
}

// Each phase's wall time, for the timing log (SKINTUNE_TIMING_LOG).
class PhaseLog {
 public:
  void Mark(const char* name) {
    const auto now = Clock::now();
    if (TimingLogPath())
      text_ += std::string(text_.empty() ? "" : ", ") + name + " " +
               std::to_string(std::chrono::duration<double, std::milli>(now - mark_).count()) + " ms";
    mark_ = now;
  }
  const std::string& text() const { return text_; }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point mark_ = Clock::now();
  std::string text_;
};

// One MeasureJob's run: the measurement it fills and what it has made so far.
struct Measuring {
  const MeasureJob& job;
  Measurement& m;
  DatasetCache::Entry& data;
  PhaseLog phases;
  const PackedMesh* packed = nullptr;  // DatasetCache's packing: nothing packs again during the job
  std::vector<KernelSource> kernels;
  std::vector<glm::vec3> positions, normals;  // the verified output, in the mesh's order
  std::vector<glm::vec4> tangents;
  std::optional<AnimatedInputs> animated;  // an animated scene's clips, palette kernel and verification states
};

// An animated scene's inputs for `variant`: its form's clips (DatasetCache::Clips),
// their palette kernel in its language writing its palette rows, and `states`.
AnimatedInputs AnimatedFor(DatasetCache& datasets, DatasetCache::Entry& data, const Variant& variant,
                           std::vector<std::vector<std::uint8_t>> states) {
  AnimatedInputs in;
  in.clips = &datasets.Clips(data, variant.animation);
  if (FusesPalette(variant.animation)) {
    in.kernel.fused = true;  // the skin launches make the palettes (Runner::Animate)
  } else {
    in.kernel = EmitPalette(variant.lang, in.clips->View(), static_cast<int>(PaletteMatrixBytes(variant) / 16));
  }
  in.states = std::move(states);
  return in;
}

// Each input set's K instances (CrowdStates), as the palette kernel reads them.
std::vector<std::vector<std::uint8_t>> StatesOfSets(const DatasetCache::Entry& data, int sets) {
  std::vector<std::vector<std::uint8_t>> states;
  for (int s = 0; s < sets; ++s) {
    const std::vector<AnimInstance> crowd = CrowdStates(data.scene, s);
    const std::span<const std::uint8_t> bytes = BufferBytes(crowd);
    states.emplace_back(bytes.begin(), bytes.end());
  }
  return states;
}

// Ends the measurement with `status`; false, so that a stage returns it.
bool Fail(Measurement& m, MeasureStatus status, std::string detail) {
  m.status = status;
  m.detail = std::move(detail);
  return false;
}

// Why the variant cannot run on the device or the scene, or "".
std::string WhyNotHere(const MeasureJob& job, const DatasetCache::Entry& data) {
  const Variant& variant = job.variant;
  if (std::find(job.languages.begin(), job.languages.end(), variant.lang) == job.languages.end())
    return std::string("language ") + Name(variant.lang) + " does not run on " + job.device->backend + " device " +
           job.device->name;
  const SkinnedMesh& mesh = data.mesh();
  ProblemShape shape = WithMorphOf({mesh.joint_count, mesh.influences, mesh.has_normals(), data.instances(),
                                    mesh.has_normals() && mesh.has_tangents(), data.rigid_joints},
                                   mesh.morph);
  shape.animated = data.scene.spec.animated;
  std::string detail;
  for (const Violation& v : CheckVariant(variant, job.limits, shape))
    detail += (detail.empty() ? "" : "; ") + std::string(Name(v.constraint)) + ": " + v.message;
  return detail;
}

// Packs the scene for the variant and emits its kernels (invalid when either throws).
bool Pack(Measuring& run) {
  try {
    run.packed = &PackScene(*run.job.datasets, run.data, run.job.variant, run.kernels);
    if (AnimatesOnDevice(run.job.variant)) {
      const std::span<const std::uint8_t> states = BufferBytes(run.data.verification_states);
      run.animated = AnimatedFor(*run.job.datasets, run.data, run.job.variant, {{states.begin(), states.end()}});
      for (const BakedClipInfo& clip : run.animated->clips->baked)  // what baking costs and loses, verified or not
        run.m.baked_clips.push_back({clip.name, static_cast<double>(clip.frames), static_cast<double>(clip.bytes), clip.max_error});
    }
  } catch (const Error& e) {
    return Fail(run.m, MeasureStatus::kInvalid, e.what());
  }
  run.phases.Mark("pack");
  return true;
}

// What the parts of the output disagree with the gold by: the first wrong
// part (a scene may have 64 instances), "" when none; records the largest
// relative error in the measurement.
std::string DisagreementWithGold(Measuring& run) {
  const GoldResult& gold = run.job.datasets->Gold(run.data, run.job.variant);
  const bool normals = SkinsNormals(run.job.variant), tangents = SkinsTangents(run.job.variant);
  const double tolerance = run.job.options.tolerance;
  std::string disagreement;
  for (const DatasetCache::Part& part : run.data.parts) {
    auto slice = [&](const auto& all) { return std::span(all).subspan(part.first, part.count); };
    const GoldComparison positions = CompareToGold(slice(gold.positions), slice(run.positions));
    run.m.max_relative_error = std::max(run.m.max_relative_error, positions.max_relative);
    std::string wrong = Disagreement("positions", positions, tolerance);
    if (normals) {
      // A packed normal format adds its stated bound (NormalFormatBound) to the tolerance.
      // max_relative_error holds what the tolerance judges: a packed format's
      // own error is the source error's normal_abs.
      const GoldComparison n = CompareToGold(slice(gold.normals), slice(run.normals));
      if (!PacksNormals(run.job.variant)) run.m.max_relative_error = std::max(run.m.max_relative_error, n.max_relative);
      const std::string text =
          Disagreement("normals", n, tolerance + NormalFormatBound(run.job.variant.normal_format));
      if (!text.empty()) wrong += (wrong.empty() ? "" : "; ") + text;
    }
    if (tangents) {
      const GoldComparison t = CompareTangentsToGold(slice(gold.tangents), slice(run.tangents));
      if (!PacksNormals(run.job.variant)) run.m.max_relative_error = std::max(run.m.max_relative_error, t.max_relative);
      const std::string text =
          Disagreement("tangents", t, tolerance + TangentFormatBound(run.job.variant.normal_format));
      if (!text.empty()) wrong += (wrong.empty() ? "" : "; ") + text;
    }
    if (!wrong.empty() && disagreement.empty()) disagreement = part.name.empty() ? wrong : part.name + ": " + wrong;
  }
  return disagreement;
}

// One run on poisoned outputs with guards, against the gold, each part of
// the scene (an instance, a batch's mesh) against its own.
bool Verify(Measuring& run) {
  const Variant& variant = run.job.variant;
  const int instances = run.data.instances();
  Executor::Output output;
  try {
    const std::vector<std::uint8_t> palette = PackPalette(run.data.verification_palette, variant);
    output = run.animated ? run.job.executor->RunAnimated(*run.packed, run.kernels, palette, instances, *run.animated)
                          : run.job.executor->Run(*run.packed, run.kernels, palette, instances);
  } catch (const Error& e) {
    return Fail(run.m, StatusOfRunnerError(e.what()), e.what());
  }
  run.phases.Mark("run (build, upload, verification launch, read-back)");
  run.positions = UnpackInstancesBy(*run.packed, output.positions, instances, Output::kPositions, &Unpack);
  if (SkinsNormals(variant))
    run.normals = UnpackInstancesBy(*run.packed, output.normals, instances, Output::kNormals, &UnpackNormals);
  if (SkinsTangents(variant))
    run.tangents = UnpackInstancesBy(*run.packed, output.tangents, instances, Output::kTangents, &UnpackTangents);
  std::string disagreement = DisagreementWithGold(run);
  if (output.poisoned_vertices > 0)
    disagreement = std::to_string(output.poisoned_vertices) + " output vectors never written (still poisoned)" +
                   (disagreement.empty() ? "" : "; " + disagreement);
  if (!disagreement.empty())
    return Fail(run.m, MeasureStatus::kVerifyFailed, "wrong results against the float64 gold: " + disagreement);
  return true;
}

// Verified: what the output is worth against the unquantised source, the
// worst part relative to its own diagonal.
void RecordSourceError(Measuring& run) {
  const Variant& variant = run.job.variant;
  const GoldResult& source = run.job.datasets->SourceGold(run.data, variant);
  SourceError& error = run.m.source_error;
  error.known = true;
  for (const DatasetCache::Part& part : run.data.parts) {
    auto slice = [&](const auto& all) { return std::span(all).subspan(part.first, part.count); };
    const double abs = CompareToGold(slice(source.positions), slice(run.positions)).max_absolute;
    if (&part == &run.data.parts.front() || Relative(abs, part.diagonal) > error.position_rel) {
      error.diagonal = part.diagonal;
      error.position_abs = abs;
      error.position_rel = Relative(abs, part.diagonal);
    }
    if (SkinsNormals(variant))
      error.normal_abs = std::max(error.normal_abs, CompareToGold(slice(source.normals), slice(run.normals)).max_absolute);
    if (SkinsTangents(variant))
      error.normal_abs = std::max(error.normal_abs,
                                  CompareTangentsToGold(slice(source.tangents), slice(run.tangents)).max_absolute);
  }
  error.quantisation_rel = run.job.datasets->QuantisationError(run.data, variant);
}

// The frame time, then the kernel time (cold samples rotating among
// `palettes.size()` input sets of different frames, to the stop rule). The
// frame time first: a Skinner's frames leave some devices launching a little
// slower for the rest of the process (NVIDIA's OpenCL: 0.15 us more to every
// later kernel time after the first frames on its queue, an H200 in December
// 2026), so every variant's kernel time, the first one's included, is taken
// in the state the frames before it left.
bool TimeKernel(Measuring& run, const std::vector<std::vector<std::uint8_t>>& palettes) {
  const MeasureJob& job = run.job;
  const int sets = static_cast<int>(palettes.size());
  try {
    std::unique_ptr<Executor::Timed> prepared;
    if (run.animated) {
      run.animated->states = StatesOfSets(run.data, sets);
      prepared = job.executor->PrepareAnimated(*run.packed, run.kernels, palettes, run.data.instances(), *run.animated);
    } else {
      prepared = job.executor->Prepare(*run.packed, run.kernels, palettes, run.data.instances());
    }
    run.m.timing.frame_ms = SampleFrameTime(*prepared, job.options, &run.m.timing.burst_frames);
    run.phases.Mark("frame time");
    RecordKernelTime(run.m, SampleKernelTime(*prepared, job.options), *job.executor, sets, prepared->bytes_per_set());
    if (const std::vector<double> palette_ms = prepared->PaletteKernelMs(); !palette_ms.empty())
      run.m.timing.palette_kernel_ms = Median(palette_ms);
    run.m.timing.warmup = std::max(job.options.warmup, 1);  // SampleKernelTime runs at least one
    run.phases.Mark("kernel time");
  } catch (const Error& e) {
    return Fail(run.m, StatusOfRunnerError(e.what()), std::string("timing: ") + e.what());
  }
  return true;
}

// The same-size copy's kernel time by the same method (x_copy); what went
// wrong with it, or "" (a kernel without its copy is still measured).
std::string TimeCopy(Measuring& run, std::uint64_t bytes_per_frame, int sets) {
  std::string problem;
  try {
    const KernelTime& copy = run.job.executor->CopyTime(run.job.variant.lang, bytes_per_frame, sets, run.job.options);
    run.m.timing.copy_ms = copy.interval.median;
    run.m.x_copy = run.m.timing.median_ms / copy.interval.median;
  } catch (const Error& e) {
    problem = std::string("the same-size copy failed: ") + e.what();
  }
  run.phases.Mark("copy");
  return problem;
}

// What identifies the measurement, before anything is measured.
Measurement Started(const MeasureJob& job) {
  Measurement m;
  m.device_id = job.device->Id();
  m.dataset = DatasetName(job.dataset.key);
  m.variant = job.variant;
  m.generator_version = kGeneratorVersion;
  m.timestamp = UtcTimestamp();
  return m;
}

}  // namespace

bool MeasureJob::Validate() const {
  return executor && datasets && device && measurement && !dataset.key.empty() && !languages.empty() &&
         TimingCanWork(options);
}

bool MeasureJob::Run() const {
  if (!Validate()) return false;
  Measurement& m = *measurement = Started(*this);
  DatasetCache::Entry& data = datasets->Get(dataset.key);
  if (const std::string why = WhyNotHere(*this, data); !why.empty()) {
    Fail(m, MeasureStatus::kInvalid, why);
    return true;
  }
  // The chip (tuner/host_lock.h): this API's work on it alone, from the
  // verification's uploads to the copy's last sample. The host's cores: a
  // CPU device's bursts hold them alone; the packing and checks before them
  // take no lock (host_lock.h says why).
  const ChipLock chip;
  const bool cpu_device = IsHostCpu(*device);
  Measuring run{*this, m, data};
  if (!Pack(run) || !Verify(run)) return true;
  RecordSourceError(run);
  // The bytes of the scene's frame: K instances move what K copies of the
  // mesh would (so the same-size copy is that of one mesh of the scene's
  // total bytes, even when an instanced kernel finds its inputs in cache).
  const std::uint64_t bytes_per_frame = FrameBytes(*run.packed, data.instances());
  m.bytes_per_frame = static_cast<double>(bytes_per_frame);
  m.least_bytes_per_frame = static_cast<double>(FloorBytes(*run.packed, data.instances()));
  const int sets = InputSetsFor(device->last_level_cache_bytes, bytes_per_frame, options.max_input_sets);
  const std::vector<std::vector<std::uint8_t>> palettes = TimedPalettes(*datasets, data, variant, sets);
  run.phases.Mark("check against the gold and the source");
  const HostLock timed(TimedMode(cpu_device));  // through the copy's samples
  if (!TimeKernel(run, palettes)) return true;
  const std::string copy_problem = TimeCopy(run, bytes_per_frame, sets);
  TimingLog([&] { return variant.Key() + " phases: " + run.phases.text(); });
  m.status = MeasureStatus::kOk;
  m.detail = copy_problem;
  return true;
}

Measurement MeasurementOf(MeasureJob job) {
  Measurement m;
  job.measurement = &m;
  if (!job.Run())
    throw Error("measuring " + job.variant.Key() + " on '" + job.dataset.key +
                "': the job's inputs are incomplete or its timing options cannot work");
  return m;
}

// ---------------------------------------------------------------- the race

namespace {

// Every variant of the race prepared for timing, with its input sets; each
// one's tie-break entry (its key and the bytes it moves a frame) into `entries`.
std::vector<std::unique_ptr<Executor::Timed>> PrepareRacers(const RaceJob& job, std::vector<RaceEntry>& entries) {
  DatasetCache::Entry& data = job.datasets->Get(job.dataset.key);  // its packing: no host lock (host_lock.h)
  std::vector<std::unique_ptr<Executor::Timed>> timed;
  for (const Variant& v : job.variants) {
    std::vector<KernelSource> kernels;
    const PackedMesh& packed = PackScene(*job.datasets, data, v, kernels);  // valid until the next packing
    const int sets = InputSetsFor(job.device->last_level_cache_bytes, FrameBytes(packed, data.instances()),
                                  job.options.max_input_sets);
    const std::vector<std::vector<std::uint8_t>> palettes = TimedPalettes(*job.datasets, data, v, sets);
    timed.push_back(AnimatesOnDevice(v) ? job.executor->PrepareAnimated(packed, kernels, palettes, data.instances(),
                                                                        AnimatedFor(*job.datasets, data, v, StatesOfSets(data, sets)))
                                        : job.executor->Prepare(packed, kernels, palettes, data.instances()));
    entries.push_back({v.Key(), {}, static_cast<double>(FrameBytes(packed, data.instances())), 0.0});
  }
  return timed;
}

}  // namespace

bool RaceJob::Validate() const {
  return executor && datasets && device && samples && !dataset.key.empty() && !variants.empty() &&
         BadStopRule(options.stop, "timing.").empty();
}

bool RaceJob::Run() const {
  if (!Validate()) return false;
  using Clock = std::chrono::steady_clock;
  const ChipLock chip;  // from the first upload to the last sample (tuner/host_lock.h)
  const auto begun = Clock::now();
  std::vector<RaceEntry> entries;
  const std::vector<std::unique_ptr<Executor::Timed>> timed = PrepareRacers(*this, entries);
  const auto prepared = Clock::now();
  // Its rounds decide the row: no process of the chip's workers lands untimed
  // work on the chip meanwhile (tuner/host_lock.h ChipQuiet).
  const ChipQuiet quiet(ChipQuiet::Mode::kRace);
  const HostLock timed_lock(TimedMode(IsHostCpu(*device)));
  const StopRule& rule = options.stop;
  for (const std::unique_ptr<Executor::Timed>& t : timed) (void)t->Cold(std::max(options.warmup, 1), 0);  // as SampleKernelTime
  const auto start = Clock::now();
  int rounds = 0;
  // Rounds of one batch each, candidate after candidate: a drift of the
  // device's clock or of its neighbours' load falls on every candidate alike.
  for (;;) {
    for (std::size_t i = 0; i < timed.size(); ++i) {
      const std::vector<double> batch = ColdSamples(*timed[i], static_cast<int>(rule.batch), options.frames_per_sample);
      entries[i].samples.insert(entries[i].samples.end(), batch.begin(), batch.end());
    }
    std::size_t fewest = entries.front().samples.size();
    for (const RaceEntry& e : entries) fewest = std::min(fewest, e.samples.size());
    if (fewest == 0) throw Error("race: the device gave no kernel time");
    const RaceOutcome outcome = JudgeRace(entries, options.tie_margin);
    const double elapsed = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    ++rounds;
    if ((outcome.settled && fewest >= rule.min_samples) || fewest >= rule.max_samples ||
        elapsed >= rule.max_ms * static_cast<double>(entries.size()))
      break;
  }
  TimingLog([&] {
    const auto ms = [](Clock::time_point from, Clock::time_point to) {
      return std::to_string(std::lround(std::chrono::duration<double, std::milli>(to - from).count()));
    };
    return device->backend + " " + device->name + " race of " + std::to_string(timed.size()) + " for " + dataset.key +
           " in this process: prepared in " + ms(begun, prepared) + " ms, warmed in " + ms(prepared, start) + " ms, " +
           std::to_string(rounds) + " rounds in " + ms(start, Clock::now()) + " ms";
  });
  samples->clear();
  for (RaceEntry& e : entries) samples->push_back(std::move(e.samples));
  return true;
}

// ---------------------------------------------------------------- what a job records

void RecordKernelTime(Measurement& m, const KernelTime& t, const Executor& executor, int sets, std::size_t bytes_per_set) {
  m.timing.median_ms = t.interval.median;
  m.timing.low_ms = t.interval.low;
  m.timing.high_ms = t.interval.high;
  m.timing.min_ms = *std::min_element(t.samples.begin(), t.samples.end());
  m.timing.max_ms = *std::max_element(t.samples.begin(), t.samples.end());
  m.timing.repetitions = static_cast<int>(t.samples.size());
  m.timing.tight = t.tight;
  m.timing.clock = executor.KernelClock();
  m.timing.input_sets = sets;
  m.timing.footprint_bytes = static_cast<double>(sets) * static_cast<double>(bytes_per_set);
  // Where the device evicts the frame's own buffers instead, those bytes.
  m.timing.flush_bytes = static_cast<double>(executor.EvictsOwnBuffers() ? bytes_per_set : executor.FlushReadBytes());
  m.timing.sm_clock_mhz = t.clock_mhz;
  m.timing.schedule = executor.ScheduleOf(m.variant.Key());
  m.timing.context = executor.ContextChoice();
  m.timing.launch_start_ms = executor.LaunchStartMs();
  m.gbps = m.timing.median_ms > 0.0 ? m.bytes_per_frame / m.timing.median_ms / 1e6 : 0.0;
}

namespace {

// The stage a runner's Error names ("<API> <stage>: ..."), or "".
std::string RunnerErrorStage(const std::string& message) {
  // The API is one word ("OpenCL", "CUDA", "GL").
  const std::size_t space = message.find(' ');
  const std::size_t colon = message.find(':');
  if (space == std::string::npos || colon == std::string::npos || space > colon) return "";
  return message.substr(space + 1, colon - space - 1);
}

}  // namespace

MeasureStatus StatusOfRunnerError(const std::string& message) {
  const std::string stage = RunnerErrorStage(message);
  if (stage == "build") return MeasureStatus::kCompileFailed;
  if (stage == "guard") return MeasureStatus::kVerifyFailed;
  return MeasureStatus::kLaunchFailed;
}

bool DeviceLostIn(const std::string& detail) {
  const std::string timing = "timing: ";
  return RunnerErrorStage(detail.rfind(timing, 0) == 0 ? detail.substr(timing.size()) : detail) == "lost";
}

}  // namespace skintune::internal::tuner_internal
