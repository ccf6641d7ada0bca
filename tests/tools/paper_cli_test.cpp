// `skintune paper` end to end on this machine's devices (PoCL, llvmpipe), on
// one small data set: the paper's kernels are measured on every device and
// language, the CPU baselines are timed, the outputs are written and a rerun
// reuses the cache; bad input writes nothing.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include <nlohmann/json.hpp>

#include "tests/common/scratch_dir.h"
#include "tests/tools/run_command.h"
#include "report/paper_result.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
using testing::CountLines;
using testing::ReadAll;
using testing::RunSkintune;

fs::path Scratch() { return skintune::internal::testing::ScratchDir("skintune_paper_cli_test"); }

std::vector<std::string> SmallRun(const fs::path& out) {
  return {"paper", "--dataset", "5000-b2", "--lang", "opencl", "--lang", "glsl-vertex", "--budget", "2",
          "--out", out.string(), "--quiet", "--software-rasterizers"};
}

TEST(PaperCli, MeasuresThePapersKernelsAndTheCpuAndWritesResultReportAndSummary) {
  const fs::path out = Scratch() / "run";
  const testing::CommandResult r = RunSkintune(SmallRun(out));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json json = nlohmann::json::parse(ReadAll(out / "paper-result.json"));
  const PaperResult result = PaperResultFromJson(json, "paper-result.json");
  ASSERT_EQ(result.cpu.size(), 1u);
  EXPECT_EQ(result.cpu[0].dataset, "5000-b2");
  EXPECT_EQ(result.cpu[0].serial.threads, 1u);
  EXPECT_GT(result.cpu[0].fast.threads, 0u);
  EXPECT_GT(result.host.copy_bandwidth_gbps, 0.0);
  // Every paper kernel of a language that ran is measured with B = 2, and
  // passes verification (opencl on PoCL, glsl-vertex on llvmpipe).
  std::set<std::string> kernels_ok;
  for (const PaperKernel& k : result.paper_kernels) {
    if (k.variant.lang != Lang::kOpenCl && k.variant.lang != Lang::kGlslVertex) continue;
    Variant want = k.variant;
    want.influences = 2;
    for (const Measurement& m : result.tuning.measurements) {
      if (m.variant == want && m.dataset == "5000-b2" && m.status == MeasureStatus::kOk) kernels_ok.insert(k.name);
    }
  }
  EXPECT_EQ(kernels_ok, (std::set<std::string>{"opencl-unoptimised", "opencl-optimised", "glsl-vertex"}));
  for (const DeviceIdentity& d : result.tuning.devices) {
    EXPECT_GT(result.tuning.copy_bandwidth_gbps.count(d.Id()), 0u) << d.Id() << " has no copy bandwidth";
  }
  const std::string html = ReadAll(out / "report.html");
  EXPECT_NE(html.find("id=\"fig1\""), std::string::npos);
  EXPECT_NE(ReadAll(out / "summary.md").find("5000-b2"), std::string::npos);
  // The printed tables.
  EXPECT_NE(r.out.find("serial"), std::string::npos) << r.out;

  // A second run measures nothing again: every device measurement is in the cache.
  const int cached = CountLines(ReadAll(out / "cache.jsonl"));
  const testing::CommandResult again = RunSkintune(SmallRun(out));
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(CountLines(ReadAll(out / "cache.jsonl")), cached);
}

// The "runs on this CPU machine within a few minutes": the whole --quick set, every
// device and language found here (PoCL, llvmpipe), a verified winner for each.
TEST(PaperCli, QuickRunsThe8DataSetsOnEveryDeviceAndLanguageFound) {
  const fs::path out = Scratch() / "quick";
  const testing::CommandResult r = RunSkintune({"paper", "--quick", "--out", out.string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const PaperResult result =
      PaperResultFromJson(nlohmann::json::parse(ReadAll(out / "paper-result.json")), "paper-result.json");
  EXPECT_TRUE(result.quick);
  ASSERT_EQ(result.cpu.size(), 8u);
  ASSERT_EQ(result.tuning.datasets.size(), 8u);
  ASSERT_FALSE(result.tuning.devices.empty());
  for (const DeviceIdentity& d : result.tuning.devices) {
    std::set<Lang> langs;
    for (const Measurement& m : result.tuning.measurements)
      if (m.device_id == d.Id()) langs.insert(m.variant.lang);
    for (Lang lang : langs) {
      for (const DatasetInfo& dataset : result.tuning.datasets) {
        bool ok = false;
        for (const Measurement& m : result.tuning.measurements) {
          ok = ok || (m.device_id == d.Id() && m.variant.lang == lang && m.dataset == dataset.key &&
                      m.status == MeasureStatus::kOk);
        }
        EXPECT_TRUE(ok) << d.Id() << " " << Name(lang) << " " << dataset.key << ": no verified variant";
      }
    }
  }
  EXPECT_NE(r.out.find("Fig. 1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Table 1"), std::string::npos) << r.out;
}

TEST(PaperCli, ABadDataSetKeyIsNamedAndNothingIsWritten) {
  const fs::path out = Scratch() / "bad-key";
  fs::create_directories(out);
  std::ofstream(out / "paper-result.json") << "previous";
  const testing::CommandResult r = RunSkintune({"paper", "--dataset", "5000-b9", "--out", out.string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("5000-b9"), std::string::npos) << r.err;
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(ReadAll(out / "paper-result.json"), "previous");
  EXPECT_FALSE(fs::exists(out / "report.html"));
}

TEST(PaperCli, NoMatchingDeviceIsAnErrorListingTheDevicesAndNothingIsWritten) {
  const fs::path out = Scratch() / "no-device";
  const testing::CommandResult r = RunSkintune(
      {"paper", "--dataset", "5000-b1", "--device", "no-such-device-anywhere", "--no-cpu", "--out", out.string(),
       "--quiet"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no-such-device-anywhere"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("found:"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out / "paper-result.json"));
}

}  // namespace
}  // namespace skintune::internal
