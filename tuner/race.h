// skintune: the race at the end of one (device, language, dataset) search
// (docs/TUNING.md "Races and ties"), run from the parent through the
// device's worker.
#pragma once

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
RaceRecord RaceSearch(IsolatedBackend& worker, const std::vector<Measurement>& measured, const std::string& device_id,
                      Lang lang, const std::string& dataset, const TimingOptions& options);

// Whether `m`'s kernel time implies more than kCeiling x the device's
// large-copy bandwidth `copy_gbps` (0: unknown, never): such a figure is
// impossible, and `m` becomes invalid with the reason (docs/TUNING.md
// "The physical ceiling"). Returns true when it did.
inline constexpr double kCeiling = 1.05;
bool RejectOverCeiling(Measurement& m, double copy_gbps);

}  // namespace skintune::internal
