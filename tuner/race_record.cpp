#include "tuner/race_record.h"

#include <cmath>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "runtime/json_fields.h"

namespace skintune::internal {

using namespace json_fields;

namespace {

Lang LangFromName(const std::string& name) {
  for (const Language& l : kLanguages)
    if (name == Name(l.lang)) return l.lang;
  throw Error("'lang' has unknown value '" + name + "' (expected " +
              OneOf(kLanguages, [](const Language& l) { return std::string(Name(l.lang)); }) + ")");
}

}  // namespace

nlohmann::json RaceJson(const RaceRecord& r) {
  nlohmann::json entries = nlohmann::json::array();
  for (const RaceRecord::Entry& e : r.entries)
    entries.push_back({{"variant", e.variant.Key()},
                       {"median_ms", e.interval.median},
                       {"low_ms", e.interval.low},
                       {"high_ms", e.interval.high},
                       {"samples", e.interval.samples},
                       {"verdict", Name(e.verdict)}});
  return {{"device_id", r.device_id}, {"lang", Name(r.lang)}, {"dataset", r.dataset},
          {"entries", entries},       {"decided", r.decided}, {"detail", r.detail}};
}

RaceRecord RaceFromJson(const nlohmann::json& j) {
  if (!j.is_object()) throw Error("expected an object");
  RaceRecord r;
  r.device_id = String(j, "device_id");
  r.lang = LangFromName(String(j, "lang"));
  r.dataset = String(j, "dataset");
  r.decided = Boolean(j, "decided");
  r.detail = String(j, "detail");
  const nlohmann::json& entries = Array(j, "entries");
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const nlohmann::json& e = entries[i];
    const std::string at = "entries[" + std::to_string(i) + "]";
    if (!e.is_object()) throw Error(at + ": expected an object");
    RaceRecord::Entry entry;
    entry.variant = ParseVariantKey(String(e, "variant"));
    entry.interval.median = Number(e, "median_ms");
    entry.interval.low = Number(e, "low_ms");
    entry.interval.high = Number(e, "high_ms");
    const std::int64_t samples = Integer(e, "samples");
    if (samples < 1) throw Error(at + ": 'samples' must be at least 1");
    entry.interval.samples = static_cast<std::size_t>(samples);
    const Interval& in = entry.interval;
    if (!(in.low > 0.0) || !(in.low <= in.median) || !(in.median <= in.high) || !std::isfinite(in.high))
      throw Error(at + ": not 0 < low_ms <= median_ms <= high_ms, finite");
    const std::string verdict = String(e, "verdict");
    bool known = false;
    for (const RaceVerdict v : {RaceVerdict::kLeader, RaceVerdict::kEqual, RaceVerdict::kUndecided, RaceVerdict::kSeparated})
      if (verdict == Name(v)) entry.verdict = v, known = true;
    if (!known) throw Error(at + ": unknown verdict '" + verdict + "'");
    r.entries.push_back(std::move(entry));
  }
  return r;
}

nlohmann::json CachedRaceLine(const std::string& race_key, const RaceRecord& race) {
  return {{"race_key", race_key}, {"race", RaceJson(race)}};
}

std::optional<std::pair<std::string, RaceRecord>> CachedRaceOf(const nlohmann::json& line) {
  if (!line.is_object() || !line.contains("race_key")) return std::nullopt;
  try {
    return std::make_pair(line.at("race_key").get<std::string>(), RaceFromJson(line.at("race")));
  } catch (const std::exception& e) {  // nlohmann's or RaceFromJson's Error
    throw Error(std::string("malformed race (") + e.what() + ")");
  }
}

}  // namespace skintune::internal
