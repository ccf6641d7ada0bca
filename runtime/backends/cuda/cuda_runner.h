// skintune (internal): runs emitted CUDA kernels on a packed mesh, with the
// checks a tuner needs to trust a result; the CUDA twin of OpenClRunner.
//
// - CUDA is loaded at run time (runtime/backends/cuda/cuda_api.h): this builds everywhere
//   and the constructor throws Error("CUDA setup: ...") where there is no
//   driver or device.
// - Build: each distinct KernelSource is compiled once per runner with NVRTC
//   to PTX for the device's architecture (NvrtcArchFor) and loaded with
//   cuModuleLoadDataEx; a failure throws Error("CUDA build ...") with the
//   first lines of the NVRTC log, or of the driver's JIT log.
// - Outputs are POISONED before every run (every 32-bit word 0x7fc00000, a
//   quiet NaN), so a vertex a kernel forgets to write reads back as NaN.
// - Each output buffer is followed by a GUARD of kGuardBytes filled with a
//   known pattern; a kernel that writes past the end throws Error("CUDA
//   guard ...") after the run. (Poison and guard: runtime/output_check.h.)
// - Every Launch of the PackedMesh runs with its own kernel, blocks of the
//   kernel's wg_size, arguments bound by name from the kernel's argument list
//   (docs/VARIANTS.md order). The palette: a device buffer (local, global);
//   for `constant` storage the rows are also copied into the module's
//   __constant__ symbol `skintune_palette` (cuModuleGetGlobal; the kernel's
//   `palette` argument gets the buffer but is not read); for `image` storage
//   the argument is a texture object over the buffer (linear, float4 texels).
// - Instances (docs/VARIANTS.md "Instancing"): with instanced kernels one run
//   skins K instances, each launch a grid (blocks, K) over the K palettes
//   (one buffer, one after another; `constant`: the symbol, sized for the
//   kernel's max_instances); the outputs hold K x vertex_count vertices,
//   instance after instance, the guard after them. K above the grid's y
//   limit or the texture width throws Error("CUDA launch ...") naming it.
// - Per-launch times from CUDA events recorded around each cuLaunchKernel.
// - Timing (the tuner's): Prepare uploads K input sets once (copies of every
//   launch's inputs, one palette each, outputs of their own); Time runs frames
//   rotating among them between CUDA events, uploading, poisoning and reading
//   back nothing (`constant` storage: the set's palette is copied into the
//   module's symbol before each frame, outside the events).
// - Skinning (the runtime's Skinner): a Prepared set is also a live set of
//   device buffers: WritePalette replaces a set's palettes, LaunchSet runs its
//   launches once on the runner's stream, ReadOutput waits for the stream and
//   reads an output back, OutputBuffer gives the CUdeviceptr. Prepared
//   outputs start POISONED like Run's. `constant` storage: LaunchSet copies
//   the set's palette buffer into the module's symbol on the stream before
//   each launch (the module, and its symbol, is shared by every set and
//   Skinner of the same kernel).
// - Program cache (UseProgramCache): NVRTC's PTX is loaded from / stored to
//   the cache, keyed by device, source hash, architecture and options
//   (CompilePtxCached); the driver still JIT-compiles PTX to the device's
//   code at module load (it keeps its own cache of that).
// Errors name the stage: "CUDA setup", "build", "launch" or "guard". A kernel
// that faults (an illegal address) leaves the CUDA context unusable: later
// runs of the same runner fail too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "runtime/program_cache.h"

namespace skintune {

struct CudaRunResult {
  std::vector<std::uint8_t> positions;  // K x vertex_count x output_stride_bytes, packed order, instance after
                                        // instance (Unpack each instance's part)
  std::vector<std::uint8_t> normals;    // likewise; empty without normals
  std::vector<double> launch_ms;        // per launch, CUDA event elapsed time
  std::size_t poisoned_vertices = 0;    // output vectors (positions, normals) still holding the poison
};

// What the driver says about a device, without a context (QueryCudaDevice).
struct CudaDeviceInfo {
  int index = 0;
  std::string name;
  int major = 0, minor = 0;                  // compute capability
  std::string arch;                          // NvrtcArchFor(major, minor); empty when NVRTC is older
  int multiprocessors = 0;
  int clock_khz = 0;
  std::uint64_t total_memory_bytes = 0;      // cuDeviceTotalMem (0 when the driver lacks it)
  std::uint64_t l2_cache_bytes = 0;
  int driver_version = 0;                    // cuDriverGetVersion: 13000 = CUDA 13.0
  DeviceLimits limits;                       // threads per block, static __shared__, __constant__, texture width
};

// Throws Error("CUDA setup: ...") when there is no NVRTC, no driver or no such device.
CudaDeviceInfo QueryCudaDevice(int device_index);

// NVRTC's PTX of `source` for `arch` ("compute_90"), from `cache` when it
// holds it (key: device_id, source hash, arch), else compiled and stored
// there; counts a build or a disk hit. Needs NVRTC only, not a driver.
// Throws Error("CUDA build: ...") with the NVRTC log when it does not compile.
std::string CompilePtxCached(const KernelSource& source, const std::string& arch, ProgramCache* cache,
                             const std::string& device_id);

// The device buffers of one variant for timing (CudaRunner::Prepare):
// input_sets() sets, each a copy of every launch's packed inputs, its own
// palette and its own outputs. Move-only; must not outlive its runner.
class CudaPrepared {
 public:
  CudaPrepared();
  ~CudaPrepared();
  CudaPrepared(CudaPrepared&&) noexcept;
  CudaPrepared& operator=(CudaPrepared&&) noexcept;
  int input_sets() const;
  std::size_t bytes_per_set() const;  // device bytes of one set: inputs + palette + outputs

  struct Impl;

 private:
  friend class CudaRunner;
  std::unique_ptr<Impl> impl_;
};

class CudaRunner {
 public:
  // CUDA device `device_index` (0 .. Probe().device_count - 1), through its
  // primary context. Throws Error("CUDA setup: ...") when there is no NVRTC,
  // no driver, or no such device.
  explicit CudaRunner(int device_index = 0);
  // A context and stream the caller made (CUcontext, CUstream; a null stream
  // is the legacy default stream), neither retained: they must outlive the
  // runner. Its launches and copies go to that stream. Throws Error("CUDA
  // setup: ...") without a driver or NVRTC, or for a null context.
  CudaRunner(void* cu_context, void* cu_stream);
  ~CudaRunner();
  CudaRunner(const CudaRunner&) = delete;
  CudaRunner& operator=(const CudaRunner&) = delete;

  const std::string& device_name() const;
  const std::string& arch() const;  // what NVRTC compiles for, e.g. "compute_90"
  // The device's limits for CheckVariant: threads per block, static __shared__
  // and __constant__ bytes, linear texture width in texels.
  const DeviceLimits& limits() const;
  const CudaDeviceInfo& info() const;

  // NVRTC's PTX loads from and stores to `cache` (null: none), keyed with
  // `device_id`; the cache must outlive the runner.
  void UseProgramCache(ProgramCache* cache, const std::string& device_id);

  // Builds (or finds already built) `source`; throws Error("CUDA build ...").
  void Build(const KernelSource& source);

  // Emits the variant's kernel for every launch (Emit(variant, launch.influences,
  // palette_joints)) and runs them. `palette`: PackPalette bytes; empty = mesh.palette.
  CudaRunResult Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette = {});

  // Emits the variant's instanced kernel for every launch and skins
  // `instances` (K >= 1) instances in one launch per launch of the mesh.
  // `palettes`: K PackPalette byte runs one after another; empty = mesh.palette
  // for every instance.
  CudaRunResult RunInstanced(const PackedMesh& mesh, int instances, std::span<const std::uint8_t> palettes = {});

  // Runs with the given kernels, one per launch, in launch order; instanced
  // kernels skin `instances` instances (`palette` holds K palettes), plain
  // ones need instances == 1 (runtime/run_shape.h lists the errors).
  CudaRunResult Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                    std::span<const std::uint8_t> palette = {}, int instances = 1);

  // Timing. Uploads one input set per palette (PackPalette bytes; one frame
  // each): copies of every launch's packed inputs, that palette (and its
  // texture object), and outputs of its own (not poisoned, never read back);
  // builds `kernels` (one per launch, in launch order). Instanced kernels:
  // each entry of `palettes` holds `instances` palettes and each frame skins
  // them all. Throws Error ("build", "launch") like Run.
  CudaPrepared Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                       std::span<const std::vector<std::uint8_t>> palettes, int instances = 1);

  // Runs `warmup` untimed frames, then `repetitions` timed ones; frame f (warm-up
  // frames counted) reads and writes set f % input_sets(). Returns one time per
  // timed frame: the sum over its launches of the CUDA event time around each
  // launch, ms.
  std::vector<double> Time(const CudaPrepared& prepared, int warmup, int repetitions);

  // Skinning with a prepared set (see the top of this file): WritePalette
  // copies `palettes` (the set's K palettes) and enqueues their upload;
  // LaunchSet enqueues every launch of set `set`; ReadOutput waits for the
  // stream and copies the set's positions (or normals) into `out`
  // (K x vertex_count x output_stride_bytes, packed order).
  void WritePalette(CudaPrepared& prepared, int set, std::span<const std::uint8_t> palettes);
  void LaunchSet(const CudaPrepared& prepared, int set);
  void ReadOutput(const CudaPrepared& prepared, int set, bool normals, std::span<std::uint8_t> out);
  // Waits for everything queued on the runner's stream.
  void Finish();
  unsigned long long OutputBuffer(const CudaPrepared& prepared, int set, bool normals) const;  // 0: none

  // A plain copy (one uint4 per thread) between two buffers of `bytes`
  // (rounded down to a multiple of 16; the source holds a non-zero pattern):
  // `warmup` untimed then `repetitions` timed runs, CUDA event time in ms each.
  std::vector<double> TimeCopy(std::size_t bytes, int warmup, int repetitions);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace skintune
