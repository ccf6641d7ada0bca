// GL in the backend table (runtime/backend_table.h): one device when a
// headless EGL context (GL 4.3 core) opens, OpenBest's rank, and
// Device::FromCurrentGl on the caller's current context.
#include <memory>

#include "runtime/api_errors.h"
#include "runtime/backend_table.h"
#include "runtime/backends/gl/gl_context.h"
#include "runtime/backends/gl/gl_runner.h"
#include "runtime/device.h"
#include "runtime/skinner.h"

namespace skintune::internal {

// skinner_gl.cpp
std::unique_ptr<SkinnerBackend> MakeGlSkinner(DeviceState& device, const PackedMesh& mesh,
                                              const std::vector<KernelSource>& kernels, const SkinnerSetup& setup);

namespace {

// A context made to ask GL about itself, then destroyed; the caller's current
// context is current again afterwards. Opening makes the runner's own context.
void Discover(Discovered& out) {
  CurrentGlRestorer keep_callers_context;
  GlContext context;
  if (!context.ok()) {
    out.skipped.push_back("gl: skipped: GL setup: " + context.reason());
    return;
  }
  FoundDevice found;
  found.identity = IdentityOf(context.info());
  found.limits = LimitsOf(context.info());
  // The largest buffer a shader can bind stands for the largest allocation.
  found.max_allocation_bytes = context.info().max_shader_storage_block_bytes;
  found.open = []() -> std::unique_ptr<Runner> { return std::make_unique<GlRunner>(); };
  out.devices.push_back(std::move(found));
}

// GL on a GPU after CUDA and OpenCL GPUs (2); on a CPU last (5).
int Preference(const DeviceIdentity& d) { return d.type.find("gpu") != std::string::npos ? 2 : 5; }

}  // namespace

BackendEntry GlEntry() {
  return {"gl", "GL", {Lang::kGlslCompute, Lang::kGlslVertex}, Discover, Preference, MakeGlSkinner};
}

}  // namespace skintune::internal

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

Result<Device> Device::FromCurrentGl(const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    std::unique_ptr<GlContext> context = GlContext::AdoptCurrent();
    if (!context->ok()) FailWith(ErrorCode::kUnavailable, "Device::FromCurrentGl: " + context->reason());
    const DeviceIdentity identity = IdentityOf(context->info());
    const DeviceLimits limits = LimitsOf(context->info());
    return MakeDevice(options, identity, limits, std::make_unique<GlRunner>(std::move(context)));
  });
}

}  // namespace skintune
