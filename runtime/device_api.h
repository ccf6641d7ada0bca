// skintune (internal): what one GPU API gives the runner driver.
//
// The driver (runtime/runner.h) writes the orchestration once: the shape
// checks (run_shape.h), poisoned outputs and guards (output_check.h), the
// input sets of timing, the Skinner's live set, the read-back. A DeviceApi
// (one per API, in runtime/backends/<api>/) does what only its API knows:
// building a kernel (with the program cache), buffers, the palette's view for
// the variant's storage, binding a launch's arguments its own way, running
// frames (bursts) with the device's timers. Modelled on Kernel
// Tuner's Backend (ready_argument_list, compile, start/stop_event,
// run_kernel, memcpy) and CLBlast's "descriptors plus one driver".
//
// Errors are skintune::internal::Error with the message "<name()> <stage>: ...", stage
// one of setup, build, launch, guard: the tuner maps the stage to a status
// (StatusOfRunnerError) and the runtime to an ErrorCode (CodeOfRunnerError).
// The driver raises launch and guard errors with the same prefix.
//
// The driver calls MakeCurrent() at the start of each of its operations; the
// objects a DeviceApi returns are owned by the driver and released by their
// destructors, which need the API's context current (ReadyToRelease).
#pragma once

#include <cstddef>
#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"
#include "runtime/program_cache.h"
#include "runtime/run_shape.h"

namespace skintune::internal {

// Something a DeviceApi made for the driver (a buffer, a palette view, a bound
// launch); releases its native object when destroyed.
class DeviceObject {
 public:
  virtual ~DeviceObject() = default;
  // Gives the native object up without releasing it: the driver calls it on
  // every object of a set when ReadyToRelease() is false (a GL context gone).
  virtual void Forget() {}
};

class DeviceBuffer : public DeviceObject {
 public:
  explicit DeviceBuffer(std::size_t bytes) : bytes_(bytes) {}
  std::size_t bytes() const { return bytes_; }
  // The API's handle: a cl_mem, or a CUdeviceptr / GL buffer name as an integer.
  virtual void* native() const = 0;

 private:
  std::size_t bytes_;
};

// One launch of a packed mesh, as the driver plans it (count > 0).
struct LaunchSpec {
  Variant variant;                       // the mesh's
  KernelSource source;                   // the launch's kernel
  std::size_t index = 0;                 // its position in PackedMesh::launches
  std::uint32_t count = 0, first = 0;    // its vertices and the output index of the first
  std::uint32_t vertex_count = 0;        // the mesh's (instanced output stride)
  int instances = 1;                     // K
  bool instanced = false;
  std::size_t palettes_bytes = 0;        // the K palettes of one input set
  std::size_t palette_joints = 0;        // joints of one palette
  std::size_t output_stride = 0;         // bytes per output vertex
  // The launch writes what the frame's later launches read (the palette
  // kernel of an animated set, Runner::Animate): GL and Vulkan put a barrier
  // after it in every use; OpenCL and CUDA order it on their one queue or stream.
  bool feeds_frame = false;
  std::string where;                     // "launch <index> of <variant key>", for messages
};

// A launch planned by the API: its built kernel and geometry.
class PlannedLaunch {
 public:
  explicit PlannedLaunch(LaunchSpec launch) : spec(std::move(launch)) {}
  virtual ~PlannedLaunch() = default;
  LaunchSpec spec;
};

// What a buffer holds: kernels read inputs and the palette, and write outputs.
enum class BufferUse { kInput, kPalette, kOutput };

// What one kernel argument of one launch of one input set is bound to.
enum class ArgumentRole { kScalar, kInput, kPalette, kOutput };
struct ArgumentBinding {
  const KernelArgument* argument = nullptr;
  ArgumentRole role = ArgumentRole::kScalar;
  DeviceBuffer* buffer = nullptr;      // kInput, kPalette, kOutput
  DeviceObject* view = nullptr;        // kPalette: the storage's view of the buffer (null: the buffer itself)
};

// How an input set is made: Run's one set has guarded outputs; timing and
// the Skinner's sets do not, and name their buffers with a suffix.
struct SetOptions {
  bool verification = false;  // outputs followed by their guard (out_bytes + kGuardBytes)
  std::string suffix;         // appended to buffer names in messages: " (input set 2)"
};

// What a frame run is for.
enum class FrameUse {
  kVerify,  // Run: one frame, each launch timed by the device and checked by the API
  kTime,    // Time: after `untimed` frames, bursts of `burst` frames each timed as a whole, then wait
  kCold,    // TimeCold: each frame after the flush, each of its launches timed alone by the device, then wait
  kLive,    // the Skinner's frame: no timers, no wait, on the caller's queue/stream
};

// A frame is every bound launch of one input set, in launch order; `frames`
// lists the sets' launches frame after frame (a set may appear many times).
//
// kTime's bursts (docs/TUNING.md "Timing"): the frames after `untimed` are
// grouped into bursts of `burst` consecutive frames, and each burst's launches
// go to the device back to back, with nothing between them (no host wait, no
// host copy, no query that serialises), and consecutive frames may overlap
// as consecutive dispatches do in GL and Vulkan (CUDA and OpenCL alternate
// two streams / queues; frames never share a set when there are two or
// more): the burst is timed by the device from the start of its first launch
// to the end of its last. A burst divided by its frames is a frame's cost
// free of launch gaps, which per-launch timers (CUDA events around each
// launch) and one serialising stream (~2 us per dependent launch on an
// H100) would add. A last, shorter group of frames is not timed.
//
// kCold, the kernel time (docs/TUNING.md "Kernel time"): before each frame
// the `flush` launches run (a kernel that reads a buffer of at least twice the
// last-level cache and writes nothing, generator/copy_kernel.h EmitFlush), so
// the frame starts from a cache holding only clean lines of other data, the
// state Nsight Compute's default cache control leaves (OpenCL on a GPU runs
// them once per launch of the frame, so the device is still flushing while
// the host queues the launches: opencl_runner.cpp TimeCold); the frame's launches
// wait for it and for each other (in order, one queue or stream). Each frame
// (its flush and launches) is queued at once and waited for before the next
// is queued, so it starts on an idle device, as Nsight Compute replays a
// kernel: queued back to back, NVIDIA's devices started a kernel after the
// flush later in some frames than in others (CUDA 1 us later in every other
// frame, OpenCL 0.3 us; Vulkan in twelve of every sixteen frames a
// submission), and a median fell on either side as that share moved (an
// H200, December 2026). CPU devices that evict (PoCL) keep their frames
// back to back (runtime/backends/opencl/opencl_runner.cpp TimeCold). Each
// launch is timed by the device's own clock from the end of the command
// before it (the flush's last launch, or the frame's previous launch) to its
// own end: its execution and the device's start of it, which every launch in
// a dependent sequence pays, and no host time (the launches are queued while
// the flush runs).
// Measured on an H100 (November 2026): the kernels' own START-to-END spans
// differ between APIs by a fixed ~1-3 us (NVIDIA's OpenCL START/END 6.2 us
// where CUPTI's kernel record spans 2.5 us for the same 25k-vertex kernel,
// and Nsight Compute's gpu__time_duration 3.8), while the end-to-end time
// is what every API's timer can stamp alike. OpenCL: a marker after the
// flush and after each launch, from the END of the one before a launch to the
// START of the one after it (an event on the launch itself costs NVIDIA's
// device 1.3-1.5 us more); CUDA: CUPTI's kernel activity
// records (events between the launches where CUPTI cannot be loaded); GL:
// GL_TIMESTAMP query counters after the flush and after each launch;
// Vulkan: timestamps after the flush and after each dispatch; the cpu
// device: the host's clock. `untimed` frames first run the same way without
// timers. Returns one vector per timed frame: each launch's time, ms, in
// launch order (their sum: the flush's end to the frame's end).
struct FrameRun {
  FrameUse use = FrameUse::kTime;
  std::vector<std::span<const std::unique_ptr<DeviceObject>>> frames;
  int untimed = 0;                 // kTime: leading frames run without timers (warm-up)
  int burst = 1;                   // kTime: frames per timed burst (>= 1)
  std::string key;                 // the variant key, for messages
  void* out_positions = nullptr;   // kLive: write positions into this native buffer instead (OpenCL-GL sharing)
  std::span<const std::unique_ptr<DeviceObject>> flush;  // kCold: the flush's bound launches, run before each frame
  // kLive: launches run once before the frames, whose writes the frames read
  // (a Skinner's palette kernel writing the palette its skin launches read):
  // ordered by each API (one in-order queue or stream in OpenCL and CUDA, a
  // barrier in GL and Vulkan, in turn on the cpu device).
  std::span<const std::unique_ptr<DeviceObject>> prologue;
  // kLive: the prologue writes what the frames queued before it may still
  // read (a set with one palette slot), so it waits for them; otherwise an
  // API may start it beside them (GL and Vulkan: RunFrames).
  bool prologue_after_frames = false;
  // Every use: the scalar arguments of the launches that take any (the
  // palette kernel's delta and fresh, in a kLive prologue or first in an
  // animated set's frame: Runner::Animate), by name, each as its 32 bits (a
  // float's bits for an f32): what each API passes with the launch itself
  // (an OpenCL kernel argument, a CUDA parameter, a GL uniform, a Vulkan push
  // constant), so that nothing is copied to the device for them.
  std::vector<std::pair<std::string, std::uint32_t>> scalars;

  // kTime: the bursts timed (frames after `untimed`, whole bursts only).
  std::size_t TimedBursts() const {
    const std::size_t timed = frames.size() - std::min<std::size_t>(frames.size(), static_cast<std::size_t>(std::max(untimed, 0)));
    return timed / static_cast<std::size_t>(std::max(burst, 1));
  }
};

// Points `slot` at `run` for as long as it lives, then back at nothing: an
// API's RunFrames keeps the run whose scalars its launches pass (ScalarOf).
class CurrentRun {
 public:
  CurrentRun(const FrameRun*& slot, const FrameRun& run) : slot_(slot) { slot_ = &run; }
  ~CurrentRun() { slot_ = nullptr; }
  CurrentRun(const CurrentRun&) = delete;
  CurrentRun& operator=(const CurrentRun&) = delete;

 private:
  const FrameRun*& slot_;
};

// What the driver does around an API's timed frames.
struct TimingPolicy {
  // Before timing, run bursts of untimed frames for at least 200 ms and until
  // two bursts in a row take the same wall time within 3% (at most 1 s): a
  // driver that lowers the clock between short bursts of work (NVIDIA's GL
  // driver on the H100: 1980 -> 345 MHz) is back at speed before the first
  // timed frame. A runner whose clock probe (a small copy) is as fast as
  // after its last warm-up is still warm: only the steadiness check
  // (runner.cpp kStillWarm).
  bool warm_until_stable = false;
};

class DeviceApi {
 public:
  virtual ~DeviceApi() = default;

  // "OpenCL", "CUDA", "GL": the first word of every error message.
  virtual const char* name() const = 0;
  virtual const std::string& device_name() const = 0;
  // Makes the API's context current on the calling thread (CUDA, GL); throws
  // Error("<name> launch|setup: ...") when it cannot be.
  virtual void MakeCurrent() {}
  // Before the driver releases a set's objects: makes the context current
  // and waits until every command queued on the device (uploads and
  // launches) has completed, so that nothing the driver still works on
  // (PoCL compiles a launch's kernel on a thread of its own) outlives the
  // objects, or the process when the program exits next. Never throws.
  // False when it cannot (then every object is Forgotten, not released).
  virtual bool ReadyToRelease() { return true; }

  // Programs are loaded from and stored to `cache` (null: none), keyed with `device_id`.
  void UseProgramCache(ProgramCache* cache, const std::string& device_id) {
    cache_ = cache;
    cache_device_id_ = device_id;
  }
  // Builds (or finds already built) `source`; throws Error("<name> build: ...").
  virtual void Build(const KernelSource& source) = 0;
  // True when Build may run on several threads at once (with MakeCurrent on
  // each): the API's context allows concurrent builds and the API guards its
  // own table of built kernels. The tuner then compiles ahead into the
  // measuring runner itself instead of into runners of its own.
  virtual bool ConcurrentBuilds() const { return false; }

  // The API's limits for a run of `shape` (instances per launch, the palette
  // in constant memory or an image): throws Error("<name> launch: ...") naming
  // the limit. Called after CheckRunShape.
  virtual void CheckRun(const PackedMesh& mesh, std::span<const KernelSource> kernels, const RunShape& shape) const = 0;
  // Bytes of a set's palette buffer: the K palettes, or more (zero-filled)
  // where the kernel declares a larger block (GL uniform blocks).
  virtual std::size_t PaletteBufferBytes(const RunShape& shape, std::span<const KernelSource> kernels) const;
  // What wrote past an output's end, for guard errors: "kernel" (GL vertex shaders: "capture").
  virtual const char* OutputWriter(const Variant& variant) const;

  // Builds the launch's kernel and plans its geometry; throws build and launch errors.
  virtual std::unique_ptr<PlannedLaunch> Plan(const LaunchSpec& spec) = 0;
  // A buffer of `bytes` (> 0) holding `initial` (null: undefined contents);
  // `what` names it in messages.
  virtual std::unique_ptr<DeviceBuffer> Allocate(BufferUse use, std::size_t bytes, const void* initial,
                                                 const std::string& what) = 0;
  // The view the variant's palette storage reads the palette through (an
  // image1d_buffer, a texture object, a texture buffer), or null when the
  // kernel reads the buffer itself.
  virtual std::unique_ptr<DeviceObject> PaletteView(const Variant& variant, DeviceBuffer& palette,
                                                    const std::string& suffix) = 0;
  // Binds one launch of one input set: every kernel argument in order (the
  // API decides how: argument slots, parameter arrays, binding points,
  // transform feedback ranges). `allocated` grows by the bytes of any buffer
  // the API adds for the launch (GL's staged captures).
  virtual std::unique_ptr<DeviceObject> Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                             const SetOptions& options, std::size_t& allocated) = 0;
  // Waits until the uploads of Prepare's input sets are done.
  virtual void FinishUploads(const std::string& key) = 0;

  // Runs `run.frames` (see FrameUse). Returns kVerify: one vector, the
  // device time of each launch in ms; kTime: one vector of one value per
  // timed burst, its device time in ms; kCold: one vector per timed frame,
  // each launch's device time in ms; kLive: nothing.
  virtual std::vector<std::vector<double>> RunFrames(const FrameRun& run) = 0;
  virtual TimingPolicy timing_policy() const { return {}; }
  // What times a kCold launch on this device (the measurement records it):
  // "OpenCL profiling START/END", "CUPTI kernel activity", ...
  virtual std::string kernel_clock() const = 0;
  // Whether kCold ignores `flush` and instead evicts each frame's own
  // buffers from every cache before it (the cpu device: clflushopt, which
  // writes back and invalidates each line in the whole coherence domain, the
  // socket's L3 included): the same clean-cold state, exact, where a flush
  // read of twice a 300 MiB L3 shared with other tenants' cores cost more than the kernel.
  // PoCL does the same with a native kernel queued in the flush's place.
  virtual bool evicts_own_buffers() const { return false; }
  // The bytes evicted so, in all (0 where the device does not evict).
  virtual std::size_t evicted_bytes() const { return 0; }
  // How the device last ran the frames of `key` (a variant key), where it
  // chooses that itself: the cpu device's threads and chunk ("16 threads x
  // 2048-vertex chunks, streaming stores"); "" elsewhere.
  virtual std::string schedule_of(const std::string& /*key*/) const { return ""; }

  // A palette's upload in two steps, so the host packs straight into
  // page-locked memory: Staging gives the buffer's own staging (buffer.bytes()
  // bytes, made on first use: CUDA cuMemHostAlloc, OpenCL a mapped
  // CL_MEM_ALLOC_HOST_PTR buffer, GL a persistently mapped buffer, Vulkan
  // host-visible memory, or the buffer itself where it is host-visible);
  // Upload queues the copy of its first `bytes` into the buffer, before any
  // launch queued later, without waiting. The driver fills a staging only
  // once every launch that read the buffer has completed (its Mark), and
  // Upload never waits. `upload_fenced`: that fence also covers the buffer's
  // last upload (a launch that read the buffer waited for it); false where
  // the buffer was uploaded and not launched since, so an API whose copy
  // reads the staging asynchronously waits in Staging for that copy first.
  virtual std::span<std::uint8_t> Staging(DeviceBuffer& buffer, const std::string& what, bool upload_fenced) = 0;
  virtual void Upload(DeviceBuffer& buffer, std::size_t bytes, const std::string& what) = 0;
  // Reads `buffer` back into `out` (its first out.size() bytes); `wait`:
  // first wait for the work queued for the caller. Run's verification reads.
  virtual void Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string& what, bool wait) = 0;
  // The Skinner's read-back: waits for the work queued so far, copies the
  // first `bytes` of `buffer` into the buffer's page-locked read-back staging
  // (made on first use; or the buffer's own mapping where it is host memory)
  // and returns those bytes, valid until the next ReadPinned of the buffer.
  virtual std::span<const std::uint8_t> ReadPinned(const DeviceBuffer& buffer, std::size_t bytes,
                                                   const std::string& what) = 0;
  // ReadPinned in chunks the host can use while later ones are still in
  // flight: queues the copies, `chunk` bytes each, and returns the staging
  // at once with `ready(end)`, which blocks until bytes [0, end) have landed
  // (callable from any thread unless `caller_only`; throws Error when the
  // copy failed). The default reads it all first (ReadPinned) and `ready`
  // returns at once. `caller_only` (GL, whose fences only the context's
  // thread can wait for): `ready` only on the thread that read, at multiples
  // of `chunk` (the chunks as queued, a multiple of the one asked for) or
  // the end.
  struct PinnedRead {
    std::span<const std::uint8_t> bytes;
    std::function<void(std::size_t end)> ready;
    bool caller_only = false;
    std::size_t chunk = 0;
  };
  virtual PinnedRead ReadPinnedChunks(const DeviceBuffer& buffer, std::size_t bytes, std::size_t chunk,
                                      const std::string& what) {
    (void)chunk;
    return {ReadPinned(buffer, bytes, what), [](std::size_t) {}};
  }
  // The palette ring's per-slot fence: `marker` (made when null, else
  // reused) is signalled once everything queued so far has completed
  // (OpenCL a marker event, CUDA an event on the Skinner's stream, GL a
  // fence sync, Vulkan the last submission). Does not wait.
  virtual void Mark(std::unique_ptr<DeviceObject>& marker, const std::string& what) = 0;
  // Blocks until `marker` is signalled.
  virtual void Wait(DeviceObject& marker, const std::string& what) = 0;
  // Whether `marker` is signalled, without blocking (the submit thread polls
  // the ring's fence with it: SubmitThread::Await). Where the API has no such
  // query, Wait, then true.
  virtual bool Signalled(DeviceObject& marker, const std::string& what) {
    Wait(marker, what);
    return true;
  }
  // True where an Upload into a buffer takes effect only after every launch
  // queued before it has read the buffer (GL: one command stream, in order;
  // only shader writes need a barrier). The palette ring's fence then need
  // only cover a slot's upload (its staging is free again once the copy ran),
  // so Mark follows each palette upload and no launch; elsewhere (CUDA and
  // OpenCL upload on a queue of their own) it follows each launch.
  virtual bool OrdersUploadsAfterLaunches() const { return false; }
  // Waits for everything queued.
  virtual void Finish() = 0;
  // True where Upload, RunFrames (kLive) and Mark may be called from a thread
  // other than the one making the API's other calls, one call at a time, in
  // order, with MakeCurrent before each (CUDA, OpenCL: Runner::UseSubmitThread).
  virtual bool SubmitsFromAnyThread() const { return false; }
  // How many live frames (RunFrames kLive) the API gathers into one
  // submission to the device before it submits them by itself (Vulkan on a
  // device skintune opened: VulkanApi::OpenFrames); 1 where each frame goes
  // to the device on its own. A loop that waits for the frame N back shares
  // submissions among at most N - 1 frames, so frames that hold no palette
  // buffer are paced at least twice this far back (Runner::AnimateFused).
  virtual std::size_t FramesPerSubmission() const { return 1; }

 protected:
  ProgramCache* cache_ = nullptr;
  std::string cache_device_id_;
};

// The value of a launch's scalar argument `name` in `run`; throws
// Error("<api> launch: ...") when the run gives none.
std::uint32_t ScalarOf(const FrameRun& run, const std::string& name, const std::string& api);

// For an API's Plan: throws Error("<api> launch: ...") when the launch's
// kernel is not of its variant's language, or (constant and local storage,
// whose kernels size the palette) was emitted for another joint count.
void CheckLaunchKernel(const LaunchSpec& spec, const std::string& api);

// `source.source_hash`, or the hash of its text when it has none.
std::string HashOf(const KernelSource& source);

}  // namespace skintune::internal
