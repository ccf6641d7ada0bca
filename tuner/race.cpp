#include "tuner/race.h"

#include <algorithm>
#include <cstdio>
#include <set>

#include "generator/emit.h"
#include "base/error.h"
#include "tuner/statistics.h"
#include "tuner/strategy.h"

namespace skintune::internal {

namespace {

bool Faster(const Measurement* a, const Measurement* b) {
  if (a->timing.median_ms != b->timing.median_ms) return a->timing.median_ms < b->timing.median_ms;
  return a->variant.Key() < b->variant.Key();
}

bool Raceable(const Measurement& m) { return m.status == MeasureStatus::kOk && m.timing.median_ms > 0.0; }

}  // namespace

std::vector<const Measurement*> RaceCandidates(const std::vector<Measurement>& measured, const TimingOptions& options,
                                               const Variant* leader, const std::vector<Variant>& around) {
  std::vector<const Measurement*> ok;
  for (const Measurement& m : measured)
    if (Raceable(m)) ok.push_back(&m);
  std::sort(ok.begin(), ok.end(), Faster);
  if (ok.size() < 2 || options.race < 2) return {};
  const Measurement& fastest = *ok.front();
  const double reach = std::max(fastest.timing.high_ms, fastest.timing.median_ms) * (1.0 + options.tie_margin);
  auto is = [](const Measurement* m, const Variant& v) { return m->variant.Key() == v.Key(); };
  // Priority 0: the leader; 1: its neighbours; 2: within reach of the fastest.
  auto priority = [&](const Measurement* m) {
    if (leader && is(m, *leader)) return 0;
    for (const Variant& v : around)
      if (is(m, v)) return 1;
    const double low = m->timing.low_ms > 0.0 ? m->timing.low_ms : m->timing.median_ms;
    return low <= reach ? 2 : 3;
  };
  std::vector<const Measurement*> out;
  for (int p = 0; p <= 2; ++p)
    for (const Measurement* m : ok)
      if (priority(m) == p && out.size() < static_cast<std::size_t>(options.race)) out.push_back(m);
  std::sort(out.begin(), out.end(), Faster);
  return out.size() >= 2 ? out : std::vector<const Measurement*>{};
}

std::optional<Variant> RaceWinner(const RaceRecord& race, const std::vector<Measurement>& measured, double margin,
                                  double spread, Choice choice) {
  if (!race.detail.empty() || race.entries.empty()) return std::nullopt;
  std::vector<RaceEntry> entries;
  std::vector<Interval> intervals;
  for (const RaceRecord::Entry& e : race.entries) {
    const auto m = std::find_if(measured.begin(), measured.end(),
                                [&](const Measurement& x) { return x.variant.Key() == e.variant.Key(); });
    entries.push_back(m != measured.end() ? RaceEntryOf(*m) : RaceEntry{e.variant.Key(), {}, 0.0, 0.0});
    intervals.push_back(e.interval);
  }
  return race.entries[JudgeIntervals(intervals, entries, margin, spread, choice).winner].variant;
}

std::string RaceCacheKey(const std::string& device_id, const std::string& dataset, Lang lang,
                         const std::vector<Variant>& candidates, double tie_margin) {
  char margin[32];
  std::snprintf(margin, sizeof margin, "%.17g", tie_margin);
  std::string key = device_id + "|" + kGeneratorVersion + "|timing " + std::to_string(kTimingVersion) + "|" + dataset +
                    "|" + Name(lang) + "|margin " + margin + "|";
  for (std::size_t i = 0; i < candidates.size(); ++i) key += (i ? "," : "") + candidates[i].Key();
  return key;
}

namespace {

// Races `candidates` (RaceCandidates of `measured`), or takes their race from `memo`.
RaceRecord RaceThese(const Racer& racer, const std::vector<const Measurement*>& candidates, const std::string& device_id,
                     Lang lang, const std::string& dataset, const TimingOptions& options, const RaceMemo& memo,
                     bool* from_memo) {
  if (from_memo) *from_memo = false;
  RaceRecord record;
  record.device_id = device_id;
  record.lang = lang;
  record.dataset = dataset;
  if (candidates.empty()) {
    record.detail = "no race: fewer than two candidates within the tie margin of the fastest";
    return record;
  }
  std::vector<Variant> variants;
  for (const Measurement* m : candidates) variants.push_back(m->variant);
  const std::string race_key = RaceCacheKey(device_id, dataset, lang, variants, options.tie_margin);
  if (memo.find) {
    if (std::optional<RaceRecord> kept = memo.find(race_key)) {
      if (from_memo) *from_memo = true;
      return *kept;
    }
  }
  std::string why;
  const auto samples = racer(variants, &why);
  if (!samples) {
    record.detail = "race failed: " + why;
    return record;
  }
  std::vector<RaceEntry> entries;
  std::vector<Interval> intervals;
  RaceOutcome outcome;
  try {  // a race answer is input: a leg without samples fails the race, never the run
    if (samples->empty()) throw Error("no leg");
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      entries.push_back(RaceEntryOf(*candidates[i]));
      std::vector<std::vector<double>> legs;
      for (const RaceSamples& leg : *samples) {
        if (leg.size() != candidates.size())
          throw Error("a leg gave samples of " + std::to_string(leg.size()) + " candidates, not " +
                      std::to_string(candidates.size()));
        legs.push_back(leg[i]);
      }
      intervals.push_back(LegsInterval(legs));
    }
    outcome = JudgeIntervals(intervals, entries, options.tie_margin);
  } catch (const Error& e) {
    record.detail = std::string("race failed: ") + e.what();
    return record;
  }
  for (std::size_t i = 0; i < candidates.size(); ++i)
    record.entries.push_back({candidates[i]->variant, outcome.intervals[i], outcome.verdicts[i]});
  record.decided = outcome.decided;
  if (memo.keep) memo.keep(race_key, record);
  return record;
}

// Whether `a` and `b` move the same bytes a frame: they differ at most on
// the axes that change how a kernel runs, not what it reads and writes
// (palette storage, work-group size, vertices per item, their assignment).
bool SameBytes(const Variant& a, const Variant& b) {
  Variant x = a;
  x.storage = b.storage;
  x.wg_size = b.wg_size;
  x.vertices_per_item = b.vertices_per_item;
  x.assignment = b.assignment;
  return x == b;
}

bool IsMeasured(const Variant& v, const std::vector<Measurement>& measured) {
  return std::any_of(measured.begin(), measured.end(), [&](const Measurement& m) { return m.variant == v; });
}

// The walk's neighbourhood of `leader` where the allowance cannot pay for
// all of it: the neighbours measured already, and the unmeasured ones that
// the tie-break would take over the leader if they tied with it (the same
// bytes, fewer storage limits or as few and a lower key; their errors are the
// leader's, as these axes do not change the arithmetic); where the plateau's
// preferred point lies along such an axis, the walk still reaches it.
std::vector<Variant> PreferredOrMeasured(const std::vector<Variant>& around, const Variant& leader,
                                         const std::vector<Measurement>& measured) {
  const auto order = [](const Variant& v) { return std::make_pair(StorageLimits(v.storage), v.Key()); };
  std::vector<Variant> out;
  for (const Variant& v : around)
    if (IsMeasured(v, measured) || (SameBytes(v, leader) && order(v) < order(leader))) out.push_back(v);
  return out;
}

std::size_t Unmeasured(const std::vector<Variant>& around, const std::vector<Measurement>& measured) {
  std::size_t n = 0;
  for (const Variant& v : around) n += IsMeasured(v, measured) ? 0 : 1;
  return n;
}

std::optional<Variant> FastestOf(const std::vector<Measurement>& measured) {
  const Measurement* best = nullptr;
  for (const Measurement& m : measured)
    if (Raceable(m) && (!best || Faster(&m, best))) best = &m;
  return best ? std::optional<Variant>(best->variant) : std::nullopt;
}

}  // namespace

RaceRecord SettleSearch(const Racer& racer, const SearchToSettle& search, const std::string& device_id, Lang lang,
                        const std::string& dataset, const TimingOptions& options, const RaceMemo& memo,
                        bool* from_memo) {
  std::optional<Variant> leader = FastestOf(search.measured());
  RaceRecord race;
  race.device_id = device_id;
  race.lang = lang;
  race.dataset = dataset;
  race.detail = "no race: no candidate was verified";
  std::set<std::string> settled;  // the leaders whose neighbourhood raced
  bool all_from_memo = true;
  std::size_t walked = 0;  // evaluations after the first neighbourhood
  for (int round = 0; leader && round < kSettleRounds; ++round) {
    std::vector<Variant> around = Neighbours(search.candidates, *leader);
    if (round > 0 && search.walk_evaluations > 0) {
      const std::vector<Measurement> so_far = search.measured();
      if (walked + Unmeasured(around, so_far) > search.walk_evaluations) around = PreferredOrMeasured(around, *leader, so_far);
      const std::size_t unmeasured = Unmeasured(around, so_far);
      if (walked + unmeasured > search.walk_evaluations) break;  // the last race stands
      walked += unmeasured;
    }
    if (search.ahead) search.ahead(around);
    for (const Variant& v : around) search.evaluate(v);
    const std::vector<Measurement> measured = search.measured();
    bool cached = false;
    race = RaceThese(racer, RaceCandidates(measured, options, &*leader, around), device_id, lang, dataset, options, memo,
                     &cached);
    all_from_memo = all_from_memo && cached;
    settled.insert(leader->Key());
    // The walk follows the winner the report will name (options are the device's: ForDevice).
    const std::optional<Variant> winner =
        RaceWinner(race, measured, options.tie_margin, options.process_spread, options.OwnChoice());
    if (!winner || settled.count(winner->Key())) break;
    leader = winner;
  }
  if (from_memo) *from_memo = all_from_memo && race.detail.empty();
  return race;
}

int RaceLegsFor(const DeviceIdentity& device) { return device.backend == "cpu" ? 2 : 1; }

Interval LegsInterval(const std::vector<std::vector<double>>& legs) {
  if (legs.empty()) throw Error("LegsInterval: no leg");
  std::vector<double> all;
  Interval out;
  for (std::size_t l = 0; l < legs.size(); ++l) {
    const Interval leg = MedianInterval(legs[l]);
    out.low = l == 0 ? leg.low : std::min(out.low, leg.low);
    out.high = l == 0 ? leg.high : std::max(out.high, leg.high);
    if (leg.resolution > 0.0 && (out.resolution == 0.0 || leg.resolution < out.resolution)) out.resolution = leg.resolution;
    all.insert(all.end(), legs[l].begin(), legs[l].end());
  }
  const Interval pooled = MedianInterval(all);
  out.median = pooled.median;
  out.samples = pooled.samples;
  out.low = std::min(out.low, out.median);
  out.high = std::max(out.high, out.median);
  return out;
}

namespace {
// The bytes the ceiling judges: the least the frame can move (an instanced
// launch's one mesh read once), else, in records without it, all of them.
double CeilingBytes(const Measurement& m) {
  return m.least_bytes_per_frame > 0.0 ? m.least_bytes_per_frame : m.bytes_per_frame;
}

// GB/s of those bytes in the median time: the recorded figure (of all the
// bytes) scaled down to them.
double CeilingGbps(const Measurement& m) {
  return m.bytes_per_frame > 0.0 ? m.gbps * (CeilingBytes(m) / m.bytes_per_frame) : m.gbps;
}

// Whether `m`'s figure is over the ceiling (RejectOverCeiling).
bool OverCeiling(const Measurement& m, double copy_gbps, double copy_traffic) {
  return IsTimed(m.status) && copy_gbps > 0.0 && CeilingGbps(m) > kCeiling * copy_traffic * copy_gbps;
}
}  // namespace

bool RejectOverCeiling(Measurement& m, double copy_gbps, double copy_traffic) {
  if (!OverCeiling(m, copy_gbps, copy_traffic)) return false;
  const double most = kCeiling * copy_traffic, gbps = CeilingGbps(m);
  char detail[400];
  std::snprintf(detail, sizeof detail,
                "impossible kernel time: %.4g ms for %.0f bytes is %.0f GB/s, %.2fx the device's copy bandwidth "
                "(%.0f GB/s; at most %.2fx is possible%s)",
                m.timing.median_ms, CeilingBytes(m), gbps, gbps / copy_gbps, copy_gbps, most,
                copy_traffic > 1.0 ? ", its copy's stores reading their lines first" : "");
  m.status = MeasureStatus::kInvalid;
  m.detail = detail;
  return true;
}

bool RejectOverCeilingMeasuringAgain(Measurement& m, double& copy_gbps, double copy_traffic, int& remeasures_left,
                                     const std::function<std::optional<double>()>& measure_copy) {
  while (OverCeiling(m, copy_gbps, copy_traffic) && remeasures_left > 0) {
    --remeasures_left;
    if (const std::optional<double> gbps = measure_copy()) copy_gbps = std::max(copy_gbps, *gbps);
  }
  return RejectOverCeiling(m, copy_gbps, copy_traffic);
}

}  // namespace skintune::internal
