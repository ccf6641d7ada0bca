// The palette kernel's own time (docs/ANIMATION.md): a crowd's palettes made
// on a CUDA device from one upload of the animation, against what the host
// pays to make the same palettes (the float64 path the Skinner's callers use
// today, SkinnedAsset::PaletteAt, and the float32 CPU palette kernel).
//
//   cuda/<model>/<K>/one      one launch for K instances, each playing its own
//                             clip at its own time, timed by CUDA events
//                             around it (the events add about a microsecond)
//   cuda/<model>/<K>/burst    64 launches back to back between two events,
//                             per launch: the launch as a frame pays it when
//                             the skin kernel follows on the same stream
//   cuda/<model>/<K>/blend    burst, every instance cross-fading two clips
//   cuda/<model>/<K>/fade3    burst, every third instance cross-fading
//   cuda/<model>/<K>/<form>-baked<R>, -local<R>, -hybrid<R>
//                             burst, blend and fade3 with the clips baked at
//                             R frames a second (--bake-rate R, repeatable;
//                             docs/ANIMATION.md "Baked clips") as palette
//                             records, local ones and both; the counter
//                             max_error is the largest stated error of its clips
//   host/<model>/<K>/palette-at   K x SkinnedAsset::PaletteAt (float64, then float32)
//   host/<model>/<K>/cpu-kernel   RunPaletteKernel on one thread (float32)
//
// <model>: each --gltf file's name and each --synthetic data-set key (its
// rig: 77 bones by default, -bones<N> for more). Without a CUDA device the
// cuda/ cases are skipped with the reason.
#include <benchmark/benchmark.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "generator/emit.h"
#include "generator/palette_kernel.h"
#include "model/gltf_import.h"
#include "model/synthetic.h"
#include "runtime/backends/cuda/cuda_api.h"

namespace skintune::internal {
namespace {

struct Options {
  std::vector<std::string> gltf, synthetic;
  std::vector<int> instances = {64, 1024};
  std::vector<double> bake_rates;  // frames a second: each adds the baked forms
} options;

constexpr int kBurst = 64;

// Instance i plays clip i mod C at its own time; every `blend_every`-th
// (0: none) cross-fades to clip (i + 1) mod C half its length further on
// (a model of one clip: the same clip) at weight 0.5 ("blend": all of them;
// "fade3": every third, as the tuner's -animblend scenes).
std::vector<AnimInstance> Crowd(const SkinnedAsset& asset, const PackedAnimation& packed, int count, int blend_every) {
  std::vector<AnimInstance> crowd(static_cast<std::size_t>(count));
  const int clips = static_cast<int>(packed.clips.size());
  for (int i = 0; i < count; ++i) {
    const auto& clip = asset.animations[static_cast<std::size_t>(packed.clips[static_cast<std::size_t>(i % clips)])];
    const double phase = std::fmod(0.618034 * i, 1.0);
    AnimInstance& in = crowd[static_cast<std::size_t>(i)];
    in.clip = static_cast<std::uint16_t>(i % clips);
    in.time = static_cast<float>(clip.start + phase * clip.duration());
    if (blend_every > 0 && i % blend_every == 0) {  // the next clip (a model of one clip: elsewhere in it)
      in.clip2 = static_cast<std::uint16_t>((i + 1) % clips);
      const auto& other = asset.animations[static_cast<std::size_t>(packed.clips[in.clip2])];
      in.time2 = static_cast<float>(other.start + std::fmod(phase + 0.5, 1.0) * other.duration());
      in.weight = 0.5f;
    }
  }
  return crowd;
}

// palette.cu on device 0: the animation uploaded once, a crowd's instances
// and palettes per case.
class CudaPalettes {
 public:
  static CudaPalettes* Get(std::string& why) {
    static std::string reason;
    static const std::unique_ptr<CudaPalettes> made = []() -> std::unique_ptr<CudaPalettes> {
      if (!Probe().nvrtc) {
        reason = "NVRTC cannot be loaded";
        return nullptr;
      }
      const cuda::DriverApi* api = cuda::Driver(&reason);
      int count = 0;
      if (api == nullptr || api->cuDeviceGetCount(&count) != cuda::kSuccess || count == 0) {
        if (reason.empty()) reason = "no CUDA device";
        return nullptr;
      }
      return std::unique_ptr<CudaPalettes>(new CudaPalettes(*api));
    }();
    why = reason;
    return made.get();
  }

  // Uploads `packed` and `instances`; allocates the K palettes. The
  // kernel's buffers by their names (generator/palette_kernel.h): sampled
  // clips' five, or baked clips' frames; the states are the instances (a
  // fresh frame takes them).
  void Load(const PackedAnimation& packed, const std::vector<AnimInstance>& instances) {
    Free();
    const PaletteKernel kernel = EmitPalette(Lang::kCuda, packed.View(), 3);
    for (const KernelArgument& a : kernel.kernel.arguments) {
      if (a.kind != ArgumentKind::kBuffer) continue;
      const std::span<const std::uint8_t> bytes = a.name == kAnimInputs[5] || a.name == kAnimStates
                                                      ? BufferBytes(instances)
                                                      : AnimationBufferBytes(packed.View(), a.name);
      const std::size_t size =
          a.name == kAnimOutput ? instances.size() * packed.joints.size() * kAnimPaletteRows * 16 : bytes.size();
      cuda::DevicePtr& buffer = buffers_.emplace_back();
      Check(api_.cuMemAlloc(&buffer, std::max<std::size_t>(size, 16)), "cuMemAlloc");
      if (!bytes.empty()) Check(api_.cuMemcpyHtoD(buffer, bytes.data(), bytes.size()), "cuMemcpyHtoD");
    }
    instance_count_ = static_cast<unsigned>(instances.size());
    // The animation's own kernel (its counts are defines: EmitPalette).
    block_ = static_cast<unsigned>(kernel.kernel.launch.wg_size);  // palette.cu's ANIM_GROUP
    const CompileResult r = CompileWithNvrtc(kernel.kernel.text, arch_, "palette.cu");
    if (!r.ok) throw std::runtime_error(r.error);
    if (module_) api_.cuModuleUnload(module_);
    module_ = nullptr;
    Check(api_.cuModuleLoadDataEx(&module_, r.ptx.c_str(), 0, nullptr, nullptr), "cuModuleLoadDataEx");
    Check(api_.cuModuleGetFunction(&function_, module_, "skintune_palette"), "cuModuleGetFunction");
  }

  // Seconds of device time per launch, `launches` of them between two events.
  double Time(int launches) {
    float delta = 0.0f;
    unsigned fresh = 1;
    std::vector<void*> parameters;
    for (cuda::DevicePtr& buffer : buffers_) parameters.push_back(&buffer);
    parameters.push_back(&delta);
    parameters.push_back(&fresh);
    Check(api_.cuEventRecord(start_, nullptr), "cuEventRecord");
    for (int l = 0; l < launches; ++l)
      Check(api_.cuLaunchKernel(function_, 1, instance_count_, 1, block_, 1, 1, 0, nullptr, parameters.data(), nullptr),
            "cuLaunchKernel");
    Check(api_.cuEventRecord(end_, nullptr), "cuEventRecord");
    Check(api_.cuEventSynchronize(end_), "cuEventSynchronize");
    float ms = 0.0f;
    Check(api_.cuEventElapsedTime(&ms, start_, end_), "cuEventElapsedTime");
    return ms * 1e-3 / launches;
  }

 private:
  explicit CudaPalettes(const cuda::DriverApi& api) : api_(api) {
    cuda::Device device = 0;
    Check(api_.cuDeviceGet(&device, 0), "cuDeviceGet");
    int major = 0, minor = 0;
    Check(api_.cuDeviceGetAttribute(&major, cuda::kAttributeComputeCapabilityMajor, device), "compute capability");
    Check(api_.cuDeviceGetAttribute(&minor, cuda::kAttributeComputeCapabilityMinor, device), "compute capability");
    arch_ = NvrtcArchFor(major, minor);
    Check(api_.cuDevicePrimaryCtxRetain(&context_, device), "cuDevicePrimaryCtxRetain");
    Check(api_.cuCtxSetCurrent(context_), "cuCtxSetCurrent");
    Check(api_.cuEventCreate(&start_, 0), "cuEventCreate");
    Check(api_.cuEventCreate(&end_, 0), "cuEventCreate");
  }
  void Free() {
    for (cuda::DevicePtr& b : buffers_)
      if (b) api_.cuMemFree(b);
    buffers_.clear();
  }
  static void Check(cuda::Result result, const char* what) {
    if (result != cuda::kSuccess) throw std::runtime_error(std::string(what) + ": " + cuda::ErrorText(result));
  }

  const cuda::DriverApi& api_;
  cuda::Context context_ = nullptr;
  cuda::Module module_ = nullptr;
  cuda::Function function_ = nullptr;
  cuda::Event start_ = nullptr, end_ = nullptr;
  std::vector<cuda::DevicePtr> buffers_;  // in the kernel's argument order
  std::string arch_;
  unsigned instance_count_ = 0;
  unsigned block_ = 0;  // threads per block: the kernel's ANIM_GROUP
};

struct Model {
  std::string name;
  std::shared_ptr<SkinnedAsset> asset;
};

std::vector<Model> Models() {
  std::vector<Model> models;
  for (const std::string& file : options.gltf)
    models.push_back({std::filesystem::path(file).filename().string(),
                      std::make_shared<SkinnedAsset>(ImportGltf(file).asset)});
  for (const std::string& key : options.synthetic)
    models.push_back({key, std::make_shared<SkinnedAsset>(GenerateDataset(ParseDatasetKey(key)))});
  return models;
}

// `rate` > 0: the clips baked at that many frames a second.
void RegisterCuda(const Model& m, int k, const char* form, double rate = 0.0, BakeSpace space = BakeSpace::kPalette) {
  char baked[32] = "";
  if (rate > 0.0)
    std::snprintf(baked, sizeof baked,
                  space == BakeSpace::kHybrid  ? "-hybrid%g"
                  : space == BakeSpace::kLocal ? "-local%g"
                                               : "-baked%g",
                  rate);
  const std::string name = "cuda/" + m.name + "/" + std::to_string(k) + "/" + form + baked;
  const std::string kind = form;
  benchmark::RegisterBenchmark(name.c_str(), [m, k, kind, rate, space](benchmark::State& state) {
    std::string why;
    CudaPalettes* cuda = CudaPalettes::Get(why);
    if (cuda == nullptr) {
      state.SkipWithError(why.c_str());
      return;
    }
    const PackedAnimation packed = rate > 0.0 ? BakeAnimation(*m.asset, rate, space) : PackAnimation(*m.asset);
    const std::vector<AnimInstance> crowd = Crowd(*m.asset, packed, k, kind == "blend" ? 1 : kind == "fade3" ? 3 : 0);
    cuda->Load(packed, crowd);
    const int launches = kind == "one" ? 1 : kBurst;
    cuda->Time(launches);  // warm: the module's first launch
    for (auto _ : state) state.SetIterationTime(cuda->Time(launches));
    state.counters["joints"] = static_cast<double>(packed.joints.size());
    state.counters["animation_bytes"] = static_cast<double>(packed.Bytes());
    double worst = 0.0;
    for (const BakedClipInfo& clip : packed.baked) worst = std::max(worst, clip.max_error);
    if (rate > 0.0) state.counters["max_error"] = worst;
  })->UseManualTime()->Unit(benchmark::kMicrosecond);
}

void RegisterHost(const Model& m, int k) {
  const std::string base = "host/" + m.name + "/" + std::to_string(k);
  benchmark::RegisterBenchmark((base + "/palette-at").c_str(), [m, k](benchmark::State& state) {
    const PackedAnimation packed = PackAnimation(*m.asset);
    const std::vector<AnimInstance> crowd = Crowd(*m.asset, packed, k, 0);
    for (auto _ : state)
      for (const AnimInstance& in : crowd)
        benchmark::DoNotOptimize(m.asset->PaletteAt(packed.clips[in.clip], in.time));
  })->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark((base + "/cpu-kernel").c_str(), [m, k](benchmark::State& state) {
    const PackedAnimation packed = PackAnimation(*m.asset);
    const std::vector<AnimInstance> crowd = Crowd(*m.asset, packed, k, 0);
    std::vector<float> rows(crowd.size() * packed.joints.size() * kAnimPaletteRows * 4);
    for (auto _ : state) {
      RunPaletteKernel(packed.View(), crowd, rows.data());
      benchmark::DoNotOptimize(rows.data());
    }
  })->Unit(benchmark::kMicrosecond);
}

void ParseOptions(int& argc, char** argv) {
  CLI::App app{"skintune_bench_palette: the palette kernel's own time on a CUDA device, against the host's"};
  app.allow_extras();
  app.add_option("--gltf", options.gltf, "a skinned glTF with animations (repeatable)")->check(CLI::ExistingFile);
  app.add_option("--synthetic", options.synthetic, "a synthetic data-set key, for its rig (repeatable)");
  app.add_option("--instances", options.instances, "crowd sizes (repeatable)")->check(CLI::Range(1, 1 << 16));
  app.add_option("--bake-rate", options.bake_rates,
                 "also time the clips baked at this many frames a second, as palette records (-baked), local "
                 "ones (-local) and both (-hybrid) (repeatable)")
      ->check(CLI::Range(1e-3, kAnimMaxBakeRate));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    std::exit(app.exit(e));
  }
  static std::vector<std::string> rest;
  rest = app.remaining();
  argc = 1;
  for (std::string& r : rest) argv[argc++] = r.data();
}

}  // namespace
}  // namespace skintune::internal

int main(int argc, char** argv) {
  using namespace skintune::internal;
  ParseOptions(argc, argv);
  try {
    for (const Model& m : Models()) {
      for (int k : options.instances) {
        for (const char* form : {"one", "burst", "blend", "fade3"}) RegisterCuda(m, k, form);
        for (const double rate : options.bake_rates)
          for (const BakeSpace space : {BakeSpace::kPalette, BakeSpace::kLocal, BakeSpace::kHybrid})
            for (const char* form : {"burst", "blend", "fade3"}) RegisterCuda(m, k, form, rate, space);
        RegisterHost(m, k);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "skintune_bench_palette: %s\n", e.what());
    return 2;
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
