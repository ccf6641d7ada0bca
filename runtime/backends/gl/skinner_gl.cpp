// The GL Skinner: one prepared input set of the device's GlRunner
// (runtime/backends/gl/gl_runner.h), written, launched and read per frame, with the
// Device's GL context current.
#include <memory>

#include "runtime/backends/gl/gl_runner.h"
#include "runtime/skinner.h"

namespace skintune {

namespace {

// kInvalidState unless the runner's context is (or can be made) current here.
void CheckCurrent(GlRunner& runner, const char* call) {
  try {
    runner.MakeCurrent();
  } catch (const Error& e) {
    FailWith(ErrorCode::kInvalidState, std::string(call) + ": " + e.what());
  }
}

class GlSkinner final : public RunnerSkinner<GlRunner, GlPrepared> {
 public:
  using RunnerSkinner::RunnerSkinner;
  void CheckUsable() const override { CheckCurrent(runner_, "Skinner"); }
};

}  // namespace

std::unique_ptr<SkinnerBackend> MakeGlSkinner(DeviceState& device, const PackedMesh& mesh,
                                              const std::vector<KernelSource>& kernels, int instances) {
  if (!device.gl) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no GL context");
  CheckCurrent(*device.gl, "Skinner::Create");
  std::unique_ptr<SkinnerBackend> skinner;
  RunOnDevice(
      [&] {
        skinner = std::make_unique<GlSkinner>(
            *device.gl, device.gl->Prepare(mesh, kernels, RestPalettes(mesh, instances), instances),
            mesh.variant.normals);
      },
      "Skinner::Create: ");
  return skinner;
}

}  // namespace skintune
