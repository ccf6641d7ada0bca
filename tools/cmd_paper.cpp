// skintune paper: the seed paper's experiment on this machine (report/paper_result.h):
// the serial and fast CPU paths, the paper's kernels and the tuned winners on
// every device found, every device's copy bandwidth. Writes the result JSON,
// its HTML report and a Markdown summary, and prints the Fig. 1- and
// Table 1-shaped tables.
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "base/error.h"
#include "reference/mesh_io.h"
#include "tools/commands.h"
#include "tools/progress.h"
#include "report/paper_result.h"
#include "report/paper_report.h"
#include "tools/experiments/paper.h"
#include "tuner/tune.h"  // kMaxBudget

namespace skintune::internal::tools {

namespace {

namespace fs = std::filesystem;

struct PaperCliOptions {
  std::string out = "paper";
  bool quick = false;
  std::vector<std::string> datasets;
  std::string device;
  bool software_rasterizers = false;
  std::vector<std::string> langs;
  std::string budget_text;  // checked by BudgetCheck; empty: the default
  bool no_cpu = false;
  bool quiet = false;
};

std::string CommandLine(int argc, char** argv) {
  std::string line;
  for (int i = 0; i < argc; ++i) line += (i ? " " : "") + std::string(argv[i]);
  return line;
}

int RunPaperCommand(const PaperCliOptions& o, const std::string& command) {
  PaperOptions options;
  options.quick = o.quick;
  options.datasets = o.datasets;
  options.device_pattern = o.device;
  options.software_rasterizers = o.software_rasterizers;
  for (const std::string& l : o.langs) options.languages.push_back(LangFromName(l));
  options.budget = o.budget_text.empty() ? 0 : *ParseWholeNumber(o.budget_text, kMaxBudget);
  options.skip_cpu = o.no_cpu;
  options.worker_executable = SelfExecutable();
  options.command = command;

  // The output directory, cache and outputs before any measurement.
  OutputDirectory out_directory(o.out);
  const fs::path& out = out_directory.path();
  options.cache_path = (out / "cache.jsonl").string();
  for (const char* name : {"paper-result.json", "report.html", "summary.md"}) CheckWritable((out / name).string());

  Progress progress(::isatty(2) != 0, "paper");
  if (!o.quiet) {
    options.progress = [&progress](std::size_t done, std::size_t total, const std::string& what) {
      if (total == 0) {
        progress.Note(what);
      } else {
        progress.Update(done, total, what);
      }
    };
  }
  PaperResult result;
  try {
    result = RunPaper(options);
  } catch (...) {
    progress.Finish(false);
    throw;
  }
  progress.Finish(true);
  out_directory.Keep();

  const PaperSummary summary = Summarise({result});
  const std::string json_text = PaperResultToJson(result).dump(2) + "\n";
  const std::string html = RenderHtml(summary);
  const std::string markdown = RenderMarkdown(summary);
  WriteFileAtomically((out / "paper-result.json").string(), json_text);
  WriteFileAtomically((out / "report.html").string(), html);
  WriteFileAtomically((out / "summary.md").string(), markdown);

  std::cout << Figure1Markdown(summary) << "\n" << Table1Markdown(summary);
  if (!o.quiet) {
    std::cerr << "skintune: paper: wrote " << (out / "paper-result.json").string() << ", "
              << (out / "report.html").string() << ", " << (out / "summary.md").string() << " (cache "
              << options.cache_path << ")\n";
  }
  return 0;
}

}  // namespace

Command RegisterPaper(CLI::App& app, int argc, char** argv) {
  auto o = std::make_shared<PaperCliOptions>();
  auto* sub = app.add_subcommand(
      "paper",
      "reproduce the paper's experiment (its Fig. 1 and Table 1) on this machine: CPU baselines, the paper's kernels "
      "and tuned winners on every device; write the result, an HTML report and a Markdown summary");
  sub->add_option("--out", o->out,
                  "output directory: paper-result.json, report.html, summary.md, cache.jsonl (resumable: a rerun "
                  "reuses every measurement recorded) (default: paper)")
      ->check(NonEmptyPath());
  sub->add_flag("--quick", o->quick,
                "the reduced set: 25k and 100k vertices x 1..4 influences, a 16-evaluation search, fewer repetitions");
  sub->add_option("--dataset", o->datasets, "only these data-set keys (default: the paper's 16, or --quick's 8)");
  sub->add_option("--device", o->device,
                  "only devices whose 'backend: platform / name' (or vendor, version) contains this (case-insensitive); "
                  "without it every device but software rasterizers");
  sub->add_flag("--software-rasterizers", o->software_rasterizers,
                "without --device, GL and Vulkan on the host's CPU too (Mesa's llvmpipe and lavapipe)");
  sub->add_option("--lang", o->langs, "only these languages: " + Choices(AxisOf<&Variant::lang>()));
  sub->add_option("--budget", o->budget_text,
                  "search evaluations per device, language and data set, 0 to " + std::to_string(kMaxBudget) +
                      " (default: the paper config's 200, 8 with --quick)")
      ->check(BudgetCheck());
  sub->add_flag("--no-cpu", o->no_cpu, "skip the CPU timings (the report then has no speedups)");
  sub->add_flag("--quiet", o->quiet, "no progress on stderr");
  const std::string command = CommandLine(argc, argv);
  return {sub, [o, command] { return RunPaperCommand(*o, command); }};
}

}  // namespace skintune::internal::tools
