// What a tuning run measures (tuner/plan.h), planned without a device: the
// tasks of devices x languages x datasets, the invalid points they record,
// and the configs that give nothing to measure failing before any device
// work, naming why.
#include "tuner/plan.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "tests/common/tiny_tune_config.h"

namespace skintune::internal {
namespace {

PlannedDevice Device(const std::string& backend, std::vector<Lang> languages, unsigned max_wg_size = 1024) {
  PlannedDevice d;
  d.identity.backend = backend;
  d.identity.platform = "Test";
  d.identity.name = backend + " device";
  d.identity.driver_version = "1";
  d.identity.type = "gpu";
  d.limits.max_wg_size = max_wg_size;
  d.limits.local_memory_bytes = 48 << 10;
  d.limits.constant_memory_bytes = 64 << 10;
  d.languages = std::move(languages);
  return d;
}

TuneConfig Config(const testing::TinyTuneConfig& tiny) { return ConfigFromJson(tiny.Json(), "plan.json"); }

const std::string kCreated = "2026-11-30T12:00:00Z";

TEST(Plan, OneTaskPerDeviceLanguageAndDatasetOfTheSpace) {
  testing::TinyTuneConfig tiny;
  tiny.langs = {"opencl", "glsl-compute"};
  tiny.wg_sizes = {64, 128};
  const TuneConfig config = Config(tiny);
  const std::vector<PlannedDataset> datasets = {PlanDataset("1000-b2"), PlanDataset("1000-b4")};
  const std::vector<PlannedDevice> devices = {Device("opencl", {Lang::kOpenCl}),
                                              Device("gl", {Lang::kGlslCompute, Lang::kGlslVertex})};
  const std::vector<Task> tasks = PlanTasks(config, {}, datasets, devices, kCreated);
  // The space's B is 2: the 1000-b4 dataset has no task; glsl-vertex is not in the space.
  ASSERT_EQ(tasks.size(), 2u);
  EXPECT_EQ(tasks[0].device, 0u);
  EXPECT_EQ(tasks[0].lang, Lang::kOpenCl);
  EXPECT_EQ(tasks[1].device, 1u);
  EXPECT_EQ(tasks[1].lang, Lang::kGlslCompute);
  for (const Task& t : tasks) {
    EXPECT_EQ(t.dataset, 0u);
    EXPECT_EQ(t.candidates.size(), 2u);  // wg64 and wg128
    EXPECT_EQ(t.planned, 2u);
    for (const Variant& v : t.candidates) EXPECT_EQ(v.lang, t.lang);
  }
  // --lang narrows the languages.
  EXPECT_EQ(PlanTasks(config, {Lang::kGlslCompute}, datasets, devices, kCreated).size(), 1u);
}

TEST(Plan, PointsADeviceCannotRunAreRecordedInvalidAndTheBudgetCapsThePlan) {
  testing::TinyTuneConfig tiny;
  tiny.wg_sizes = {32, 64, 128, 256};
  TuneConfig config = Config(tiny);
  config.strategy.name = "random";
  config.strategy.budget = 1;
  const std::vector<Task> tasks =
      PlanTasks(config, {}, {PlanDataset("1000-b2")}, {Device("opencl", {Lang::kOpenCl}, 64)}, kCreated);
  ASSERT_EQ(tasks.size(), 1u);
  EXPECT_EQ(tasks[0].candidates.size(), 2u);  // wg32 and wg64
  EXPECT_EQ(tasks[0].planned, 1u);            // the budget
  ASSERT_EQ(tasks[0].invalid.size(), 2u);     // wg128 and wg256
  for (const Measurement& m : tasks[0].invalid) {
    EXPECT_EQ(m.status, MeasureStatus::kInvalid);
    EXPECT_EQ(m.device_id, "opencl:Test/opencl device/1");
    EXPECT_EQ(m.dataset, "1000-b2");
    EXPECT_EQ(m.timestamp, kCreated);
    EXPECT_NE(m.detail.find("wg_size"), std::string::npos) << m.detail;
  }
}

TEST(Plan, BaselinesTakeTheDatasetsInfluencesAndCountInThePlan) {
  TuneConfig config = Config(testing::TinyTuneConfig{});
  config.baselines = {ParseVariantKey("opencl.b4.soa.wg128"), ParseVariantKey("opencl.b4.soa.wg128"),
                      ParseVariantKey("cuda.b4.soa.wg128")};
  const std::vector<Task> tasks =
      PlanTasks(config, {}, {PlanDataset("1000-b2")}, {Device("opencl", {Lang::kOpenCl})}, kCreated);
  ASSERT_EQ(tasks.size(), 1u);
  ASSERT_EQ(tasks[0].baselines.size(), 1u);  // once; the CUDA one is not of this language
  EXPECT_EQ(tasks[0].baselines[0].influences, 2);
  EXPECT_EQ(tasks[0].planned, tasks[0].candidates.size() + 1);
}

TEST(Plan, AConfigWithNothingToMeasureFailsNamingWhy) {
  const TuneConfig config = Config(testing::TinyTuneConfig{});
  const std::vector<PlannedDataset> b2 = {PlanDataset("1000-b2")};
  try {
    (void)PlanTasks(config, {}, b2, {Device("cuda", {Lang::kCuda})}, kCreated);
    ADD_FAILURE() << "no device offers opencl";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "no device offers a language of the space (the devices offer: cuda)");
  }
  try {
    (void)PlanTasks(config, {}, {PlanDataset("1000-b4")}, {Device("opencl", {Lang::kOpenCl})}, kCreated);
    ADD_FAILURE() << "no dataset of B=2";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the space's influences include no dataset's B (1000-b4: B=4)"),
              std::string::npos)
        << e.what();
  }
  try {
    (void)PlanTasks(config, {}, b2, {Device("opencl", {Lang::kOpenCl}, 32)}, kCreated);
    ADD_FAILURE() << "wg64 on a device of 32 items per group";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("all 1 points break a constraint (wg_size"), std::string::npos) << e.what();
  }
}

TEST(Plan, ARunWithoutAWorkerOrWithAnImpossibleConfigFailsBeforeAnyDevice) {
  TuneConfig config = Config(testing::TinyTuneConfig{});
  TuneOptions options;
  EXPECT_THROW(ValidateRun(config, options), Error);  // no worker executable
  options.worker_executable = "/bin/true";
  EXPECT_NO_THROW(ValidateRun(config, options));
  config.timing.tolerance = 0.5;
  EXPECT_THROW(ValidateRun(config, options), Error);
  config = Config(testing::TinyTuneConfig{});
  config.strategy.name = "random";  // without a budget
  EXPECT_THROW(ValidateRun(config, options), Error);
}

PlannedDevice OnTheHost(PlannedDevice d, const std::string& name) {
  d.identity.type = "cpu";
  d.identity.name = name;
  return d;
}

std::vector<std::string> Backends(const std::vector<PlannedDevice>& devices) {
  std::vector<std::string> backends;
  for (const PlannedDevice& d : devices) backends.push_back(d.identity.backend + " " + d.identity.type);
  return backends;
}

TEST(Plan, SoftwareRasterizersAreTunedOnlyWhenAskedFor) {
  const std::vector<PlannedDevice> found = {
      OnTheHost(Device("opencl", {Lang::kOpenCl}), "pthread"),
      OnTheHost(Device("gl", {Lang::kGlslCompute, Lang::kGlslVertex}), "llvmpipe (LLVM 15)"),
      OnTheHost(Device("vulkan", {Lang::kVulkan}), "llvmpipe (LLVM 15)"),
      Device("gl", {Lang::kGlslCompute}),
      OnTheHost(Device("cpu", {Lang::kCpu}), "Xeon")};
  TuneOptions options;
  std::vector<std::string> skipped = {"cuda: no driver"};
  EXPECT_EQ(Backends(SelectDevices(found, options, skipped)),
            (std::vector<std::string>{"opencl cpu", "gl gpu", "cpu cpu"}));
  ASSERT_EQ(skipped.size(), 3u);  // discovery's line kept, one line for each left out
  EXPECT_NE(skipped[1].find("gl:Test/llvmpipe (LLVM 15)/1: a software rasterizer"), std::string::npos) << skipped[1];
  EXPECT_NE(skipped[2].find("--software-rasterizers"), std::string::npos) << skipped[2];

  options.software_rasterizers = true;
  skipped.clear();
  EXPECT_EQ(SelectDevices(found, options, skipped).size(), found.size());
  EXPECT_TRUE(skipped.empty());

  options.software_rasterizers = false;
  options.device_pattern = "llvmpipe";  // named: tuned
  EXPECT_EQ(Backends(SelectDevices(found, options, skipped)), (std::vector<std::string>{"gl cpu", "vulkan cpu"}));
  EXPECT_TRUE(skipped.empty());

  options.device_pattern.clear();  // all there is: tuned
  const std::vector<PlannedDevice> only = {found[1], found[2]};
  EXPECT_EQ(SelectDevices(only, options, skipped).size(), 2u);
  EXPECT_TRUE(skipped.empty());

  options.device_pattern = "nothing-like-it";
  EXPECT_THROW(SelectDevices(found, options, skipped), Error);
}

}  // namespace
}  // namespace skintune::internal
