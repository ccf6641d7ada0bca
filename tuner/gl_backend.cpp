// skintune: the OpenGL backend: one headless GL 4.3+ core context through EGL
// (runtime/backends/gl/gl_context.h), measuring glsl-compute and glsl-vertex variants
// through GlRunner.
#include <memory>

#include "reference/error.h"
#include "runtime/device_identity.h"
#include "runtime/backends/gl/gl_context.h"
#include "runtime/backends/gl/gl_runner.h"
#include "tuner/backends_internal.h"

namespace skintune::tuner_internal {

namespace {

class GlBackend final : public Backend {
 public:
  GlBackend(std::unique_ptr<GlRunner> runner, int index) : runner_(std::move(runner)) {
    const GlContextInfo& info = runner_->info();
    identity_.backend = "gl";
    identity_.index = index;
    identity_.platform = info.egl_platform;
    identity_.vendor = info.vendor;
    identity_.name = info.renderer;
    identity_.driver_version = info.version;  // GL_VERSION names the driver: "4.5 (Core Profile) Mesa 22.3.6"
    identity_.api_version = info.version;
    identity_.type = GlDeviceType(info.renderer);
    identity_.compute_units = 0;              // GL does not say
    identity_.global_memory_bytes = 0;        // core GL does not say
    identity_.local_memory_bytes = info.max_compute_shared_memory_bytes;
    identity_.constant_memory_bytes = info.max_uniform_block_bytes;
    identity_.last_level_cache_bytes = 0;     // unknown: the rotation rule assumes 64 MiB
  }

  const DeviceIdentity& identity() const override { return identity_; }
  DeviceLimits limits() const override { return LimitsOf(runner_->info()); }
  std::vector<Lang> languages() const override { return {Lang::kGlslCompute, Lang::kGlslVertex}; }

  Measurement Measure(const Variant& variant, const TuningDataset& dataset, const TimingOptions& options) override {
    RunnerExecutor<GlRunner> executor(*runner_);
    return MeasureWith(executor, datasets_, identity_, limits(), languages(), variant, dataset, options);
  }

  double CopyBandwidthGBps(std::size_t bytes) override {
    // The largest buffer a shader can bind stands for the largest allocation.
    const std::size_t size = CopyBytesCapped(bytes, runner_->info().max_shader_storage_block_bytes);
    return CopyGBps(size, runner_->TimeCopy(size, 2, 10));
  }

 private:
  std::unique_ptr<GlRunner> runner_;
  DeviceIdentity identity_;
  DatasetCache datasets_;
};

}  // namespace

std::unique_ptr<Backend> MakeGlBackend(int index, std::string& why) {
  std::unique_ptr<GlRunner> runner;
  try {
    runner = std::make_unique<GlRunner>();
  } catch (const Error& e) {
    why = e.what();
    return nullptr;
  }
  return std::make_unique<GlBackend>(std::move(runner), index);
}

}  // namespace skintune::tuner_internal
