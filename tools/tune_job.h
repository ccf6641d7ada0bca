// skintune command-line tool: the tuning job that `tune` and `run` share:
// load the config, tune every device found (tuner/tune.h), then write the
// output files together, and print the winners.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "tuner/report.h"
#include "tuner/tune.h"

namespace skintune::internal::tools {

struct TuneJobOptions {
  std::string command = "tune";        // for progress and messages: "tune", "run"
  std::string config;                  // a built-in name or a JSON file ("": default)
  std::string device;                  // --device
  std::vector<std::string> langs;      // --lang
  std::string strategy;                // --strategy ("": the config's)
  std::optional<std::size_t> budget;   // --budget
  std::string max_error_text;          // --max-error (ParseMaxError, one message naming the flag); "": the config's
  std::string out = "results";
  bool quiet = false;
  bool html = false;                   // also write report.html
  bool one_device_at_a_time = false;   // no devices at the same time (TuneOptions::parallel_devices)
  bool software_rasterizers = false;   // TuneOptions::software_rasterizers
};

// Adds the options `tune` and `run` share to `sub`: --config, --device,
// --lang, --max-error, --out, --one-device-at-a-time, --quiet.
void AddTuneJobOptions(CLI::App& sub, TuneJobOptions& o);

struct TuneJobResult {
  TuningReport report;
  std::filesystem::path out;
  std::filesystem::path cache;
  std::vector<std::filesystem::path> written;  // in writing order
};

// --config NAME (a built-in config: no '/' and no .json) or FILE, as JSON.
nlohmann::json LoadConfigJson(const std::string& config);
// The same as a checked TuneConfig.
TuneConfig LoadTuneConfig(const std::string& config);

// Checks the output directory and every file before any device work, tunes,
// then writes report.json, report.t4.json, winners-db.json (and report.html)
// together: every file is written in full to a temporary file first and only
// then are they renamed over the old ones, so a failure (in the tuning, or in
// writing any file) leaves the previous results as they were.
TuneJobResult RunTuneJob(const TuneJobOptions& options);

// Writes every (path, contents) to "<path>.tmp.<pid>" first, then renames
// them all; Error("<path>: ...") naming the file that failed, with every
// temporary file removed and no existing file touched, when a write fails.
void WriteFilesTogether(const std::vector<std::pair<std::filesystem::path, std::string>>& files);

// One row per precision class's winner (device, lang, B, vertices, variant,
// ms, GB/s, x copy, the errors, the budget): the run's winner of each key
// (the fastest within the budget) marked "*", the others "over" the budget
// or not; then the measurement counts per status and the budget.
void PrintWinners(const TuningReport& report);

// "3 invalid (local_memory 3), 12 ok": the report's measurements counted by
// status, the invalid ones by what ruled them out (the constraint their
// detail names first, or "when run" for a figure rejected once measured).
std::string MeasurementCounts(const TuningReport& report);

// "1.2e-04": an error in the tables.
std::string Sci(double value);

// Rows of text as columns two spaces apart; the columns in `right` (numbers)
// aligned right.
std::string FormatTable(const std::vector<std::vector<std::string>>& rows, const std::vector<std::size_t>& right);

}  // namespace skintune::internal::tools
