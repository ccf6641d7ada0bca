// skintune (internal): the runner driver (runtime/runner.h) on a GL 4.3
// context (runtime/backends/gl/gl_context.h): glsl-compute and glsl-vertex
// kernels. Its DeviceApi (gl_api.h; gl_runner.cpp, gl_frames.cpp):
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
// - Each launch of Run is timed with a GL_TIME_ELAPSED query.
// - Timing (the tuner's): each burst of Time's frames inside one
//   GL_TIME_ELAPSED query. On Mesa's software renderers (llvmpipe, softpipe,
//   swrast), whose GL_TIME_ELAPSED covers neither compute dispatches nor
//   vertex processing (it times their rasteriser threads: ~0), each burst is
//   timed by the host clock between two glFinish calls instead
//   (host_timed()). On a GPU the driver first warms up until two bursts of
//   frames take the same time (TimingPolicy::warm_until_stable): NVIDIA's GL
//   driver drops the H100's SM clock from 1980 to 345 MHz a few seconds into
//   a process whose GL work comes in short bursts, and a few warm-up frames
//   (tens of microseconds) do not bring it back: kernels timed later ran
//   2-4x slower than the same kernels timed first (docs/PERFORMANCE.md).
// Errors name the stage: "GL setup", "build", "launch" or "guard".
//
// - Skinning (the runtime's Skinner): WritePalette writes each palette
//   slot's persistently mapped staging buffer (glBufferStorage, GL 4.4 or
//   ARB_buffer_storage) and queues a glCopyBufferSubData into the slot, or
//   without buffer storage a glBufferSubData into the idle slot; the ring's
//   fences are glFenceSync (and a glFlush); read-backs copy into a
//   persistently mapped buffer and wait for a fence (else
//   glGetBufferSubData). LaunchSet runs the set's launches once (then
//   glMemoryBarrier(GL_ALL_BARRIER_BITS)) and restores the program, vertex
//   array, framebuffers, transform feedback object and rasteriser-discard
//   state it found; the indexed buffer bindings (storage, uniform, transform
//   feedback) and texture units it used stay bound.
// - Program cache (UseProgramCache): where the driver offers program binary
//   formats (GL_NUM_PROGRAM_BINARY_FORMATS > 0), linked programs are stored
//   with glGetProgramBinary and loaded with glProgramBinary (a binary the
//   driver refuses is rebuilt from source).
//
// GL calls need the runner's context current: every public method makes it
// current on the calling thread.
#pragma once

#include <memory>
#include <string>

#include "runtime/backends/gl/gl_context.h"
#include "runtime/runner.h"

namespace skintune::internal {

namespace gl {
class GlApi;
}

class GlRunner final : public Runner {
 public:
  // Creates its own context (GlContext(device_index)); throws
  // Error("GL setup: <why>") when none can be made.
  explicit GlRunner(int device_index = -1);
  // On a context made elsewhere (GlContext::AdoptCurrent); throws
  // Error("GL setup: <why>") when it is not ok().
  explicit GlRunner(std::unique_ptr<GlContext> context);

  const GlContextInfo& info() const;
  // Whether Time times bursts with the host clock (software
  // renderers) instead of GL_TIME_ELAPSED queries.
  bool host_timed() const;
  // The barriers issued to make live frames' outputs readable so far: on its
  // own context one before each read after frames, not one a frame.
  std::uint64_t read_barriers() const;
  // Makes the runner's context current; throws Error("GL setup: ...") when
  // it cannot be (an adopted context that is not current any more).
  void MakeCurrent();

 private:
  const gl::GlApi& gl_api() const;
};

using GlRunResult = RunResult;
using GlPrepared = Prepared;

}  // namespace skintune::internal
