// The CUDA Skinner: one prepared input set of the device's CudaRunner
// (runtime/backends/cuda/cuda_runner.h), written, launched and read per frame on the
// Device's stream.
#include <memory>

#include "runtime/backends/cuda/cuda_runner.h"
#include "runtime/skinner.h"

namespace skintune {

std::unique_ptr<SkinnerBackend> MakeCudaSkinner(DeviceState& device, const PackedMesh& mesh,
                                                const std::vector<KernelSource>& kernels, int instances) {
  if (!device.cuda) FailWith(ErrorCode::kInvalidState, "Skinner::Create: the Device has no CUDA context");
  std::unique_ptr<SkinnerBackend> skinner;
  RunOnDevice(
      [&] {
        skinner = std::make_unique<RunnerSkinner<CudaRunner, CudaPrepared>>(
            *device.cuda, device.cuda->Prepare(mesh, kernels, RestPalettes(mesh, instances), instances),
            mesh.variant.normals);
      },
      "Skinner::Create: ");
  return skinner;
}

}  // namespace skintune
