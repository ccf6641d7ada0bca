// templates/palette.cu, the CUDA palette kernel (docs/ANIMATION.md), compiled
// with NVRTC: it must compile cleanly and take the same eleven arguments as
// templates/palette.cl, which
// tests/generator/palette_kernel_test.cpp runs against the gold. Running it
// needs a CUDA device; without NVRTC the test skips naming what was tried.
// (No check for a stack frame, unlike the skin kernels' test: sinf's
// reduction of huge arguments keeps one in the PTX, on a path the slerp's
// angles, 0..pi/2, never take.)
#include <gtest/gtest.h>

#include <string>

#include "generator/emit.h"
#include "runtime/backends/cuda/cuda_api.h"

namespace skintune::internal {
namespace {

TEST(PaletteKernelCuda, CompilesCleanlyWithNvrtcWithTheOpenClKernelsArguments) {
  static const CudaAvailability available = Probe();
  if (!available.nvrtc) GTEST_SKIP() << "NVRTC cannot be loaded: " << available.nvrtc_missing;
  const CompileResult r = CompileWithNvrtc(ExpandedTemplate("palette.cu"), "compute_90", "palette.cu");
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.log.find("warning"), std::string::npos) << r.log;
  EXPECT_NE(r.ptx.find(".entry skintune_palette("), std::string::npos) << "no extern \"C\" entry skintune_palette";
  // node_count .. palette: parameters 0..10, as in palette.cl.
  EXPECT_NE(r.ptx.find("skintune_palette_param_10"), std::string::npos);
  EXPECT_EQ(r.ptx.find("skintune_palette_param_11"), std::string::npos);
  // The instance is the grid's y, the joint its x.
  EXPECT_NE(r.ptx.find("%ctaid.y"), std::string::npos);
}

}  // namespace
}  // namespace skintune::internal
