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
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "report/paper_result.h"
#include "report/paper_report.h"
#include "tests/common/scratch_dir.h"
#include "tests/common/tiny_tune_config.h"
#include "tests/tools/expect_error_line.h"
#include "tests/tools/run_command.h"
#include "tests/tuner/sample_report.h"
#include "tuner/report.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
using testing::CountLines;
using testing::ReadAll;
using testing::ExpectOneErrorLine;
using testing::RunSkintune;
using testing::Write;

constexpr std::uint64_t kTwoGiB = 2ull << 30;
constexpr unsigned kTimeoutS = 60;  // a blocked read is killed (exit 142)

// `json` as text with "1e400" as its first member's value: valid JSON
// grammar, a number no double holds.
std::string WithOverflow(const nlohmann::json& json) {
  std::string text = json.dump();
  return text.insert(1, "\"overflow\": 1e400, ");
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

// A verification tolerance of 1.0 let a kernel whose output was 0.39 of the
// diagonal off win; a timeout of 1e10 s failed later as "worker process did
// not start within 1e+10 s". Both are settings that cannot work, refused
// (exit 2) before anything is made.
TEST(UntrustedInput, AnAbsurdToleranceOrVariantTimeoutInAConfigIsOneErrorNamingTheField) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  const fs::path out = dir / "out";
  struct Case {
    const char* field;
    nlohmann::json value;
    std::string says;
  };
  for (const Case& c : {Case{"tolerance", 1.0, "timing.tolerance: must be a positive number at most 0.001 (got 1.0)"},
                        Case{"tolerance", 1e308, "timing.tolerance: must be a positive number at most 0.001"},
                        Case{"variant_timeout_s", 1e10, "variant_timeout_s: must be a positive number at most 86400"}}) {
    SCOPED_TRACE(c.says);
    nlohmann::json config = testing::TinyTuneConfig().Json();
    if (std::string(c.field) == "tolerance") {
      config["timing"]["tolerance"] = c.value;
    } else {
      config[c.field] = c.value;
    }
    const std::string path = Write(dir / "config.json", config.dump());
    ExpectOneErrorLine(RunSkintune({"tune", "--config", path, "--out", out.string(), "--quiet"}, kTwoGiB, kTimeoutS),
                       path + ": " + c.says, 2);
    EXPECT_FALSE(fs::exists(out));
  }
}

// A measurement cache is input: a line a run could not have written is
// refused on resume, naming the file and line, before anything is measured,
// and a report or database made from such figures is refused the same way.
TEST(UntrustedInput, ImpossibleFiguresInACacheOrReportAreRefusedNamingTheFileAndElement) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  const std::string config = Write(dir / "config.json", testing::TinyTuneConfig().Json().dump());
  TuningReport sample = testing::SampleReport();
  std::size_t ok = 0;
  while (sample.measurements.at(ok).status != MeasureStatus::kOk) ++ok;
  SourceError& error = sample.measurements[ok].source_error;  // as a verified kernel of f32 weights has it
  error.known = true;
  error.diagonal = 2.5;
  error.position_rel = 1.5e-7;
  error.position_abs = 2.5 * 1.5e-7;
  const nlohmann::json line = sample.measurements[ok];
  struct Case {
    std::function<void(nlohmann::json&)> edit;
    std::string says;
  };
  const std::vector<Case> cases = {
      {[](nlohmann::json& j) { j["timing"]["footprint_bytes"] = "nan"; }, "'footprint_bytes' is nan"},
      {[](nlohmann::json& j) { j["timing"]["footprint_bytes"] = -4096; }, "'footprint_bytes' is -4096"},
      {[](nlohmann::json& j) { j["timing"]["burst_frames"] = -1; }, "'burst_frames' is -1"},
      {[](nlohmann::json& j) { j["timing"]["input_sets"] = 0; }, "'input_sets' is 0"},
      {[](nlohmann::json& j) { j["timing"]["warmup"] = -1; }, "'warmup' is -1"},
      {[](nlohmann::json& j) { j["max_relative_error"] = 0.5; }, "'max_relative_error' is 0.5"},
      {[](nlohmann::json& j) { j["source_error"]["position_rel"] = 1e308; }, "'source_error.position_rel' is 1e+308"},
      {[](nlohmann::json& j) {
         j["bytes_per_frame"] = 1e308;
         j["gbps"] = 1e308;
       },
       "'bytes_per_frame' 1e+308 / 'median_ms'"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.says);
    nlohmann::json bad = line;
    c.edit(bad);
    const fs::path out = dir / "out";
    fs::remove_all(out);
    fs::create_directories(out);
    const std::string cache = Write(out / "cache.jsonl", bad.dump() + "\n");
    ExpectOneErrorLine(RunSkintune({"tune", "--config", config, "--out", out.string(), "--quiet"}, kTwoGiB, kTimeoutS),
                       cache + ":1: measurement: impossible figures: status ok with ");
    EXPECT_EQ(ReadAll(cache), bad.dump() + "\n");
    EXPECT_FALSE(fs::exists(out / "report.json"));
    nlohmann::json report = ReportToJson(sample);
    report["measurements"][ok] = bad;
    const std::string path = Write(dir / "report.json", report.dump());
    const testing::CommandResult merged =
        RunSkintune({"db", "merge", path, "-o", (dir / "db.json").string()}, kTwoGiB, kTimeoutS);
    ExpectOneErrorLine(merged, path + ": measurements[" + std::to_string(ok) + "]: measurement: impossible figures: ");
    EXPECT_NE(merged.err.find(c.says), std::string::npos) << merged.err;
  }
}

// A config that cannot run (no valid variant, a dataset that does not fit, a
// scene with a bad glTF) is one error naming the config and the dataset, and
// leaves no --out folder behind; `variants --config` takes only a config.
TEST(UntrustedInput, AConfigThatCannotRunNamesItselfAndCreatesNoOutputFolder) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  const std::string junk = Write(dir / "junk.gltf", "{\"asset\": 42}");
  struct Case {
    nlohmann::json datasets;
    std::vector<std::string> index;
    std::string says;  // after "<config>: "
  };
  const std::vector<Case> cases = {
      {{"5000-b2-bones300"}, {"u8"}, ""},  // 300 joints fit no u8 index: "no valid variant ..."
      {{"5000-b2", "4000m-b2"}, {"u16"}, "datasets[1]: dataset '4000m-b2': needs about "},
      {{"5000-b2+" + junk}, {"u16"}, "datasets[0]: scene '5000-b2+" + junk + "': meshes[1] "},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.datasets.dump());
    testing::TinyTuneConfig tiny;
    tiny.indices = c.index;
    nlohmann::json config = tiny.Json();
    config["datasets"] = c.datasets;
    const std::string path = Write(dir / "config.json", config.dump());
    const fs::path out = dir / "new" / "out";
    const testing::CommandResult r =
        RunSkintune({"tune", "--config", path, "--out", out.string(), "--quiet"}, kTwoGiB, kTimeoutS);
    if (c.says.empty()) {
      ExpectOneErrorLine(r, "no valid variant of the space on any device: ");
    } else {
      ExpectOneErrorLine(r, path + ": " + c.says);
    }
    EXPECT_FALSE(fs::exists(dir / "new")) << r.err;
  }
  for (const char* text : {"42", "null", "[]", "{}"}) {
    SCOPED_TRACE(text);
    const std::string path = Write(dir / "not-a-config.json", text);
    const testing::CommandResult r = RunSkintune({"variants", "--config", path}, kTwoGiB, kTimeoutS);
    ExpectOneErrorLine(r, path + ": ");
    EXPECT_EQ(r.out, "");
  }
}

// A reader quotes the bad string it finds: 100 KB of it (or its newlines)
// made a 100 KB error of many lines.
TEST(UntrustedInput, ALongOrMultiLineBadStringIsQuotedShortOnOneLine) {
  const fs::path dir = testing::ScratchDir("skintune_untrusted");
  const std::string long_string(100000, 'x');
  nlohmann::json long_value = testing::TinyTuneConfig().Json();
  long_value["space"]["layout"] = {"soa", long_string};
  nlohmann::json lines = testing::TinyTuneConfig().Json();
  lines["datasets"] = {"5000-b2\nskintune: error: a second line"};
  for (const nlohmann::json& config : {long_value, lines}) {
    const std::string path = Write(dir / "config.json", config.dump());
    const testing::CommandResult r =
        RunSkintune({"tune", "--config", path, "--out", (dir / "out").string(), "--quiet"}, kTwoGiB, kTimeoutS);
    ExpectOneErrorLine(r, path + ": ");
    EXPECT_LT(r.err.size(), 1000u) << r.err.substr(0, 300);
  }
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"skin", "--dataset", long_string, "--out", (dir / "x.obj").string()},
        std::vector<std::string>{"emit", "--variant", long_string, "--out", (dir / "e").string()}}) {
    const testing::CommandResult r = RunSkintune(args, kTwoGiB, kTimeoutS);
    ExpectOneErrorLine(r, "");
    EXPECT_LT(r.err.size(), 1000u) << r.err.substr(0, 300);
    EXPECT_NE(r.err.find("... (1000"), std::string::npos) << r.err.substr(0, 300);  // its start and its length
  }
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
