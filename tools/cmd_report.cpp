// skintune report: the paper experiment's results as one self-contained HTML
// page (Fig. 1, Table 1, GB/s against the copy bandwidth, the variant axes,
// the devices) and optionally a Markdown summary.
//
//   skintune report RESULT.json... -o report.html [--markdown FILE|-]
//
// Each input is a paper result (kind skintune-paper-result, from `skintune
// paper`) or a plain tuning report (kind skintune-report, from `skintune
// tune`: no CPU timings and no paper kernels, so its figures have no serial
// baseline). Every input is read before anything is written; a bad one is one
// error line naming the file and the element, and the outputs are written
// atomically (a temporary file in the same folder, then a rename), so an
// existing report is never left half-written or replaced by a failed run.
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "reference/mesh_io.h"
#include "tools/commands.h"
#include "report/paper_result.h"
#include "report/paper_report.h"
#include "tuner/report.h"

namespace skintune::internal::tools {

namespace {

constexpr const char* kReportKind = "skintune-report";

struct ReportOptions {
  std::vector<std::string> inputs;
  std::string output;
  std::string markdown;  // "" none, "-" stdout
};

PaperResult ReadResult(const std::string& path) {
  const nlohmann::json json = ReadJsonFile(path);
  const nlohmann::json* kind = json.is_object() && json.contains("kind") ? &json["kind"] : nullptr;
  const std::string name = kind && kind->is_string() ? kind->get<std::string>() : "";
  if (name == kPaperResultKind) return PaperResultFromJson(json, path);
  if (name == kReportKind) return PaperResultFromReport(ReportFromJson(json, path));
  throw Error(path + ": not a paper result or tuning report (" +
              (!json.is_object() ? std::string("not a JSON object")
               : !kind           ? std::string("no \"kind\"")
                                 : "\"kind\" is " + kind->dump()) +
              "; expected \"kind\": \"" + kPaperResultKind + "\" or \"" + kReportKind + "\")");
}

int RunReport(const ReportOptions& o) {
  CheckWritable(o.output);
  if (!o.markdown.empty() && o.markdown != "-") CheckWritable(o.markdown);
  std::vector<PaperResult> results;
  for (const std::string& path : o.inputs) results.push_back(ReadResult(path));
  const PaperSummary summary = Summarise(results);
  const std::string html = RenderHtml(summary);
  const std::string markdown = o.markdown.empty() ? "" : RenderMarkdown(summary);
  WriteFileAtomically(o.output, html);
  if (o.markdown == "-") {
    std::cout << markdown;
  } else if (!o.markdown.empty()) {
    WriteFileAtomically(o.markdown, markdown);
  }
  std::cerr << "skintune: report of " << results.size() << " result(s), " << summary.devices.size()
            << " device(s) -> " << o.output << (o.markdown.empty() || o.markdown == "-" ? "" : " and " + o.markdown)
            << "\n";
  return 0;
}

}  // namespace

Command RegisterReport(CLI::App& app) {
  auto o = std::make_shared<ReportOptions>();
  auto* sub = app.add_subcommand(
      "report", "an HTML report (and a Markdown summary) of paper results or tuning reports: Fig. 1, Table 1, GB/s "
                "against the copy bandwidth, the variant axes, the devices");
  sub->add_option("results", o->inputs,
                  "paper results (skintune-paper-result) and/or tuning reports (skintune-report)")
      ->required()
      ->check(NonEmptyPath());
  sub->add_option("-o,--out", o->output, "the HTML file to write (atomically; untouched on error)")
      ->required()
      ->check(NonEmptyPath());
  sub->add_option("--markdown", o->markdown, "also write a Markdown summary to FILE (- for stdout)")
      ->check(NonEmptyPath());
  return {sub, [o] { return RunReport(*o); }};
}

}  // namespace skintune::internal::tools
