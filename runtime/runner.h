// skintune (internal): the runner driver: runs emitted kernels on a packed
// mesh with the checks a tuner needs to trust a result, written once over a
// DeviceApi (runtime/device_api.h) that each API implements in
// runtime/backends/<api>/ (OpenClRunner, CudaRunner and GlRunner are this
// class on their API).
//
// - Build: each distinct KernelSource is built once per runner (the API's
//   program cache: runtime/program_cache.h); a failure throws
//   Error("<API> build: ...") with the first lines of the log.
// - Run (verification): outputs are POISONED (every 32-bit word 0x7fc00000, a
//   quiet NaN), so a vertex a kernel forgets to write reads back as NaN, and
//   each is followed by a GUARD of kGuardBytes; a kernel (or a capture) that
//   writes past the end throws Error("<API> guard: ..."). (runtime/output_check.h.)
// - Every Launch of the PackedMesh runs with its own kernel (bucketed: one
//   specialised per influence count), its arguments bound by name from the
//   kernel's argument list (docs/VARIANTS.md order); the palette through the
//   view the variant's storage needs.
// - Instances (docs/VARIANTS.md "Instancing"): with instanced kernels one run
//   skins K instances, each launch over the K palettes (one buffer, one
//   after another); the outputs hold K x vertex_count vertices, instance
//   after instance, the guard after them. runtime/run_shape.h lists the
//   shape errors; the API names the device limit a run exceeds.
// - Timing (the tuner's): Prepare uploads one input set per palette (copies
//   of every launch's inputs, that palette, outputs of their own, poisoned
//   but unguarded); Time runs frames rotating among them, uploading,
//   poisoning and reading back nothing, in bursts timed as a whole by the
//   device (launch-gap free); verify with Run first. PrepareCopy prepares the
//   same-size copy (generator/copy_kernel.h) the same way.
// - Skinning (the runtime's Skinner): a Prepared set is also a live set of
//   device buffers, prepared with N palette buffers (the palette ring; a
//   Skinner's SkinnerOptions::palette_buffers), each with its own bound launches over the set's one copy of the
//   inputs and outputs. WritePalette for frame n+1 uploads into the slot
//   after frame n's, asynchronously from that slot's page-locked staging
//   (DeviceApi::Write), so it never overwrites a palette a queued frame still
//   reads; it waits only when that slot's last frame, N frames back, has
//   not completed (its DeviceApi::Mark). LaunchSet queues the
//   launches of the last written slot on the caller's queue and marks the
//   slot; nothing else waits. ReadOutput waits and reads an output back
//   through page-locked staging; OutputBuffer gives the native buffer.
// Errors name the stage: "<API> setup", "build", "launch" or "guard".
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"
#include "generator/palette_kernel.h"
#include "runtime/device_api.h"
#include "runtime/program_cache.h"
#include "runtime/submit_thread.h"

namespace skintune::internal {

struct RunResult {
  std::vector<std::uint8_t> positions;  // K x vertex_count x output_stride_bytes, packed order, instance after
                                        // instance (Unpack each instance's part)
  std::vector<std::uint8_t> normals;    // likewise; empty without normals
  std::vector<std::uint8_t> tangents;   // likewise; empty without tangents
  std::vector<double> launch_ms;        // per launch, the device's time
  std::size_t poisoned_vertices = 0;    // output vectors (positions, normals, tangents) still holding the poison

  std::vector<std::uint8_t>& Bytes(Output o) {
    return o == Output::kPositions ? positions : o == Output::kNormals ? normals : tangents;
  }
};

// The device buffers of one variant (Runner::Prepare): input_sets() sets,
// each a copy of every launch's packed inputs, its own palette and its own
// outputs. Move-only; must not outlive its runner.
class Prepared {
 public:
  Prepared();
  ~Prepared();
  Prepared(Prepared&&) noexcept;
  Prepared& operator=(Prepared&&) noexcept;
  int input_sets() const;
  std::size_t bytes_per_set() const;  // device bytes of one set: inputs + palette + outputs (+ staging)
  std::size_t output_bytes(Output output = Output::kPositions) const;  // K x vertex_count x the output's stride

  struct Impl;

 private:
  friend class Runner;
  std::unique_ptr<Impl> impl_;
};

// SKINTUNE_TIMING_LOG=FILE: a diagnostic log of the timing method's
// decisions (warm-ups, bursts, the host's wall time per frame) and, from the
// tuner, each measurement's phases. The file ("-": standard error), or null
// when unset.
const char* TimingLogPath();
// Appends "<unix time> <line>" to the log (nothing when it is off).
void AppendTimingLog(const std::string& line);
// Appends `line()`, built only when the log is on.
template <typename Line>
void TimingLog(Line&& line) {
  if (TimingLogPath()) AppendTimingLog(line());
}

// The most frames one timed burst holds (Runner::BurstFrames).
inline constexpr int kMaxBurstFrames = 1024;

// The default depth of a Skinner's palette ring (the palette ring above;
// SkinnerOptions::palette_buffers, whose default kDefaultPaletteBuffers
// skinner.cpp checks is this): frames that may be queued at once before
// SetPalette waits for the oldest. Three, as engines buffer frames in flight:
// the frame the device skins, the one queued behind it, and the one the host
// is writing.
inline constexpr int kPaletteSlots = 3;

// The seconds an animated set's clocks advance per frame in FrameMs: a 60 Hz frame.
inline constexpr float kFrameDelta = 1.0f / 60.0f;

class Runner {
 public:
  explicit Runner(std::unique_ptr<DeviceApi> api);
  virtual ~Runner();
  Runner(const Runner&) = delete;
  Runner& operator=(const Runner&) = delete;

  DeviceApi& api() const { return *api_; }
  const std::string& device_name() const { return api_->device_name(); }

  // Builds load from and store to `cache` (null: none), keyed with `device_id`;
  // the cache must outlive the runner.
  void UseProgramCache(ProgramCache* cache, const std::string& device_id);

  // Builds (or finds already built) `source`; throws Error("<API> build ...").
  void Build(const KernelSource& source);
  // True when Build may be called from several threads at once (OpenCL,
  // CUDA: DeviceApi::ConcurrentBuilds), the runner's other calls staying on one.
  bool ConcurrentBuilds() const { return api_->ConcurrentBuilds(); }

  // The tuner's runners: the buffers of timed sets (never a verification's:
  // those of Prepare with SetOptions::verification; never a Skinner's palette
  // ring) are kept, up to `max_bytes`, and set k of a later Prepare binds
  // them instead of allocating and uploading its own: an input or a palette
  // of the same name and bytes, an output of the same name and size (a timed
  // output's bytes are never read). The variants of one packing (they differ
  // in palette storage or work-group size only) then upload their 8 input
  // sets once, and no later variant allocates an output or a palette. Inputs
  // and palettes are never written by a kernel; each set still has buffers
  // of its own, so the footprint rule (input sets beyond twice the cache)
  // holds. Uses of one kept buffer never overlap: a runner times one
  // Prepared at a time.
  void ShareTimedInputs(std::size_t max_bytes);

  // Emits the variant's kernel for every launch (Emit(variant, launch.influences,
  // palette_joints)) and runs them. `palette`: PackPalette bytes; empty = mesh.palette.
  RunResult Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette = {});

  // Emits the variant's instanced kernel for every launch and skins
  // `instances` (K >= 1) instances in one launch per launch of the mesh.
  // `palettes`: K PackPalette byte runs one after another (instance i's at
  // i x palette size); empty = mesh.palette for every instance.
  RunResult RunInstanced(const PackedMesh& mesh, int instances, std::span<const std::uint8_t> palettes = {});

  // Runs with the given kernels, one per launch, in launch order; instanced
  // kernels skin `instances` instances (`palette` holds K palettes), plain
  // ones need instances == 1 (runtime/run_shape.h lists the errors).
  RunResult Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                std::span<const std::uint8_t> palette = {}, int instances = 1);
  // The same with the palettes made on the device (the tuner's animated data
  // sets): Animate(`animation`, `kernel`) on the run's set, `states` (K
  // AnimInstance records) uploaded as a frame's instances, then the frame
  // with the palette kernel first (its time first in launch_ms). `palette`
  // only sizes the palettes the kernel writes.
  struct Animated {
    const AnimationView* animation = nullptr;
    const PaletteKernel* kernel = nullptr;
    std::span<const std::uint8_t> states;
  };
  RunResult Run(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::span<const std::uint8_t> palette,
                int instances, const Animated& animated);

  // Timing. Uploads one input set per palette (PackPalette bytes; one frame
  // each) and builds `kernels` (one per launch, in launch order). Instanced
  // kernels: each entry of `palettes` holds `instances` palettes and each
  // frame skins them all. Throws Error ("build", "launch") like Run.
  // `palette_slots` (>= 1): palette buffers per set, the Skinner's ring
  // (SkinnerOptions::palette_buffers); timing uses the first only.
  Prepared Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                   std::span<const std::vector<std::uint8_t>> palettes, int instances = 1, int palette_slots = 1);

  // Runs `warmup` untimed frames, then `bursts` bursts of `burst_frames`
  // frames each (>= 1; FrameRun in device_api.h): a burst's launches go to
  // the device back to back and are timed as a whole by its timers, free of
  // launch gaps. Frame f (warm-up frames counted) reads and writes set
  // f % input_sets(). Nothing is uploaded or read back. Returns one time per
  // burst: its device time divided by its frames, ms. (The API may warm up
  // further: TimingPolicy.)
  std::vector<double> Time(const Prepared& prepared, int warmup, int bursts, int burst_frames = 1);

  // Frames per burst so that a burst takes about `burst_ms` of device time
  // (0.71 to 1.41 x): after `warmup` frames, three bursts of one frame are
  // timed and their median decides; the power of two nearest on a log
  // scale, 1..kMaxBurstFrames (so that variants of one data set share a few
  // burst lengths, and the tuner times each same-size copy once per length,
  // not once per variant).
  int BurstFrames(const Prepared& prepared, int warmup, double burst_ms);

  // The copy every measurement is judged against (generator/copy_kernel.h):
  // EmitCopy(lang, bytes) prepared with `input_sets` sets of its own, to be
  // timed by Time like any kernel (the same rotation, the same bursts).
  Prepared PrepareCopy(Lang lang, std::size_t bytes, int input_sets);

  // The kernel time (docs/TUNING.md "Kernel time"; FrameUse::kCold):
  // PrepareFlush prepares the flush (generator/copy_kernel.h EmitFlush) over
  // `read_bytes` (FlushBytes of the device's last-level cache); TimeCold runs
  // `untimed` frames and then `samples` frames of `prepared`, frame f on set
  // f % input_sets(), each after the flush, and returns each timed frame's
  // kernel time: the sum of its launches' own device times, ms. (The API may
  // warm up first: TimingPolicy.) `launch_ms` (when given) receives those
  // launch times, one vector per timed frame, in launch order.
  // `before_each` (when given) is called before each timed frame, with the
  // device idle: the frames then go to the device one at a time, each after
  // `flush` (a device whose memory is the host's is flushed by the host's
  // own reads, tuner/executor.h HostFlush, and `flush` is then a launch that
  // only marks where the frame's time starts).
  Prepared PrepareFlush(Lang lang, std::size_t read_bytes);
  std::vector<double> TimeCold(const Prepared& prepared, const Prepared& flush, int untimed, int samples,
                               std::vector<std::vector<double>>* launch_ms = nullptr,
                               const std::function<void()>& before_each = {});

  // The frame time (docs/TUNING.md "Frame time"): `untimed` frames, then
  // `frames` frames of set 0 issued back to back as a Skinner issues them
  // (LaunchSet on its queue: no palette upload, no wait between frames; an
  // animated set's frame is AdvanceAnimation by kFrameDelta, then LaunchSet),
  // then a wait for the last; the host's wall time from the first timed
  // frame's issue to that wait's end, per frame, ms. Host issue included.
  double FrameMs(Prepared& prepared, int untimed, int frames);

  // Skinning with a prepared set (see the top of this file). WritePalette
  // copies `palettes` (the set's K palettes) into the next palette slot's
  // staging and queues its upload, first waiting for that slot's last frame
  // when it has not completed (only then does it block); LaunchSet queues
  // every launch of set `set` with the last written slot, writing positions
  // into `out_positions` (a native buffer of the set's output size;
  // OpenCL-GL sharing) instead of the set's own when given, and never waits;
  // ReadOutput waits for the queued work and returns the set's positions (or
  // normals, or tangents) in the API's page-locked read-back staging (K x vertex_count x
  // output_stride_bytes, packed order), valid until the next ReadOutput of
  // that output.
  void WritePalette(Prepared& prepared, int set, std::span<const std::uint8_t> palettes);
  // WritePalette in two steps, for a caller that packs the palettes itself
  // straight into page-locked memory (the Skinner): PaletteStaging waits as
  // WritePalette does and gives the next slot's staging (the set's K
  // palettes' bytes); UploadPalette queues its upload and makes it the slot
  // LaunchSet uses. A staging given and never uploaded takes no slot.
  std::span<std::uint8_t> PaletteStaging(Prepared& prepared, int set);
  void UploadPalette(Prepared& prepared, int set);
  // Morph variants: the staged slot's morph weights (K x T float32), between
  // PaletteStaging and UploadPalette, which uploads them with the palettes.
  // Its bytes are the slot's from its last upload: write them all each frame.
  std::span<std::uint8_t> MorphWeightsStaging(Prepared& prepared, int set);
  void LaunchSet(Prepared& prepared, int set, void* out_positions = nullptr);
  std::span<const std::uint8_t> ReadOutput(const Prepared& prepared, int set, Output output);
  // ReadOutput in chunks of `chunk_bytes` (DeviceApi::ReadPinnedChunks): the
  // staging at once, and `ready(end)` blocking until its first `end` bytes are in.
  DeviceApi::PinnedRead ReadOutputChunks(const Prepared& prepared, int set, Output output, std::size_t chunk_bytes);
  // Animation on the device (docs/ANIMATION.md): from now on set `set`'s
  // palettes are written by the palette kernel (generator/palette_kernel.h
  // EmitPalette of `animation`, in this runner's language, with the variant's
  // palette rows), run before the skin launches of every LaunchSet on the
  // same queue. The animation's buffers are uploaded once; each palette slot
  // gets an instances buffer of K AnimInstance records (the rest pose until
  // the first upload) and the kernel bound to write that slot's palette, run
  // by the first LaunchSet after each upload into the slot (a LaunchSet with
  // no upload since reuses the palette it computed); from
  // then on PaletteStaging, UploadPalette and WritePalette stage and upload
  // those K x 16 bytes instead of the palettes, through the same ring.
  // Time and TimeCold (the tuner's animated data sets) run the palette
  // kernel in every frame as the frame's first launch (its own time first in
  // TimeCold's `launch_ms`), on the states uploaded last, advanced by
  // nothing. Each input set may be animated once, all with the same kernel
  // and each with buffers of its own; a Prepared with any set animated takes
  // instances, not palettes, in every set (animate them all before the first
  // upload). Throws Error("<API> build|launch ...") when the kernel does not
  // build, the set is animated already, or the animation's joints and rows
  // do not fill the set's palettes exactly.
  void Animate(Prepared& prepared, int set, const AnimationView& animation, const PaletteKernel& kernel);
  // An animated set's frame without an upload: takes the next palette slot
  // as PaletteStaging does (waiting only as it does) and makes its next
  // LaunchSet's palette kernel advance the states it keeps on the device (the
  // last frame's) by `delta` seconds, each clip's clock looping in its range
  // (AdvanceAnimInstances), instead of taking the slot's uploaded ones. The
  // delta travels with the launch (FrameRun::scalars): nothing is
  // copied to the device. Throws Error for a set that is not animated.
  // A morph variant's `morph_weights` (the K instances', as MorphWeightsStaging
  // takes them) go up into the slot's weights buffer, the frame's one copy.
  // A fused set (PaletteKernel::fused) takes no slot and waits only for the
  // frame its pace reaches back to (the slots, or twice the API's frames a
  // submission where more: AnimateFused); its launches add the deltas summed
  // since the last upload to the uploaded clocks. Past kFusedRebaseSeconds from it, the states advanced
  // on the host (AdvanceAnimInstances, as the kernels advance them) go up as
  // an upload would, so that a float32 clock never drifts further.
  void AdvanceAnimation(Prepared& prepared, int set, float delta, std::span<const std::uint8_t> morph_weights = {});
  static constexpr double kFusedRebaseSeconds = 16.0;
  // The native output buffer (cl_mem; CUdeviceptr or GL buffer name as an integer); null: none.
  void* OutputBuffer(const Prepared& prepared, int set, Output output) const;
  // The palette slot LaunchSet uses next: that of the last WritePalette (tests).
  int PaletteSlot(const Prepared& prepared, int set) const;
  // Waits for everything queued.
  void Finish();

  // From now on UploadPalette and LaunchSet (without out_positions) hand
  // their driver calls to a thread of the runner's own and return
  // (DeviceOptions::submit_thread); every other call first waits until that
  // thread has made them, and an error of theirs is thrown by the next call.
  // PaletteStaging then queries a slot's fence once (DeviceApi::Signalled)
  // and, when it is not yet signalled, lets that thread poll it
  // (SubmitThread::Await) instead of waiting in the driver itself.
  // False, and nothing changes, where the API's calls cannot be made from
  // another thread (DeviceApi::SubmitsFromAnyThread). Call before Prepare.
  bool UseSubmitThread();

 private:
  // Waits until the submit thread (if any) has made every call handed to it;
  // throws the first error among them.
  void Settle();
  // The palette slot after set `set`'s current one, once no queued frame
  // still reads it (its fence; PaletteStaging and AdvanceAnimation).
  std::size_t TakeNextSlot(Prepared& prepared, int set);
  Prepared PrepareSets(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                       std::span<const std::vector<std::uint8_t>> palettes, const RunShape& shape,
                       const SetOptions& options, int palette_slots);
  void AddSet(Prepared::Impl& p, const PackedMesh& mesh, std::span<const KernelSource> kernels,
              const std::vector<std::uint8_t>& palettes, const RunShape& shape, const SetOptions& options,
              int palette_slots);
  // One launch's arguments for set `set_index`: its inputs allocated (or
  // shared) and bound, its outputs bound; the palette left to AddSet's slots.
  // `bytes` grows by the inputs' sizes.
  std::vector<ArgumentBinding> InputBindings(Prepared::Impl& p, std::size_t set_index, const LaunchSpec& spec,
                                             const Launch& launch, const SetOptions& options, std::size_t& bytes);
  // A buffer of `set` holding `content`: its own, or, under a non-empty
  // `share_key` (ShareKey), the runner's kept buffer (allocated and kept on first use).
  DeviceBuffer* SetBuffer(Prepared::Impl& p, std::size_t set_index, BufferUse use, std::span<const std::uint8_t> content,
                          const std::string& what, const std::string& share_key);
  // ShareTimedInputs' key of a timed set's buffer: "<set>|<use>|<name>|<bytes>"
  // and, for inputs and palettes, their bytes' hash; "" when not shared
  // (sharing off, or a verification set).
  std::string ShareKey(const SetOptions& options, std::size_t set, BufferUse use, const std::string& name,
                       std::span<const std::uint8_t> content);
  void ReadChecked(const Prepared::Impl& p, const PackedMesh& mesh, const RunShape& shape, RunResult& result);
  // Warms the device before timed frames (TimingPolicy::warm_until_stable):
  // 200 ms of bursts and steady, or only steady when the clock probe says the
  // device is still as fast as after its last full warm-up (runner.cpp).
  void WarmUntilStable(const Prepared::Impl& p);
  // The clock probe: the median time of a small copy (PrepareCopy in the
  // language of `p`'s kernels, made once), ms; nothing when it fails.
  std::optional<double> ProbeMs(const Prepared::Impl& p);
  // Time without the warm-up: `warmup` frames, then the bursts.
  std::vector<double> TimeFrames(const Prepared::Impl& p, int warmup, int bursts, int burst_frames);
  [[noreturn]] void Fail(const std::string& stage, const std::string& message) const;
  // Animate of a fused PaletteKernel: set `set` bound to the skin launches
  // fused with `animation` (EmitFused), no palette kernel.
  void AnimateFused(Prepared& prepared, int set, const AnimationView& animation);

  std::unique_ptr<DeviceApi> api_;
  std::unique_ptr<SubmitThread> submit_;  // after api_: stopped before it goes
  std::optional<double> warm_probe_ms_;  // the fastest clock probe right after a warm-up
  // When the device last finished timed or warm-up frames (WarmUntilStable
  // skips its probe within kStillBusyMs of it).
  std::optional<std::chrono::steady_clock::time_point> busy_until_;
  std::unique_ptr<Prepared> probe_;     // the clock probe's copy (ProbeMs)
  Lang probe_lang_ = Lang::kOpenCl;
  // ShareTimedInputs: kept buffers of timed sets, oldest first, by ShareKey.
  struct SharedBuffer {
    std::string key;
    std::shared_ptr<DeviceBuffer> buffer;
  };
  std::vector<SharedBuffer> shared_buffers_;
  std::size_t shared_bytes_ = 0, shared_max_bytes_ = 0;
  std::map<const void*, std::size_t> input_hashes_;  // within one PrepareSets: packed input -> its hash
};

}  // namespace skintune::internal
