// skintune: a headless desktop OpenGL 4.3+ core context through EGL, for the
// glsl-compute and glsl-vertex kernels.
//
// No window system and no surface: the context is made current with
// EGL_NO_SURFACE (EGL_KHR_surfaceless_context). Displays are tried in order:
//   1. EGL_EXT_platform_device: every device of eglQueryDevicesEXT (a GPU
//      driver's device, e.g. NVIDIA with __EGL_VENDOR_LIBRARY_FILENAMES
//      pointing at its vendor JSON; Mesa also lists its software device);
//   2. EGL_MESA_platform_surfaceless (Mesa: a render node or llvmpipe);
//   3. eglGetDisplay(EGL_DEFAULT_DISPLAY), as a last resort.
// On each: eglInitialize, eglBindAPI(EGL_OPENGL_API), a context asking for
// GL 4.3 core (the driver may give a later version), made current without a
// surface. The first display that gives a context of at least GL 4.3 wins.
//
// Never throws and never aborts for a missing driver: when no context can be
// made, ok() is false and reason() says why, one line per display tried
// (libEGL missing, no platform extension, eglInitialize failed, GL version
// too old, ...). GL and EGL functions are loaded through libepoxy; libEGL and
// libOpenGL are checked with dlopen first, since libepoxy aborts the process
// when it cannot load them.
//
// The context is current on the thread that created it; MakeCurrent() makes
// it current on the calling thread (after releasing it elsewhere).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "generator/constraints.h"
#include "runtime/device_identity.h"

namespace skintune::internal {

struct GlContextInfo {
  std::string egl_platform;   // "device", "surfaceless" or "default"
  std::string egl_device;     // the EGL device (platform "device"): index and its extensions / DRM node
  std::string egl_vendor, egl_version;
  std::string vendor, renderer, version, glsl_version;  // GL_VENDOR, GL_RENDERER, GL_VERSION, GLSL version
  int major = 0, minor = 0;   // GL_MAJOR_VERSION, GL_MINOR_VERSION
  std::uint64_t max_compute_work_group_invocations = 0;  // GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS
  std::uint64_t max_compute_work_group_size_x = 0;       // GL_MAX_COMPUTE_WORK_GROUP_SIZE[0]
  std::uint64_t max_compute_work_group_count_x = 0;      // GL_MAX_COMPUTE_WORK_GROUP_COUNT[0]
  std::uint64_t max_compute_work_group_count_y = 0;      // GL_MAX_COMPUTE_WORK_GROUP_COUNT[1] (instances per launch)
  std::uint64_t max_compute_shared_memory_bytes = 0;     // GL_MAX_COMPUTE_SHARED_MEMORY_SIZE
  std::uint64_t max_uniform_block_bytes = 0;             // GL_MAX_UNIFORM_BLOCK_SIZE
  std::uint64_t max_texture_buffer_texels = 0;           // GL_MAX_TEXTURE_BUFFER_SIZE
  std::uint64_t max_vertex_shader_storage_blocks = 0;    // GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS
  std::uint64_t max_compute_shader_storage_blocks = 0;   // GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS
  std::uint64_t max_shader_storage_block_bytes = 0;      // GL_MAX_SHADER_STORAGE_BLOCK_SIZE
  std::uint64_t max_transform_feedback_separate_attribs = 0;  // GL_MAX_TRANSFORM_FEEDBACK_SEPARATE_ATTRIBS
  std::string device_uuid;  // GL_EXT_memory_object's GL_DEVICE_UUID_EXT of device 0, 32 hex digits ("" when not offered)
  // The context was made with EGL's reset notification strategy
  // EGL_LOSE_CONTEXT_ON_RESET: when the driver resets it (a kernel that ran
  // past the driver's limit, here or in another process), every later call
  // raises GL_CONTEXT_LOST instead of doing nothing, and the runner reports
  // the device lost (stage "lost") instead of outputs never written.
  bool reset_notification = false;
};

class GlContext {
 public:
  // device_index >= 0: only that EGL device (platform "device"); -1: the
  // first display of the order above that works.
  explicit GlContext(int device_index = -1);
  // The context current on the calling thread, whoever made it (the
  // runtime's Device::FromCurrentGl): not owned (never destroyed here) and
  // never made current here: MakeCurrent throws unless it still is current.
  // ok() is false, with the reason, when no EGL context is current or it is
  // older than GL 4.3. info().egl_platform is "current".
  static std::unique_ptr<GlContext> AdoptCurrent();
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  bool ok() const;
  const std::string& reason() const;  // why there is no context (empty when ok())
  const GlContextInfo& info() const;  // filled when ok()

  // Makes the context current on the calling thread; throws Error("GL setup: ...")
  // when there is no context or EGL refuses.
  void MakeCurrent();
  bool IsCurrent() const;

 private:
  struct AdoptTag {};
  explicit GlContext(AdoptTag);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Saves the calling thread's current EGL display, surfaces and context, and
// makes them current again when destroyed, so code that makes a GlContext
// of its own (Device::List) leaves the caller's GL context as it found it.
// Does nothing where libEGL cannot be loaded.
class CurrentGlRestorer {
 public:
  CurrentGlRestorer();
  ~CurrentGlRestorer();
  CurrentGlRestorer(const CurrentGlRestorer&) = delete;
  CurrentGlRestorer& operator=(const CurrentGlRestorer&) = delete;

 private:
  bool active_ = false;
  void* display_ = nullptr;
  void* draw_ = nullptr;
  void* read_ = nullptr;
  void* context_ = nullptr;
};

// The limits the generator's constraints need (GLSL: the work-group limit is
// the smaller of GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS and
// GL_MAX_COMPUTE_WORK_GROUP_SIZE[0]; "constant" storage is a uniform block;
// images are texture buffers, always present in GL 4.3 core).
DeviceLimits LimitsOf(const GlContextInfo& info);

// "cpu" for Mesa's software rasterisers (llvmpipe, softpipe, swrast, any
// renderer saying "software"), else "gpu".
std::string GlDeviceType(const std::string& renderer);

// Backend "gl": the EGL platform, GL_VENDOR, GL_RENDERER as the name,
// GL_VERSION (which names the driver: "4.5 (Core Profile) Mesa 22.3.6") as
// driver and API version, GlDeviceType; shared memory and the uniform block
// as local and constant memory (GL says nothing of compute units, memory or
// caches).
DeviceIdentity IdentityOf(const GlContextInfo& info);

void to_json(nlohmann::json& out, const GlContextInfo& info);

}  // namespace skintune::internal
