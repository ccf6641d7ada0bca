#include "runtime/backends/opencl/opencl_gl_sharing.h"

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <CL/cl_gl.h>
#include <dlfcn.h>
#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <sstream>
#include <vector>

#include "runtime/api_errors.h"
#include "runtime/backends/opencl/opencl_info.h"

namespace skintune::internal {

namespace {

bool HasWord(const std::string& list, const std::string& word) {
  std::istringstream in(list);
  std::string w;
  while (in >> w)
    if (w == word) return true;
  return false;
}

}  // namespace

OpenClGlHandles OpenClContextForCurrentGl(std::string& why) {
  // libepoxy aborts without libEGL: look first.
  if (!dlopen("libEGL.so.1", RTLD_LAZY | RTLD_GLOBAL)) {
    why = "libEGL.so.1 cannot be loaded, so no EGL context can be current";
    return {};
  }
  const EGLContext gl_context = eglGetCurrentContext();
  const EGLDisplay gl_display = eglGetCurrentDisplay();
  if (gl_context == EGL_NO_CONTEXT) {
    why = "no EGL context is current on this thread";
    return {};
  }
  cl_uint count = 0;
  if (clGetPlatformIDs(0, nullptr, &count) != CL_SUCCESS || count == 0) {
    why = "no OpenCL platform";
    return {};
  }
  std::vector<cl_platform_id> platforms(count);
  clGetPlatformIDs(count, platforms.data(), nullptr);
  std::string reasons;
  for (cl_platform_id platform : platforms) {
    const std::string name = PlatformString(platform, CL_PLATFORM_NAME);
    auto skip = [&](const std::string& reason) { reasons += (reasons.empty() ? "" : "; ") + name + ": " + reason; };
    if (!HasWord(PlatformString(platform, CL_PLATFORM_EXTENSIONS), "cl_khr_gl_sharing")) {
      skip("no cl_khr_gl_sharing");
      continue;
    }
    const auto get_info = reinterpret_cast<clGetGLContextInfoKHR_fn>(
        clGetExtensionFunctionAddressForPlatform(platform, "clGetGLContextInfoKHR"));
    if (!get_info) {
      skip("clGetGLContextInfoKHR not found");
      continue;
    }
    const cl_context_properties properties[] = {
        CL_GL_CONTEXT_KHR,   reinterpret_cast<cl_context_properties>(gl_context),
        CL_EGL_DISPLAY_KHR,  reinterpret_cast<cl_context_properties>(gl_display),
        CL_CONTEXT_PLATFORM, reinterpret_cast<cl_context_properties>(platform),
        0};
    cl_device_id device = nullptr;
    cl_int err = get_info(properties, CL_CURRENT_DEVICE_FOR_GL_CONTEXT_KHR, sizeof device, &device, nullptr);
    if (err != CL_SUCCESS || !device) {
      skip("no device for the current EGL context (clGetGLContextInfoKHR error " + std::to_string(err) + ")");
      continue;
    }
    cl_context context = clCreateContext(properties, 1, &device, nullptr, nullptr, &err);
    if (err != CL_SUCCESS) {
      skip("clCreateContext with the GL context failed with error " + std::to_string(err));
      continue;
    }
    cl_command_queue queue = clCreateCommandQueue(context, device, 0, &err);
    if (err != CL_SUCCESS) {
      clReleaseContext(context);
      skip("clCreateCommandQueue failed with error " + std::to_string(err));
      continue;
    }
    return {device, context, queue};
  }
  why = "no OpenCL platform shares buffers with this GL context (" + reasons + ")";
  return {};
}

void Release(const OpenClGlHandles& handles) {
  if (handles.queue) clReleaseCommandQueue(static_cast<cl_command_queue>(handles.queue));
  if (handles.context) clReleaseContext(static_cast<cl_context>(handles.context));
}

GlBufferWriter::~GlBufferWriter() {
  for (const auto& [name, mem] : shared_) clReleaseMemObject(static_cast<cl_mem>(mem));
}

void GlBufferWriter::Write(unsigned int gl_buffer, std::size_t bytes, const std::function<void(void*)>& launch) {
  const auto queue = static_cast<cl_command_queue>(queue_);
  auto found = shared_.find(gl_buffer);
  if (found == shared_.end()) {
    cl_int err = CL_SUCCESS;
    cl_mem mem = clCreateFromGLBuffer(static_cast<cl_context>(context_), CL_MEM_WRITE_ONLY, gl_buffer, &err);
    if (err != CL_SUCCESS)
      FailWith(ErrorCode::kInvalidArgument, "Skinner::SkinIntoGlBuffer: clCreateFromGLBuffer(" +
                                                std::to_string(gl_buffer) + ") failed with error " +
                                                std::to_string(err) + " (not a buffer of the shared GL context?)");
    found = shared_.emplace(gl_buffer, mem).first;
  }
  const auto mem = static_cast<cl_mem>(found->second);
  std::size_t size = 0;
  clGetMemObjectInfo(mem, CL_MEM_SIZE, sizeof size, &size, nullptr);
  if (size < bytes)
    FailWith(ErrorCode::kInvalidArgument, "Skinner::SkinIntoGlBuffer: GL buffer " + std::to_string(gl_buffer) +
                                              " holds " + std::to_string(size) + " bytes, the output " +
                                              std::to_string(bytes));
  glFinish();  // GL is done with the buffer before OpenCL takes it (no cl_khr_gl_event assumed)
  cl_int err = clEnqueueAcquireGLObjects(queue, 1, &mem, 0, nullptr, nullptr);
  if (err != CL_SUCCESS)
    FailWith(ErrorCode::kDeviceError, "Skinner::SkinIntoGlBuffer: clEnqueueAcquireGLObjects failed with error " +
                                          std::to_string(err));
  try {
    launch(mem);
  } catch (...) {
    clEnqueueReleaseGLObjects(queue, 1, &mem, 0, nullptr, nullptr);
    clFinish(queue);
    throw;
  }
  err = clEnqueueReleaseGLObjects(queue, 1, &mem, 0, nullptr, nullptr);
  if (err == CL_SUCCESS) err = clFinish(queue);  // GL may use the buffer once OpenCL is done with it
  if (err != CL_SUCCESS)
    FailWith(ErrorCode::kDeviceError, "Skinner::SkinIntoGlBuffer: releasing the GL buffer failed with error " +
                                          std::to_string(err));
}

}  // namespace skintune::internal
