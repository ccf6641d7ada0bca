// Fuzz target for the report readers (ReportFromJson, PaperResultFromJson:
// `skintune report`, `db merge`, `db replay`) and for what runs on what they
// accept: the winners, the T4 export, the database, the summary and its HTML
// and Markdown (where an impossible time once exhausted memory).
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "base/input_file.h"
#include "report/paper_result.h"
#include "report/paper_report.h"
#include "tests/fuzz/fuzz_support.h"
#include "tuner/report.h"

using namespace skintune::internal;  // the readers under test and fuzz_support.h's helpers

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  nlohmann::json json;
  try {
    json = ParseJson(std::string(reinterpret_cast<const char*>(data), size), "report.json");  // 1e400 included
  } catch (const Error& e) {
    fuzz::ExpectNamed("report_fuzz", e, "report.json");
    return 0;
  }
  const bool paper = json.is_object() && json.contains("kind") && json["kind"] == kPaperResultKind;
  const std::string name = paper ? "result.json" : "report.json";
  PaperResult result;
  try {
    if (paper) {
      result = PaperResultFromJson(json, name);
    } else {
      result = PaperResultFromReport(ReportFromJson(json, name));
    }
  } catch (const Error& e) {
    fuzz::ExpectNamed("report_fuzz", e, name);
    return 0;
  }
  // Accepted: everything made from it works, without an error of its own.
  try {
    (void)ReportToJson(result.tuning).dump();
    (void)ReportToT4(result.tuning).dump();
    (void)WinnersDatabase(result.tuning).dump();
    const PaperSummary summary = Summarise({result});
    (void)RenderHtml(summary);
    (void)RenderMarkdown(summary);
  } catch (const Error& e) {
    fuzz::Die("report_fuzz", std::string("an accepted input failed later: ") + e.what());
  }
  return 0;
}
