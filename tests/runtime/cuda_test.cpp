// CUDA: templates/skin.cu through NVRTC, and the CUDA runner against the gold.
//
// - Compile-only (needs NVRTC, no GPU): a pairwise covering array of the
//   CUDA variant space, built by a small greedy generator below, every row
//   compiled with NVRTC; any error, any warning, or a stack frame in the PTX
//   (an array the template expects in registers) fails. Plus the template
//   alone with no defines, and the NVRTC error path.
// - Runs (need a CUDA driver and GPU): ~30 variants against the float64 gold
//   on a fresh random synthetic mesh each run (the seed is printed;
//   SKINTUNE_TEST_SEED=<n> reproduces a run) and on CesiumMan for the
//   bucketed launches; the poisoned output, the guard and build errors.
// Every test that cannot run here skips with what is missing (the NVRTC
// libraries tried, or why there is no driver or device).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <iostream>
#include <memory>
#include <random>
#include <set>

#include "generator/constraints.h"
#include "generator/covering.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "base/error.h"
#include "runner_test_support.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/cuda/cuda_runner.h"
#include "runtime/run_shape.h"

namespace skintune::internal {
namespace {

using testing::Asset;
using testing::Case;
using testing::CaseName;
using testing::ExpectCaseMatchesGold;
using testing::ExpectCoveringSetMatchesGold;
using testing::ExpectHalfPoisoned;
using testing::ExpectRunFails;
using testing::Faulty;
using testing::LaunchTimes;
using testing::Seed;
using testing::WithFault;

constexpr const char* kCompileArch = "compute_90";  // any architecture NVRTC 12/13 supports
constexpr int kJoints = 77;                          // the synthetic rig's; sizes local/constant palettes
constexpr int kMorphTargets = 4;                     // morph variants' (testing::CoveringShape's)

const CudaAvailability& Available() {
  static const CudaAvailability a = Probe();
  return a;
}

#define SKIP_WITHOUT_NVRTC()                                                          \
  if (!Available().nvrtc) GTEST_SKIP() << "NVRTC cannot be loaded: " << Available().nvrtc_missing

// ---------------------------------------------------------------- covering array

// One axis of the CUDA variant space as the key tokens of its values. The
// work axis joins vertices per item and assignment (v1s does not exist).
struct Axis {
  const char* name;
  std::vector<const char*> tokens;
};

const std::vector<Axis>& Axes() {
  static const std::vector<Axis> axes = {
      {"influences", {"b1", "b2", "b3", "b4", "b5", "b6", "b7", "b8"}},
      {"mixed", {"padded", "bucketed"}},
      {"layout", {"aos", "soa", "soa-split"}},
      {"position", {"float4", "float3"}},
      {"index", {"i32", "u16", "u8"}},
      {"weight", {"f32", "unorm16", "unorm8"}},
      {"palette", {"mat4", "mat3x4"}},
      {"storage", {"constant", "local", "global", "image"}},
      {"blend", {"matrix", "point"}},
      {"work", {"v1c", "v2c", "v2s", "v4c", "v4s", "v8c", "v8s"}},
      {"wg", {"wg32", "wg64", "wg128", "wg256", "wg512", "wg1024"}},
      {"normals", {"nonormals", "normals", "tangents"}},
      {"morph", {"nomorph", "morph-dense", "morph-sparse", "morph-dense-half", "morph-sparse-half"}},
  };
  return axes;
}

using Row = std::vector<std::size_t>;  // a value index per axis

// Pairs of (axis a, value i) x (axis b, value j), a < b, not yet in any row.
class PairSet {
 public:
  explicit PairSet(const std::vector<std::size_t>& sizes) : sizes_(sizes) {
    for (std::size_t a = 0; a < sizes.size(); ++a)
      for (std::size_t b = a + 1; b < sizes.size(); ++b)
        for (std::size_t i = 0; i < sizes[a]; ++i)
          for (std::size_t j = 0; j < sizes[b]; ++j) open_.insert(Key(a, i, b, j));
  }
  bool Open(std::size_t a, std::size_t i, std::size_t b, std::size_t j) const {
    return a < b ? open_.count(Key(a, i, b, j)) > 0 : open_.count(Key(b, j, a, i)) > 0;
  }
  void Cover(const Row& row) {
    for (std::size_t a = 0; a < row.size(); ++a)
      for (std::size_t b = a + 1; b < row.size(); ++b) open_.erase(Key(a, row[a], b, row[b]));
  }
  bool Empty() const { return open_.empty(); }
  std::size_t Size() const { return open_.size(); }
  // The first open pair, as (a, i, b, j).
  std::array<std::size_t, 4> First() const {
    const std::uint64_t k = *open_.begin();
    return {static_cast<std::size_t>(k >> 48), static_cast<std::size_t>(k >> 32 & 0xffff),
            static_cast<std::size_t>(k >> 16 & 0xffff), static_cast<std::size_t>(k & 0xffff)};
  }

 private:
  static std::uint64_t Key(std::size_t a, std::size_t i, std::size_t b, std::size_t j) {
    return static_cast<std::uint64_t>(a) << 48 | static_cast<std::uint64_t>(i) << 32 |
           static_cast<std::uint64_t>(b) << 16 | static_cast<std::uint64_t>(j);
  }
  std::vector<std::size_t> sizes_;
  std::set<std::uint64_t> open_;
};

// Greedy pairwise covering array (AETG-style): each new row starts from the
// first uncovered pair, then fixes the other axes in a random order, each to
// the value that covers most open pairs with the axes fixed so far; the best
// of several such candidates is kept. std::mt19937's sequence is fixed by the
// standard, so the rows are the same on every machine.
std::vector<Row> CoveringArray(const std::vector<std::size_t>& sizes, std::uint32_t seed, int candidates = 24) {
  std::mt19937 rng(seed);
  PairSet open(sizes);
  std::vector<Row> rows;
  const std::size_t axes = sizes.size();
  while (!open.Empty()) {
    Row best;
    std::size_t best_gain = 0;
    for (int c = 0; c < candidates; ++c) {
      const auto [a0, i0, b0, j0] = open.First();
      Row row(axes, 0);
      std::vector<bool> fixed(axes, false);
      row[a0] = i0, row[b0] = j0;
      fixed[a0] = fixed[b0] = true;
      std::vector<std::size_t> order;
      for (std::size_t a = 0; a < axes; ++a)
        if (!fixed[a]) order.push_back(a);
      for (std::size_t k = order.size(); k > 1; --k) std::swap(order[k - 1], order[rng() % k]);
      for (const std::size_t a : order) {
        std::size_t chosen = rng() % sizes[a], chosen_gain = 0;
        for (std::size_t v = 0; v < sizes[a]; ++v) {
          std::size_t gain = 0;
          for (std::size_t b = 0; b < axes; ++b)
            if (fixed[b] && open.Open(a, v, b, row[b])) ++gain;
          if (gain > chosen_gain) chosen = v, chosen_gain = gain;
        }
        row[a] = chosen;
        fixed[a] = true;
      }
      std::size_t gain = 0;
      for (std::size_t a = 0; a < axes; ++a)
        for (std::size_t b = a + 1; b < axes; ++b) gain += open.Open(a, row[a], b, row[b]) ? 1 : 0;
      if (gain > best_gain) best = row, best_gain = gain;
    }
    open.Cover(best);
    rows.push_back(best);
  }
  return rows;
}

std::vector<std::size_t> AxisSizes() {
  std::vector<std::size_t> sizes;
  for (const Axis& axis : Axes()) sizes.push_back(axis.tokens.size());
  return sizes;
}

std::string KeyOf(const Row& row) {
  std::string key = "cuda";
  for (std::size_t a = 0; a < row.size(); ++a) key += std::string(".") + Axes()[a].tokens[row[a]];
  return key;
}

const std::vector<std::string>& CoveringKeys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const Row& row : CoveringArray(AxisSizes(), 20240611)) k.push_back(KeyOf(row));
    return k;
  }();
  return keys;
}

// The driver's sticky errors are stage "lost" whatever the caller's stage (the
// tune worker then exits); every other result keeps the caller's. No GPU needed.
TEST(CudaCheck, AStickyErrorIsStageLost) {
  const auto message = [](cuda::Result r) {
    try {
      cuda::Check(r, "launch", "cuStreamSynchronize");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  for (const cuda::Result r : cuda::kContextLostResults)
    EXPECT_EQ(message(r).rfind("CUDA lost: cuStreamSynchronize failed: ", 0), 0u) << message(r);
  EXPECT_EQ(message(cuda::kErrorInvalidValue).rfind("CUDA launch: cuStreamSynchronize failed: ", 0), 0u)
      << message(cuda::kErrorInvalidValue);
  EXPECT_EQ(message(cuda::kErrorNotReady).rfind("CUDA launch: ", 0), 0u);
  EXPECT_EQ(message(cuda::kSuccess), "no error");
}

TEST(CudaCoveringArray, CoversEveryPairOfAxisValues) {
  const std::vector<std::size_t> sizes = AxisSizes();
  PairSet open(sizes);
  std::size_t largest_product = 0;
  for (std::size_t a = 0; a < sizes.size(); ++a)
    for (std::size_t b = a + 1; b < sizes.size(); ++b) largest_product = std::max(largest_product, sizes[a] * sizes[b]);
  std::set<std::string> distinct;
  for (const std::string& key : CoveringKeys()) {
    const Variant v = ParseVariantKey(key);  // every row is a valid key
    EXPECT_EQ(v.lang, Lang::kCuda);
    distinct.insert(v.Key());
    Row row;
    for (const Axis& axis : Axes()) {
      std::size_t value = 0;
      while (key.find(std::string(".") + axis.tokens[value] + ".") == std::string::npos &&
             !key.ends_with(std::string(".") + axis.tokens[value]))
        ++value;
      row.push_back(value);
    }
    open.Cover(row);
  }
  EXPECT_TRUE(open.Empty()) << open.Size() << " pairs of axis values never compiled together";
  EXPECT_EQ(distinct.size(), CoveringKeys().size()) << "a row repeats another";
  EXPECT_GE(CoveringKeys().size(), largest_product);
  EXPECT_LE(CoveringKeys().size(), largest_product + largest_product / 3) << "the greedy generator got worse";
  std::cout << "[ covering ] " << CoveringKeys().size() << " CUDA variants cover every pair of values of "
            << sizes.size() << " axes (at least " << largest_product << " needed)\n";
}

// ---------------------------------------------------------------- compile only

// "" when `source` compiles cleanly; else the reason.
std::string CompileProblem(const std::string& source, std::string* ptx = nullptr) {
  const CompileResult r = CompileWithNvrtc(source, kCompileArch);
  if (!r.ok) return r.error;
  if (r.log.find("warning") != std::string::npos) return "compiled with warnings:\n" + r.log;
  // A local depot is an array (joints, weights, words) spilled to the stack:
  // the template's loops are meant to unroll into registers.
  if (r.ptx.find("__local_depot") != std::string::npos) return "the PTX uses a stack frame (local memory)";
  if (r.ptx.find(".entry skin(") == std::string::npos) return "no extern \"C\" entry 'skin' in the PTX";
  if (ptx) *ptx = r.ptx;
  return "";
}

class CudaCompile : public ::testing::TestWithParam<std::string> {};

TEST_P(CudaCompile, NvrtcCompilesCleanly) {
  SKIP_WITHOUT_NVRTC();
  const Variant variant = ParseVariantKey(GetParam());
  const KernelSource source = Emit(variant, 0, kJoints, EmitOptions{.morph_targets = kMorphTargets});
  EXPECT_EQ(CompileProblem(source.text), "") << source.text.substr(0, source.text.find("#line"));
}

std::string KeyName(const ::testing::TestParamInfo<std::string>& info) {
  std::string name = std::to_string(info.index) + "_" + info.param;
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return name;
}

// The same rows instanced (docs/VARIANTS.md "Instancing": blockIdx.y, K palettes).
TEST_P(CudaCompile, InstancedNvrtcCompilesCleanly) {
  SKIP_WITHOUT_NVRTC();
  const Variant variant = ParseVariantKey(GetParam());
  const KernelSource source = Emit(variant, 0, kJoints, EmitOptions{true, 4, kMorphTargets});
  EXPECT_EQ(CompileProblem(source.text), "") << source.text.substr(0, source.text.find("#line"));
}

INSTANTIATE_TEST_SUITE_P(Pairwise, CudaCompile, ::testing::ValuesIn(CoveringKeys()), KeyName);

// CUDA's limits on every device CUDA 12+ runs on (the runner queries the real ones).
DeviceLimits CudaLimits() {
  DeviceLimits d;
  d.max_wg_size = 1024;
  d.local_memory_bytes = 48 * 1024;  // static __shared__
  d.constant_memory_bytes = 64 * 1024;
  d.image_support = true;
  d.image_buffer_max_texels = std::uint64_t{1} << 27;
  return d;
}

const ProblemShape kCoveringShape = testing::CoveringShape();

// The project's covering set (generator/covering.h), which the tools use.
TEST(CudaCoveringSet, EveryVariantCompilesCleanly) {
  SKIP_WITHOUT_NVRTC();
  const CoveringSet set = BuildCoveringSet(Lang::kCuda, CudaLimits(), kCoveringShape);
  ASSERT_TRUE(set.uncoverable.empty());
  for (const Variant& v : set.variants)
    EXPECT_EQ(CompileProblem(Emit(v, 0, kJoints, EmitOptions{.morph_targets = kMorphTargets}).text), "") << v.Key();
  std::cout << "[ covering ] " << set.variants.size() << " variants of generator/covering.h compiled\n";
}

TEST(CudaTemplate, CompilesAloneWithNvrtcAndNoDefines) {
  SKIP_WITHOUT_NVRTC();
  std::string ptx;
  EXPECT_EQ(CompileProblem(ExpandedTemplate("skin.cu"), &ptx), "");
  // The default variant reads the palette through the read-only cache with 16-byte loads.
  EXPECT_NE(ptx.find("ld.global.nc.v4.f32"), std::string::npos);
}

TEST(CudaTemplate, EachStorageReadsThePaletteFromItsMemory) {
  SKIP_WITHOUT_NVRTC();
  const std::pair<const char*, const char*> expected[] = {
      {"cuda.constant", "ld.const.v4.f32"},
      {"cuda.local", "ld.shared.v4.f32"},
      {"cuda.global", "ld.global.nc.v4.f32"},
      {"cuda.image", "tex.1d.v4.f32.s32"},
  };
  for (const auto& [key, instruction] : expected) {
    std::string ptx;
    ASSERT_EQ(CompileProblem(Emit(ParseVariantKey(key), 0, kJoints).text, &ptx), "") << key;
    EXPECT_NE(ptx.find(instruction), std::string::npos) << key << " has no " << instruction;
  }
  std::string ptx;
  ASSERT_EQ(CompileProblem(Emit(ParseVariantKey("cuda.constant"), 0, kJoints).text, &ptx), "");
  EXPECT_NE(ptx.find(".const .align 16 .b8 skintune_palette[" + std::to_string(kJoints * 3 * 16) + "]"),
            std::string::npos)
      << "the __constant__ palette is sized by JOINTS";
}

TEST(CudaTemplate, InstancedConstantSymbolHoldsMaxInstancesPalettes) {
  SKIP_WITHOUT_NVRTC();
  std::string ptx;
  ASSERT_EQ(CompileProblem(Emit(ParseVariantKey("cuda.constant"), 0, kJoints, EmitOptions{true, 5}).text, &ptx), "");
  EXPECT_NE(ptx.find(".const .align 16 .b8 skintune_palette[" + std::to_string(5 * kJoints * 3 * 16) + "]"),
            std::string::npos)
      << "the instanced __constant__ palette is sized by PALETTE_INSTANCES x JOINTS";
  // The instance is the grid's y.
  EXPECT_NE(ptx.find("%ctaid.y"), std::string::npos);
}

TEST(CudaTemplate, CompilesAloneWithJustTheInstancedDefine) {
  SKIP_WITHOUT_NVRTC();
  EXPECT_EQ(CompileProblem("#define INSTANCED 1\n" + ExpandedTemplate("skin.cu")), "");
}

TEST(CudaCompile, AnErrorCarriesTheNvrtcLog) {
  SKIP_WITHOUT_NVRTC();
  std::string text = Emit(ParseVariantKey("cuda.b2"), 0, kJoints).text;
  const std::string from = "if (v >= n) break;";
  ASSERT_NE(text.find(from), std::string::npos) << "update the test: the template changed";
  text.replace(text.find(from), from.size(), from + " undeclared_name_xyz = 1;");
  const CompileResult r = CompileWithNvrtc(text, kCompileArch);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("NVRTC compile of skin.cu for compute_90 failed"), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("undeclared_name_xyz"), std::string::npos) << r.error;
  EXPECT_TRUE(r.ptx.empty());
}

TEST(CudaCompile, AnErrorInAPreludeNamesItsFileAndLine) {
  SKIP_WITHOUT_NVRTC();
  const std::string line = "#define PALETTE_FLOAT4S (JOINTS * PALETTE_ROWS)";
  const std::string params = TemplateText("skin_params.h");
  ASSERT_NE(params.find(line), std::string::npos) << "update the test: skin_params.h changed";
  const auto number = std::count(params.begin(), params.begin() + static_cast<long>(params.find(line)), '\n') + 1;
  std::string text = Emit(ParseVariantKey("cuda.b2"), 0, kJoints).text;
  text.replace(text.find(line), line.size(), "#error skintune injected fault");
  const CompileResult r = CompileWithNvrtc(text, kCompileArch);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("skin_params.h(" + std::to_string(number) + ")"), std::string::npos) << r.error;
}

TEST(CudaApi, ProbeSaysWhatIsMissing) {
  const CudaAvailability& a = Available();
  std::cout << "[ cuda ] " << a.Describe() << "\n";
  if (a.nvrtc) {
    EXPECT_FALSE(a.nvrtc_library.empty());
    EXPECT_GE(a.nvrtc_major, 11);
  } else if (a.nvrtc_missing.starts_with("NVRTC not found")) {
    for (const std::string& candidate : NvrtcCandidates())
      EXPECT_NE(a.nvrtc_missing.find(candidate), std::string::npos) << "the reason names every path tried";
  }
  if (!a.driver) {
    EXPECT_FALSE(a.driver_missing.empty());
  }
}

TEST(CudaApi, ChoosesTheNewestArchitectureNvrtcSupports) {
  SKIP_WITHOUT_NVRTC();
  EXPECT_EQ(NvrtcArchFor(9, 0), "compute_90");
  EXPECT_EQ(NvrtcArchFor(1, 0), "") << "no NVRTC compiles for compute capability 1.0";
  const std::string future = NvrtcArchFor(99, 9);
  EXPECT_TRUE(future.starts_with("compute_")) << future;
  EXPECT_EQ(CompileWithNvrtc(ExpandedTemplate("skin.cu"), future).error, "");
}

// ---------------------------------------------------------------- runs on a GPU

// The first CUDA device, or null (with the reason) when the machine has none.
CudaRunner* Runner(std::string& why) {
  static std::string reason;
  static std::unique_ptr<CudaRunner> runner = []() -> std::unique_ptr<CudaRunner> {
    if (!Available().CanRun()) {
      reason = "no CUDA device to run on: " + Available().Describe();
      return nullptr;
    }
    return std::make_unique<CudaRunner>(0);
  }();
  why = reason;
  return runner.get();
}

#define RUNNER_OR_SKIP(runner)      \
  std::string why;                  \
  CudaRunner* runner = Runner(why); \
  if (!runner) GTEST_SKIP() << why

class CudaVariant : public ::testing::TestWithParam<Case> {};

TEST_P(CudaVariant, MatchesTheGold) {
  RUNNER_OR_SKIP(runner);
  const Case& c = GetParam();
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + ", seed " + std::to_string(Seed()) +
               " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name() + " (" + runner->arch() + ")");
  ExpectCaseMatchesGold(*runner, c, ParseVariantKey(c.key), LaunchTimes::kPositive);
}

// The cases of tests/runtime/opencl_runner_test.cpp, in CUDA: every value of
// every axis; every layout with every index format, every weight format and
// every storage; bucketed launches on CesiumMan.
const Case kCases[] = {
    // layout x index x weight
    {"cuda.b4.padded.aos.float4.i32.f32.mat4.constant.matrix.v1c.wg64.nonormals", "b4"},
    {"cuda.b3.padded.aos.float3.u16.unorm16.mat3x4.local.point.v2c.wg32.normals", "b3"},
    {"cuda.b1.padded.aos.float4.u8.unorm8.mat3x4.image.matrix.v4s.wg256.normals", "b1"},
    {"cuda.b2.padded.soa.float3.i32.unorm16.mat3x4.global.point.v8c.wg128.nonormals", "b2"},
    {"cuda.b5.padded.soa.float4.u16.unorm8.mat4.image.matrix.v2s.wg64.normals", "b5-random"},
    {"cuda.b8.padded.soa.float3.u8.f32.mat4.local.matrix.v1c.wg1024.nonormals", "b8"},
    {"cuda.b6.padded.soa-split.float4.i32.unorm8.mat3x4.constant.point.v4c.wg32.normals", "b6-random"},
    {"cuda.b7.padded.soa-split.float3.u16.f32.mat4.global.matrix.v8s.wg512.nonormals", "b7"},
    {"cuda.b4.padded.soa-split.float4.u8.unorm16.mat3x4.local.matrix.v2c.wg256.normals", "b4"},
    // the storage each layout has not seen yet
    {"cuda.b4.padded.aos.float3.u16.unorm8.mat4.global.point.v1c.wg128.normals", "b4"},
    {"cuda.b4.padded.soa.float4.u16.f32.mat3x4.constant.matrix.v1c.wg128.normals", "b4-random"},
    {"cuda.b3.padded.soa-split.float3.u8.unorm8.mat4.image.point.v4s.wg64.normals", "b3"},
    // padding: more slots than the mesh uses
    {"cuda.b8.padded.aos.float4.i32.f32.mat3x4.global.matrix.v1c.wg128.nonormals", "b3"},
    {"cuda.b4.padded.soa-split.float3.u8.f32.mat3x4.constant.matrix.v2c.wg64.normals", "cesium"},
    // bucketed: one launch per influence count, each with its own kernel
    {"cuda.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.normals", "cesium"},
    {"cuda.b4.bucketed.aos.float3.u8.unorm8.mat4.local.point.v2s.wg64.normals", "cesium"},
    {"cuda.b4.bucketed.soa-split.float4.u16.unorm16.mat3x4.image.matrix.v4c.wg32.nonormals", "cesium"},
    {"cuda.b2.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v8s.wg256.nonormals", "b2"},
    {"cuda.b4.bucketed.soa.float3.i32.unorm16.mat4.constant.point.v8s.wg512.normals", "cesium"},
    {"cuda.b6.bucketed.soa-split.float3.u8.unorm8.mat4.local.point.v2c.wg64.normals", "cesium"},
    {"cuda.b8.padded.soa.float4.u16.unorm16.mat4.global.matrix.v1c.wg128.normals", "cesium"},
    // more crossings: point blend with every storage and layout, local copies with large groups
    {"cuda.b4.padded.aos.float4.u8.f32.mat3x4.constant.point.v8s.wg256.normals", "b4"},
    {"cuda.b2.padded.aos.float3.i32.unorm16.mat4.image.point.v2c.wg512.nonormals", "b2"},
    {"cuda.b6.padded.aos.float4.u16.unorm8.mat4.local.matrix.v4c.wg1024.normals", "b6"},
    {"cuda.b1.padded.soa.float4.u8.unorm16.mat4.constant.point.v4s.wg32.normals", "b1"},
    {"cuda.b3.padded.soa.float3.u16.f32.mat3x4.local.point.v8s.wg256.normals", "b3-random"},
    {"cuda.b7.padded.soa.float4.i32.unorm8.mat3x4.image.point.v1c.wg64.normals", "b7"},
    {"cuda.b8.padded.soa-split.float4.u16.f32.mat4.local.point.v8c.wg128.normals", "b8-random"},
    {"cuda.b5.padded.soa-split.float3.i32.unorm16.mat3x4.constant.matrix.v2s.wg1024.normals", "b5"},
    {"cuda.b1.padded.soa-split.float4.u8.unorm8.mat3x4.global.point.v1c.wg32.normals", "b1"},
};

INSTANTIATE_TEST_SUITE_P(EveryAxis, CudaVariant, ::testing::ValuesIn(kCases), CaseName);

TEST(CudaVariantCases, CompileCleanlyHere) {
  // The run cases compile cleanly here as well, so a GPU machine only finds run-time problems.
  SKIP_WITHOUT_NVRTC();
  for (const Case& c : kCases) {
    const Variant v = ParseVariantKey(c.key);
    const int b = v.mixed == MixedCounts::kBucketed ? 1 : v.influences;  // a bucket's smallest count
    EXPECT_EQ(CompileProblem(Emit(v, b, kJoints).text), "") << c.key;
  }
}

// The generated covering set for this device (generator/covering.h), each
// variant on a fresh mesh with its own influence count.
TEST(CudaCoveringSet, EveryVariantMatchesTheGold) {
  RUNNER_OR_SKIP(runner);
  const CoveringSet set = BuildCoveringSet(Lang::kCuda, runner->limits(), testing::CoveringShape());
  ASSERT_TRUE(set.uncoverable.empty());
  ExpectCoveringSetMatchesGold(*runner, set, LaunchTimes::kPositive);
  std::cout << "[ covering ] " << set.variants.size() << " CUDA variants verified on " << runner->device_name()
            << "\n";
}

// The faulty kernels: one padded soa launch (WithFault).
constexpr const char* kFaultKey = "cuda.b2.soa.float4.u16.f32.wg64";

TEST(CudaRunner, PoisonedOutputCatchesAKernelThatSkipsVertices) {
  RUNNER_OR_SKIP(runner);
  Faulty f = WithFault(kFaultKey, "if (v >= n) break;", "if (v >= n / 2) break;");
  ExpectHalfPoisoned(f, runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant)));
}

TEST(CudaRunner, GuardCatchesAKernelThatWritesPastTheEnd) {
  RUNNER_OR_SKIP(runner);
  Faulty f = WithFault(kFaultKey, "STORE_XYZ(out_positions, out_first + v,", "STORE_XYZ(out_positions, out_first + v + 64,");
  ExpectRunFails(*runner, f, "a kernel writing 64 vertices past its output was not caught",
                 {"CUDA guard", "out_positions", "wrote past the end"});
}

TEST(CudaRunner, BuildFailureCarriesTheNvrtcLog) {
  RUNNER_OR_SKIP(runner);
  Faulty f = WithFault(kFaultKey, "if (v >= n) break;", "if (v >= n) break; undeclared_name_xyz = 1;");
  ExpectRunFails(*runner, f, "a kernel with an undeclared name built", {"CUDA build", "undeclared_name_xyz"});
}

TEST(CudaRunner, RejectsAConstantPaletteLargerThanTheKernelsSymbol) {
  RUNNER_OR_SKIP(runner);
  // Emitted for 2 joints: its __constant__ skintune_palette cannot hold the mesh's.
  Faulty f = WithFault("cuda.b2.soa.constant", "if (v >= n) break;", "if (v >= n) break;", 2);
  ExpectRunFails(*runner, f, "a palette larger than the kernel's __constant__ symbol was copied",
                 {"skintune_palette holds 96 bytes"});
}

TEST(CudaRunner, RejectsAPaletteOfTheWrongSizeAndAMissingDevice) {
  RUNNER_OR_SKIP(runner);
  const PackedMesh packed = Pack(Asset("b2").mesh, ParseVariantKey("cuda.b2.soa"));
  const std::vector<std::uint8_t> short_palette(16);
  try {
    runner->Run(packed, short_palette);
    ADD_FAILURE() << "a 16-byte palette was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("palette has 16 bytes"), std::string::npos) << e.what();
  }
  try {
    CudaRunner missing(1000);
    ADD_FAILURE() << "device 1000 exists";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("CUDA setup"), std::string::npos) << e.what();
  }
}

TEST(CudaRunner, SetupFailsWithTheReasonWhereThereIsNoGpu) {
  if (Available().CanRun()) GTEST_SKIP() << "this machine has a CUDA device";
  try {
    CudaRunner runner(0);
    ADD_FAILURE() << "a runner was made without a CUDA device";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("CUDA setup: "), std::string::npos) << message;
    const std::string& reason = Available().nvrtc ? Available().driver_missing : Available().nvrtc_missing;
    if (!reason.empty()) {
      EXPECT_NE(message.find(reason), std::string::npos) << message;
    }
  }
}

// Runners on contexts of their own (the tuner's choice of the quickest): each
// its own context, neither the primary one, each matching the gold, and the
// shared runner still working after they are destroyed with their contexts.
TEST(CudaRunner, RunnersOnContextsOfTheirOwnMatchTheGoldAndCloseThem) {
  RUNNER_OR_SKIP(runner);
  const Case c{"cuda.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg256.nonormals", "b4"};
  {
    CudaRunner first(0, CudaRunner::OwnContext{});
    CudaRunner second(0, CudaRunner::OwnContext{});
    EXPECT_NE(first.context(), second.context());
    EXPECT_NE(first.context(), runner->context());
    EXPECT_NE(second.context(), runner->context());
    ExpectCaseMatchesGold(second, c, ParseVariantKey(c.key), LaunchTimes::kPositive);
    ExpectCaseMatchesGold(first, c, ParseVariantKey(c.key), LaunchTimes::kPositive);
  }
  ExpectCaseMatchesGold(*runner, c, ParseVariantKey(c.key), LaunchTimes::kPositive);
}

TEST(CudaRunner, AContextOfItsOwnFailsWithTheReasonWhereThereIsNoGpu) {
  if (Available().CanRun()) GTEST_SKIP() << "this machine has a CUDA device";
  try {
    CudaRunner runner(0, CudaRunner::OwnContext{});
    ADD_FAILURE() << "a runner on a context of its own was made without a CUDA device";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("CUDA setup: "), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------- instances

// K instances per launch against the gold of each instance's palette: the
// cases of tests/runtime/opencl_runner_test.cpp (OpenClInstanced) in CUDA.
const Case kInstancedCases[] = {
    {"cuda.b4.padded.aos.float4.u16.f32.mat4.constant.matrix.v1c.wg64.normals", "b4"},
    {"cuda.b3.padded.soa.float3.u8.unorm8.mat3x4.local.point.v2s.wg128.nonormals", "b3-random"},
    {"cuda.b2.padded.soa-split.float4.i32.unorm16.mat3x4.image.matrix.v4c.wg32.normals", "b2"},
    {"cuda.b5.padded.aos.float4.i32.unorm16.mat3x4.image.point.v1c.wg32.nonormals", "b5"},
    {"cuda.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v8s.wg256.normals", "cesium"},
    {"cuda.b4.bucketed.aos.float3.u8.unorm8.mat4.local.matrix.v2c.wg64.nonormals", "cesium"},
    {"cuda.b4.bucketed.soa-split.float3.u16.f32.mat3x4.constant.point.v4s.wg128.normals", "cesium"},
};

class CudaInstanced : public ::testing::TestWithParam<testing::InstanceCase> {};

TEST_P(CudaInstanced, EveryInstanceMatchesTheGoldOfItsPalette) {
  RUNNER_OR_SKIP(runner);
  const testing::InstanceCase& c = GetParam();
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + " x" + std::to_string(c.instances) + ", seed " +
               std::to_string(Seed()) + " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name());
  testing::ExpectInstanceCaseMatchesGold(*runner, c, runner->limits());
}

INSTANTIATE_TEST_SUITE_P(Spread, CudaInstanced, ::testing::ValuesIn(testing::WithInstanceCounts(kInstancedCases)),
                         testing::InstanceCaseName);

TEST(CudaInstancedCases, CompileCleanlyHere) {
  // Every bucket's instanced kernel, for the largest K the cases run.
  SKIP_WITHOUT_NVRTC();
  for (const Case& c : kInstancedCases) {
    const Variant v = ParseVariantKey(c.key);
    const PackedMesh packed = Pack(testing::SmallAsset(c.mesh).mesh, v);
    for (const KernelSource& k : EmitLaunchKernels(packed, 64)) EXPECT_EQ(CompileProblem(k.text), "") << c.key;
  }
}

TEST(CudaInstancedRunner, PoisonCatchesAKernelThatWritesEveryInstanceOverTheFirst) {
  RUNNER_OR_SKIP(runner);
  std::vector<KernelSource> kernels;
  const testing::InstancedRun run =
      testing::WithInstancedFault("cuda.b2.soa.float4.u16.f32.wg64", 7, "const u32 out_first = instance * vertex_count + first;",
                                  "const u32 out_first = first + 0u * vertex_count;", kernels);
  EXPECT_EQ(runner->Run(run.packed, kernels, run.palette_bytes, 7).poisoned_vertices, 6 * run.packed.vertex_count);
}

TEST(CudaInstancedRunner, RejectsMoreInstancesThanTheConstantSymbolHolds) {
  RUNNER_OR_SKIP(runner);
  const testing::InstancedRun run = testing::InstancedInputs(ParseVariantKey("cuda.b2.soa.constant"), "b2", 7);
  const std::vector<KernelSource> kernels = EmitLaunchKernels(run.packed, 3);  // a symbol for 3 palettes
  try {
    runner->Run(run.packed, kernels, run.palette_bytes, 7);
    ADD_FAILURE() << "7 palettes were copied into a symbol for 3";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the kernel's constant palette holds 3"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skintune::internal
