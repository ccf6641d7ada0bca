#include "tuner/race.h"

#include <algorithm>
#include <cstdio>

#include "generator/emit.h"
#include "tuner/statistics.h"

namespace skintune::internal {

std::vector<const Measurement*> RaceCandidates(const std::vector<Measurement>& measured, const TimingOptions& options) {
  std::vector<const Measurement*> ok;
  for (const Measurement& m : measured)
    if (m.status == MeasureStatus::kOk && m.timing.median_ms > 0.0) ok.push_back(&m);
  std::sort(ok.begin(), ok.end(), [](const Measurement* a, const Measurement* b) {
    if (a->timing.median_ms != b->timing.median_ms) return a->timing.median_ms < b->timing.median_ms;
    return a->variant.Key() < b->variant.Key();
  });
  if (ok.size() < 2 || options.race < 2) return {};
  const Measurement& fastest = *ok.front();
  const double reach = std::max(fastest.timing.high_ms, fastest.timing.median_ms) * (1.0 + options.tie_margin);
  std::vector<const Measurement*> out;
  for (const Measurement* m : ok) {
    const double low = m->timing.low_ms > 0.0 ? m->timing.low_ms : m->timing.median_ms;
    if (low <= reach && out.size() < static_cast<std::size_t>(options.race)) out.push_back(m);
  }
  return out.size() >= 2 ? out : std::vector<const Measurement*>{};
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

RaceRecord RaceSearch(IsolatedBackend& worker, const std::vector<Measurement>& measured, const std::string& device_id,
                      Lang lang, const std::string& dataset, const TimingOptions& options, const RaceMemo& memo,
                      bool* from_memo) {
  if (from_memo) *from_memo = false;
  RaceRecord record;
  record.device_id = device_id;
  record.lang = lang;
  record.dataset = dataset;
  const std::vector<const Measurement*> candidates = RaceCandidates(measured, options);
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
  const auto samples = worker.Race(variants, TuningDataset{measured.front().dataset}, options, &why);
  if (!samples) {
    record.detail = "race failed: " + why;
    return record;
  }
  std::vector<RaceEntry> entries;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const Measurement& m = *candidates[i];
    entries.push_back({m.variant.Key(), (*samples)[i], m.bytes_per_frame, m.source_error.known ? m.source_error.position_rel : 0.0});
  }
  const RaceOutcome outcome = JudgeRace(entries, options.tie_margin);
  for (std::size_t i = 0; i < candidates.size(); ++i)
    record.entries.push_back({candidates[i]->variant, outcome.intervals[i], outcome.verdicts[i]});
  record.decided = outcome.decided;
  if (memo.keep) memo.keep(race_key, record);
  return record;
}

bool RejectOverCeiling(Measurement& m, double copy_gbps) {
  if (!IsTimed(m.status) || !(copy_gbps > 0.0) || !(m.gbps > kCeiling * copy_gbps)) return false;
  char detail[320];
  std::snprintf(detail, sizeof detail,
                "impossible kernel time: %.4g ms for %.0f bytes is %.0f GB/s, %.2fx the device's copy bandwidth "
                "(%.0f GB/s; at most %.2fx is possible)",
                m.timing.median_ms, m.bytes_per_frame, m.gbps, m.gbps / copy_gbps, copy_gbps, kCeiling);
  m.status = MeasureStatus::kInvalid;
  m.detail = detail;
  return true;
}

}  // namespace skintune::internal
