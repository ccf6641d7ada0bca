// skintune db: the winners database of many machines' reports, and replay of
// recorded measurements.
//
//   skintune db merge A.json B.json ... -o db.json
//
// Each input is a tuning report or a winners database (told apart by "kind").
// Per device id (which includes the driver), language, influences and measured
// vertex count the entry of the newest report (by `created`) wins. A missing or
// malformed input is one error line naming the file; the output is written
// atomically, only when every input was read.
//
//   skintune db replay RECORDED --device-id ID --dataset KEY [--seeds N] [--budgets 0.05,0.1] [--json]
//
// Compares the search strategies on recorded measurements (a measurement
// cache or a report) without a device: per strategy and budget, the best time
// found over the exhaustive optimum (docs/TUNING.md, Replay).
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "reference/mesh_io.h"
#include "tools/commands.h"
#include "tuner/replay.h"
#include "tuner/report.h"

namespace skintune::internal::tools {

namespace {

struct DbOptions {
  std::vector<std::string> inputs;
  std::string output;
  // replay
  std::string recorded;
  std::string device_id;
  std::string dataset;
  int seeds = 10;
  std::vector<double> budgets{0.05, 0.1, 0.25, 0.5};
  bool json = false;
  CLI::App* merge = nullptr;
};

int RunDbMerge(const DbOptions& o) {
  CheckWritable(o.output);
  std::vector<nlohmann::json> inputs;
  for (const std::string& path : o.inputs) inputs.push_back(ReadJsonFile(path));
  const nlohmann::json db = MergeWinnersDatabases(inputs, o.inputs);
  WriteFileAtomically(o.output, db.dump(2) + "\n");
  std::cerr << "skintune: " << db["entries"].size() << " winner(s) from " << o.inputs.size() << " input(s) -> "
            << o.output << "\n";
  return 0;
}

// A report (a JSON object of kind skintune-report) or a measurement cache (JSON lines).
ReplayEvaluator LoadRecorded(const DbOptions& o) {
  const std::string text = ReadInputFile(o.recorded, kMeasurementCacheInput);
  // A report is one JSON document of at most kJsonInput; a cache's lines are not one document.
  const nlohmann::json whole = text.size() <= kJsonInput.bytes
                                   ? nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false)
                                   : nlohmann::json();
  // A measurement line has no "kind": an object with one is a report, and
  // ReportFromJson names what is wrong with it ("kind": 42 included).
  if (whole.is_object() && whole.contains("kind")) {
    return ReplayEvaluator::FromReport(ReportFromJson(whole, o.recorded), o.device_id, o.dataset, o.recorded);
  }
  return ReplayEvaluator::FromCacheFile(o.recorded, o.device_id, o.dataset);
}

int RunDbReplay(const DbOptions& o) {
  ReplayEvaluator replay = LoadRecorded(o);
  const StrategyComparison c = CompareStrategies(replay.variants(), replay.AsEvaluator(), o.budgets, o.seeds);
  if (o.json) {
    std::cout << nlohmann::json(c).dump(2) << "\n";
  } else {
    std::cout << "replay: " << o.recorded << ", device " << o.device_id << ", dataset " << o.dataset << "\n"
              << FormatComparison(c);
  }
  return 0;
}

}  // namespace

Command RegisterDb(CLI::App& app) {
  auto o = std::make_shared<DbOptions>();
  auto* sub = app.add_subcommand("db", "the winners database merged from tuning reports of many machines");
  sub->require_subcommand(1);
  auto* merge = sub->add_subcommand(
      "merge", "merge reports and/or databases into one database (per device+driver, language, influences and "
               "vertex bucket the newest report wins)");
  merge->add_option("inputs", o->inputs, "tuning reports (skintune-report) or winners databases (skintune-winners-db)")
      ->required()
      ->check(NonEmptyPath());
  merge->add_option("-o,--output", o->output, "the database to write (atomically; untouched on error)")
      ->required()
      ->check(NonEmptyPath());
  o->merge = merge;
  auto* replay = sub->add_subcommand(
      "replay", "compare the search strategies on recorded measurements (a measurement cache or a report), no device");
  replay->add_option("recorded", o->recorded, "measurement cache (JSON lines) or tuning report")
      ->required()
      ->check(NonEmptyPath());
  replay->add_option("--device-id", o->device_id, "device id as recorded (\"<backend>:<platform>/<name>/<driver>\")")
      ->required();
  replay->add_option("--dataset", o->dataset, "dataset key as recorded")->required();
  replay->add_option("--seeds", o->seeds, "seeds per strategy and budget (default 10)")->check(CLI::Range(1, 1000));
  replay->add_option("--budgets", o->budgets, "budgets as fractions of the candidates (default 0.05,0.1,0.25,0.5)")
      ->delimiter(',')
      ->check(CLI::Range(1e-9, 1.0));
  replay->add_flag("--json", o->json, "print JSON");
  return {sub, [o] { return o->merge->parsed() ? RunDbMerge(*o) : RunDbReplay(*o); }};
}

}  // namespace skintune::internal::tools
