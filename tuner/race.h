// skintune: the race at the end of one (device, language, dataset) search
// (docs/TUNING.md "Races and ties"), run from the parent through the
// device's worker.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "tuner/timing_options.h"
#include "tuner/measurement.h"
#include "tuner/report.h"

namespace skintune::internal {

// The candidates a search's measurements send to the race, of its status-ok
// measurements (within the budget): `leader`'s and every one of `around`
// (its neighbourhood, whatever their search figures: a neighbour's search
// figure is as noisy as the leader's), then the others whose interval
// reaches within the tie margin of the fastest's (low <= fastest's high x
// (1 + margin)); at most `options.race` in that priority, returned fastest
// first; none when fewer than two qualify (the fastest is then alone,
// separated by its own interval). Without a leader, the fastest leads and
// nothing is raced for being a neighbour.
std::vector<const Measurement*> RaceCandidates(const std::vector<Measurement>& measured, const TimingOptions& options,
                                               const Variant* leader = nullptr, const std::vector<Variant>& around = {});

// The race's winner: TieBreak among the candidates it did not separate from
// its fastest (the contenders at `margin`, or the tie set at `margin` +
// `spread`: JudgeIntervals's `choice`), judged on its own intervals (the
// measurements give the tie-break's bytes and errors); nullopt for a race
// that did not run.
std::optional<Variant> RaceWinner(const RaceRecord& race, const std::vector<Measurement>& measured, double margin,
                                  double spread = 0.0, Choice choice = Choice::kContenders);

// A race between verified variants (TunedDevice::Race through the device's
// worker), in one or more legs: per leg, each variant's kernel-time samples
// (legs[l][v]); nullopt with `why` when the race failed. A leg is one
// worker process. On skintune's cpu device a variant's times depend on its
// process's memory placement and threads, steady within a process and not
// between two (on the H200 machine's host its 5k-b4-x8 winner took 301,
// 379 and 496 us in three runs), so the race runs there in two processes
// (RaceLegsFor) and a variant's interval spans both legs' (LegsInterval);
// its kernels are compiled in, so a fresh process costs no build. PoCL's
// races stay in one process: a second would build every candidate again
// (about 24 s of a default run on that host), and its rows named the same
// winners in three runs without it.
using RaceSamples = std::vector<std::vector<double>>;  // per variant
using Racer = std::function<std::optional<std::vector<RaceSamples>>(const std::vector<Variant>& variants, std::string* why)>;
int RaceLegsFor(const DeviceIdentity& device);
// The median of every leg's samples together, from the lowest leg's low
// end to the highest leg's high end (MedianInterval of each leg).
Interval LegsInterval(const std::vector<std::vector<double>>& legs);

// `memo` remembers races between runs (the measurement cache): a race of
// the same key (RaceCacheKey) is taken from it and not run again, and a
// race that ran is given to it.
struct RaceMemo {
  std::function<std::optional<RaceRecord>(const std::string& race_key)> find;
  std::function<void(const std::string& race_key, const RaceRecord& race)> keep;
};

// Settles one search (docs/TUNING.md "Races and ties"). The search's path
// depends on noise (its moves compare single measurements), so two runs may
// stop at different points of one plateau of near-equal variants. The
// settling makes the end independent of the path: the leader (the fastest
// verified measurement) and its whole neighbourhood (Neighbours: every
// candidate one axis away, measured now where the search did not) race as
// one set; when the race's winner (TieBreak among the tied) is not the
// leader, the winner's own neighbourhood races next, up to kSettleRounds
// races (each step goes to a point the tie-break prefers), so runs entering a plateau at different points walk to the same
// preferred point of it. Where the walk's allowance cannot pay for a whole
// neighbourhood, the step races the neighbours measured already and
// measures only those the tie-break would prefer to the leader on a tie
// (the same bytes, a lower key: another palette storage or work-group
// size); only when even these are too many does the last race stand. On
// the H200 (2026-11-29) the GPU rows that named different winners in three
// runs were such pairs: Vulkan 100k-b3's constant and global storage of one
// format, 5.4-5.6 us, one run's walk ending before the constant one was
// measured. Returns the last race (a record saying why when none ran).
inline constexpr int kSettleRounds = 6;
// The walk's allowance when the search has no budget (exhaustive: the walk
// then finds every neighbour measured and spends nothing).
inline constexpr std::size_t kSettleWalkDefault = 8;
struct SearchToSettle {
  const std::vector<Variant>& candidates;         // the search's space
  const std::function<std::optional<double>(const Variant&)>& evaluate;  // measures one (or finds it cached)
  std::function<std::vector<Measurement>()> measured;  // the search's measurements so far
  std::function<void(const std::vector<Variant>&)> ahead;  // told the neighbours about to be measured
  // The walk's allowance: evaluations after the first neighbourhood's, at
  // most (0: no cap). A walk that would need more stops, and its last race
  // stands: on a CPU device, where a wide margin ties most of the space,
  // the walk otherwise wandered over it (PoCL on the 2-core machine: 23
  // evaluations and 4.5 races a row).
  std::size_t walk_evaluations = 0;
};
RaceRecord SettleSearch(const Racer& race, const SearchToSettle& search, const std::string& device_id, Lang lang,
                        const std::string& dataset, const TimingOptions& options, const RaceMemo& memo = {},
                        bool* from_memo = nullptr);

// What a race's verdicts depend on: the device (with its driver), the
// generator and timing versions, the data set, the language, the tie margin
// and the candidates in their order.
std::string RaceCacheKey(const std::string& device_id, const std::string& dataset, Lang lang,
                         const std::vector<Variant>& candidates, double tie_margin);

// Whether `m`'s kernel time implies more than kCeiling x the device's
// large-copy bandwidth `copy_gbps` (0: unknown, never) x `copy_traffic`:
// such a figure is impossible, and `m` becomes invalid with the reason
// (docs/TUNING.md "The physical ceiling"). Returns true when it did. The
// bytes judged are the least the frame can move
// (Measurement::least_bytes_per_frame): an instanced launch reads its one
// mesh once and may find it in cache for every other instance, so a crowd
// of 1024 x 5k-b4 ran at 4.8 TB/s of its K copies' bytes on an H200 whose
// copy moves 4.3 (2026-11-30), and was rejected before.
// `copy_traffic`: the bytes the device's copy really moves per byte it
// counts. On the host's CPU (kHostCopyTraffic) a store first reads its line
// (write-allocate), so a copy counted as read + write moves 1.5 times that,
// as STREAM's documentation says of its Copy; a kernel that mostly reads,
// as skinning does, then legitimately runs above the copy's figure: the cpu
// device's cold 25k-100k frames at 23-32 GB/s against a 21 GB/s copy on the
// 2-core machine (2026-11-29). A GPU's stores do not read: 1.
inline constexpr double kCeiling = 1.05;
inline constexpr double kHostCopyTraffic = 1.5;
bool RejectOverCeiling(Measurement& m, double copy_gbps, double copy_traffic = 1.0);

// RejectOverCeiling against the highest copy bandwidth measured. Load on the
// host only ever lowers a copy's bandwidth, so while `m` is over the ceiling
// of `copy_gbps`, the copy is measured again (`measure_copy`, at most
// `remeasures_left` times, which it counts down; nothing when it fails) and
// `copy_gbps` raised to the highest figure; then `m` is judged. On the
// 2-core machine, beside another tuning run, the cpu device's copy measured
// 16 GB/s at its start, and every variant of one data set (22-36 GB/s, their
// same-size copies 40 GB/s) was rejected (2026-11-29).
inline constexpr int kCopyRemeasures = 4;  // a device's, in one run
bool RejectOverCeilingMeasuringAgain(Measurement& m, double& copy_gbps, double copy_traffic, int& remeasures_left,
                                     const std::function<std::optional<double>()>& measure_copy);

}  // namespace skintune::internal
