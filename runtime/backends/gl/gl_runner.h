// skintune (internal): runs emitted GLSL kernels (glsl-compute and
// glsl-vertex) on a packed mesh through a headless GL 4.3 context
// (runtime/backends/gl/gl_context.h), with the same checks as the OpenCL runner.
//
// - Build: each distinct KernelSource is compiled and linked once per runner;
//   a failure throws Error("GL build ...") with the first lines of the log.
//   glsl-vertex programs are linked with glTransformFeedbackVaryings
//   {"out_position"[, "out_normal"]} in GL_SEPARATE_ATTRIBS mode, and the
//   captured types are checked against the output format.
// - Inputs: one storage buffer per packed input of each launch, bound at the
//   argument's binding (buffers and the palette take consecutive bindings in
//   argument order, scalars excluded: the sidecar's "binding"). Palette:
//   STORAGE constant -> uniform buffer at that binding; local/global ->
//   storage buffer; image -> a GL_RGBA32F texture buffer on texture unit =
//   that binding. Uniforms n and first are set per launch.
// - Outputs are POISONED before every run (every 32-bit word 0x7fc00000) and
//   followed in the same buffer by a GUARD of kGuardBytes of a known pattern:
//   glsl-compute binds the whole buffer (the shader could write into the
//   guard); glsl-vertex captures each launch into its range
//   [first, first + n) of the buffer with transform feedback, and the guard
//   after the captured range is checked the same way. A guard word changed
//   throws Error("GL guard ..."). (Poison and guard: runtime/output_check.h.)
// - glsl-compute: glDispatchCompute(GlobalItems(n) / wg) per launch.
//   glsl-vertex: glDrawArrays(GL_POINTS, 0, n) with GL_RASTERIZER_DISCARD,
//   capture range first*stride .. (first+n)*stride (gl_VertexID = v), and a
//   GL_TRANSFORM_FEEDBACK_PRIMITIVES_WRITTEN query must count n points.
// - Instances (docs/VARIANTS.md "Instancing"): with instanced kernels one run
//   skins K instances; the outputs hold K x vertex_count vertices, instance
//   after instance, the guard after them. glsl-compute dispatches (groups, K,
//   1) with the uniform vertex_count; glsl-vertex draws
//   glDrawArraysInstanced(GL_POINTS, 0, n, K), whose capture holds the K
//   instances one after another: captured straight into the outputs when the
//   mesh takes one draw, else (buckets) into a poisoned staging buffer copied
//   to i * vertex_count + first (K glCopyBufferSubData, inside the launch's
//   timing). Instanced constant storage binds a buffer as large as the
//   kernel's uniform block (max_instances palettes).
// - Each launch is timed with a GL_TIME_ELAPSED query.
// - Timing (the tuner's): Prepare uploads K input sets once (copies of every
//   launch's inputs, one palette each, outputs of their own); Time runs frames
//   rotating among them, each launch inside a GL_TIME_ELAPSED query, uploading,
//   poisoning and reading back nothing; verify with Run first. On Mesa's
//   software renderers (llvmpipe, softpipe, swrast), whose GL_TIME_ELAPSED
//   covers neither compute dispatches nor vertex processing (it times their
//   rasteriser threads: ~0), each launch is timed by the host clock between
//   two glFinish calls instead (host_timed()).
// Errors name the stage: "GL setup", "build", "launch" or "guard".
//
// - Skinning (the runtime's Skinner): a Prepared set is also a live set of
//   buffers: WritePalette replaces a set's palettes (glBufferSubData),
//   LaunchSet runs its launches once (then glMemoryBarrier(GL_ALL_BARRIER_BITS)),
//   ReadOutput reads an output back, OutputBuffer gives the buffer name.
//   Prepared outputs start POISONED like Run's. LaunchSet restores the
//   program, vertex array, framebuffers, transform feedback object and
//   rasteriser-discard state it found; the indexed buffer bindings (storage,
//   uniform, transform feedback) and texture units it used stay bound.
// - Program cache (UseProgramCache): where the driver offers program binary
//   formats (GL_NUM_PROGRAM_BINARY_FORMATS > 0), linked programs are stored
//   with glGetProgramBinary and loaded with glProgramBinary (a binary the
//   driver refuses is rebuilt from source).
//
// GL calls need the runner's context current: every public method makes it
// current on the calling thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"
#include "runtime/backends/gl/gl_context.h"
#include "runtime/program_cache.h"

namespace skintune {

struct GlRunResult {
  std::vector<std::uint8_t> positions;  // K x vertex_count x output_stride_bytes, packed order, instance after
                                        // instance (Unpack each instance's part)
  std::vector<std::uint8_t> normals;    // likewise; empty without normals
  std::vector<double> launch_ms;        // per launch, GL_TIME_ELAPSED
  std::size_t poisoned_vertices = 0;    // output vectors (positions, normals) still holding the poison
};

// The GL buffers of one variant for timing (GlRunner::Prepare): input_sets()
// sets, each a copy of every launch's packed inputs, its own palette and its
// own outputs. Move-only; must not outlive its runner.
class GlPrepared {
 public:
  GlPrepared();
  ~GlPrepared();
  GlPrepared(GlPrepared&&) noexcept;
  GlPrepared& operator=(GlPrepared&&) noexcept;
  int input_sets() const;
  std::size_t bytes_per_set() const;  // buffer bytes of one set: inputs + palette + outputs

  struct Impl;

 private:
  friend class GlRunner;
  std::unique_ptr<Impl> impl_;
};

class GlRunner {
 public:
  // Creates its own context (GlContext(device_index)); throws
  // Error("GL setup: <why>") when none can be made.
  explicit GlRunner(int device_index = -1);
  // On a context made elsewhere (GlContext::AdoptCurrent); throws
  // Error("GL setup: <why>") when it is not ok().
  explicit GlRunner(std::unique_ptr<GlContext> context);
  ~GlRunner();
  GlRunner(const GlRunner&) = delete;
  GlRunner& operator=(const GlRunner&) = delete;

  const std::string& device_name() const;  // GL_RENDERER
  const GlContextInfo& info() const;
  // Whether Time and TimeCopy time launches with the host clock (software
  // renderers) instead of GL_TIME_ELAPSED queries.
  bool host_timed() const;

  // Makes the runner's context current; throws Error("GL setup: ...") when
  // it cannot be (an adopted context that is not current any more).
  void MakeCurrent();

  // Linked programs load from and store to `cache` (null: none), keyed with
  // `device_id`; the cache must outlive the runner.
  void UseProgramCache(ProgramCache* cache, const std::string& device_id);

  // Compiles and links (or finds already built) `source`; throws Error("GL build ...").
  void Build(const KernelSource& source);

  // Emits the variant's kernel for every launch (Emit(variant, launch.influences,
  // palette_joints)) and runs them. `palette`: PackPalette bytes; empty = mesh.palette.
  GlRunResult Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette = {});

  // Emits the variant's instanced kernel for every launch and skins
  // `instances` (K >= 1) instances in one launch per launch of the mesh.
  // `palettes`: K PackPalette byte runs one after another; empty = mesh.palette
  // for every instance.
  GlRunResult RunInstanced(const PackedMesh& mesh, int instances, std::span<const std::uint8_t> palettes = {});

  // Runs with the given kernels, one per launch, in launch order; instanced
  // kernels skin `instances` instances (`palette` holds K palettes), plain
  // ones need instances == 1 (runtime/run_shape.h lists the errors).
  GlRunResult Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                  std::span<const std::uint8_t> palette = {}, int instances = 1);

  // Timing. Uploads one input set per palette (PackPalette bytes; one frame
  // each): copies of every launch's packed inputs, that palette (and its
  // texture buffer), and outputs of its own (not poisoned, never read back);
  // builds `kernels` (one per launch, in launch order). Instanced kernels:
  // each entry of `palettes` holds `instances` palettes and each frame skins
  // them all. Throws Error ("build", "launch") like Run.
  GlPrepared Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                     std::span<const std::vector<std::uint8_t>> palettes, int instances = 1);

  // Runs `warmup` untimed frames, then `repetitions` timed ones; frame f (warm-up
  // frames counted) reads and writes set f % input_sets(). Returns one time per
  // timed frame: the sum over its launches of their GL_TIME_ELAPSED (or host
  // time, host_timed()), ms.
  std::vector<double> Time(const GlPrepared& prepared, int warmup, int repetitions);

  // Skinning with a prepared set (see the top of this file). `palettes`: the
  // set's K palettes; `out` receives K x vertex_count x output_stride_bytes
  // (packed order).
  void WritePalette(GlPrepared& prepared, int set, std::span<const std::uint8_t> palettes);
  void LaunchSet(const GlPrepared& prepared, int set);
  void ReadOutput(const GlPrepared& prepared, int set, bool normals, std::span<std::uint8_t> out);
  // glFinish on the runner's context (made current).
  void Finish();
  unsigned int OutputBuffer(const GlPrepared& prepared, int set, bool normals) const;  // 0: none

  // A plain copy compute shader (one uvec4 per invocation and step, grid-stride)
  // between two storage buffers of `bytes` (rounded down to a multiple of 16, at
  // most GL_MAX_SHADER_STORAGE_BLOCK_SIZE; the source holds a non-zero pattern):
  // `warmup` untimed then `repetitions` timed runs, GL_TIME_ELAPSED (or host
  // time, host_timed()) in ms each.
  std::vector<double> TimeCopy(std::size_t bytes, int warmup, int repetitions);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace skintune
