// `skintune run` end to end on this machine's devices (PoCL and llvmpipe here;
// every device found elsewhere): the CPU check line, the tuning of every
// device, the four files, the per-device winners table, the report's path and
// an emit command that works; bad input leaves earlier results untouched.
// A tiny config (two OpenCL and two GLSL compute variants on 5000 vertices:
// two, so that a GPU's OpenCL and CUDA compile them ahead) keeps it to seconds.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/common/scratch_dir.h"
#include "tests/common/tiny_tune_config.h"
#include "tests/tools/run_command.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
using testing::CountLines;
using testing::ReadAll;
using testing::RunSkintune;

fs::path Scratch() { return skintune::internal::testing::ScratchDir("skintune_run_cli_test"); }

const std::vector<std::string> kOutputs = {"report.json", "report.t4.json", "winners-db.json", "report.html"};

std::string TinyConfig(const fs::path& dir) {
  testing::TinyTuneConfig config;
  config.langs = {"opencl", "glsl-compute"};
  config.indices = {"u16", "u8"};
  config.max_input_sets = 2;
  config.variant_timeout_s = 20;
  const fs::path path = dir / "tiny.json";
  std::ofstream(path) << config.Json().dump(2);
  return path.string();
}

std::map<std::string, std::string> Outputs(const fs::path& out) {
  std::map<std::string, std::string> contents;
  for (const std::string& name : kOutputs) contents[name] = ReadAll(out / name);
  return contents;
}

TEST(RunCli, TunesEveryDeviceWritesTheFilesAndPrintsEachDevicesWinners) {
  const fs::path dir = Scratch();
  const fs::path out = dir / "results";
  const auto r = RunSkintune({"run", "--config", TinyConfig(dir), "--out", out.string(), "--cpu-check", "2k-b2",
                              "--software-rasterizers"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("CPU reference: serial and fast agree with the float64 gold within 1e-5"), std::string::npos)
      << r.out;
  for (const std::string& name : kOutputs) EXPECT_TRUE(fs::is_regular_file(out / name)) << name;
  EXPECT_NE(ReadAll(out / "report.html").find("<html"), std::string::npos);

  // Every device of the report has its section, with the winner of each of its languages.
  const nlohmann::json report = nlohmann::json::parse(ReadAll(out / "report.json"));
  std::set<std::string> backends;
  for (const nlohmann::json& d : report.at("devices")) {
    const std::string header = "== " + d.at("backend").get<std::string>() + ": " + d.at("name").get<std::string>();
    EXPECT_NE(r.out.find(header), std::string::npos) << header << "\n" << r.out;
    backends.insert(d.at("backend").get<std::string>());
  }
  EXPECT_TRUE(backends.count("opencl")) << r.out;  // PoCL, on every machine of this project
  EXPECT_TRUE(backends.count("gl")) << r.out;      // llvmpipe at least
  const nlohmann::json winners = report.at("winners");
  ASSERT_FALSE(winners.empty());
  // Every winner within the budget is printed (the faster classes over it are counted).
  for (const nlohmann::json& w : winners) {
    if (!w.at("within_budget").get<bool>()) continue;
    const std::string key = w.at("variant").at("key").get<std::string>();
    EXPECT_NE(r.out.find(key), std::string::npos) << key;
  }
  // Each device's table has the same header (columns padded to their width).
  std::size_t headers = 0;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("lang ", 0) != 0) continue;
    ++headers;
    std::istringstream words(line);
    std::vector<std::string> columns;
    for (std::string w; words >> w;) columns.push_back(w);
    EXPECT_EQ(columns, (std::vector<std::string>{"lang", "B", "vertices", "dataset", "variant", "kernel", "us", "[95%]",
                                                 "frame", "us", "GB/s", "x", "copy", "ties", "err/diag", "format",
                                                 "costs"}));
  }
  EXPECT_EQ(headers, report.at("devices").size()) << r.out;
  // Each device's footer names the margin its candidates were judged at: a
  // device on the host's CPU (all of this machine's) its wider one.
  for (const nlohmann::json& d : report.at("devices")) {
    const std::string header = "== " + d.at("backend").get<std::string>() + ": " + d.at("name").get<std::string>();
    const std::size_t at = r.out.find(header);
    ASSERT_NE(at, std::string::npos);
    const bool host = d.at("type").get<std::string>().find("cpu") != std::string::npos;
    const double margin = report.at(host ? "host_tie_margin" : "tie_margin").get<double>();
    char expected[64];
    std::snprintf(expected, sizeof expected, "within the tie margin %.1f%%", margin * 100.0);
    const std::size_t next = r.out.find("\n== ", at + 1);
    const std::string block = r.out.substr(at, next == std::string::npos ? std::string::npos : next - at);
    EXPECT_NE(block.find(expected), std::string::npos) << expected << " under " << header << "\n" << r.out;
    // The SM clock line where the device's samples recorded a clock (an
    // NVIDIA GPU read through NVML), and nowhere else.
    bool clocked = false;
    for (const nlohmann::json& m : report.at("measurements"))
      clocked = clocked || (m.at("device_id") == d.at("id") && m.at("timing").value("sm_clock_mhz", 0.0) > 0.0);
    EXPECT_EQ(block.find("SM clock around the samples") != std::string::npos, clocked) << header << "\n" << r.out;
    // The launch start line where the device's contexts were probed (a GPU), and nowhere else.
    bool probed = false;
    for (const nlohmann::json& m : report.at("measurements"))
      probed = probed || (m.at("device_id") == d.at("id") && m.at("timing").value("launch_start_ms", 0.0) > 0.0);
    EXPECT_EQ(block.find("\nlaunch start: ") != std::string::npos, probed) << header << "\n" << r.out;
  }

  // The report's path, and an emit command that takes the kernels.
  EXPECT_NE(r.out.find("report: " + fs::absolute(out / "report.html").string() + "\n"), std::string::npos) << r.out;
  const std::string emit = "  skintune emit --db '" + (out / "winners-db.json").string() + "' --device '' --out skintune-kernels\n";
  ASSERT_NE(r.out.find(emit), std::string::npos) << r.out;
  const fs::path kernels = dir / "kernels";
  const auto e = RunSkintune({"emit", "--db", (out / "winners-db.json").string(), "--device", "", "--out", kernels.string()});
  EXPECT_EQ(e.exit_code, 0) << e.err;
  EXPECT_TRUE(fs::is_regular_file(kernels / "skintune_kernels.h"));

  // A second run reuses the measurement cache: every variant and every race
  // cached, the same winners.
  const auto again = RunSkintune(
      {"run", "--config", TinyConfig(dir), "--out", out.string(), "--cpu-check", "none", "--software-rasterizers"});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(again.out.find("CPU reference"), std::string::npos);
  // (The copy bandwidth, and so copy_fraction, is measured again.)
  auto timed = [](const nlohmann::json& ws) {
    std::map<std::string, double> times;
    for (const nlohmann::json& w : ws) times[w.at("variant").at("key").get<std::string>()] = w.at("median_ms").get<double>();
    return times;
  };
  const nlohmann::json second = nlohmann::json::parse(ReadAll(out / "report.json"));
  EXPECT_EQ(timed(second.at("winners")), timed(winners));
  EXPECT_EQ(second.at("races"), report.at("races"));  // not raced again
  EXPECT_EQ(again.err.find("compiling"), std::string::npos) << again.err;  // nothing left to compile ahead
}

// The run's count of invalid points says what ruled them out: the cpu
// device has no local memory, so its local-storage points are invalid by
// that constraint, not failures.
TEST(RunCli, TheCountOfInvalidPointsNamesWhatRuledThemOut) {
  const fs::path dir = Scratch();
  testing::TinyTuneConfig config;
  config.langs = {"cpu"};
  config.storages = {"global", "local"};
  config.wg_sizes = {0};
  const fs::path path = dir / "cpu.json";
  std::ofstream(path) << config.Json().dump(2);
  const auto r = RunSkintune({"run", "--config", path.string(), "--out", (dir / "results").string(), "--cpu-check",
                              "none", "--device", "cpu"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json report = nlohmann::json::parse(ReadAll(dir / "results" / "report.json"));
  std::size_t invalid = 0;
  for (const nlohmann::json& m : report.at("measurements")) {
    if (m.at("status") != "invalid") continue;
    ++invalid;
    EXPECT_EQ(m.at("detail").get<std::string>().rfind("local_memory: ", 0), 0u) << m.dump();
  }
  ASSERT_GT(invalid, 0u) << r.out;
  const std::string expected = std::to_string(invalid) + " invalid (local_memory " + std::to_string(invalid) + ")";
  EXPECT_NE(r.out.find("measurements: " + expected), std::string::npos) << expected << "\n" << r.out;
}

TEST(RunCli, BadInputIsOneErrorLineAndLeavesThePreviousResults) {
  const fs::path dir = Scratch();
  const fs::path out = dir / "results";
  const std::string config = TinyConfig(dir);
  ASSERT_EQ(RunSkintune({"run", "--config", config, "--out", out.string(), "--cpu-check", "none", "--device",
                         "Portable Computing Language"})
                .exit_code,
            0);
  const std::map<std::string, std::string> before = Outputs(out);

  // A config with an unknown field: named, with the file.
  nlohmann::json bad = nlohmann::json::parse(ReadAll(config));
  bad["spaces"] = bad["space"];
  std::ofstream(dir / "bad.json") << bad.dump();
  auto r = RunSkintune({"run", "--config", (dir / "bad.json").string(), "--out", out.string(), "--cpu-check", "none"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("bad.json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("spaces"), std::string::npos) << r.err;
  EXPECT_EQ(Outputs(out), before);

  // An output file that cannot be replaced: found before any tuning, nothing written.
  fs::remove(out / "report.html");
  fs::create_directories(out / "report.html");
  r = RunSkintune({"run", "--config", config, "--out", out.string(), "--cpu-check", "none"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("report.html"), std::string::npos) << r.err;
  for (const std::string name : {"report.json", "report.t4.json", "winners-db.json"})
    EXPECT_EQ(ReadAll(out / name), before.at(name)) << name;

  // --out naming a file.
  std::ofstream(dir / "file") << "x";
  r = RunSkintune({"run", "--config", config, "--out", (dir / "file").string(), "--cpu-check", "none"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(ReadAll(dir / "file"), "x");
}

}  // namespace
}  // namespace skintune::internal
