// The CUDA Skinner: one prepared input set of the device's CudaRunner
// (RunnerSkinner), and CUDA-OpenGL interop, the paper's section 4.1 path:
// SkinIntoGlBuffer registers each GL buffer once
// (cuGraphicsGLRegisterBuffer, write-discard: the kernel overwrites it), then
// per call maps it on the skinning stream, skins into its device pointer and
// unmaps it. The map orders the kernel after GL's earlier commands on the
// buffer and the unmap GL's later ones after the kernel, so nothing waits on
// the host.
#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "runtime/api_errors.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/cuda/cuda_runner.h"
#include "runtime/backends/gl/gl_context.h"
#include "runtime/skinner.h"

namespace skintune::internal {

namespace {

class CudaSkinner final : public RunnerSkinner {
 public:
  CudaSkinner(CudaRunner& runner, Prepared prepared) : RunnerSkinner(runner, std::move(prepared)), cuda_(runner) {}

  ~CudaSkinner() override {
    const cuda::DriverApi* api = cuda::Driver();
    if (!api || registered_.empty()) return;
    api->cuCtxSetCurrent(static_cast<cuda::Context>(cuda_.context()));
    for (auto& [name, resource] : registered_) api->cuGraphicsUnregisterResource(resource);  // best effort
  }

  void SkinIntoGlBuffer(unsigned int gl_buffer) override {
    const cuda::DriverApi* api = cuda::Driver();
    if (!api || !api->cuGraphicsGLRegisterBuffer || !api->cuGraphicsMapResources || !api->cuGraphicsUnmapResources ||
        !api->cuGraphicsResourceGetMappedPointer || !api->cuGraphicsUnregisterResource)
      FailWith(ErrorCode::kUnavailable,
               "Skinner::SkinIntoGlBuffer: this CUDA driver has no OpenGL interop (cuGraphicsGLRegisterBuffer)");
    const std::string buffer = "GL buffer " + std::to_string(gl_buffer);
    RunOnDevice([&] {
      cuda::Check(api->cuCtxSetCurrent(static_cast<cuda::Context>(cuda_.context())), "launch", "cuCtxSetCurrent");
      cuda::GraphicsResource resource = Registered(*api, gl_buffer, buffer);
      const auto stream = static_cast<cuda::Stream>(cuda_.stream());
      cuda::Check(api->cuGraphicsMapResources(1, &resource, stream), "launch", "cuGraphicsMapResources of " + buffer);
      cuda::DevicePtr pointer = 0;
      std::size_t bytes = 0;
      const cuda::Result mapped = api->cuGraphicsResourceGetMappedPointer(&pointer, &bytes, resource);
      // The positions of every instance: the least the GL buffer must hold.
      const std::size_t needed = prepared_.output_bytes();
      if (mapped != cuda::kSuccess || bytes < needed) {
        api->cuGraphicsUnmapResources(1, &resource, stream);
        cuda::Check(mapped, "launch", "cuGraphicsResourceGetMappedPointer of " + buffer);
        FailWith(ErrorCode::kInvalidArgument, "Skinner::SkinIntoGlBuffer: " + buffer + " holds " +
                                                  std::to_string(bytes) + " bytes; the positions need " +
                                                  std::to_string(needed));
      }
      try {
        runner_.LaunchSet(prepared_, 0, reinterpret_cast<void*>(static_cast<std::uintptr_t>(pointer)));
      } catch (...) {
        api->cuGraphicsUnmapResources(1, &resource, stream);
        throw;
      }
      cuda::Check(api->cuGraphicsUnmapResources(1, &resource, stream), "launch", "cuGraphicsUnmapResources of " + buffer);
    });
  }

 private:
  // `gl_buffer`'s registration, made on first use. It needs the buffer's GL
  // context current on this thread.
  cuda::GraphicsResource Registered(const cuda::DriverApi& api, unsigned int gl_buffer, const std::string& buffer) {
    if (auto found = registered_.find(gl_buffer); found != registered_.end()) return found->second;
    cuda::GraphicsResource resource = nullptr;
    const cuda::Result r = api.cuGraphicsGLRegisterBuffer(&resource, gl_buffer, cuda::kGraphicsRegisterWriteDiscard);
    if (r != cuda::kSuccess) {
      // The driver says "invalid value" both without a current GL context
      // and for a name that is no buffer (seen on the H100): ask EGL which.
      const std::unique_ptr<GlContext> current = GlContext::AdoptCurrent();
      if (!current->ok())
        FailWith(ErrorCode::kInvalidState, "Skinner::SkinIntoGlBuffer: " + current->reason() +
                                               " (cuGraphicsGLRegisterBuffer of " + buffer + ": " + cuda::ErrorText(r) +
                                               ")");
      if (r == cuda::kErrorInvalidValue || r == cuda::kErrorInvalidHandle)
        FailWith(ErrorCode::kInvalidArgument, "Skinner::SkinIntoGlBuffer: " + buffer +
                                                  " is not a buffer object of the current GL context (" +
                                                  cuda::ErrorText(r) + ")");
    }
    cuda::Check(r, "launch", "cuGraphicsGLRegisterBuffer of " + buffer);
    registered_[gl_buffer] = resource;
    return resource;
  }

  CudaRunner& cuda_;
  std::map<unsigned int, cuda::GraphicsResource> registered_;  // unregistered by the destructor
};

}  // namespace

std::unique_ptr<SkinnerBackend> MakeCudaSkinner(DeviceState& device, const PackedMesh& mesh,
                                                const std::vector<KernelSource>& kernels, const SkinnerSetup& setup) {
  auto* runner = dynamic_cast<CudaRunner*>(device.runner.get());
  if (!runner) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no CUDA stream");
  return std::make_unique<CudaSkinner>(*runner, PrepareSkinnerSet(device, mesh, kernels, setup));
}

}  // namespace skintune::internal
