// skintune (internal to tuner/): what a measurement needs from a device's
// runner (Executor), the one executor over the runner driver, and how kernel
// and frame times are sampled from it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/clip_packer.h"
#include "generator/copy_kernel.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "runtime/device_identity.h"
#include "runtime/runner.h"
#include "tuner/clock_guard.h"
#include "tuner/statistics.h"
#include "tuner/schedule.h"  // IsHostCpu
#include "tuner/timing_options.h"

namespace skintune::internal {
class ThreadPool;  // base/thread_pool.h
}  // namespace skintune::internal

namespace skintune::internal::tuner_internal {

// A kernel time (docs/TUNING.md "Kernel time"): its cold samples, taken
// until the stop rule is met or a cap is reached (SampleKernelTime).
struct KernelTime {
  std::vector<double> samples;
  Interval interval;
  bool tight = false;  // the interval met the rule (not stopped by a cap)
  unsigned clock_mhz = 0;  // the lowest SM clock read around the batches kept (0: not read)
};
// An animated scene's palettes, made on the device (Runner::Animate,
// docs/ANIMATION.md): the model's clips packed as the variant's animation
// axis says, their palette kernel in the variant's language, and K
// AnimInstance records per input set (RunAnimated: one, the verification's).
struct AnimatedInputs {
  const PackedAnimation* clips = nullptr;
  PaletteKernel kernel;
  std::vector<std::vector<std::uint8_t>> states;
};

// What a job (tuner/measure_job.h) needs from a device's runner.
class Executor {
 public:
  struct Output {
    std::vector<std::uint8_t> positions, normals, tangents;  // packed order
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
    // The lowest SM clock read around its batches of samples so far
    // (tuner/clock_guard.h); 0 where the device's clock is not read.
    virtual unsigned ClockMhz() const { return 0; }
    // An animated scene's (PrepareAnimated): each timed sample's first
    // launch, the palette kernel's own time, ms; empty elsewhere.
    virtual std::vector<double> PaletteKernelMs() const { return {}; }
  };
  virtual ~Executor() = default;
  // One verification run: poisoned outputs and guards (the runners' Run).
  // `instances` K: instanced kernels, `palette` holding K palettes.
  virtual Output Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                     std::span<const std::uint8_t> palette, int instances) = 0;
  // Prepares one input set per palette (K palettes each for K instances).
  virtual std::unique_ptr<Timed> Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                         std::span<const std::vector<std::uint8_t>> palettes, int instances) = 0;
  // Run and Prepare of an animated scene: the palettes (sized by `palette`,
  // `palettes`) made each frame by `animated`'s palette kernel, from each
  // set's states, as the frame's first launch (Runner::Animate). An executor
  // that cannot animate throws Error("... launch: ...").
  virtual Output RunAnimated(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                             std::span<const std::uint8_t> palette, int instances, const AnimatedInputs& animated);
  virtual std::unique_ptr<Timed> PrepareAnimated(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                                 std::span<const std::vector<std::uint8_t>> palettes, int instances,
                                                 const AnimatedInputs& animated);
  // The same-size copy (generator/copy_kernel.h) moving `bytes` per frame in
  // `lang`'s API with `input_sets` sets of its own, prepared (Copy); its
  // kernel time, measured once per (language, bytes, sets) and remembered
  // (CopyTime: every variant of one size is judged against the same copy).
  virtual std::unique_ptr<Timed> Copy(Lang lang, std::size_t bytes, int input_sets) = 0;
  const KernelTime& CopyTime(Lang lang, std::size_t bytes, int input_sets, const TimingOptions& options);
  // What times a kernel-time sample on this device (DeviceApi::kernel_clock).
  virtual std::string KernelClock() const = 0;
  // How the device last ran `key`'s frames where it chooses that itself
  // (DeviceApi::schedule_of: the cpu device's threads and chunk); "" elsewhere.
  virtual std::string ScheduleOf(const std::string& /*key*/) const { return ""; }
  // How the runner's context was chosen where the tuner chose it among
  // several (tuner/runner_device.h OpenMeasuringRunner); "" elsewhere.
  virtual std::string ContextChoice() const { return ""; }
  // The context's launch start, ms (OpenMeasuringRunner); 0 where not probed.
  virtual double LaunchStartMs() const { return 0.0; }
  // The bytes the flush before each sample reads (generator/copy_kernel.h
  // FlushBytes); 0 where the device evicts each frame's own buffers instead.
  virtual std::size_t FlushReadBytes() const = 0;
  // Whether the device evicts each sample's own buffers from every cache
  // instead of a flush (DeviceApi::evicts_own_buffers: the cpu device).
  virtual bool EvictsOwnBuffers() const { return false; }

 private:
  std::map<std::string, std::unique_ptr<KernelTime>> copy_times_;
};

// The flush of a GPU API run on the host's CPU (HostFlushes: llvmpipe's GL,
// lavapipe's Vulkan), done by the host: `bytes` of its own buffer read by
// one thread per core, each core its share, so every core's caches and the
// shared last-level cache hold only clean lines of that buffer, as the
// device's own flush kernel leaves them. That kernel ran at the rasterizer's
// compute speed: on llvmpipe (2-core machine, 2026-11-28) reading 32 MiB
// took ~9 ms a sample, 3-4 times the kernel being timed, and most of a
// default run's time on that machine.
class HostFlush {
 public:
  explicit HostFlush(std::size_t bytes);
  ~HostFlush();
  HostFlush(const HostFlush&) = delete;
  HostFlush& operator=(const HostFlush&) = delete;
  void operator()();
  std::size_t bytes() const { return words_.size() * sizeof(std::uint64_t); }

 private:
  std::vector<std::uint64_t> words_;
  std::unique_ptr<ThreadPool> threads_;
};

// Executor over the runner driver (runtime/runner.h): Run, Prepare +
// TimeCold / FrameMs with the flush of FlushBytes(`last_level_cache_bytes`),
// made once per language; copies prepared once per size and kept. On a
// device whose memory is the host's the host flushes (HostFlush) and the
// device's flush is a launch of kAnchorBytes that only starts the frame's time.
// Whether `device` is flushed by the host (HostFlush): a software rasterizer
// (IsSoftwareRasterizer: a GL or Vulkan device on the host's CPU). PoCL and
// skintune's cpu device evict each frame's own buffers instead
// (DeviceApi::evicts_own_buffers), in one submission of many frames; flushed
// by the host, a sample at a time, PoCL's kernel times took 1.4-1.7 times as
// long to sample on the H200 machine's 16-core host (2026-11-28).
bool HostFlushes(const DeviceIdentity& device);

class RunnerExecutor final : public Executor {
 public:
  static constexpr std::size_t kAnchorBytes = 4096;
  RunnerExecutor(Runner& runner, const DeviceIdentity& device);
  // With `clock` read around each batch of samples instead of the one the
  // device's driver tells (null: none): the tests' stand-in.
  RunnerExecutor(Runner& runner, const DeviceIdentity& device, std::unique_ptr<DeviceClock> clock);
  ~RunnerExecutor() override;
  Output Run(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::span<const std::uint8_t> palette,
             int instances) override;
  std::unique_ptr<Timed> Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                 std::span<const std::vector<std::uint8_t>> palettes, int instances) override;
  Output RunAnimated(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::span<const std::uint8_t> palette,
                     int instances, const AnimatedInputs& animated) override;
  std::unique_ptr<Timed> PrepareAnimated(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                         std::span<const std::vector<std::uint8_t>> palettes, int instances,
                                         const AnimatedInputs& animated) override;
  std::unique_ptr<Timed> Copy(Lang lang, std::size_t bytes, int input_sets) override;
  std::string KernelClock() const override { return runner_.api().kernel_clock(); }
  std::string ScheduleOf(const std::string& key) const override { return runner_.api().schedule_of(key); }
  std::string ContextChoice() const override { return context_choice_; }
  double LaunchStartMs() const override { return launch_start_ms_; }
  void SetContext(std::string choice, double launch_start_ms) {
    context_choice_ = std::move(choice);
    launch_start_ms_ = launch_start_ms;
  }
  std::size_t FlushReadBytes() const override { return flush_bytes_; }
  bool EvictsOwnBuffers() const override { return runner_.api().evicts_own_buffers(); }
  // The flush in `lang`'s API (prepared on first use): the anchor launch
  // where the host flushes.
  const Prepared& Flush(Lang lang);
  // Releases the flushes prepared so far: the next sample prepares its own
  // (skintune_bench_kernel_time's reflush step).
  void ReleaseFlushes() { flushes_.clear(); }
  // The host's flush before each sample, or none: the device flushes itself.
  std::function<void()> BeforeEachSample();
  // The GPU's clock around each batch of samples (inactive where it is not read).
  ClockGuard& clock() { return clock_; }

 private:
  Runner& runner_;
  std::string context_choice_;  // ContextChoice
  double launch_start_ms_ = 0.0;  // LaunchStartMs
  std::size_t flush_bytes_;
  std::unique_ptr<HostFlush> host_flush_;
  std::map<Lang, Prepared> flushes_;
  ClockGuard clock_;
};

// Wraps the executor a device measures through in another that adds to what
// it does (tuner/fault_injection.h breaks one variant's kernels for the
// failure tests); `device` is the device it runs on.
using ExecutorDecorator = std::function<std::unique_ptr<Executor>(std::unique_ptr<Executor> inner, const DeviceIdentity& device)>;

// Cold samples of `timed` until the stop rule is met or a cap is reached
// (`options.stop`), after `options.warmup` untimed cold frames; each sample
// the quickest of `options.frames_per_sample` cold frames (ColdSamples).
KernelTime SampleKernelTime(Executor::Timed& timed, const TimingOptions& options);
// `samples` kernel-time samples of `timed`, each the quickest of `frames`
// (>= 1) cold frames, a sample's frames spread over the batch (sample j of
// n: frames j, j + n, j + 2n, ...) rather than taken in a row. On the host's
// CPU a neighbour's thread that preempts one of the frame's threads doubles
// the frame (TimingOptions::host_frames_per_sample); the quickest of three
// frames is that kernel's time unless all three were hit.
std::vector<double> ColdSamples(Executor::Timed& timed, int samples, int frames);
// The frame time: frames per repetition chosen to last about burst_ms, the
// median over `repetitions` repetitions, ms per frame; `frames` says how many.
double SampleFrameTime(Executor::Timed& timed, const TimingOptions& options, int* frames);

// Median (the mean of the middle two for an even count), of a non-empty list.
double Median(std::vector<double> values);

// GB/s of a copy of `bytes` (read + written) from its per-run times in ms.
double CopyGBps(std::size_t bytes, const std::vector<double>& ms);

// The copy size CopyBandwidthGBps uses: `bytes` capped at a quarter of the
// device's largest allocation (when known), rounded down to 4 KiB, at least 4 KiB.
std::size_t CopyBytesCapped(std::size_t bytes, std::uint64_t max_allocation_bytes);

// The device's copy bandwidth as a tuning run measures it before the
// device's first measurement (TunedDevice::CopyBandwidthGBps). The bytes
// each of the probe copy's source and destination hold: together four times
// the last-level cache, so the copy streams from memory (a larger one cost a
// CPU device seconds of allocation and first touch).
std::size_t ProbeCopyBytes(const DeviceIdentity& d);
// GB/s of `copy` (an Executor::Copy of 2 x `bytes` in one set, `bytes` from
// CopyBytesCapped(ProbeCopyBytes(...))): its kernel time by the same method
// as every variant's (the flush, then each copy alone), a short stop rule.
double ProbeCopyGBps(Executor::Timed& copy, std::size_t bytes);

}  // namespace skintune::internal::tuner_internal
