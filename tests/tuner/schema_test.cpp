// Reports, winners databases and T4 exports validate against configs/*.schema.json
// with Python's jsonschema (scripts/bootstrap installs python3-jsonschema: a
// missing module fails these tests, it never skips them).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/tuner/sample_report.h"
#include "report/paper_result.h"
#include "tuner/report.h"

#ifndef SKINTUNE_PYTHON3
#define SKINTUNE_PYTHON3 "python3"
#endif

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

fs::path TempDir() {
  const fs::path dir = fs::temp_directory_path() / ("skintune_schema_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

class CleanUp : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(TempDir()); }
};
const auto* const kCleanUp = ::testing::AddGlobalTestEnvironment(new CleanUp);

// The exit code of validate_json.py: 0 valid, 3 invalid, anything else a broken set-up.
int Validate(const nlohmann::json& instance, const std::string& schema, const std::string& name) {
  const fs::path file = TempDir() / (name + ".json");
  std::ofstream(file) << instance.dump(2);
  const std::string command = std::string("'") + SKINTUNE_PYTHON3 + "' '" + SKINTUNE_SOURCE_DIR +
                              "/tests/tuner/validate_json.py' '" + file.string() + "' '" + SKINTUNE_SOURCE_DIR +
                              "/configs/" + schema + "'";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

TEST(Schema, JsonschemaIsInstalled) {
  const std::string command = std::string("'") + SKINTUNE_PYTHON3 + "' -c 'import jsonschema'";
  ASSERT_EQ(std::system(command.c_str()), 0)
      << SKINTUNE_PYTHON3 << " has no jsonschema module: run scripts/bootstrap (it installs python3-jsonschema)";
}

// The report schema's status enum is the tuner's list (kAllMeasureStatuses):
// a status added to one and not the other fails here.
TEST(Schema, ReportSchemaListsEveryMeasureStatus) {
  std::ifstream in(std::string(SKINTUNE_SOURCE_DIR) + "/configs/report.schema.json");
  ASSERT_TRUE(in);
  const nlohmann::json schema = nlohmann::json::parse(in);
  std::vector<std::string> listed, names;
  for (const nlohmann::json& s : schema.at("$defs").at("measurement").at("properties").at("status").at("enum"))
    listed.push_back(s.get<std::string>());
  for (MeasureStatus s : kAllMeasureStatuses) names.emplace_back(Name(s));
  EXPECT_EQ(listed, names);
}

TEST(Schema, ReportsValidate) {
  EXPECT_EQ(Validate(ReportToJson(testing::SampleReport()), "report.schema.json", "report"), 0);
  TuningReport empty;
  empty.created = "2025-01-31T12:00:00Z";
  empty.config = "default";
  empty.strategy = "coordinate";
  EXPECT_EQ(Validate(ReportToJson(empty), "report.schema.json", "empty"), 0);
}

TEST(Schema, ReportsWithSourceErrorsTooImpreciseAndPrecisionClassesValidate) {
  TuningReport report = testing::SampleReport();
  report.max_error = 1e-3;
  int changed = 0;
  for (Measurement& m : report.measurements) {
    if (m.status != MeasureStatus::kOk) continue;
    m.source_error = {true, 2.0, 4e-3, 2e-3, 1e-6, changed % 2 ? 2e-3 : 0.0};
    ApplyBudget(m, report.max_error);
    ++changed;
  }
  ASSERT_GT(changed, 1);
  const nlohmann::json j = ReportToJson(report);
  EXPECT_EQ(Validate(j, "report.schema.json", "precision"), 0);
  EXPECT_EQ(Validate(WinnersDatabase(report), "winners-db.schema.json", "precision-db"), 0);
  const nlohmann::json t4 = ReportToT4(report);
  EXPECT_EQ(Validate(t4, "t4-results.schema.json", "precision-t4"), 0);
  int too_imprecise = 0;
  for (const nlohmann::json& result : t4.at("results")) {
    if (result.at("status") != "too_imprecise") continue;
    ++too_imprecise;
    EXPECT_EQ(result.at("correctness"), 1);  // right, only over the budget
    EXPECT_EQ(result.at("times").at("runtimes").size(), 1u);
  }
  EXPECT_GT(too_imprecise, 0);
  nlohmann::json bad = j;
  for (nlohmann::json& m : bad["measurements"])
    if (m.contains("source_error")) m["source_error"].erase("quantisation_rel");
  EXPECT_EQ(Validate(bad, "report.schema.json", "precision-bad"), 3);
}

TEST(Schema, BrokenReportsFailValidation) {
  const nlohmann::json good = ReportToJson(testing::SampleReport());
  nlohmann::json j = good;
  j.erase("created");
  EXPECT_EQ(Validate(j, "report.schema.json", "no-created"), 3);
  j = good;
  j["measurements"][0]["status"] = "fast";
  EXPECT_EQ(Validate(j, "report.schema.json", "bad-status"), 3);
  j = good;
  j["measurements"][0]["variant"]["layout"] = "aosoa";
  EXPECT_EQ(Validate(j, "report.schema.json", "bad-axis"), 3);
  j = good;
  j["schema_version"] = "0.9.0";
  EXPECT_EQ(Validate(j, "report.schema.json", "bad-version"), 3);
  j = good;
  j["winners"][0]["vertex_bucket"] = "3k";
  EXPECT_EQ(Validate(j, "report.schema.json", "bad-bucket"), 3);
  // docs/INPUTS.md: what the readers refuse as impossible, the schema refuses too
  // (all but the GB/s consistency, which a schema cannot state).
  std::size_t ok = 0;
  while (good["measurements"][ok]["status"] != "ok") ++ok;
  j = good;
  j["measurements"][ok].erase("timing");
  EXPECT_EQ(Validate(j, "report.schema.json", "ok-without-timing"), 3);
  j = good;
  j["measurements"][ok]["timing"]["median_ms"] = 0;
  EXPECT_EQ(Validate(j, "report.schema.json", "ok-median-0"), 3);
  j = good;
  j["measurements"][ok]["timing"]["median_ms"] = "nan";
  EXPECT_EQ(Validate(j, "report.schema.json", "ok-median-nan"), 3);
  j = good;
  j["measurements"][ok]["bytes_per_frame"] = 0;
  EXPECT_EQ(Validate(j, "report.schema.json", "ok-bytes-0"), 3);
}

TEST(Schema, WinnersDatabasesValidate) {
  const nlohmann::json db = WinnersDatabase(testing::SampleReport());
  EXPECT_EQ(Validate(db, "winners-db.schema.json", "db"), 0);
  const nlohmann::json merged = MergeWinnersDatabases(
      {ReportToJson(testing::SampleReport("2025-01-01T00:00:00Z")), db,
       ReportToJson(testing::SampleReport("2025-03-01T00:00:00Z", 2.0, "2.0"))},
      {"a", "b", "c"});
  EXPECT_EQ(Validate(merged, "winners-db.schema.json", "merged"), 0);
  nlohmann::json broken = db;
  broken["entries"][0].erase("created");
  EXPECT_EQ(Validate(broken, "winners-db.schema.json", "db-broken"), 3);
  EXPECT_EQ(Validate(ReportToJson(testing::SampleReport()), "winners-db.schema.json", "report-as-db"), 3);
}

TEST(Schema, EmbedFixtureDatabasesValidate) {
  // tests/data/embed-winners-db.json and embed-scenes-winners-db.json, written by hand for
  // `skintune emit --db`'s tests.
  for (const std::string name : {"embed-winners-db.json", "embed-scenes-winners-db.json"}) {
    std::ifstream in(std::string(SKINTUNE_TEST_DATA_DIR) + "/" + name);
    ASSERT_TRUE(in) << "tests/data/" << name << " not found";
    const nlohmann::json fixture = nlohmann::json::parse(in);
    EXPECT_EQ(Validate(fixture, "winners-db.schema.json", name), 0);
    nlohmann::json broken = fixture;
    broken["entries"][0]["variant"]["storage"] = "texture";
    EXPECT_EQ(Validate(broken, "winners-db.schema.json", name + "-broken"), 3);
  }
}

// A paper result embeds a tuning report: its schema refers to report.schema.json by $id.
TEST(Schema, PaperResultsValidateAndTheirBrokenCopiesDoNot) {
  PaperResult r;
  r.created = "2025-01-31T12:00:00Z";
  r.command = "skintune paper";
  r.host = {"Example CPU", 16, 80.5};
  r.reported = BuiltInPaperReported();
  r.reported.figure1 = {{"cuda", 40.0}};
  r.paper_kernels = PaperKernels();
  r.tuning = testing::SampleReport();
  r.cpu = {{"25k-b4", {12.5, 12.0, 13.0, 9, 8, 1, 4.0e6, 0.32, 1e-7}, {1.5, 1.4, 1.9, 9, 8, 16, 3.0e6, 2.0, 2e-7}}};
  const nlohmann::json good = PaperResultToJson(r);
  EXPECT_EQ(Validate(good, "paper-result.schema.json", "paper"), 0);
  nlohmann::json bad = good;
  bad["cpu"][0]["serial"]["median_ms"] = 0;
  EXPECT_EQ(Validate(bad, "paper-result.schema.json", "paper_bad_cpu"), 3);
  bad = good;
  bad["tuning"]["measurements"][0]["status"] = "fine";  // checked through the report schema
  EXPECT_EQ(Validate(bad, "paper-result.schema.json", "paper_bad_tuning"), 3);
  bad = good;
  bad["reported"]["figure1"]["cuda"] = -1;
  EXPECT_EQ(Validate(bad, "paper-result.schema.json", "paper_bad_reported"), 3);
}

// The committed results (the H100 paper run, whose report docs/results/paper-h100 holds, and
// docs/results/paper-2core) and the report tests' fixture follow the schema and read back: a
// format change must regenerate or migrate them.
TEST(Schema, CommittedPaperResultsValidateAndReadBack) {
  for (const char* file : {"tests/data/paper/h100-result.json", "docs/results/paper-2core/paper-result.json",
                           "tests/data/paper/sample-result.json"}) {
    std::ifstream in(std::string(SKINTUNE_SOURCE_DIR) + "/" + file);
    ASSERT_TRUE(in) << file;
    const nlohmann::json json = nlohmann::json::parse(in);
    EXPECT_EQ(Validate(json, "paper-result.schema.json", "committed"), 0) << file;
    EXPECT_NO_THROW(PaperResultFromJson(json, file)) << file;
  }
}

TEST(Schema, T4ExportsValidate) {
  const nlohmann::json t4 = ReportToT4(testing::SampleReport());
  EXPECT_EQ(Validate(t4, "t4-results.schema.json", "t4"), 0);
  nlohmann::json broken = t4;
  broken["results"][0]["invalidity"] = "slow";
  EXPECT_EQ(Validate(broken, "t4-results.schema.json", "t4-broken"), 3);
  broken = t4;
  broken["results"][0].erase("correctness");
  EXPECT_EQ(Validate(broken, "t4-results.schema.json", "t4-no-correctness"), 3);
}

}  // namespace
}  // namespace skintune::internal
