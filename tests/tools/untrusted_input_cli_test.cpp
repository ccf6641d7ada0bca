// Input files the commands cannot trust, end to end: a number beyond double
// (1e400) in any JSON input, a folder, a FIFO, a device or an oversized file
// where a file is expected, an empty path for any file option. Each must end
// in one error line naming the file (or the option), never "internal error",
// a hang or memory without bound. Commands run under an address-space limit
// and an alarm, so a regression fails fast.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "report/paper.h"
#include "report/paper_report.h"
#include "tests/common/scratch_dir.h"
#include "tests/common/tiny_tune_config.h"
#include "tests/tools/run_command.h"
#include "tests/tuner/sample_report.h"
#include "tuner/report.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
using testing::CountLines;
using testing::ReadAll;
using testing::RunSkintune;

constexpr std::uint64_t kTwoGiB = 2ull << 30;
constexpr unsigned kTimeoutS = 60;  // a blocked read is killed (exit 142)

std::string Write(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

// `json` as text with "1e400" as its first member's value: valid JSON
// grammar, a number no double holds.
std::string WithOverflow(const nlohmann::json& json) {
  std::string text = json.dump();
  return text.insert(1, "\"overflow\": 1e400, ");
}

// One line on stderr: "skintune: error: " + `start`..., exit 1, no internal error.
void ExpectOneErrorLine(const testing::CommandResult& r, const std::string& start) {
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("skintune: error: " + start, 0), 0u) << r.err;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
}

// A command of the tool that reads `path` as one of its inputs.
struct Reader {
  const char* what;
  std::vector<std::string> (*args)(const std::string& path, const fs::path& dir);
};

const std::vector<Reader>& Readers() {
  static const std::vector<Reader> readers = {
      {"tune --config", [](const std::string& p, const fs::path& d) {
         return std::vector<std::string>{"tune", "--config", p, "--out", (d / "out").string(), "--quiet"};
       }},
      {"variants --config", [](const std::string& p, const fs::path&) {
         return std::vector<std::string>{"variants", "--config", p};
       }},
      {"report", [](const std::string& p, const fs::path& d) {
         return std::vector<std::string>{"report", p, "-o", (d / "report.html").string()};
       }},
      {"db merge", [](const std::string& p, const fs::path& d) {
         return std::vector<std::string>{"db", "merge", p, "-o", (d / "db.json").string()};
       }},
      {"db replay", [](const std::string& p, const fs::path&) {
         return std::vector<std::string>{"db", "replay", p, "--device-id", "x", "--dataset", "5000-b2"};
       }},
      {"emit --db", [](const std::string& p, const fs::path& d) {
         return std::vector<std::string>{"emit", "--db", p, "--device", "", "--out", (d / "kernels").string()};
       }},
      {"skin --check", [](const std::string& p, const fs::path&) {
         return std::vector<std::string>{"skin", "--dataset", "500-b2", "--check", p};
       }},
      {"skin --mesh", [](const std::string& p, const fs::path& d) {
         return std::vector<std::string>{"skin", "--mesh", p, "--out", (d / "out.obj").string()};
       }},
  };
  return readers;
}

TEST(UntrustedInput, ANumberBeyondDoubleInAnyJsonInputIsOneErrorNamingTheFile) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  const TuningReport report = testing::SampleReport();
  const nlohmann::json cache_line = report.measurements.front();
  struct Case {
    std::string path, text;
    std::vector<std::string> args;
  };
  const std::string html = (dir / "r.html").string(), db = (dir / "db.json").string();
  const std::string config = (dir / "config.json").string(), report_path = (dir / "report.json").string();
  const std::string paper = (dir / "paper.json").string(), winners = (dir / "winners.json").string();
  const std::string cache = (dir / "cache.jsonl").string();
  const std::vector<Case> cases = {
      {config, WithOverflow(testing::TinyTuneConfig().Json()),
       {"tune", "--config", config, "--out", (dir / "out").string(), "--quiet"}},
      {config, WithOverflow(testing::TinyTuneConfig().Json()), {"variants", "--config", config}},
      {report_path, WithOverflow(ReportToJson(report)), {"report", report_path, "-o", html}},
      {report_path, WithOverflow(ReportToJson(report)), {"db", "merge", report_path, "-o", db}},
      {paper, WithOverflow(PaperResultToJson(PaperResultFromReport(report))), {"report", paper, "-o", html}},
      {winners, WithOverflow(WinnersDatabase(report)), {"emit", "--db", winners, "--device", "", "--out", (dir / "k").string()}},
      {winners, WithOverflow(WinnersDatabase(report)), {"db", "merge", winners, "-o", db}},
      {cache, WithOverflow(cache_line) + "\n", {"db", "replay", cache, "--device-id", "x", "--dataset", "y"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args[0] + " " + c.args[1] + " " + c.path);
    Write(c.path, c.text);
    const testing::CommandResult r = RunSkintune(c.args, kTwoGiB, kTimeoutS);
    ExpectOneErrorLine(r, c.path + ":");
    EXPECT_NE(r.err.find("1e400"), std::string::npos) << r.err;
  }
}

TEST(UntrustedInput, AFolderAFifoADeviceOrAnOversizedFileIsOneErrorNamingItBeforeAnyRead) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  const std::string folder = (dir / "folder.json").string();
  fs::create_directories(folder);
  const std::string fifo = (dir / "fifo.json").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string huge = (dir / "huge.json").string();
  {
    std::ofstream(huge, std::ios::binary) << "{";
    fs::resize_file(huge, 300ull << 30);  // sparse: 300 GiB claimed, nothing stored
  }
  struct Input {
    std::string path, says;
  };
  const std::vector<Input> inputs = {{folder, "is a directory, not a file"},
                                     {fifo, "is a FIFO (named pipe), not a regular file"},
                                     {"/dev/zero", "is a character device, not a regular file"},
                                     {huge, "is 300.0 GiB, more than the "}};
  for (const Reader& reader : Readers()) {
    for (const Input& input : inputs) {
      SCOPED_TRACE(std::string(reader.what) + " " + input.path);
      const testing::CommandResult r = RunSkintune(reader.args(input.path, dir), kTwoGiB, kTimeoutS);
      ExpectOneErrorLine(r, input.path + ": ");
      EXPECT_NE(r.err.find(input.says), std::string::npos) << r.err;
    }
  }
}

TEST(UntrustedInput, AFileThatCannotBeReadIsAnErrorNotAnInternalOne) {
  // /proc/self/mem: a regular file of size 0 whose read at offset 0 fails.
  ExpectOneErrorLine(RunSkintune({"skin", "--mesh", "/proc/self/mem", "--out", "/dev/null"}, kTwoGiB, kTimeoutS),
                     "/proc/self/mem: ");
}

TEST(UntrustedInput, AReportWhoseKindIsNotAStringIsReplayedAsAReportAndRefusedNamingTheField) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  nlohmann::json report = ReportToJson(testing::SampleReport());
  report["kind"] = 42;
  const std::string path = Write(dir / "report.json", report.dump());
  const testing::CommandResult r =
      RunSkintune({"db", "replay", path, "--device-id", "x", "--dataset", "y"}, kTwoGiB, kTimeoutS);
  ExpectOneErrorLine(r, path + ": kind: ");
}

TEST(UntrustedInput, AnEmptyPathIsACommandLineErrorNamingTheOption) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  const std::string out = (dir / "out").string();
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {"--check", {"skin", "--dataset", "500-b2", "--check", ""}},
      {"--out", {"skin", "--dataset", "500-b2", "--out", ""}},
      {"--palette-out", {"skin", "--dataset", "500-b2", "--palette-out", ""}},
      {"--mesh", {"skin", "--mesh", "", "--out", out}},
      {"--config", {"tune", "--config", "", "--out", out}},
      {"--config", {"run", "--config", "", "--out", out}},
      {"--config", {"variants", "--config", ""}},
      {"--out", {"tune", "--out", ""}},
      {"--out", {"paper", "--out", ""}},
      {"--db", {"emit", "--db", "", "--device", "", "--out", out}},
      {"--out", {"emit", "--variant", "opencl.b2.soa", "--out", ""}},
      {"results", {"report", "", "-o", out}},
      {"--out", {"report", "x.json", "-o", ""}},
      {"--markdown", {"report", "x.json", "-o", out, "--markdown", ""}},
      {"inputs", {"db", "merge", "", "-o", out}},
      {"--output", {"db", "merge", "x.json", "-o", ""}},
      {"recorded", {"db", "replay", "", "--device-id", "x", "--dataset", "y"}},
  };
  for (const auto& [option, args] : cases) {
    SCOPED_TRACE(args[0] + " " + option);
    const testing::CommandResult r = RunSkintune(args, kTwoGiB, kTimeoutS);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(CountLines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(option + ": an empty path names no file"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out)) << r.err;
  }
}

}  // namespace
}  // namespace skintune::internal
