// The CUDA Skinner: one prepared input set of the device's CudaRunner
// (runtime/cuda_runner.h), written, launched and read per frame on the
// Device's stream.
#include <cstdint>
#include <memory>

#include "runtime/api_errors.h"
#include "runtime/cuda_runner.h"
#include "runtime/skinner.h"

namespace skintune {

namespace {

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

class CudaSkinner final : public SkinnerBackend {
 public:
  CudaSkinner(CudaRunner& runner, CudaPrepared prepared, bool normals)
      : runner_(runner), prepared_(std::move(prepared)), normals_(normals) {}

  void WritePalette(std::span<const std::uint8_t> palettes) override {
    Run([&] { runner_.WritePalette(prepared_, 0, palettes); });
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
  void* DevicePositions() const override {
    return reinterpret_cast<void*>(static_cast<std::uintptr_t>(runner_.OutputBuffer(prepared_, 0, false)));
  }

 private:
  CudaRunner& runner_;
  CudaPrepared prepared_;
  bool normals_;
};

}  // namespace

std::unique_ptr<SkinnerBackend> MakeCudaSkinner(DeviceState& device, const PackedMesh& mesh,
                                                const std::vector<KernelSource>& kernels, int instances) {
  if (!device.cuda) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no CUDA context");
  try {
    std::vector<std::vector<std::uint8_t>> palettes(1);  // one input set of `instances` rest-pose palettes
    for (int k = 0; k < instances; ++k) palettes[0].insert(palettes[0].end(), mesh.palette.begin(), mesh.palette.end());
    CudaPrepared prepared = device.cuda->Prepare(mesh, kernels, palettes, instances);
    return std::make_unique<CudaSkinner>(*device.cuda, std::move(prepared), mesh.variant.normals);
  } catch (const ApiError&) {
    throw;
  } catch (const Error& e) {
    FailWith(CodeOfRunnerError(e.what()), std::string("Skinner::Create: ") + e.what());
  }
}

}  // namespace skintune
