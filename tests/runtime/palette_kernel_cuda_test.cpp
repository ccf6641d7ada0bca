// templates/palette.cu, the CUDA palette kernel (docs/ANIMATION.md), compiled
// with NVRTC: it must compile cleanly and take the same eleven arguments as
// templates/palette.cl, which
// tests/generator/palette_kernel_test.cpp runs against the gold. Where a CUDA
// device is, it runs through the driver API against the same float64 gold,
// the same bound and the same instances (tests/generator/palette_gold.h);
// without NVRTC or a device the tests skip naming what was tried.
// (No check for a stack frame, unlike the skin kernels' test: sinf's
// reduction of huge arguments keeps one in the PTX, on a path the slerp's
// angles, 0..pi/2, never take.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/clip_packer.h"
#include "generator/emit.h"
#include "generator/palette_kernel.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "tests/common/test_asset.h"
#include "tests/generator/deep_rig.h"
#include "tests/generator/palette_checks.h"
#include "tests/generator/palette_gold.h"

namespace skintune::internal {
namespace {

TEST(PaletteKernelCuda, CompilesCleanlyWithNvrtcWithTheOpenClKernelsArguments) {
  static const CudaAvailability available = Probe();
  if (!available.nvrtc) GTEST_SKIP() << "NVRTC cannot be loaded: " << available.nvrtc_missing;
  const CompileResult r = CompileWithNvrtc(ExpandedTemplate("palette.cu"), "compute_90", "palette.cu");
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.log.find("warning"), std::string::npos) << r.log;
  EXPECT_NE(r.ptx.find(".entry skintune_palette("), std::string::npos) << "no extern \"C\" entry skintune_palette";
  // nodes .. palette, clips, states, delta, fresh: parameters 0..10, as in palette.cl (the counts are defines).
  EXPECT_NE(r.ptx.find("skintune_palette_param_10"), std::string::npos);
  EXPECT_EQ(r.ptx.find("skintune_palette_param_11"), std::string::npos);
  // The instance is the grid's y, the joint its x.
  EXPECT_NE(r.ptx.find("%ctaid.y"), std::string::npos);
  // Baked clips: frames, instances, palette, clips, states, delta, fresh.
  // Both record forms (Fox's similarities, the deep rig's stretches).
  for (const SkinnedAsset* asset : {&testing::TestAsset("Fox.gltf"), &testing::DeepRig()}) {
    const PackedAnimation baked = BakeAnimation(*asset, 30.0);
    const CompileResult b =
        CompileWithNvrtc(EmitPalette(Lang::kCuda, baked.View(), 3).kernel.text, "compute_90", "palette.cu (baked)");
    ASSERT_TRUE(b.ok) << b.error;
    EXPECT_EQ(b.log.find("warning"), std::string::npos) << b.log;
    EXPECT_NE(b.ptx.find("skintune_palette_param_6"), std::string::npos);
    EXPECT_EQ(b.ptx.find("skintune_palette_param_7"), std::string::npos);
  }
}

using testing::Blends;
using testing::ExpectBakedClipsMatchTheirFrames;
using testing::ExpectBlendsMatchTheGold;
using testing::ExpectEveryClipOfTheGltfModelsMatchesTheGold;
using testing::ExpectNanRowsForAClipOutOfRange;
using testing::ExpectTheDeepRigMatchesTheGold;
using testing::On;
using testing::PaletteInputBytes;
using testing::Compare;
using testing::DeepRig;
using testing::EveryClipAlone;
using testing::ExpectWithinBound;
using testing::Name;
using testing::TestAsset;


// palette.cu for device 0, in its primary context: each packed animation's
// kernel (EmitPalette) compiled and loaded once.
class CudaPaletteKernel {
 public:
  // Null, with the reason in `why`, without NVRTC, a driver or a device.
  static CudaPaletteKernel* Get(std::string& why) {
    static std::string reason;
    static const std::unique_ptr<CudaPaletteKernel> kernel = []() -> std::unique_ptr<CudaPaletteKernel> {
      const CudaAvailability available = Probe();
      if (!available.nvrtc) {
        reason = "NVRTC cannot be loaded: " + available.nvrtc_missing;
        return nullptr;
      }
      const cuda::DriverApi* api = cuda::Driver(&reason);
      if (api == nullptr) return nullptr;
      int count = 0;
      if (api->cuDeviceGetCount(&count) != cuda::kSuccess || count == 0) {
        reason = "no CUDA device";
        return nullptr;
      }
      return std::unique_ptr<CudaPaletteKernel>(new CudaPaletteKernel(*api));
    }();
    why = reason;
    return kernel.get();
  }

  // The palette rows of `instances`, as RunPaletteKernel writes them.
  std::vector<float> Run(const PackedAnimation& packed, const std::vector<AnimInstance>& instances) {
    Check(api_.cuCtxSetCurrent(context_), "cuCtxSetCurrent");
    const std::size_t joints = packed.joints.size();
    std::vector<float> rows(instances.size() * joints * 12);
    const PaletteKernel kernel = EmitPalette(Lang::kCuda, packed.View(), 3);
    // Every buffer by its name (the palette allocated, read back below), then
    // delta and fresh: a fresh frame, so the states are the instances.
    std::vector<cuda::DevicePtr> buffers;
    cuda::DevicePtr palette = 0;
    for (const KernelArgument& a : kernel.kernel.arguments) {
      if (a.kind != ArgumentKind::kBuffer) continue;
      const std::span<const std::uint8_t> bytes = PaletteInputBytes(packed, instances, a.name);
      cuda::DevicePtr& buffer = buffers.emplace_back();
      const std::size_t size = a.name == kAnimOutput ? rows.size() * sizeof(float) : bytes.size();
      Check(api_.cuMemAlloc(&buffer, std::max<std::size_t>(size, 16)), "cuMemAlloc");  // no empty allocation
      if (!bytes.empty()) Check(api_.cuMemcpyHtoD(buffer, bytes.data(), bytes.size()), "cuMemcpyHtoD");
      if (a.name == kAnimOutput) palette = buffer;
    }
    float delta = 0.0f;
    unsigned fresh = 1;
    std::vector<void*> parameters;
    for (cuda::DevicePtr& buffer : buffers) parameters.push_back(&buffer);
    parameters.push_back(&delta);
    parameters.push_back(&fresh);
    const auto instance_count = static_cast<unsigned>(instances.size());
    const auto block = static_cast<unsigned>(kernel.kernel.launch.wg_size);  // palette.cu's ANIM_GROUP, a block per instance
    Check(api_.cuLaunchKernel(FunctionFor(kernel.kernel.text), 1, instance_count, 1, block, 1, 1, 0, nullptr,
                              parameters.data(), nullptr),
          "cuLaunchKernel");
    Check(api_.cuCtxSynchronize(), "cuCtxSynchronize");
    Check(api_.cuMemcpyDtoH(rows.data(), palette, rows.size() * sizeof(float)), "cuMemcpyDtoH");
    for (cuda::DevicePtr b : buffers) api_.cuMemFree(b);
    return rows;
  }

 private:
  explicit CudaPaletteKernel(const cuda::DriverApi& api) : api_(api) {
    cuda::Device device = 0;
    Check(api_.cuDeviceGet(&device, 0), "cuDeviceGet");
    int major = 0, minor = 0;
    Check(api_.cuDeviceGetAttribute(&major, cuda::kAttributeComputeCapabilityMajor, device), "compute capability");
    Check(api_.cuDeviceGetAttribute(&minor, cuda::kAttributeComputeCapabilityMinor, device), "compute capability");
    arch_ = NvrtcArchFor(major, minor);
    Check(api_.cuDevicePrimaryCtxRetain(&context_, device), "cuDevicePrimaryCtxRetain");
    Check(api_.cuCtxSetCurrent(context_), "cuCtxSetCurrent");
  }

  // The kernel of `text`, compiled and loaded once.
  cuda::Function FunctionFor(const std::string& text) {
    const std::string hash = SourceHash(text);
    if (const auto found = functions_.find(hash); found != functions_.end()) return found->second;
    const CompileResult r = CompileWithNvrtc(text, arch_, "palette.cu");
    if (!r.ok) throw std::runtime_error(r.error);
    cuda::Module module = nullptr;
    Check(api_.cuModuleLoadDataEx(&module, r.ptx.c_str(), 0, nullptr, nullptr), "cuModuleLoadDataEx");
    cuda::Function function = nullptr;
    Check(api_.cuModuleGetFunction(&function, module, "skintune_palette"), "cuModuleGetFunction");
    return functions_[hash] = function;  // the module lives as long as the context
  }

  static void Check(cuda::Result result, const char* what) {
    if (result != cuda::kSuccess) throw std::runtime_error(std::string(what) + ": " + cuda::ErrorText(result));
  }

  const cuda::DriverApi& api_;
  cuda::Context context_ = nullptr;
  std::string arch_;
  std::map<std::string, cuda::Function> functions_;  // by source hash
};

#define SKIP_WITHOUT_CUDA(kernel)                          \
  std::string why;                                         \
  CudaPaletteKernel* kernel = CudaPaletteKernel::Get(why); \
  if (kernel == nullptr) GTEST_SKIP() << why

TEST(PaletteKernelCuda, MatchesTheGoldForEveryClipOfTheGltfModels) {
  SKIP_WITHOUT_CUDA(kernel);
  ExpectEveryClipOfTheGltfModelsMatchesTheGold(On(kernel), "cuda");
}

TEST(PaletteKernelCuda, MatchesTheGoldOnADeepRigWithEveryInterpolation) {
  SKIP_WITHOUT_CUDA(kernel);
  ExpectTheDeepRigMatchesTheGold(On(kernel), "cuda");
}

TEST(PaletteKernelCuda, BlendsTwoClipsInLocalSpaceLikeTheGold) {
  SKIP_WITHOUT_CUDA(kernel);
  ExpectBlendsMatchTheGold(On(kernel), "cuda");
}

TEST(PaletteKernelCuda, WritesNanRowsForAClipOutOfRangeInsteadOfReadingBeyond) {
  SKIP_WITHOUT_CUDA(kernel);
  ExpectNanRowsForAClipOutOfRange(On(kernel));
}

TEST(PaletteKernelCuda, BakedClipsMatchTheirFramesAloneAndBlended) {
  SKIP_WITHOUT_CUDA(kernel);
  ExpectBakedClipsMatchTheirFrames(On(kernel), "cuda");
  ExpectNanRowsForAClipOutOfRange(On(kernel), Animation::kBaked30);
  ExpectNanRowsForAClipOutOfRange(On(kernel), Animation::kLocal30);
}

}  // namespace
}  // namespace skintune::internal
