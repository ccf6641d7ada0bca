// The GL Skinner: one prepared input set of the device's GlRunner
// (RunnerSkinner), usable only with the Device's GL context current.
#include <memory>

#include "runtime/backends/gl/gl_runner.h"
#include "runtime/skinner.h"

namespace skintune::internal {

namespace {

// kInvalidState unless the runner's context is (or can be made) current here.
void CheckCurrent(GlRunner& runner, const char* call) {
  try {
    runner.MakeCurrent();
  } catch (const Error& e) {
    FailWith(ErrorCode::kInvalidState, std::string(call) + ": " + e.what());
  }
}

class GlSkinner final : public RunnerSkinner {
 public:
  GlSkinner(GlRunner& runner, Prepared prepared) : RunnerSkinner(runner, std::move(prepared)), gl_runner_(runner) {}
  void CheckUsable() const override { CheckCurrent(gl_runner_, "Skinner"); }

 private:
  GlRunner& gl_runner_;
};

}  // namespace

std::unique_ptr<SkinnerBackend> MakeGlSkinner(DeviceState& device, const PackedMesh& mesh,
                                              const std::vector<KernelSource>& kernels, const SkinnerSetup& setup) {
  auto* runner = dynamic_cast<GlRunner*>(device.runner.get());
  if (!runner) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no GL context");
  CheckCurrent(*runner, "Skinner::Create");
  Prepared prepared = PrepareSkinnerSet(device, mesh, kernels, setup);
  return std::make_unique<GlSkinner>(*runner, std::move(prepared));
}

}  // namespace skintune::internal
