// `skintune db merge`: reports and databases in, one database out, atomically;
// a bad input is one error line naming the file and leaves the output alone.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/tools/run_command.h"
#include "tests/tuner/sample_report.h"
#include "tuner/report.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

fs::path TempDir() {
  const fs::path dir = fs::temp_directory_path() / ("skintune_db_cli_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

class CleanUp : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(TempDir()); }
};
const auto* const kCleanUp = ::testing::AddGlobalTestEnvironment(new CleanUp);

std::string Write(const std::string& name, const std::string& text) {
  const fs::path p = TempDir() / name;
  std::ofstream(p) << text;
  return p.string();
}

std::size_t Lines(const std::string& text) { return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')); }

TEST(DbCli, MergesReportsAndDatabases) {
  const std::string a = Write("a.json", ReportToJson(testing::SampleReport("2025-01-01T00:00:00Z")).dump());
  const std::string b = Write("b.json", ReportToJson(testing::SampleReport("2025-02-01T00:00:00Z", 2.0)).dump());
  const std::string out = (TempDir() / "db.json").string();
  const testing::CommandResult r = testing::RunSkintune({"db", "merge", a, b, "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json db = nlohmann::json::parse(testing::ReadAll(out));
  EXPECT_EQ(db["kind"], "skintune-winners-db");
  // One entry per precision class of every key (database 1.3.0).
  ASSERT_EQ(db["entries"].size(), ComputeWinners(testing::SampleReport()).size());
  for (const nlohmann::json& e : db["entries"]) EXPECT_EQ(e["created"], "2025-02-01T00:00:00Z");
  // The database itself is an input too.
  const std::string out2 = (TempDir() / "db2.json").string();
  const testing::CommandResult again = testing::RunSkintune({"db", "merge", out, a, "-o", out2});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(nlohmann::json::parse(testing::ReadAll(out2)), db);
}

TEST(DbCli, BadInputIsOneLineNamingTheFileAndTheOutputIsUntouched) {
  const std::string good = Write("good.json", ReportToJson(testing::SampleReport()).dump());
  const std::string out = Write("keep.json", "previous contents\n");
  const std::string missing = (TempDir() / "missing.json").string();
  const std::string not_json = Write("garbage.json", "{\"kind\": ");
  nlohmann::json broken = ReportToJson(testing::SampleReport());
  broken["measurements"][2]["variant"]["layout"] = "aosoa";
  const std::string malformed = Write("broken.json", broken.dump());
  for (const std::string& bad : {missing, not_json, malformed}) {
    const testing::CommandResult r = testing::RunSkintune({"db", "merge", good, bad, "-o", out});
    EXPECT_EQ(r.exit_code, 1) << bad;
    EXPECT_EQ(Lines(r.err), 1u) << r.err;
    EXPECT_NE(r.err.find("skintune: error: " + bad + ": "), std::string::npos) << r.err;
    EXPECT_EQ(testing::ReadAll(out), "previous contents\n");
  }
  EXPECT_NE(testing::RunSkintune({"db", "merge", good, malformed, "-o", out}).err.find("measurements[2]"),
            std::string::npos);
  EXPECT_EQ(testing::RunSkintune({"db", "merge", "-o", out}).exit_code, 2);  // no inputs
  EXPECT_EQ(testing::RunSkintune({"db", "merge", good}).exit_code, 2);       // no -o
}

TEST(DbCli, ReplayComparesStrategiesOnACacheOrAReport) {
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  std::string lines;
  for (std::size_t i = 0; i < 2000; ++i) {
    lines += nlohmann::json(testing::SyntheticMeasurement(candidates[i * 7], "opencl:P/D/1", "100k-b4")).dump() + "\n";
  }
  const std::string cache = Write("cache.jsonl", lines);
  testing::CommandResult r = testing::RunSkintune(
      {"db", "replay", cache, "--device-id", "opencl:P/D/1", "--dataset", "100k-b4", "--seeds", "3"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("| coordinate | 10% (200) |"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("| random | 50% (1000) |"), std::string::npos) << r.out;
  r = testing::RunSkintune({"db", "replay", cache, "--device-id", "opencl:P/D/1", "--dataset", "100k-b4", "--seeds",
                            "2", "--budgets", "0.1,1", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["candidates"], 2000);
  ASSERT_EQ(j["rows"].size(), 6u);
  EXPECT_EQ(j["rows"][1]["mean_ratio"], 1.0);  // exhaustive at 100%
  // A report replays too.
  const std::string report = Write("r.json", ReportToJson(testing::SampleReport()).dump());
  r = testing::RunSkintune(
      {"db", "replay", report, "--device-id", testing::SampleGpu().Id(), "--dataset", "25k-b4", "--seeds", "2"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // Nothing recorded for that pair: one line naming the file and what was recorded.
  r = testing::RunSkintune({"db", "replay", cache, "--device-id", "opencl:P/D/1", "--dataset", "25k-b1"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(Lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find(cache + ": no measurement"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("'100k-b4'"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace skintune::internal
