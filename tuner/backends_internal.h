// skintune (internal to tuner/): what the tuner's one Backend
// (device_backend.cpp, over the runtime's runner driver) is made of: the
// dataset cache, the one Measure procedure (verify, then time) written over a
// small executor interface, the rotation rule, the injected faults' kernel
// edits, and the factory DiscoverBackends calls.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "generator/constraints.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "model/asset.h"
#include "model/scene.h"
#include "reference/skinning.h"
#include "runtime/backend_table.h"
#include "runtime/runner.h"
#include "generator/copy_kernel.h"
#include "tuner/backend.h"
#include "tuner/statistics.h"

namespace skintune::internal::tuner_internal {

// ---------------------------------------------------------------- rotation rule

// The last-level cache assumed when a device does not report one.
inline constexpr std::uint64_t kUnknownLastLevelCacheBytes = 64ull << 20;

// Input sets to rotate among while timing, so that no repetition finds its
// inputs in cache: K = ceil(2 * LLC / bytes_per_set), clamped to
// 1..max_input_sets (at least 1 whatever max_input_sets says), with LLC =
// last_level_cache_bytes, or kUnknownLastLevelCacheBytes when that is 0;
// then made even (one up, or one down at max_input_sets) when above 1, so
// the two lanes of CUDA and OpenCL bursts never share a set.
int InputSetsFor(std::uint64_t last_level_cache_bytes, std::uint64_t bytes_per_set, int max_input_sets);

// ---------------------------------------------------------------- datasets

// The scenes a backend measures on, made once per key (model/scene.h): a
// synthetic dataset key or a glTF path (.gltf / .glb), K instances of one
// ("25k-b4-x64"), or a batch ("a.gltf+25k-b2", "mix1600k-b4"), with, per
// weight format and normals, the float64 gold of the verification frame and,
// per normals, the gold of the unquantised source. Golds hold the whole
// scene's output in the kernel's order: instance after instance, or mesh after
// mesh of a batch; each part (an instance, a batch's mesh) is compared on its own.
class DatasetCache {
 public:
  // A part of a scene's output, verified against its own gold.
  struct Part {
    std::string name;         // "" (one mesh), "instance 3", "meshes[2] (Fox.gltf)"
    std::size_t first = 0;    // its first vertex in the scene's output
    std::size_t count = 0;    // its vertices
    double diagonal = 0.0;    // BoundingBoxDiagonal of its rest positions
  };
  struct Entry {
    SkinnedScene scene;
    // The verification frame's palette as the kernel reads it: instance
    // after instance (K x joints), a batch's meshes one after another.
    std::vector<glm::mat4> verification_palette;
    std::vector<Part> parts;
    std::map<std::pair<int, bool>, GoldResult> gold;  // (weight format, normals)
    std::map<bool, GoldResult> source_gold;           // normals
    std::map<std::pair<int, bool>, double> quantisation;  // (weight format, normals): gold vs source gold, / diagonal
    std::map<int, std::vector<std::vector<glm::mat4>>> frames;  // ScenePalettes by count
    // The last few packings (PackingKey, its packed mesh), newest last.
    std::vector<std::pair<std::string, PackedMesh>> packings;
    const SkinnedMesh& mesh() const { return scene.mesh(); }
    int instances() const { return scene.spec.instances; }
  };
  // Throws Error for a malformed key or a glTF file that cannot be imported.
  Entry& Get(const std::string& key);
  // The gold of `variant`'s quantised mesh at the verification frame.
  const GoldResult& Gold(Entry& entry, const Variant& variant);
  // The gold of the unquantised source mesh (the weights as the dataset has them).
  const GoldResult& SourceGold(Entry& entry, bool normals);
  // The largest over the parts of MaxDistance(Gold, SourceGold) of the
  // positions / the part's diagonal: what `variant`'s weight format alone
  // moves them, relative (0 when it holds the weights exactly).
  double QuantisationError(Entry& entry, const Variant& variant);
  // ScenePalettes(entry.scene, count), made once per count.
  const std::vector<std::vector<glm::mat4>>& Frames(Entry& entry, int count);
  // Pack(entry.mesh(), variant), reused from a variant of the same packing
  // (PackingKey): the variants of one packing differ in their kernels only.
  // The cached packing itself, its `variant` set to `variant`, not a copy (a
  // 6400k-vertex packing is ~200 MB: copying it cost 85 ms a measurement,
  // and compile-ahead packs every variant it announces): valid, and of
  // `variant`, until the next call. Throws Error (naming `variant`) when it
  // cannot be packed.
  const PackedMesh& Packed(Entry& entry, const Variant& variant);

 private:
  std::map<std::string, std::unique_ptr<Entry>> entries_;
};

bool IsGltfPath(const std::string& key);

// `count` palettes of the asset's first animation at evenly spaced times
// (frame k at start + duration * (k + 0.5) / count); the rest pose, repeated,
// when the asset has no animation.
std::vector<std::vector<glm::mat4>> FramePalettes(const SkinnedAsset& asset, int count);
// `count` frames of a scene, each as the kernel reads it: one mesh's
// FramePalettes; K instances: K different frames (set s, instance k: frame
// s x K + k of count x K); a batch: each mesh's frame s, one after another.
std::vector<std::vector<glm::mat4>> ScenePalettes(const SkinnedScene& scene, int count);

// `variant`'s key with every axis the packer does not read (generator/packer.h)
// set to one value: the variants with one packing key have the same packed
// bytes. An axis not listed here counts as one that changes them.
std::string PackingKey(Variant variant);

// The variant packed for the scene's mesh (DatasetCache::Packed: valid until
// the next packing) and its kernels, one per launch (instanced for K
// instances). Throws Error when it cannot be packed or emitted.
const PackedMesh& PackScene(DatasetCache& datasets, DatasetCache::Entry& entry, const Variant& variant,
                            std::vector<KernelSource>& kernels);

// ---------------------------------------------------------------- measuring

// A kernel time (docs/TUNING.md "Kernel time"): its cold samples, taken
// until the stop rule is met or a cap is reached (SampleKernelTime).
struct KernelTime {
  std::vector<double> samples;
  Interval interval;
  bool tight = false;  // the interval met the rule (not stopped by a cap)
};
// What Measure needs from a backend's runner.
class Executor {
 public:
  struct Output {
    std::vector<std::uint8_t> positions, normals;  // packed order
    std::size_t poisoned_vertices = 0;
  };
  // A variant (or a copy) prepared for timing: its input sets on the device.
  class Timed {
   public:
    virtual ~Timed() = default;
    // Kernel-time samples (Runner::TimeCold): `untimed` cold frames, then
    // `samples` more, each its launches' device time from a flushed cache, ms.
    virtual std::vector<double> Cold(int untimed, int samples) = 0;
    // The frame time (Runner::FrameMs): `untimed` frames, then `frames`
    // issued back to back as a Skinner issues them; host ms per frame.
    virtual double FrameMs(int untimed, int frames) = 0;
    virtual std::size_t bytes_per_set() const = 0;  // device bytes of one input set
  };
  virtual ~Executor() = default;
  // One verification run: poisoned outputs and guards (the runners' Run).
  // `instances` K: instanced kernels, `palette` holding K palettes.
  virtual Output Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                     std::span<const std::uint8_t> palette, int instances) = 0;
  // Prepares one input set per palette (K palettes each for K instances).
  virtual std::unique_ptr<Timed> Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                         std::span<const std::vector<std::uint8_t>> palettes, int instances) = 0;
  // The same-size copy (generator/copy_kernel.h) moving `bytes` per frame in
  // `lang`'s API with `input_sets` sets of its own, prepared (Copy); its
  // kernel time, measured once per (language, bytes, sets) and remembered
  // (CopyTime: every variant of one size is judged against the same copy).
  virtual std::unique_ptr<Timed> Copy(Lang lang, std::size_t bytes, int input_sets) = 0;
  const KernelTime& CopyTime(Lang lang, std::size_t bytes, int input_sets, const TimingOptions& options);
  // What times a kernel-time sample on this device (DeviceApi::kernel_clock).
  virtual std::string KernelClock() const = 0;
  // The bytes the flush before each sample reads (generator/copy_kernel.h FlushBytes).
  virtual std::size_t FlushReadBytes() const = 0;

 private:
  std::map<std::string, std::unique_ptr<KernelTime>> copy_times_;
};

// Executor over the runner driver (runtime/runner.h): Run, Prepare +
// TimeCold / FrameMs with the flush of FlushBytes(`last_level_cache_bytes`),
// made once per language; copies prepared once per size and kept.
class RunnerExecutor final : public Executor {
 public:
  RunnerExecutor(Runner& runner, const DeviceIdentity& device)
      : runner_(runner),
        flush_bytes_(FlushBytes(device.last_level_cache_bytes, device.type.find("cpu") != std::string::npos)) {}
  Output Run(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::span<const std::uint8_t> palette,
             int instances) override;
  std::unique_ptr<Timed> Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                 std::span<const std::vector<std::uint8_t>> palettes, int instances) override;
  std::unique_ptr<Timed> Copy(Lang lang, std::size_t bytes, int input_sets) override;
  std::string KernelClock() const override { return runner_.api().kernel_clock(); }
  std::size_t FlushReadBytes() const override { return flush_bytes_; }
  // The flush in `lang`'s API (prepared on first use).
  const Prepared& Flush(Lang lang);

 private:
  Runner& runner_;
  std::size_t flush_bytes_;
  std::map<Lang, Prepared> flushes_;
};

// The bytes one frame of `packed` moves (inputs, outputs, palette) for K
// `instances`: what K copies of the mesh would move (an instanced kernel
// may find its one mesh in cache; the same-size copy is that of the scene's
// total bytes).
std::uint64_t FrameBytes(const PackedMesh& packed, int instances);
// `sets` frames' palettes of the scene, packed as `variant` reads them.
std::vector<std::vector<std::uint8_t>> TimedPalettes(DatasetCache& datasets, DatasetCache::Entry& data,
                                                     const Variant& variant, int sets);
// The race (Backend::Race): every variant prepared, then rounds of one
// batch of cold samples each, candidate after candidate, until JudgeRace
// decides them all (each with at least min_samples), or max_samples each,
// or max_ms per candidate of wall time. Returns each variant's samples.
std::vector<std::vector<double>> RaceWith(Executor& executor, DatasetCache& datasets, const DeviceIdentity& identity,
                                          const std::vector<Variant>& variants, const TuningDataset& dataset,
                                          const TimingOptions& options);

// Cold samples of `timed` until the stop rule is met or a cap is reached
// (`options.stop`), after `options.warmup` untimed cold frames.
KernelTime SampleKernelTime(Executor::Timed& timed, const TimingOptions& options);
// Records `t` in `m` (timing's median, interval, samples, clock, input sets,
// footprint and flush; gbps).
void RecordKernelTime(Measurement& m, const KernelTime& t, const Executor& executor, int sets, std::size_t bytes_per_set);
// The frame time: frames per repetition chosen to last about burst_ms, the
// median over `repetitions` repetitions, ms per frame; `frames` says how many.
double SampleFrameTime(Executor::Timed& timed, const TimingOptions& options, int* frames);

// The one Measure of every backend (tuner/backend.h): checks the variant
// against the device's limits and the scene (invalid), packs and emits it
// (invalid when that throws), applies the injected fault, verifies one run
// against the gold, each instance or batch mesh on its own (compile_failed /
// launch_failed / verify_failed, naming the part), then measures its
// kernel time (cold samples rotating among InputSetsFor(...) input sets,
// to the stop rule), its frame time, and the same-size copy's kernel time
// by the same method (x_copy).
Measurement MeasureWith(Executor& executor, DatasetCache& datasets, const DeviceIdentity& identity,
                        const DeviceLimits& limits, const std::vector<Lang>& languages, const Variant& variant,
                        const TuningDataset& dataset, const TimingOptions& options);

// The status a runner's Error stands for, from the stage its message names
// ("<API> <stage>: ..."): build -> compile_failed, guard -> verify_failed,
// anything else -> launch_failed.
MeasureStatus StatusOfRunnerError(const std::string& message);

// Whether a Measurement's detail is a runner's Error of stage "lost" (after
// an optional "timing: "): the device or its context is gone for this
// process (a GL context the driver reset), so no later measurement in it can
// be trusted (the tune worker then exits, and the parent measures the variant
// again in a fresh one).
bool DeviceLostIn(const std::string& detail);

// Edits an emitted kernel so that it fails as `kind` says ("compile": a
// syntax error; "wrong": vertex 0 of each launch gets x + 1; "hang": a loop
// on a volatile read of the first input that never ends), and updates its
// hash. Throws Error for another kind, or when the template no longer has
// the line the edit hooks on.
void InjectFault(KernelSource& source, const Variant& variant, const std::string& kind);

// Median (the mean of the middle two for an even count), of a non-empty list.
double Median(std::vector<double> values);

// GB/s of a copy of `bytes` (read + written) from its per-run times in ms.
double CopyGBps(std::size_t bytes, const std::vector<double>& ms);

// The copy size CopyBandwidthGBps uses: `bytes` capped at a quarter of the
// device's largest allocation (when known), rounded down to 4 KiB, at least 4 KiB.
std::size_t CopyBytesCapped(std::size_t bytes, std::uint64_t max_allocation_bytes);

// Now, UTC, ISO 8601: "2026-11-22T10:11:12Z".
std::string UtcTimestamp();

// ---------------------------------------------------------------- factory

// The Backend of a device discovery found (runtime/backend_table.h), running
// `languages`, numbered `index`. Its runner is opened on the first Measure or
// copy, so discovery in a worker that serves one device sets up only that one.
std::unique_ptr<Backend> MakeDeviceBackend(FoundDevice device, std::vector<Lang> languages, int index);

}  // namespace skintune::internal::tuner_internal
