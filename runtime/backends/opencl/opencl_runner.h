// skintune (internal): runs emitted OpenCL kernels on a packed mesh, with the
// checks a tuner needs to trust a result.
//
// - Build: each distinct KernelSource is built once per runner; a failure
//   throws Error("OpenCL build ...") with the first lines of the build log.
// - Outputs are POISONED before every run (every 32-bit word 0x7fc00000, a
//   quiet NaN), so a vertex a kernel forgets to write reads back as NaN and
//   fails the comparison with the gold instead of passing on stale data.
// - Each output buffer is followed by a GUARD of kGuardBytes filled with a
//   known pattern; a kernel that writes past the end throws Error("OpenCL
//   guard ...") after the run. (Poison and guard: runtime/output_check.h.)
// - Every Launch of the PackedMesh runs with its own kernel (bucketed: one
//   specialised per influence count), arguments bound by name from the
//   kernel's argument list (docs/VARIANTS.md order), palette as a buffer or,
//   for `image` storage, an image1d_buffer (CL_RGBA / CL_FLOAT) over it.
// - Instances (docs/VARIANTS.md "Instancing"): with instanced kernels one run
//   skins K instances, each launch a 2-D NDRange (items, K) over the K
//   palettes (one buffer, one after another); the outputs hold K x
//   vertex_count vertices, instance after instance, the guard after them.
//   K palettes larger than the device's __constant buffer or image buffer
//   limit throw Error("OpenCL launch ...") naming the limit.
// - Timing (the tuner's): Prepare uploads K input sets once (copies of every
//   launch's inputs, one palette each, outputs of their own); Time runs frames
//   rotating among them with profiling events, uploading, poisoning and
//   reading back nothing; verify with Run first, Time checks nothing.
// - Skinning (the runtime's Skinner): a Prepared set is also a live set of
//   device buffers: WritePalette replaces a set's palette, LaunchSet runs its
//   launches once (no events), ReadOutput reads an output back, OutputBuffer
//   gives the cl_mem. Prepared outputs start POISONED like Run's.
// - Program cache (UseProgramCache): builds load the program binary stored
//   for (device, source hash, options) instead of compiling, and store it
//   after compiling (runtime/program_cache.h); the cache counts both, and
//   the lookups that found the program already built in this runner.
// Errors name the stage: "OpenCL setup", "build", "launch" or "guard".
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"
#include "runtime/program_cache.h"

namespace skintune {

struct OpenClRunResult {
  std::vector<std::uint8_t> positions;  // K x vertex_count x output_stride_bytes, packed order, instance after
                                        // instance (Unpack each instance's part)
  std::vector<std::uint8_t> normals;    // likewise; empty without normals
  std::vector<double> launch_ms;        // per launch, profiling end - start
  std::size_t poisoned_vertices = 0;    // output vectors (positions, normals) still holding the poison
};

// The device buffers of one variant for timing (OpenClRunner::Prepare):
// input_sets() sets, each a copy of every launch's packed inputs, its own
// palette and its own outputs. Move-only; must not outlive its runner.
class OpenClPrepared {
 public:
  OpenClPrepared();
  ~OpenClPrepared();
  OpenClPrepared(OpenClPrepared&&) noexcept;
  OpenClPrepared& operator=(OpenClPrepared&&) noexcept;
  int input_sets() const;
  std::size_t bytes_per_set() const;  // device bytes of one set: inputs + palette + outputs

  struct Impl;

 private:
  friend class OpenClRunner;
  std::unique_ptr<Impl> impl_;
};

class OpenClRunner {
 public:
  // The device `device_index` of platform `platform_index` (as enumerated by
  // EnumerateOpenCl). Throws Error("OpenCL setup: ...") when it does not exist.
  OpenClRunner(int platform_index, int device_index);
  ~OpenClRunner();
  OpenClRunner(const OpenClRunner&) = delete;
  OpenClRunner& operator=(const OpenClRunner&) = delete;

  // A device, context and in-order queue the caller made (cl_device_id,
  // cl_context, cl_command_queue): retained here, released by the
  // destructor. Throws Error("OpenCL setup: ...") for a null handle or a
  // device that is not in the context. Time needs a queue with profiling.
  OpenClRunner(void* cl_device, void* cl_context, void* cl_queue);

  const std::string& device_name() const;
  void* device() const;   // cl_device_id
  void* context() const;  // cl_context
  void* queue() const;    // cl_command_queue

  // Builds load from and store to `cache` (null: none), keyed with `device_id`;
  // the cache must outlive the runner.
  void UseProgramCache(ProgramCache* cache, const std::string& device_id);

  // Builds (or finds already built) `source`; throws Error("OpenCL build ...").
  void Build(const KernelSource& source);

  // Emits the variant's kernel for every launch (Emit(variant, launch.influences,
  // palette_joints)) and runs them. `palette`: PackPalette bytes; empty = mesh.palette.
  OpenClRunResult Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette = {});

  // Emits the variant's instanced kernel for every launch and skins
  // `instances` (K >= 1) instances in one launch per launch of the mesh.
  // `palettes`: K PackPalette byte runs one after another (instance i's at
  // i x palette size); empty = mesh.palette for every instance.
  OpenClRunResult RunInstanced(const PackedMesh& mesh, int instances, std::span<const std::uint8_t> palettes = {});

  // Runs with the given kernels, one per launch, in launch order; instanced
  // kernels skin `instances` instances (`palette` holds K palettes), plain
  // ones need instances == 1 (runtime/run_shape.h lists the errors).
  OpenClRunResult Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                      std::span<const std::uint8_t> palette = {}, int instances = 1);

  // Timing. Uploads one input set per palette (PackPalette bytes; one frame
  // each): copies of every launch's packed inputs, that palette (and its
  // image), and outputs of its own (not poisoned, never read back); builds
  // `kernels` (one per launch, in launch order). Instanced kernels: each
  // entry of `palettes` holds `instances` palettes and each frame skins them
  // all. Throws Error ("build", "launch") like Run.
  OpenClPrepared Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                         std::span<const std::vector<std::uint8_t>> palettes, int instances = 1);

  // Runs `warmup` untimed frames, then `repetitions` timed ones; frame f (warm-up
  // frames counted) reads and writes set f % input_sets(). Nothing is uploaded
  // or read back. Returns one time per timed frame: the sum over its launches
  // of the profiling time (end - start), ms.
  std::vector<double> Time(const OpenClPrepared& prepared, int warmup, int repetitions);

  // Skinning with a prepared set (see the top of this file). WritePalette
  // copies `palette` (PackPalette bytes) and enqueues its upload; LaunchSet
  // enqueues every launch of set `set`, writing positions into
  // `out_positions` (a cl_mem of the set's output size) instead of the set's
  // own when given; ReadOutput waits and copies the set's positions (or
  // normals) into `out` (vertex_count x output_stride_bytes, packed order).
  void WritePalette(OpenClPrepared& prepared, int set, std::span<const std::uint8_t> palette);
  void LaunchSet(const OpenClPrepared& prepared, int set, void* out_positions = nullptr);
  void ReadOutput(const OpenClPrepared& prepared, int set, bool normals, std::span<std::uint8_t> out);
  void* OutputBuffer(const OpenClPrepared& prepared, int set, bool normals) const;  // cl_mem; null: none
  void Finish();

  // A plain copy (one uint4 per work-item) between two buffers of `bytes`
  // (rounded down to a multiple of 16; the source holds a non-zero pattern):
  // `warmup` untimed then `repetitions` timed runs, profiling time in ms each.
  std::vector<double> TimeCopy(std::size_t bytes, int warmup, int repetitions);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace skintune
