// Tune configs (tuner/tune.h: ConfigFromJson, EmbeddedConfig): the embedded
// default and paper configs, and errors that name the element.
#include <gtest/gtest.h>

#include <fstream>
#include <functional>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "tuner/tune.h"

namespace skintune::internal {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

std::string ErrorOf(const char* text) {
  return ErrorOf([&] { ConfigFromJson(nlohmann::json::parse(text), "c.json"); });
}

TEST(TuneConfig, EmbeddedConfigsAreTheFilesOfConfigs) {
  for (const char* name : {"animated-crowds", "default", "dual-quaternions", "morph-targets", "packed-normals", "paper"}) {
    std::ifstream in(std::string(SKINTUNE_SOURCE_DIR) + "/configs/" + name + ".json", std::ios::binary);
    ASSERT_TRUE(in) << name;
    const std::string file((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(EmbeddedConfig(name), file) << name;
  }
  EXPECT_EQ(ErrorOf([] { EmbeddedConfig("fast"); }), "no built-in config 'fast' (built in: animated-crowds, default, dual-quaternions, morph-targets, packed-normals, paper)");
}

TEST(TuneConfig, DefaultConfigIsValidAndSmall) {
  const TuneConfig c = ConfigFromJson(nlohmann::json::parse(EmbeddedConfig("default")), "default");
  EXPECT_EQ(c.name, "default");
  EXPECT_FALSE(c.datasets.empty());
  // Quick: the default strategy with a small budget per device, language
  // and data set, over a space small enough that the search covers a third.
  EXPECT_EQ(c.strategy.name, "coordinate");
  EXPECT_GT(c.strategy.budget, 0u);
  EXPECT_LE(c.strategy.budget, 16u);
  TuningSpace per_dataset = ForDataSet(c.space, ProblemShape{});  // a data set without morph targets
  per_dataset.influences = {4};
  EXPECT_LE(per_dataset.Size(), 250u);  // 216: five languages
  ProblemShape morph;
  morph.morph_targets = 2;
  morph.morph_moves = true;
  per_dataset = ForDataSet(c.space, morph);
  per_dataset.influences = {4};
  EXPECT_LE(per_dataset.Size(), 4 * 250u) << "one with morph targets: the four ways to store their offsets";
  EXPECT_TRUE(nlohmann::json::parse(EmbeddedConfig("default")).at("description").is_string());
}

TEST(TuneConfig, PaperConfigHasTheSixteenDatasetsAndATuningSpace) {
  const TuneConfig c = ConfigFromJson(nlohmann::json::parse(EmbeddedConfig("paper")), "paper");
  ASSERT_EQ(c.datasets.size(), 16u);
  EXPECT_EQ(c.datasets.front(), "25k-b1");
  EXPECT_EQ(c.datasets.back(), "1600k-b4");
  EXPECT_GT(c.space.Size(), 0u);
}

TEST(TuneConfig, ReadsEveryField) {
  const TuneConfig c = ConfigFromJson(nlohmann::json::parse(R"({
    "description": "x",
    "space": {"lang": ["opencl"], "wg_size": [64]},
    "datasets": ["5000-b2", {"key": "25k-b1", "name": "n", "vertices": 25000, "influences": 1, "bones": 77}],
    "timing": {"warmup": 0, "repetitions": 3, "max_input_sets": 2, "tolerance": 1e-4},
    "strategy": {"name": "random", "budget": 5, "seed": 7},
    "variant_timeout_s": 2.5})"),
                                      "c.json");
  EXPECT_EQ(c.name, "c.json");
  EXPECT_EQ(c.space.langs, std::vector<Lang>{Lang::kOpenCl});
  EXPECT_EQ(c.datasets, (std::vector<std::string>{"5000-b2", "25k-b1"}));
  EXPECT_EQ(c.timing.warmup, 0);
  EXPECT_EQ(c.timing.repetitions, 3);
  EXPECT_EQ(c.timing.max_input_sets, 2);
  EXPECT_EQ(c.timing.tolerance, 1e-4);
  EXPECT_EQ(c.strategy.name, "random");
  EXPECT_EQ(c.strategy.budget, 5u);
  EXPECT_EQ(c.strategy.seed, 7u);
  EXPECT_EQ(c.variant_timeout_s, 2.5);
}

// Scene keys (docs/DATA.md "Scenes"): crowds and batches are datasets; their
// keys are checked as the config is read, and only a synthetic dataset of one
// mesh states its numbers.
TEST(TuneConfig, DatasetsMayBeCrowdsAndBatches) {
  const TuneConfig c = ConfigFromJson(nlohmann::json::parse(R"({"space": {},
    "datasets": ["25k-b4-x64", "a.gltf+5k-b2+mix200k-b4", {"key": "1600k-b4", "vertices": 1600000}]})"),
                                      "c.json");
  EXPECT_EQ(c.datasets, (std::vector<std::string>{"25k-b4-x64", "a.gltf+5k-b2+mix200k-b4", "1600k-b4"}));
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5k-b2+"]})"),
            "c.json: datasets[0]: scene '5k-b2+': meshes[1] is empty (a stray '+')");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": [{"key": "25k-b4-x64", "vertices": 25000}]})"),
            "c.json: datasets[0].vertices: only a synthetic dataset of one mesh states its numbers ('25k-b4-x64' is "
            "not one)");
}

TEST(TuneConfig, ErrorsNameTheElement) {
  EXPECT_EQ(ErrorOf(R"([1])"), "c.json: a tune config must be a JSON object");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "speed": 1})"),
            "c.json: speed: unknown field (expected description, space, datasets, timing, strategy, "
            "variant_timeout_s, max_error)");
  EXPECT_EQ(ErrorOf(R"({"datasets": ["5000-b2"]})"), "c.json: space: missing (an object of axis -> list of values)");
  EXPECT_EQ(ErrorOf(R"({"space": {}})"), "c.json: datasets: missing (a list of dataset keys)");
  EXPECT_EQ(ErrorOf(R"({"space": {"layout": ["soa", "zigzag"]}, "datasets": ["5000-b2"]})"),
            "c.json: space.layout[1]: unknown value 'zigzag' (expected one of aos, soa, soa-split)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": []})"), "c.json: datasets: is empty");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2", 7]})"),
            "c.json: datasets[1]: expected a dataset key (string) or an object with \"key\"");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-q2"]})").rfind("c.json: datasets[0]: dataset '5000-q2'", 0),
            0u);
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": [{"key": "25k-b1", "influences": 2}]})"),
            "c.json: datasets[0].influences: 2 does not match the key '25k-b1' (1)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2", "5000-b2"]})"),
            "c.json: datasets[1]: '5000-b2' is listed twice");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "timing": {"repetitions": 0}})"),
            "c.json: timing.repetitions: must be an integer from 1 to 1000000 (got 0)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "timing": {"reps": 3}})"),
            "c.json: timing.reps: unknown field (expected one of warmup, repetitions, max_input_sets, tolerance, burst_ms, interval, min_samples, max_samples, sample_batch, sample_ms, race, tie_margin, host_tie_margin, process_spread, host_process_spread, frames_per_sample, host_frames_per_sample, choose_in_tie_set, host_choose_in_tie_set, choose_unseparated, host_choose_unseparated)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "timing": {"tolerance": -1}})"),
            "c.json: timing.tolerance: must be a positive number (got -1)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "timing": {"race": -1}})"),
            "c.json: timing.race: must be an integer from 0 to 1000000 (got -1)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "strategy": {"name": "genetic"}})"),
            "c.json: strategy.name: unknown strategy 'genetic' (expected one of exhaustive, random, coordinate)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "strategy": {"name": "random"}})"),
            "c.json: strategy.budget: the random strategy needs a budget (evaluations per device, language and "
            "dataset)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "strategy": {"budget": -3}})"),
            "c.json: strategy.budget: must be a whole number from 0 to 1000000000 (got -3)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "strategy": {"budget": 18446744073709551616}})"),
            "c.json: strategy.budget: must be a whole number from 0 to 1000000000 (got 1.8446744073709552e+19)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "strategy": {"budget": 1000000001}})"),
            "c.json: strategy.budget: must be a whole number from 0 to 1000000000 (got 1000000001)");
  EXPECT_EQ(ErrorOf(R"({"space": {}, "datasets": ["5000-b2"], "variant_timeout_s": 0})"),
            "c.json: variant_timeout_s: must be a positive number (got 0)");
}

}  // namespace
}  // namespace skintune::internal

namespace skintune::internal {
namespace {

// An impossible stop rule is a setting that cannot work (UsageError: exit 2),
// one line naming the field.
TEST(TuneConfig, ImpossibleStopRulesNameTheField) {
  const auto usage = [](const std::string& timing) -> std::string {
    try {
      (void)ConfigFromJson(nlohmann::json::parse(R"({"space": {}, "datasets": ["5000-b2"], "timing": )" + timing + "}"), "c.json");
    } catch (const UsageError& e) {
      return e.what();
    } catch (const Error& e) {
      return std::string("not a UsageError: ") + e.what();
    }
    return "accepted";
  };
  EXPECT_NE(usage(R"({"interval": 0})").find("'timing.interval' is 0"), std::string::npos) << usage(R"({"interval": 0})");
  EXPECT_NE(usage(R"({"interval": -0.5})").find("'timing.interval' is -0.5"), std::string::npos);
  EXPECT_NE(usage(R"({"max_samples": 5, "sample_batch": 10})").find("'timing.max_samples' is 5: below one batch"),
            std::string::npos);
  EXPECT_NE(usage(R"({"sample_ms": 1e300})").find("'timing.sample_ms'"), std::string::npos) << usage(R"({"sample_ms": 1e300})");
  EXPECT_NE(usage(R"({"tie_margin": 0.9})").find("'timing.tie_margin' is 0.9"), std::string::npos);
  EXPECT_NE(usage(R"({"host_tie_margin": 0})").find("'timing.host_tie_margin' is 0"), std::string::npos)
      << usage(R"({"host_tie_margin": 0})");
  EXPECT_EQ(usage(R"({"interval": 0.02, "min_samples": 5, "max_samples": 40, "sample_batch": 5, "tie_margin": 0.03, "host_tie_margin": 0.2})"),
            "accepted");
  EXPECT_NE(usage(R"({"process_spread": -0.01})").find("'timing.process_spread' is -0.01"), std::string::npos)
      << usage(R"({"process_spread": -0.01})");
  EXPECT_EQ(usage(R"({"process_spread": 0, "host_process_spread": 0.5})"), "accepted");
  EXPECT_EQ(usage(R"({"choose_in_tie_set": false, "host_choose_in_tie_set": true})"), "accepted");
  EXPECT_EQ(usage(R"({"choose_unseparated": true, "host_choose_unseparated": false})"), "accepted");
  EXPECT_NE(usage(R"({"host_choose_unseparated": "no"})").find("timing.host_choose_unseparated: expected true or false"),
            std::string::npos)
      << usage(R"({"host_choose_unseparated": "no"})");
  EXPECT_NE(usage(R"({"choose_in_tie_set": 1})").find("timing.choose_in_tie_set: expected true or false (got 1)"),
            std::string::npos)
      << usage(R"({"choose_in_tie_set": 1})");
  EXPECT_NE(usage(R"({"host_frames_per_sample": 0})").find("'timing.host_frames_per_sample' is 0"), std::string::npos)
      << usage(R"({"host_frames_per_sample": 0})");
  EXPECT_NE(usage(R"({"frames_per_sample": 17})").find("'timing.frames_per_sample' is 17"), std::string::npos)
      << usage(R"({"frames_per_sample": 17})");
  EXPECT_EQ(usage(R"({"frames_per_sample": 2, "host_frames_per_sample": 16})"), "accepted");
  EXPECT_EQ(usage(R"({"interval": 0})").find('\n'), std::string::npos) << "one line";
}

}  // namespace
}  // namespace skintune::internal

namespace skintune::internal {
namespace {

// A device is timed with its own margin and a stop interval that is the same
// fraction of it: a CPU device's wider margin brings a wider interval, a
// GPU's keeps the config's.
TEST(TuneConfig, ADeviceIsTimedWithItsMarginAndAnIntervalInProportion) {
  TimingOptions t;
  t.tie_margin = 0.04;
  t.host_tie_margin = 0.2;
  t.stop.interval = 0.01;
  DeviceIdentity gpu;
  gpu.type = "gpu";
  DeviceIdentity cpu;
  cpu.type = "cpu";
  const TimingOptions on_gpu = t.ForDevice(gpu);
  EXPECT_DOUBLE_EQ(on_gpu.tie_margin, 0.04);
  EXPECT_DOUBLE_EQ(on_gpu.stop.interval, 0.01);
  const TimingOptions on_cpu = t.ForDevice(cpu);
  EXPECT_DOUBLE_EQ(on_cpu.tie_margin, 0.2);
  EXPECT_DOUBLE_EQ(on_cpu.stop.interval, 0.05);
  EXPECT_EQ(on_cpu.stop.max_samples, t.stop.max_samples) << "only the interval follows the margin";
  EXPECT_EQ(on_gpu.frames_per_sample, 1);
  EXPECT_EQ(on_cpu.frames_per_sample, 3) << "the host's CPU takes the quickest of three frames a sample";
  // Never beyond the stop rule's own bound.
  t.stop.interval = 0.3;
  EXPECT_DOUBLE_EQ(t.ForDevice(cpu).stop.interval, 0.5);
  EXPECT_TRUE(BadStopRule(t.ForDevice(cpu).stop, "timing.").empty());
}

}  // namespace
}  // namespace skintune::internal
