// `skintune report`: paper results and tuning reports in, one HTML page (and
// a Markdown summary) out; a bad input is one error line naming the file and
// the element, exit 1, and an existing output is left as it was.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/common/scratch_dir.h"
#include "tests/tools/run_command.h"
#include "tests/report/sample_paper_result.h"
#include "tests/tuner/sample_report.h"
#include "report/paper_result.h"
#include "tuner/report.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
using testing::Write;

std::string PaperJson() { return PaperResultToJson(testing::SamplePaperResult()).dump(); }

// The names in `dir` (to see that no temporary file was left behind).
std::vector<std::string> Names(const fs::path& dir) {
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(ReportCli, WritesOneHtmlPageAndAMarkdownSummaryOfPaperResultsAndTuningReports) {
  const fs::path dir = testing::ScratchDir("skintune_report_cli");
  const std::string paper = Write(dir / "paper.json", PaperJson());
  const std::string tuning = Write(dir / "report.json", ReportToJson(testing::SampleReport()).dump());
  const std::string html = (dir / "report.html").string(), md = (dir / "report.md").string();
  const testing::CommandResult r = testing::RunSkintune({"report", paper, tuning, "-o", html, "--markdown", md});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(testing::CountLines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("2 result(s), 7 device(s)"), std::string::npos) << r.err;
  const std::string page = testing::ReadAll(html);
  EXPECT_EQ(page.rfind("<!DOCTYPE html>", 0), 0u);
  for (const char* id : {"fig1", "fig1-0", "fig1-1", "table1-opencl-vs-cuda", "table1-opencl-vs-glsl", "gbps-6",
                         "axes-0", "devices"}) {
    EXPECT_NE(page.find(std::string("id=\"") + id + "\""), std::string::npos) << id;
  }
  EXPECT_EQ(page.find("<script"), std::string::npos);
  EXPECT_NE(page.find("No serial baseline"), std::string::npos);  // the tuning report's figure
  const std::string summary = testing::ReadAll(md);
  EXPECT_NE(summary.find("## Fig. 1"), std::string::npos);
  EXPECT_NE(summary.find("### Table 1: OpenCL relative to CUDA"), std::string::npos);
  EXPECT_NE(summary.find("run 2: Model GPU"), std::string::npos);
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"paper.json", "report.html", "report.json", "report.md"}));
}

TEST(ReportCli, MarkdownDashGoesToStandardOutput) {
  const fs::path dir = testing::ScratchDir("skintune_report_cli");
  const std::string paper = Write(dir / "paper.json", PaperJson());
  const testing::CommandResult r =
      testing::RunSkintune({"report", paper, "-o", (dir / "r.html").string(), "--markdown", "-"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("# The paper's experiment", 0), 0u) << r.out.substr(0, 200);
  EXPECT_NE(r.out.find("| NVIDIA H100 80GB HBM3 \xC2\xB7 CUDA | CUDA tuned (cuda) |"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "r.html"));
}

struct BadInput {
  const char* name;
  std::string text;
  std::vector<std::string> error_mentions;
};

TEST(ReportCli, BadInputIsOneErrorLineNamingFileAndElementAndLeavesTheOutputAlone) {
  nlohmann::json bad_measurement = PaperResultToJson(testing::SamplePaperResult());
  bad_measurement["tuning"]["measurements"][3]["status"] = "exploded";
  nlohmann::json bad_cpu = PaperResultToJson(testing::SamplePaperResult());
  bad_cpu["cpu"][2]["serial"]["median_ms"] = "fast";
  nlohmann::json bad_report = ReportToJson(testing::SampleReport());
  bad_report["devices"][1].erase("name");
  const std::vector<BadInput> cases = {
      {"not-json.json", "{\"kind\": \"skintune-paper-result\", ", {"not valid JSON"}},
      {"wrong-kind.json", R"({"schema_version": "1.0.0", "kind": "skintune-winners-db", "entries": []})",
       {"\"skintune-winners-db\"", "expected \"kind\": \"skintune-paper-result\" or \"skintune-report\""}},
      {"no-kind.json", R"({"schema_version": "1.0.0"})", {"no \"kind\"", "skintune-paper-result"}},
      {"array.json", "[1, 2]", {"not a JSON object", "skintune-report"}},
      {"bad-measurement.json", bad_measurement.dump(), {"tuning: measurements[3]", "exploded"}},
      {"bad-cpu.json", bad_cpu.dump(), {"cpu[2]: serial: 'median_ms' must be a number"}},
      {"bad-report.json", bad_report.dump(), {"devices[1]", "name"}},
  };
  const fs::path dir = testing::ScratchDir("skintune_report_cli");
  const std::string good = Write(dir / "good.json", PaperJson());
  const std::string html = Write(dir / "report.html", "the previous report\n");
  const std::string md = Write(dir / "report.md", "the previous summary\n");
  for (const BadInput& c : cases) {
    const std::string path = Write(dir / c.name, c.text);
    const testing::CommandResult r = testing::RunSkintune({"report", good, path, "-o", html, "--markdown", md});
    EXPECT_EQ(r.exit_code, 1) << c.name << ": " << r.err;
    EXPECT_EQ(testing::CountLines(r.err), 1) << c.name << ": " << r.err;
    EXPECT_EQ(r.err.rfind("skintune: error: " + path + ": ", 0), 0u) << c.name << ": " << r.err;
    for (const std::string& mention : c.error_mentions) {
      EXPECT_NE(r.err.find(mention), std::string::npos) << c.name << ": wanted '" << mention << "' in " << r.err;
    }
    EXPECT_EQ(testing::ReadAll(html), "the previous report\n") << c.name;
    EXPECT_EQ(testing::ReadAll(md), "the previous summary\n") << c.name;
    fs::remove(path);
  }
  const testing::CommandResult missing = testing::RunSkintune({"report", (dir / "absent.json").string(), "-o", html});
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find((dir / "absent.json").string() + ": cannot open file"), std::string::npos) << missing.err;
  EXPECT_EQ(testing::ReadAll(html), "the previous report\n");
  // Nothing but the inputs and the untouched outputs: no temporary file left.
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"good.json", "report.html", "report.md"}));
}

TEST(ReportCli, UnwritableOutputIsAnErrorNamingIt) {
  const fs::path dir = testing::ScratchDir("skintune_report_cli");
  const std::string paper = Write(dir / "paper.json", PaperJson());
  const std::string out = (dir / "no-such-folder" / "report.html").string();
  const testing::CommandResult r = testing::RunSkintune({"report", paper, "-o", out});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(out + ": cannot write"), std::string::npos) << r.err;
}

TEST(ReportCli, MissingOutputOrInputIsACommandLineError) {
  const fs::path dir = testing::ScratchDir("skintune_report_cli");
  const std::string paper = Write(dir / "paper.json", PaperJson());
  EXPECT_EQ(testing::RunSkintune({"report", paper}).exit_code, 2);
  EXPECT_EQ(testing::RunSkintune({"report", "-o", (dir / "r.html").string()}).exit_code, 2);
  EXPECT_FALSE(fs::exists(dir / "r.html"));
}

}  // namespace
}  // namespace skintune::internal
