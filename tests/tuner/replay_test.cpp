#include "tuner/replay.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "base/error.h"
#include "tests/tuner/synthetic_model.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

constexpr const char* kDevice = "opencl:Synthetic/Model GPU/1.0";
constexpr const char* kDataset = "100k-b4";

fs::path TempDir() {
  const fs::path dir = fs::temp_directory_path() / ("skintune_replay_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

// The synthetic model recorded as a measurement cache (JSON lines), with a
// few measurements of another device and dataset and a torn last line.
const fs::path& SyntheticCache() {
  static const fs::path path = [] {
    const fs::path p = TempDir() / "synthetic.jsonl";
    std::ofstream out(p, std::ios::binary);
    const std::vector<Variant> candidates = testing::SyntheticCandidates();
    for (std::size_t i = 0; i < 20; ++i) {
      out << nlohmann::json(testing::SyntheticMeasurement(candidates[i], "cuda:CUDA/Other/2.0", kDataset)).dump()
          << "\n";
      out << nlohmann::json(testing::SyntheticMeasurement(candidates[i], kDevice, "25k-b4")).dump() << "\n";
    }
    for (const Variant& v : candidates) {
      out << nlohmann::json(testing::SyntheticMeasurement(v, kDevice, kDataset)).dump() << "\n";
    }
    out << "{\"device_id\": \"" << kDevice << "\", \"data";  // killed mid-write
    return p;
  }();
  return path;
}

// Removes this process's temporary files at the end.
class CleanUp : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(TempDir()); }
};
const auto* const kCleanUp = ::testing::AddGlobalTestEnvironment(new CleanUp);

// For every value of every axis of the table: a variant differing from the
// default in that axis only hashes apart from it (and from the others).
TEST(Replay, FieldHashTellsApartVariantsDifferingInAnyOneAxis) {
  const VariantFieldHash hash;
  std::unordered_map<std::size_t, std::string> seen = {{hash(Variant{}), Variant{}.Key()}};
  for (const Axis& axis : kAxes) {
    for (const AxisValueSpec& value : axis.values) {
      Variant v;
      axis.Set(v, value.code);
      if (v == Variant{}) continue;
      const auto [it, fresh] = seen.emplace(hash(v), v.Key());
      EXPECT_TRUE(fresh) << v.Key() << " hashes like " << it->second;
    }
  }
}

TEST(Replay, ServesRecordedTimesAndCountsLookups) {
  ReplayEvaluator replay = ReplayEvaluator::FromCacheFile(SyntheticCache().string(), kDevice, kDataset);
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  ASSERT_EQ(replay.variants().size(), candidates.size());
  EXPECT_EQ(replay.variants().front(), candidates.front());
  std::size_t ok = 0;
  for (const Variant& v : candidates) ok += testing::SyntheticStatus(v) == MeasureStatus::kOk ? 1 : 0;
  EXPECT_EQ(replay.ok_count(), ok);
  EXPECT_LT(ok, candidates.size());  // the model has failures

  const Evaluator evaluate = replay.AsEvaluator();
  for (std::size_t i = 0; i < 200; ++i) {
    const Variant& v = candidates[i];
    const std::optional<double> t = evaluate(v);
    if (testing::SyntheticStatus(v) == MeasureStatus::kOk) {
      ASSERT_TRUE(t) << v.Key();
      EXPECT_DOUBLE_EQ(*t, testing::SyntheticTimeMs(v));
    } else {
      EXPECT_FALSE(t) << v.Key();
    }
  }
  EXPECT_EQ(replay.lookups(), 200u);
  EXPECT_EQ(replay.missing(), 0u);

  Variant unknown = candidates.front();
  unknown.influences = 7;  // never recorded
  EXPECT_FALSE(evaluate(unknown));
  EXPECT_EQ(replay.lookups(), 201u);
  EXPECT_EQ(replay.missing(), 1u);
  replay.ResetCounters();
  EXPECT_EQ(replay.lookups(), 0u);
}

TEST(Replay, ReadsWithoutModifyingTheCache) {
  const auto size = fs::file_size(SyntheticCache());
  ReplayEvaluator::FromCacheFile(SyntheticCache().string(), kDevice, kDataset);
  EXPECT_EQ(fs::file_size(SyntheticCache()), size);  // the torn line is ignored, not cut off
}

TEST(Replay, ErrorsNameTheFileAndWhatWasRecorded) {
  try {
    ReplayEvaluator::FromCacheFile((TempDir() / "absent.jsonl").string(), kDevice, kDataset);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("absent.jsonl"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(TempDir() / "absent.jsonl"));
  try {
    ReplayEvaluator::FromCacheFile(SyntheticCache().string(), kDevice, "1600k-b4");
    FAIL() << "no error";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("synthetic.jsonl"), std::string::npos) << message;
    EXPECT_NE(message.find("'1600k-b4'"), std::string::npos) << message;
    EXPECT_NE(message.find("'25k-b4'"), std::string::npos) << message;  // what was recorded
  }
  const fs::path bad = TempDir() / "bad.jsonl";
  {
    std::ofstream out(bad);
    out << nlohmann::json(testing::SyntheticMeasurement(Variant{}, kDevice, kDataset)).dump() << "\n"
        << "{\"device_id\": 3}\n";
  }
  try {
    ReadMeasurementLines(bad.string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.jsonl:2:"), std::string::npos) << e.what();
  }
}

// A cache holds races beside the measurements: read and checked, not
// replayed, and a malformed one is an error naming the line.
TEST(Replay, ReadsACacheWithARaceLine) {
  const fs::path path = TempDir() / "with-race.jsonl";
  const std::string measurement = nlohmann::json(testing::SyntheticMeasurement(Variant{}, kDevice, kDataset)).dump();
  RaceRecord race;
  race.device_id = kDevice;
  race.dataset = kDataset;
  RaceRecord::Entry entry;
  entry.variant = Variant{};
  entry.interval = {0.01, 0.009, 0.011, 20};
  race.entries = {entry, entry};
  const std::string race_line = nlohmann::json{{"race_key", "k"}, {"race", RaceJson(race)}}.dump();
  std::ofstream(path) << measurement << "\n" << race_line << "\n";
  EXPECT_EQ(ReadMeasurementLines(path.string()).size(), 1u);
  nlohmann::json bad = nlohmann::json::parse(race_line);
  bad["race"]["entries"][0]["samples"] = 0;
  std::ofstream(path) << measurement << "\n" << bad.dump() << "\n";
  try {
    ReadMeasurementLines(path.string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("with-race.jsonl:2: malformed race ("), std::string::npos) << e.what();
  }
}

TEST(Replay, ReplaysAReport) {
  TuningReport report;
  report.datasets = {{kDataset, 100000, 4, 77}};
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  for (std::size_t i = 0; i < 100; ++i) {
    report.measurements.push_back(testing::SyntheticMeasurement(candidates[i], kDevice, kDataset));
  }
  ReplayEvaluator replay = ReplayEvaluator::FromReport(report, kDevice, kDataset, "report.json");
  EXPECT_EQ(replay.variants().size(), 100u);
  EXPECT_THROW(ReplayEvaluator::FromReport(report, "cuda:x/y/z", kDataset, "report.json"), Error);
}

// The comparison on the synthetic model: the figures docs/TUNING.md quotes
// (labelled synthetic) are printed here.
TEST(Replay, StrategyComparisonOnTheSyntheticModel) {
  ReplayEvaluator replay = ReplayEvaluator::FromCacheFile(SyntheticCache().string(), kDevice, kDataset);
  const StrategyComparison c = CompareStrategies(replay.variants(), replay.AsEvaluator(), {0.05, 0.1, 0.25, 0.5}, 10);
  std::cout << FormatComparison(c);
  EXPECT_EQ(c.candidates, replay.variants().size());
  EXPECT_EQ(c.ok, replay.ok_count());
  EXPECT_EQ(c.rows.size(), 12u);
  EXPECT_EQ(replay.missing(), 0u);  // every candidate was recorded
  for (const StrategyComparisonRow& row : c.rows) {
    EXPECT_GE(row.mean_ratio, 1.0) << row.strategy;
    EXPECT_GE(row.worst_ratio, row.mean_ratio) << row.strategy;
    EXPECT_LE(row.mean_evaluations, static_cast<double>(row.budget)) << row.strategy;
  }
  const nlohmann::json j = c;
  EXPECT_EQ(j["rows"].size(), 12u);

  // Coordinate descent at 10% of the evaluations: within 2% of the optimum on
  // average over the seeds, and within 5% at worst.
  bool checked = false;
  for (const StrategyComparisonRow& row : c.rows) {
    if (row.strategy == "coordinate" && row.budget_fraction == 0.1) {
      EXPECT_LE(row.mean_ratio, 1.02);
      EXPECT_LE(row.worst_ratio, 1.05);
      checked = true;
    }
  }
  EXPECT_TRUE(checked);
}

TEST(Replay, ExhaustiveAtTheFullBudgetIsExactlyOptimal) {
  ReplayEvaluator replay = ReplayEvaluator::FromCacheFile(SyntheticCache().string(), kDevice, kDataset);
  const StrategyComparison c = CompareStrategies(replay.variants(), replay.AsEvaluator(), {1.0}, 2);
  ASSERT_EQ(c.rows.size(), 3u);
  EXPECT_EQ(c.rows[0].strategy, "exhaustive");
  EXPECT_EQ(c.rows[0].budget, c.candidates);
  EXPECT_EQ(c.rows[0].mean_ratio, 1.0);
  EXPECT_EQ(c.rows[0].worst_ratio, 1.0);
  EXPECT_EQ(c.rows[0].found_optimum, 2);
  EXPECT_EQ(c.rows[1].mean_ratio, 1.0);  // random with every candidate: also exact
  ASSERT_TRUE(c.optimum);
  EXPECT_DOUBLE_EQ(c.optimum_ms, testing::SyntheticTimeMs(*c.optimum));
  EXPECT_EQ(testing::SyntheticStatus(*c.optimum), MeasureStatus::kOk);
}

// The same comparison on real measurements: exhaustive runs on the H100
// machine (docs/TUNING.md, "Figures (H100)"): a 576-variant space (480 valid)
// recorded by `skintune tune --config tests/data/tuning/exhaustive-1600k-b4.json`
// (timing version 2), and the wide space of 864 (720 valid, 480 within
// the default error budget) by `--config tests/data/tuning/exhaustive-wide-1600k-b4.json`
// (timing version 4) in OpenCL, CUDA and GLSL compute, at 1600k-b4 and at
// 6400k-b4 (`--config tests/data/tuning/exhaustive-wide-6400k-b4.json`).
struct Recorded {
  const char* file;
  const char* device_id;
  const char* dataset;
  std::size_t ok;
};
constexpr const char* kH100Cuda = "cuda:CUDA/NVIDIA H100 80GB HBM3/580.159.04 (CUDA 13.0)";
constexpr const char* kH100Gl = "gl:device/NVIDIA H100 80GB HBM3/PCIe/SSE2/4.3.0 NVIDIA 580.159.04";
constexpr const char* kH100OpenCl = "opencl:NVIDIA CUDA/NVIDIA H100 80GB HBM3/580.159.04";
const Recorded kRecorded[] = {
    {"h100-cuda-1600k-b4.jsonl", kH100Cuda, "1600k-b4", 480},
    {"h100-glsl-compute-1600k-b4.jsonl", kH100Gl, "1600k-b4", 480},
    {"h100-v4-opencl-1600k-b4-wide.jsonl", kH100OpenCl, "1600k-b4", 480},
    {"h100-v4-cuda-1600k-b4-wide.jsonl", kH100Cuda, "1600k-b4", 480},
    {"h100-v4-glsl-compute-1600k-b4-wide.jsonl", kH100Gl, "1600k-b4", 480},
    {"h100-v4-opencl-6400k-b4-wide.jsonl", kH100OpenCl, "6400k-b4", 480},
    {"h100-v4-cuda-6400k-b4-wide.jsonl", kH100Cuda, "6400k-b4", 480},
    {"h100-v4-glsl-compute-6400k-b4-wide.jsonl", kH100Gl, "6400k-b4", 480},
};

TEST(Replay, StrategyComparisonOnRecordedH100Measurements) {
  for (const Recorded& recorded : kRecorded) {
    SCOPED_TRACE(recorded.file);
    const std::string path = std::string(SKINTUNE_TEST_DATA_DIR) + "/tuning/" + recorded.file;
    ReplayEvaluator replay = ReplayEvaluator::FromCacheFile(path, recorded.device_id, recorded.dataset);
    EXPECT_EQ(replay.ok_count(), recorded.ok);
    const StrategyComparison c =
        CompareStrategies(replay.variants(), replay.AsEvaluator(), {0.02, 0.05, 0.1, 0.25, 0.5}, 20);
    std::cout << recorded.file << "\n" << FormatComparison(c);
    // The default strategy's bar (docs/TUNING.md): the default strategy (coordinate descent) with 5% of
    // the evaluations lands within 5% of the exhaustive optimum, on average
    // and at worst over the seeds; random search at the same budget is not
    // better on average.
    const StrategyComparisonRow* coordinate = nullptr;
    const StrategyComparisonRow* random = nullptr;
    for (const StrategyComparisonRow& row : c.rows) {
      if (row.budget_fraction != 0.05) continue;
      if (row.strategy == "coordinate") coordinate = &row;
      if (row.strategy == "random") random = &row;
    }
    ASSERT_TRUE(coordinate && random);
    EXPECT_LE(coordinate->mean_ratio, 1.05);
    EXPECT_LE(coordinate->worst_ratio, 1.05);
    EXPECT_LE(coordinate->mean_ratio, random->mean_ratio);
  }
}

TEST(Replay, ComparisonNeedsAnOkCandidate) {
  const Evaluator all_fail = [](const Variant&) -> std::optional<double> { return std::nullopt; };
  EXPECT_THROW(CompareStrategies(testing::SyntheticCandidates(), all_fail, {0.1}, 1), Error);
  EXPECT_THROW(CompareStrategies(testing::SyntheticCandidates(), testing::SyntheticEvaluate, {1.5}, 1), Error);
}

}  // namespace
}  // namespace skintune::internal
