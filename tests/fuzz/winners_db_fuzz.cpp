// Fuzz target for the winners database readers: WinnersDbFromJson (behind
// the runtime's WinnersDb::Load / Parse and `skintune emit --db`) and
// MergeWinnersDatabases (`skintune db merge`, which takes reports too).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "base/input_file.h"
#include "runtime/winners_db.h"
#include "skintune/skintune.h"
#include "tests/fuzz/fuzz_support.h"
#include "tuner/report.h"

using namespace skintune::internal;  // the readers under test and fuzz_support.h's helpers

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  // The runtime's public reader: a Status naming the file, never an exception.
  const skintune::Result<skintune::WinnersDb> parsed = skintune::WinnersDb::Parse(text, "db.json");
  if (!parsed.ok() && parsed.status().message().rfind("db.json:", 0) != 0)
    fuzz::Die("winners_db_fuzz", "WinnersDb::Parse error without the input's name: " + parsed.status().message());
  nlohmann::json json;
  try {
    json = ParseJson(text, "db.json");  // invalid JSON and 1e400 included
  } catch (const Error& e) {
    fuzz::ExpectNamed("winners_db_fuzz", e, "db.json");
    return 0;
  }
  try {
    for (const WinnersEntry& e : WinnersDbFromJson(json, "db.json")) {
      if (!(e.median_ms > 0.0) || !std::isfinite(e.median_ms) || !(e.gbps >= 0.0) || !std::isfinite(e.gbps))
        fuzz::Die("winners_db_fuzz", "accepted an impossible time in " + Describe(e));
    }
  } catch (const Error& e) {
    fuzz::ExpectNamed("winners_db_fuzz", e, "db.json");
  }
  try {
    const nlohmann::json merged = MergeWinnersDatabases({json, json}, {"a.json", "a.json"});
    // A merged database reads back, and merges into itself unchanged.
    (void)WinnersDbFromJson(merged, "merged");
    if (MergeWinnersDatabases({merged}, {"merged"}) != merged)
      fuzz::Die("winners_db_fuzz", "merging a merged database changed it");
  } catch (const Error& e) {
    fuzz::ExpectNamed("winners_db_fuzz", e, "a.json");
  }
  return 0;
}
