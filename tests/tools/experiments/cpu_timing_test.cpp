// The CPU baselines of the paper experiment: verified, counted, rotated like
// the tuner's device inputs.
#include <gtest/gtest.h>

#include "base/error.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "tuner/datasets.h"
#include "tuner/measure_job.h"
#include "tools/experiments/cpu_timing.h"

namespace skintune::internal {
namespace {

SkinnedAsset Small(int influences) {
  DatasetSpec spec;
  spec.vertices = 3000;
  spec.influences = influences;
  return GenerateDataset(spec);
}

TEST(CpuTiming, SerialIsVerifiedAgainstTheGoldAndCountsItsArrayOfStructuresBytes) {
  const SkinnedAsset asset = Small(3);
  CpuTimingOptions options;
  options.repetitions = 5;
  options.min_seconds = 0.0;
  const CpuTiming t = TimeSerial(asset, options);
  EXPECT_GT(t.median_ms, 0.0);
  EXPECT_LE(t.min_ms, t.median_ms);
  EXPECT_LE(t.median_ms, t.max_ms);
  EXPECT_EQ(t.repetitions, 5);
  EXPECT_EQ(t.threads, 1u);
  EXPECT_LE(t.max_relative_error, 1e-5);
  // Per vertex: a vec3 read and one written, 3 x (u16 joint + float weight).
  EXPECT_DOUBLE_EQ(t.bytes_per_frame, 3000.0 * (24 + 3 * 6));
  EXPECT_NEAR(t.gbps, t.bytes_per_frame / (t.median_ms * 1e6), 1e-12);
}

TEST(CpuTiming, FastRunsOnTheRequestedThreadsAndCountsTheSkinnersBytes) {
  const SkinnedAsset asset = Small(2);
  CpuTimingOptions options;
  options.repetitions = 3;
  options.min_seconds = 0.0;
  const CpuTiming t = TimeFast(asset, options, 2);
  EXPECT_EQ(t.threads, 2u);
  FastSkinner skinner(asset.mesh, 1);
  EXPECT_DOUBLE_EQ(t.bytes_per_frame, static_cast<double>(skinner.BytesPerRun(false)));
  EXPECT_LE(t.max_relative_error, 1e-5);
}

TEST(CpuTiming, RotatesAsManyMeshCopiesAsTheTunersRuleAsks) {
  const SkinnedAsset asset = Small(1);
  CpuTimingOptions options;
  options.repetitions = 3;
  options.min_seconds = 0.0;
  options.max_input_sets = 3;
  const CpuTiming t = TimeSerial(asset, options);
  EXPECT_EQ(t.input_sets, tuner_internal::InputSetsFor(HostLastLevelCacheBytes(),
                                                       static_cast<std::uint64_t>(t.bytes_per_frame), 3));
  EXPECT_GE(t.input_sets, 1);
  EXPECT_LE(t.input_sets, 3);
}

TEST(CpuTiming, TakesMoreRepetitionsUntilTheMinimumTimeUpToTenfold) {
  const SkinnedAsset asset = Small(1);
  CpuTimingOptions options;
  options.repetitions = 2;
  options.min_seconds = 1000.0;  // never reached: the cap applies
  const CpuTiming t = TimeSerial(asset, options);
  EXPECT_EQ(t.repetitions, 20);
}

TEST(CpuTiming, AnInvalidMeshIsRefusedWithItsSource) {
  SkinnedAsset asset = Small(2);
  asset.mesh.joints[5] = 500;  // out of range of 77 joints
  try {
    TimeSerial(asset);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(asset.source), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("500"), std::string::npos) << e.what();
  }
}

TEST(CpuTiming, HostCopyBandwidthIsMeasured) {
  const double gbps = HostCopyBandwidthGBps(1);
  EXPECT_GT(gbps, 0.1);
  EXPECT_LT(gbps, 10000.0);
}

}  // namespace
}  // namespace skintune::internal
