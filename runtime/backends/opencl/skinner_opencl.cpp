// The OpenCL Skinner: one prepared input set of the device's OpenClRunner
// (RunnerSkinner); with a GL-sharing Device, also skinned straight into GL
// buffers.
#include <memory>

#include "runtime/backends/opencl/opencl_gl_sharing.h"
#include "runtime/backends/opencl/opencl_runner.h"
#include "runtime/skinner.h"

namespace skintune::internal {

namespace {

class OpenClSkinner final : public RunnerSkinner {
 public:
  // `gl_sharing`: the runner's context shares buffers with a GL context (SkinIntoGlBuffer).
  OpenClSkinner(OpenClRunner& runner, Prepared prepared, bool gl_sharing)
      : RunnerSkinner(runner, std::move(prepared)) {
    if (gl_sharing) gl_writer_ = std::make_unique<GlBufferWriter>(runner.context(), runner.queue());
  }

  void SkinIntoGlBuffer(unsigned int gl_buffer) override {
    if (!gl_writer_) return SkinnerBackend::SkinIntoGlBuffer(gl_buffer);  // kUnavailable
    RunOnDevice([&] {
      gl_writer_->Write(gl_buffer, prepared_.output_bytes(), [&](void* mem) { runner_.LaunchSet(prepared_, 0, mem); });
    });
  }

 private:
  std::unique_ptr<GlBufferWriter> gl_writer_;  // a member of the derived class: its cl_mems go before prepared_
};

}  // namespace

std::unique_ptr<SkinnerBackend> MakeOpenClSkinner(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, const SkinnerSetup& setup) {
  auto* runner = dynamic_cast<OpenClRunner*>(device.runner.get());
  if (!runner) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no OpenCL queue");
  return std::make_unique<OpenClSkinner>(*runner, PrepareSkinnerSet(device, mesh, kernels, setup),
                                         device.gl_sharing);
}

}  // namespace skintune::internal
