// skintune (internal): the runner driver (runtime/runner.h) on a CUDA
// device. Its DeviceApi (cuda_runner.cpp):
//
// - CUDA is loaded at run time (cuda_api.h): this builds everywhere and the
//   constructor throws Error("CUDA setup: ...") where there is no driver or
//   device.
// - Build: each distinct KernelSource is compiled once per runner with NVRTC
//   to PTX for the device's architecture (NvrtcArchFor) and loaded with
//   cuModuleLoadDataEx; a failure throws Error("CUDA build ...") with the
//   first lines of the NVRTC log, or of the driver's JIT log. The program
//   cache holds the PTX (CompilePtxCached), keyed by device, source hash and
//   architecture; the driver still JIT-compiles PTX at module load.
// - Launches: blocks of the kernel's wg_size, a parameter array per launch
//   and input set; instanced kernels a grid (blocks, K). K above the grid's y
//   limit or the texture width throws Error("CUDA launch ...") naming it.
// - Palette: a device buffer (local, global); for `constant` storage the rows
//   are also copied into the module's __constant__ symbol `skintune_palette`
//   (cuModuleGetGlobal, sized for the kernel's joints and max_instances; the
//   kernel's `palette` argument gets the buffer but is not read): from the
//   host before each launch of Run and Time (outside the events), on the
//   caller's stream from the set's palette buffer before each Skinner launch
//   (the module, and its symbol, is shared by every set and Skinner of the
//   same kernel). For `image` storage the argument is a texture object over
//   the buffer (linear, float4 texels).
// - Times: CUDA events recorded around each cuLaunchKernel (Run and Time on
//   the legacy default stream, then cuCtxSynchronize).
// - Skinning: palette uploads (cuMemcpyHtoDAsync from each palette slot's
//   page-locked, write-combined staging), launches, the ring's fences
//   (events) and read-backs (cuMemcpyDtoHAsync into page-locked memory, then
//   cuStreamSynchronize) go to the runner's stream.
// Errors name the stage: "CUDA setup", "build", "launch" or "guard". A kernel
// that faults (an illegal address) leaves the CUDA context unusable: later
// runs of the same runner fail too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "runtime/backends/cuda/cuda_devices.h"
#include "runtime/program_cache.h"
#include "runtime/runner.h"

namespace skintune::internal {

// NVRTC's PTX of `source` for `arch` ("compute_90"), from `cache` when it
// holds it (key: device_id, source hash, arch), else compiled and stored
// there; counts a build or a disk hit. Needs NVRTC only, not a driver.
// Throws Error("CUDA build: ...") with the NVRTC log when it does not compile.
std::string CompilePtxCached(const KernelSource& source, const std::string& arch, ProgramCache* cache,
                             const std::string& device_id);

class CudaApi;

class CudaRunner final : public Runner {
 public:
  // CUDA device `device_index` (0 .. Probe().device_count - 1), through its
  // primary context. Throws Error("CUDA setup: ...") when there is no NVRTC,
  // no driver, or no such device.
  explicit CudaRunner(int device_index = 0);
  // Device `device_index` through a context made for this runner alone
  // (cuCtxCreate), destroyed with it: the device's start of a launch after
  // the command before it differs by up to 0.16 us from one context to the
  // next and not within one (docs/TUNING.md "Kernel time"), so the tuner
  // opens several and times on the quickest. Throws Error("CUDA setup: ...")
  // as above, or where the driver makes no such context.
  struct OwnContext {};
  CudaRunner(int device_index, OwnContext);
  // A context and stream the caller made (CUcontext, CUstream; a null stream
  // is the legacy default stream), neither retained: they must outlive the
  // runner. Its skinning launches and copies go to that stream. Throws
  // Error("CUDA setup: ...") without a driver or NVRTC, or for a null context.
  CudaRunner(void* cu_context, void* cu_stream);

  const std::string& arch() const;  // what NVRTC compiles for, e.g. "compute_90"
  // The device's limits for CheckVariant: threads per block, static __shared__
  // and __constant__ bytes, linear texture width in texels.
  const DeviceLimits& limits() const;
  const CudaDeviceInfo& info() const;
  // The context (CUcontext) and the skinning stream (CUstream; null: the
  // legacy default stream), for the Skinner's CUDA-GL interop.
  void* context() const;
  void* stream() const;
};

using CudaRunResult = RunResult;
using CudaPrepared = Prepared;

}  // namespace skintune::internal
