// skintune tune: times and verifies the variants of a tuning space on every
// device found, each device in its own child process (skintune tune-worker),
// with a resumable measurement cache; writes the report, its T4 export and the
// winners database, and prints the winners.
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "reference/error.h"
#include "reference/mesh_io.h"
#include "tools/commands.h"
#include "tools/progress.h"
#include "tuner/report.h"
#include "tuner/tune.h"

namespace skintune::tools {

namespace {

namespace fs = std::filesystem;

struct TuneCliOptions {
  std::string config;
  std::string device;
  std::vector<std::string> langs;
  std::string strategy;
  std::string budget_text;  // checked by BudgetCheck
  std::string max_error_text;  // checked in RunTune (one message naming the flag)
  std::string out = "results";
  bool quiet = false;
};

bool EndsWith(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// --config NAME (a built-in config: no '/' and no .json) or FILE.
TuneConfig LoadConfig(const std::string& config) {
  const std::string name = config.empty() ? "default" : config;
  if (name.find('/') == std::string::npos && !EndsWith(name, ".json")) {
    std::string text;
    try {
      text = EmbeddedConfig(name);
    } catch (const Error& e) {
      throw Error("--config '" + name + "': not a file path (no '/' or .json) and " + e.what());
    }
    return ConfigFromJson(ParseJson(text, name), name);
  }
  return ConfigFromJson(ReadJsonFile(name), name);
}

std::string Sci(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1e", value);
  return text;
}

// One row per precision class's winner: the run's winner of each key (the
// fastest within the budget) marked "*", the others "over" the budget or not.
void PrintWinners(const TuningReport& report) {
  const std::vector<Winner> winners = ComputeWinners(report);
  const std::vector<Winner> chosen = BudgetWinners(winners);
  std::map<std::string, std::string> names;
  for (const DeviceIdentity& d : report.devices) names[d.Id()] = d.name;
  std::vector<std::vector<std::string>> rows = {{"device", "lang", "B", "vertices", "variant", "ms", "GB/s", "x copy",
                                                 "err/diag", "quant/diag", "vs quantised", "budget"}};
  for (const Winner& w : winners) {
    const bool is_chosen = std::any_of(chosen.begin(), chosen.end(), [&](const Winner& c) {
      return c.device_id == w.device_id && c.variant == w.variant && c.vertices == w.vertices;
    });
    char ms[32], gbps[32], fraction[32];
    std::snprintf(ms, sizeof ms, "%.4f", w.median_ms);
    std::snprintf(gbps, sizeof gbps, "%.1f", w.gbps);
    // The time over a copy of the same bytes timed the same way (docs/TUNING.md "Timing").
    if (w.x_copy > 0.0) {
      std::snprintf(fraction, sizeof fraction, "%.2f", w.x_copy);
    } else {
      std::snprintf(fraction, sizeof fraction, "-");
    }
    const auto name = names.find(w.device_id);
    const SourceError& e = w.source_error;
    rows.push_back({name != names.end() ? name->second : w.device_id, Name(w.lang), std::to_string(w.influences),
                    VertexCountName(w.vertices), w.variant.Key(), ms, gbps, fraction,
                    e.known ? Sci(e.position_rel) : "-", e.known ? Sci(e.quantisation_rel) : "-",
                    Sci(w.max_relative_error),
                    is_chosen ? "* winner" : w.within_budget ? "within" : "over"});
  }
  std::map<std::string, std::size_t> statuses;
  for (const Measurement& m : report.measurements) ++statuses[Name(m.status)];
  std::string counts;
  for (const auto& [status, n] : statuses) counts += (counts.empty() ? "" : ", ") + std::to_string(n) + " " + status;
  if (winners.empty()) {
    std::cout << "no variant passed verification on any device\n";
  } else {
    std::vector<std::size_t> widths(rows.front().size(), 0);
    for (const auto& row : rows) {
      for (std::size_t c = 0; c < row.size(); ++c) widths[c] = std::max(widths[c], row[c].size());
    }
    const std::set<std::size_t> right = {2, 5, 6, 7, 8, 9, 10};  // numbers
    for (const auto& row : rows) {
      std::string line;
      for (std::size_t c = 0; c < row.size(); ++c) {
        const std::string pad(widths[c] - row[c].size(), ' ');
        line += right.count(c) ? pad + row[c] : row[c] + (c + 1 < row.size() ? pad : "");
        if (c + 1 < row.size()) line += "  ";
      }
      std::cout << line << "\n";
    }
  }
  if (!winners.empty() && chosen.empty()) std::cout << "no verified variant is within the budget\n";
  std::cout << "measurements: " << (counts.empty() ? "none" : counts) << "\n";
  std::cout << "budget: max_error " << Sci(report.max_error)
            << " of the bounding-box diagonal (err/diag: the kernel against the unquantised source; quant/diag: what "
               "the weight format alone costs, compared with the budget; vs quantised: relative error against the "
               "gold of its quantised weights)\n";
}

int RunTune(const TuneCliOptions& o, bool budget_given) {
  TuneConfig config = LoadConfig(o.config);
  if (!o.strategy.empty()) config.strategy.name = o.strategy;
  if (budget_given) config.strategy.budget = *ParseWholeNumber(o.budget_text, kMaxBudget);
  if (!o.max_error_text.empty()) config.max_error = ParseMaxError(o.max_error_text, "--max-error");
  if (config.strategy.name == "random" && config.strategy.budget == 0) {
    throw Error("the random strategy needs a budget: --budget N (evaluations per device, language and dataset)");
  }

  TuneOptions options;
  options.device_pattern = o.device;
  for (const std::string& l : o.langs) options.languages.push_back(LangFromName(l));
  options.worker_executable = SelfExecutable();

  // The output directory and every file written at the end: checked (and the
  // cache opened) before any device work.
  const fs::path out = OutputDirectory(o.out);
  options.cache_path = (out / "cache.jsonl").string();
  for (const char* name : {"report.json", "report.t4.json", "winners-db.json"}) CheckWritable((out / name).string());

  Progress progress(::isatty(2) != 0, "tune");
  if (!o.quiet) {
    options.progress = [&progress](std::size_t done, std::size_t total, const std::string& what) {
      progress.Update(done, total, what);
    };
  }
  TuningReport report;
  try {
    report = RunTuning(config, options);
  } catch (...) {
    progress.Finish(false);
    throw;
  }
  progress.Finish(true);

  // Everything is computed before anything is written; each file is replaced atomically.
  const std::string report_text = ReportToJson(report).dump(2) + "\n";
  const std::string t4_text = ReportToT4(report).dump(2) + "\n";
  const std::string db_text = WinnersDatabase(report).dump(2) + "\n";
  WriteFileAtomically((out / "report.json").string(), report_text);
  WriteFileAtomically((out / "report.t4.json").string(), t4_text);
  WriteFileAtomically((out / "winners-db.json").string(), db_text);

  PrintWinners(report);
  if (!o.quiet) {
    std::cerr << "skintune: tune: wrote " << (out / "report.json").string() << ", "
              << (out / "report.t4.json").string() << ", " << (out / "winners-db.json").string() << " (cache "
              << options.cache_path << ")\n";
  }
  return 0;
}

}  // namespace

double ParseMaxError(const std::string& text, const std::string& flag) {
  std::size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size())
    throw Error(flag + " '" + text + "': not a number (an error relative to the bounding-box diagonal, e.g. 1e-4)");
  if (const std::string bad = BadMaxError(value); !bad.empty()) throw Error(flag + " '" + text + "': " + bad);
  return value;
}

CLI::Validator BudgetCheck() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        if (ParseWholeNumber(text, kMaxBudget)) return "";
        return "must be a whole number from 0 to " + std::to_string(kMaxBudget) + " (got '" + text + "')";
      },
      "0.." + std::to_string(kMaxBudget));
}

Command RegisterTune(CLI::App& app) {
  auto o = std::make_shared<TuneCliOptions>();
  auto* sub = app.add_subcommand(
      "tune", "time and verify the variants of a tuning space on every device found; write the report and winners");
  sub->add_option("--config", o->config,
                  "tuning config: a JSON file (configs/*.json), or a built-in name: default, paper (default: default)");
  sub->add_option("--device", o->device,
                  "only the devices this matches: a case-insensitive substring of the id "
                  "'<backend>:<platform>/<name>/<driver>', vendor, type or platform short name (pocl), as every "
                  "--device");
  sub->add_option("--lang", o->langs, "only these languages: opencl, cuda, glsl-compute, glsl-vertex");
  sub->add_option("--strategy", o->strategy, "search strategy (overrides the config's)")
      ->check(CLI::IsMember({"exhaustive", "random", "coordinate"}));
  auto* budget = sub->add_option("--budget", o->budget_text,
                                 "evaluations per device, language and dataset, 0 to " + std::to_string(kMaxBudget) +
                                     " (overrides the config's)")
                     ->check(BudgetCheck());
  sub->add_option("--max-error", o->max_error_text,
                  "error budget: the largest error, relative to the bounding-box diagonal, that a winner's weight "
                  "format may cost (overrides the config's max_error; default 1e-4: unorm16 yes, unorm8 no for float "
                  "weights)");
  sub->add_option("--out", o->out,
                  "output directory: cache.jsonl (resumable: reused by the next run), report.json, report.t4.json, "
                  "winners-db.json (default: results)");
  sub->add_flag("--quiet", o->quiet, "no progress on stderr");
  return {sub, [o, budget] { return RunTune(*o, budget->count() > 0); }};
}

Command RegisterTuneWorker(CLI::App& app) {
  auto index = std::make_shared<int>(-1);
  auto* sub = app.add_subcommand("tune-worker", "measure variants for `skintune tune` (internal)");
  sub->group("");  // hidden: started by `skintune tune` only
  sub->add_option("--backend-index", *index, "the backend's position in discovery order")->required();
  auto device_id = std::make_shared<std::string>();
  sub->add_option("--device-id", *device_id, "the backend's identity (takes precedence over the index)");
  return {sub, [index, device_id] { return RunTuneWorker(*index, *device_id); }};
}

}  // namespace skintune::tools
