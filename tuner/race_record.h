// skintune: the record of one race (docs/TUNING.md "Races and ties") and its
// JSON, kept in the report's "races" and in the measurement cache.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/variant.h"
#include "tuner/statistics.h"

namespace skintune::internal {

// The race at the end of one (device, language, dataset) search
// (docs/TUNING.md "Races and ties"): its candidates measured again,
// interleaved in one worker, and judged against the fastest.
struct RaceRecord {
  std::string device_id;
  Lang lang = Lang::kOpenCl;
  std::string dataset;
  struct Entry {
    Variant variant;
    Interval interval;  // of the race's own samples
    RaceVerdict verdict = RaceVerdict::kUndecided;
  };
  std::vector<Entry> entries;
  bool decided = false;  // every candidate separated from the fastest or proven equal to it
  std::string detail;    // why the race did not run or failed ("": it ran)
};

// A race record as JSON (the report's "races", the measurement cache's race
// lines) and back; FromJson throws Error naming the field.
nlohmann::json RaceJson(const RaceRecord& r);
RaceRecord RaceFromJson(const nlohmann::json& j);

// A race as a line of the measurement cache, beside the measurements:
// {"race_key": KEY, "race": RaceJson(race)}. CachedRaceOf reads one back: the
// key and record of a race line, nullopt for any other line (a measurement);
// throws Error("malformed race (...)") for a race line that is not one.
nlohmann::json CachedRaceLine(const std::string& race_key, const RaceRecord& race);
std::optional<std::pair<std::string, RaceRecord>> CachedRaceOf(const nlohmann::json& line);

}  // namespace skintune::internal
