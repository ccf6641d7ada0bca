// skintune: the race at the end of one (device, language, dataset) search
// (docs/TUNING.md "Races and ties"), run from the parent through the
// device's worker.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "tuner/backend.h"
#include "tuner/measurement.h"
#include "tuner/report.h"
#include "tuner/worker.h"

namespace skintune::internal {

// The candidates a search's measurements send to the race: its status-ok
// measurements (within the budget) whose interval reaches within the tie
// margin of the fastest's (low <= fastest's high x (1 + margin)), fastest
// first, at most `options.race`; none when fewer than two qualify (the
// fastest is then alone, separated by its own interval).
std::vector<const Measurement*> RaceCandidates(const std::vector<Measurement>& measured, const TimingOptions& options);

// Races the candidates of `measured` (one search's measurements) in
// `worker` and judges them; a record with `detail` saying why when no race
// was needed or it failed (the winners are then judged on the search's own
// intervals).
//
// `memo` remembers races between runs (the measurement cache): a race of
// the same key (RaceCacheKey) is taken from it and not run again, and a
// race that ran is given to it.
struct RaceMemo {
  std::function<std::optional<RaceRecord>(const std::string& race_key)> find;
  std::function<void(const std::string& race_key, const RaceRecord& race)> keep;
};
RaceRecord RaceSearch(IsolatedBackend& worker, const std::vector<Measurement>& measured, const std::string& device_id,
                      Lang lang, const std::string& dataset, const TimingOptions& options, const RaceMemo& memo = {},
                      bool* from_memo = nullptr);

// What a race's verdicts depend on: the device (with its driver), the
// generator and timing versions, the data set, the language, the tie margin
// and the candidates in their order.
std::string RaceCacheKey(const std::string& device_id, const std::string& dataset, Lang lang,
                         const std::vector<Variant>& candidates, double tie_margin);

// Whether `m`'s kernel time implies more than kCeiling x the device's
// large-copy bandwidth `copy_gbps` (0: unknown, never): such a figure is
// impossible, and `m` becomes invalid with the reason (docs/TUNING.md
// "The physical ceiling"). Returns true when it did.
inline constexpr double kCeiling = 1.05;
bool RejectOverCeiling(Measurement& m, double copy_gbps);

}  // namespace skintune::internal
