// TuneConfig::baselines (the paper's kernels in `skintune paper`): measured on
// every device x language x dataset of their language before the search,
// with B set to the dataset's, even outside the space; an invalid one is
// recorded with its constraint. Runs on this machine's OpenCL device (PoCL).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "tests/common/scratch_dir.h"
#include "tuner/tune.h"

namespace skintune::internal {
namespace {

TEST(TuneBaselines, AreMeasuredWithTheDatasetsBOutsideTheSpaceAndInvalidOnesAreRecorded) {
  const auto dir = skintune::internal::testing::ScratchDir("skintune_tune_baselines_test");
  TuneConfig config;
  config.name = "baselines";
  config.space.langs = {Lang::kOpenCl};
  config.space.influences = {2};
  config.space.mixed = {MixedCounts::kPadded};
  config.space.layouts = {Layout::kSoa};
  config.space.positions = {PositionFormat::kFloat4};
  config.space.indices = {IndexFormat::kU16};
  config.space.weights = {WeightFormat::kF32};
  config.space.palettes = {PaletteFormat::kMat3x4};
  config.space.storages = {PaletteStorage::kGlobal};
  config.space.blends = {Blend::kMatrix};
  config.space.vertices_per_item = {1};
  config.space.assignments = {Assignment::kContiguous};
  config.space.wg_sizes = {64};
  config.space.normals = {Normals::kNone};
  config.space.morphs = {Morph::kNone};
  config.space.normal_formats = {NormalFormat::kF32};
  config.space.animations = {Animation::kHost};
  config.datasets = {"3000-b2-bones300"};
  config.timing = {1, 3, 2, 1e-5};
  config.variant_timeout_s = 30;
  // Outside the space (aos, i32, wg128), given with B = 4: measured with B = 2.
  const Variant outside = ParseVariantKey("opencl.b4.padded.aos.float3.i32.f32.mat4.global.matrix.v1c.wg128.nonormals");
  // u8 indices cannot address 300 joints: invalid.
  const Variant invalid = ParseVariantKey("opencl.b2.padded.soa.float4.u8.f32.mat4.global.matrix.v1c.wg128.nonormals");
  // No CUDA device here, and not a language of the space: ignored.
  const Variant cuda = ParseVariantKey("cuda.b2");
  config.baselines = {outside, invalid, cuda};

  TuneOptions options;
  options.device_pattern = "Portable Computing Language";
  options.cache_path = (dir / "cache.jsonl").string();
  options.worker_executable = (std::filesystem::path(SKINTUNE_BINARY_DIR) / "bin" / "skintune").string();
  const TuningReport report = RunTuning(config, options);

  Variant outside_b2 = outside;
  outside_b2.influences = 2;
  auto find = [&](const Variant& v) {
    return std::find_if(report.measurements.begin(), report.measurements.end(),
                        [&](const Measurement& m) { return m.variant == v; });
  };
  const auto measured = find(outside_b2);
  ASSERT_NE(measured, report.measurements.end()) << "the baseline outside the space was not measured";
  EXPECT_EQ(measured->status, MeasureStatus::kOk) << measured->detail;
  EXPECT_EQ(find(outside), report.measurements.end()) << "measured with the B it was given, not the dataset's";
  const auto rejected = find(invalid);
  ASSERT_NE(rejected, report.measurements.end());
  EXPECT_EQ(rejected->status, MeasureStatus::kInvalid);
  EXPECT_NE(rejected->detail.find("index_range"), std::string::npos) << rejected->detail;
  for (const Measurement& m : report.measurements) EXPECT_NE(m.variant.lang, Lang::kCuda);
  // The space's one point and the valid baseline: two device measurements, no more.
  EXPECT_EQ(std::count_if(report.measurements.begin(), report.measurements.end(),
                          [](const Measurement& m) { return m.status != MeasureStatus::kInvalid; }),
            2);
}

}  // namespace
}  // namespace skintune::internal
