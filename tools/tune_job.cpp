#include "tools/tune_job.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "base/error.h"
#include "reference/mesh_io.h"
#include "report/paper_report.h"
#include "tools/commands.h"
#include "tools/progress.h"

namespace skintune::internal::tools {

namespace {

namespace fs = std::filesystem;

// The output files of a job, in writing order (report.html only when asked).
std::vector<std::string> OutputNames(bool html) {
  std::vector<std::string> names = {"report.json", "report.t4.json", "winners-db.json"};
  if (html) names.push_back("report.html");
  return names;
}

std::string ContentsOf(const std::string& name, const TuningReport& report) {
  if (name == "report.json") return ReportToJson(report).dump(2) + "\n";
  if (name == "report.t4.json") return ReportToT4(report).dump(2) + "\n";
  if (name == "winners-db.json") return WinnersDatabase(report).dump(2) + "\n";
  if (name == "report.html") return RenderHtml(Summarise({PaperResultFromReport(report)}));
  throw Error("internal: no contents for output file '" + name + "'");
}

// The constraint an invalid measurement's detail names first, the variant
// ruled out before it ran ("local_memory: storage local: ... exceeds local
// memory 0 B"), or "when run" (a figure rejected once measured, such as a
// kernel time beyond the device's bandwidth).
std::string RuledOutBy(const std::string& detail) {
  const std::size_t colon = detail.find(':');
  const std::string head = detail.substr(0, colon);
  const bool named = colon != std::string::npos && !head.empty() && std::all_of(head.begin(), head.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || c == '_';
  });
  return named ? head : "when run";
}

}  // namespace

nlohmann::json LoadConfigJson(const std::string& config) {
  const std::string name = config.empty() ? "default" : config;
  if (name.find('/') == std::string::npos && !name.ends_with(".json")) {
    std::string text;
    try {
      text = EmbeddedConfig(name);
    } catch (const Error& e) {
      throw Error("--config '" + name + "': not a file path (no '/' or .json) and " + e.what());
    }
    return ParseJson(text, name);
  }
  return ReadJsonFile(name);
}

TuneConfig LoadTuneConfig(const std::string& config) {
  return ConfigFromJson(LoadConfigJson(config), config.empty() ? "default" : config);
}

void WriteFilesTogether(const std::vector<std::pair<fs::path, std::string>>& files) {
  const std::string suffix = ".tmp." + std::to_string(::getpid());
  std::vector<std::string> temps;
  auto remove_temps = [&] {
    for (const std::string& t : temps) std::remove(t.c_str());
  };
  for (const auto& [path, contents] : files) {
    const std::string temp = path.string() + suffix;
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) {
      const int err = errno;
      remove_temps();
      throw Error(path.string() + ": cannot write (" + std::strerror(err) + ")");
    }
    temps.push_back(temp);
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out) {
      const int err = errno;
      remove_temps();
      throw Error(path.string() + ": write failed (" + std::strerror(err) + ")");
    }
  }
  // Every file is complete on disk: only renames remain (in one folder, they
  // do not fail for want of space).
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (std::rename(temps[i].c_str(), files[i].first.c_str()) != 0) {
      const int err = errno;
      for (std::size_t j = i; j < temps.size(); ++j) std::remove(temps[j].c_str());
      throw Error(files[i].first.string() + ": cannot replace (" + std::strerror(err) + ")");
    }
  }
}

TuneJobResult RunTuneJob(const TuneJobOptions& o) {
  TuneConfig config = LoadTuneConfig(o.config);
  if (!o.strategy.empty()) config.strategy.name = o.strategy;
  if (o.budget) config.strategy.budget = *o.budget;
  if (!o.max_error_text.empty()) config.max_error = ParseMaxError(o.max_error_text, "--max-error");
  if (config.strategy.name == "random" && config.strategy.budget == 0) {
    throw Error("the random strategy needs a budget: --budget N (evaluations per device, language and dataset)");
  }

  TuneOptions options;
  options.device_pattern = o.device;
  options.software_rasterizers = o.software_rasterizers;
  for (const std::string& l : o.langs) options.languages.push_back(LangFromName(l));
  options.worker_executable = SelfExecutable();
  options.parallel_devices = !o.one_device_at_a_time;

  // The output directory and every file written at the end: checked (and the
  // cache opened) before any device work.
  TuneJobResult result;
  OutputDirectory out(o.out);
  result.out = out.path();
  result.cache = result.out / "cache.jsonl";
  options.cache_path = result.cache.string();
  const std::vector<std::string> names = OutputNames(o.html);
  for (const std::string& name : names) CheckWritable((result.out / name).string());

  Progress progress(::isatty(2) != 0, o.command);
  if (!o.quiet) {
    options.progress = [&progress](std::size_t done, std::size_t total, const std::string& what) {
      progress.Update(done, total, what);
    };
  }
  try {
    result.report = RunTuning(config, options);
  } catch (...) {
    progress.Finish(false);
    throw;
  }
  progress.Finish(true);
  out.Keep();

  // Everything is computed before anything is written, then written together.
  std::vector<std::pair<fs::path, std::string>> files;
  for (const std::string& name : names) files.emplace_back(result.out / name, ContentsOf(name, result.report));
  WriteFilesTogether(files);
  for (const auto& file : files) result.written.push_back(file.first);
  return result;
}

void AddTuneJobOptions(CLI::App& sub, TuneJobOptions& o) {
  sub.add_option("--config", o.config,
                 "tuning config: a JSON file (configs/*.json), or a built-in name: " + EmbeddedConfigNames() +
                     " (default: default)")
      ->check(NonEmptyPath());
  sub.add_option("--device", o.device,
                 "only the devices this matches: a case-insensitive substring of the id "
                 "'<backend>:<platform>/<name>/<driver>', vendor, type or platform short name (pocl), as every "
                 "--device; without it every device but software rasterizers");
  sub.add_flag("--software-rasterizers", o.software_rasterizers,
               "without --device, tune GL and Vulkan on the host's CPU too (Mesa's llvmpipe and lavapipe: left out "
               "by default, as no build ships kernels for them)");
  sub.add_option("--lang", o.langs, "only these languages: " + Choices(AxisOf<&Variant::lang>()));
  sub.add_option("--max-error", o.max_error_text,
                 "error budget: the largest error, relative to the bounding-box diagonal, that a winner's weight "
                 "format may cost (overrides the config's max_error; default 1e-4: unorm16 yes, unorm8 no for float "
                 "weights)");
  const std::string files = o.html ? "report.json, report.t4.json, winners-db.json, report.html"
                                   : "report.json, report.t4.json, winners-db.json";
  sub.add_option("--out", o.out,
                 "output directory: cache.jsonl (resumable: reused by the next run), " + files +
                     " (default: results)")
      ->check(NonEmptyPath());
  sub.add_flag("--one-device-at-a-time", o.one_device_at_a_time,
               "tune one device after another (by default devices that share no hardware, such as a CPU device "
               "and a GPU, are tuned at the same time, and so are one GPU's APIs, each holding the chip alone "
               "for its work on it)");
  sub.add_flag("--quiet", o.quiet, "no progress on stderr");
}

std::string MeasurementCounts(const TuningReport& report) {
  std::map<std::string, std::size_t> statuses;
  std::map<std::string, std::size_t> ruled_out;  // invalid points by the constraint named first in their detail
  for (const Measurement& m : report.measurements) {
    ++statuses[Name(m.status)];
    if (m.status == MeasureStatus::kInvalid) ++ruled_out[RuledOutBy(m.detail)];
  }
  std::string counts;
  for (const auto& [status, n] : statuses) {
    counts += (counts.empty() ? "" : ", ") + std::to_string(n) + " " + status;
    if (status != Name(MeasureStatus::kInvalid)) continue;
    std::string by;
    for (const auto& [constraint, k] : ruled_out) by += (by.empty() ? "" : ", ") + constraint + " " + std::to_string(k);
    counts += " (" + by + ")";
  }
  return counts;
}

std::string FormatTable(const std::vector<std::vector<std::string>>& rows, const std::vector<std::size_t>& right) {
  std::vector<std::size_t> widths;
  for (const auto& row : rows) {
    if (widths.size() < row.size()) widths.resize(row.size(), 0);
    for (std::size_t c = 0; c < row.size(); ++c) widths[c] = std::max(widths[c], row[c].size());
  }
  const std::set<std::size_t> numbers(right.begin(), right.end());
  std::string text;
  for (const auto& row : rows) {
    std::string line;
    for (std::size_t c = 0; c < row.size(); ++c) {
      const std::string pad(widths[c] - row[c].size(), ' ');
      line += numbers.count(c) ? pad + row[c] : row[c] + (c + 1 < row.size() ? pad : "");
      if (c + 1 < row.size()) line += "  ";
    }
    text += line + "\n";
  }
  return text;
}

std::string Sci(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1e", value);
  return text;
}

void PrintWinners(const TuningReport& report) {
  const std::vector<Winner> winners = ComputeWinners(report);
  const std::vector<Winner> chosen = BudgetWinners(winners, report.tie_margin);
  std::map<std::string, std::string> names;
  for (const DeviceIdentity& d : report.devices) names[d.Id()] = d.name;
  std::vector<std::vector<std::string>> rows = {{"device", "lang", "B", "vertices", "variant", "ms", "GB/s", "x copy",
                                                 "err/diag", "quant/diag", "vs quantised", "budget"}};
  for (const Winner& w : winners) {
    const bool is_chosen = std::any_of(chosen.begin(), chosen.end(), [&](const Winner& c) {
      return c.device_id == w.device_id && c.variant == w.variant && c.vertices == w.vertices && c.shape == w.shape &&
             c.instances == w.instances && c.meshes == w.meshes;
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
                    RowName(w), w.variant.Key(), ms,
                    gbps, fraction,
                    e.known ? Sci(e.position_rel) : "-", e.known ? Sci(e.quantisation_rel) : "-",
                    Sci(w.max_relative_error), is_chosen ? "* winner" : w.within_budget ? "within" : "over"});
  }
  const std::string counts = MeasurementCounts(report);
  if (winners.empty()) {
    std::cout << "no variant passed verification on any device\n";
  } else {
    std::cout << FormatTable(rows, {2, 5, 6, 7, 8, 9, 10});
  }
  if (!winners.empty() && chosen.empty()) std::cout << "no verified variant is within the budget\n";
  std::cout << "measurements: " << (counts.empty() ? "none" : counts) << "\n";
  std::cout << "budget: max_error " << Sci(report.max_error)
            << " of the bounding-box diagonal (err/diag: the kernel against the unquantised source; quant/diag: what "
               "the weight format alone costs, compared with the budget; vs quantised: relative error against the "
               "gold of its quantised weights)\n";
}

}  // namespace skintune::internal::tools
