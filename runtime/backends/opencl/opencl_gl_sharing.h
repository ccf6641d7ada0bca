// skintune (internal): OpenCL-OpenGL interop (cl_khr_gl_sharing), as in the
// paper: an OpenCL context made for the GL context current on this thread,
// so kernels write straight into GL buffer objects.
//
// - OpenClContextForCurrentGl: for every OpenCL platform whose extensions
//   include cl_khr_gl_sharing, asks clGetGLContextInfoKHR (loaded with
//   clGetExtensionFunctionAddressForPlatform) for the device of the current
//   EGL context (CL_GL_CONTEXT_KHR + CL_EGL_DISPLAY_KHR properties), and
//   makes a context and an in-order queue on it. Without one, says why per
//   platform (PoCL: the extension is absent).
// - GlBufferWriter: per GL buffer name, one cl_mem from clCreateFromGLBuffer
//   (made once); Write acquires it (after glFinish: GL is done with it),
//   runs the caller's launches into it, releases it and waits (clFinish), so
//   GL may draw from it next.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>

namespace skintune::internal {

struct OpenClGlHandles {
  void* device = nullptr;   // cl_device_id
  void* context = nullptr;  // cl_context, created with the GL context's properties (released by the caller)
  void* queue = nullptr;    // cl_command_queue, in-order (released by the caller)
};

// Handles, or all null with `why` set (no EGL context current, no platform
// with cl_khr_gl_sharing, no device for this GL context). Never throws.
OpenClGlHandles OpenClContextForCurrentGl(std::string& why);
// Releases the context and queue of `handles` (the caller's references).
void Release(const OpenClGlHandles& handles);

class GlBufferWriter {
 public:
  GlBufferWriter(void* cl_context, void* cl_queue) : context_(cl_context), queue_(cl_queue) {}
  ~GlBufferWriter();
  GlBufferWriter(const GlBufferWriter&) = delete;
  GlBufferWriter& operator=(const GlBufferWriter&) = delete;

  // Runs `launch(cl_mem)` with GL buffer `gl_buffer` acquired as a cl_mem of
  // at least `bytes`. Throws ApiError: kInvalidArgument for a name that is
  // not a buffer of the shared GL context or one that is too small,
  // kDeviceError when OpenCL refuses.
  void Write(unsigned int gl_buffer, std::size_t bytes, const std::function<void(void*)>& launch);

 private:
  void* context_;
  void* queue_;
  std::map<unsigned int, void*> shared_;  // GL buffer name -> cl_mem (released by the destructor)
};

}  // namespace skintune::internal
