// The OpenCL Skinner: one prepared input set of the device's OpenClRunner
// (runtime/opencl_runner.h), written, launched and read per frame.
#include <memory>

#include "runtime/api_errors.h"
#include "runtime/opencl_gl_sharing.h"
#include "runtime/opencl_runner.h"
#include "runtime/skinner.h"

namespace skintune {

namespace {

class OpenClSkinner final : public SkinnerBackend {
 public:
  // `out_bytes`: the positions of every instance; `gl_sharing`: the runner's
  // context shares buffers with a GL context (SkinIntoGlBuffer).
  OpenClSkinner(OpenClRunner& runner, OpenClPrepared prepared, bool normals, std::size_t out_bytes, bool gl_sharing)
      : runner_(runner), prepared_(std::move(prepared)), normals_(normals), out_bytes_(out_bytes) {
    if (gl_sharing) gl_writer_ = std::make_unique<GlBufferWriter>(runner.context(), runner.queue());
  }

  void WritePalette(std::span<const std::uint8_t> palette) override {
    Run([&] { runner_.WritePalette(prepared_, 0, palette); });
  }
  void Skin() override {
    Run([&] { runner_.LaunchSet(prepared_, 0); });
  }
  void Finish() override {
    Run([&] { runner_.Finish(); });
  }
  void Read(bool normals, std::span<std::uint8_t> out) override {
    Run([&] { runner_.ReadOutput(prepared_, 0, normals && normals_, out); });
  }
  void* DevicePositions() const override { return runner_.OutputBuffer(prepared_, 0, false); }
  void SkinIntoGlBuffer(unsigned int gl_buffer) override {
    if (!gl_writer_) return SkinnerBackend::SkinIntoGlBuffer(gl_buffer);  // kUnavailable
    Run([&] { gl_writer_->Write(gl_buffer, out_bytes_, [&](void* mem) { runner_.LaunchSet(prepared_, 0, mem); }); });
  }

 private:
  template <typename F>
  void Run(F&& call) {
    try {
      call();
    } catch (const ApiError&) {
      throw;
    } catch (const Error& e) {
      FailWith(CodeOfRunnerError(e.what()), e.what());
    }
  }

  OpenClRunner& runner_;
  OpenClPrepared prepared_;
  bool normals_;
  std::size_t out_bytes_;
  std::unique_ptr<GlBufferWriter> gl_writer_;  // destroyed before prepared_: its cl_mems go first
};

}  // namespace

std::unique_ptr<SkinnerBackend> MakeOpenClSkinner(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, int instances) {
  if (!device.opencl) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no OpenCL queue");
  try {
    std::vector<std::vector<std::uint8_t>> palettes(1);  // one input set of `instances` rest-pose palettes
    for (int k = 0; k < instances; ++k) palettes[0].insert(palettes[0].end(), mesh.palette.begin(), mesh.palette.end());
    OpenClPrepared prepared = device.opencl->Prepare(mesh, kernels, palettes, instances);
    const std::size_t out_bytes = static_cast<std::size_t>(instances) * mesh.vertex_count * mesh.output_stride_bytes;
    return std::make_unique<OpenClSkinner>(*device.opencl, std::move(prepared), mesh.variant.normals, out_bytes,
                                           device.gl_sharing);
  } catch (const ApiError&) {
    throw;
  } catch (const Error& e) {
    FailWith(CodeOfRunnerError(e.what()), std::string("Skinner::Create: ") + e.what());
  }
}

}  // namespace skintune
