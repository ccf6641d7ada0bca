// skintune: the statistics of the tuner's figures (docs/TUNING.md
// "Intervals, races and ties").
//
// - A kernel time is the median of its cold samples, with a distribution-free
//   95% interval from the order statistics (the interval every sample
//   distribution allows: no normality assumed, since GPU times are skewed
//   and have outliers). Sampling stops when the interval's half-width is at
//   most `interval` of the median, or at a cap (StopRule), as nvbench stops
//   on its noise criterion and Google Benchmark's repetitions report spread.
// - A race (RaceOutcome) decides the leading candidates of one search from
//   samples measured interleaved in one process: each candidate is either
//   separated from the fastest (slower by more than the tie margin, with
//   both intervals saying so), proven equal to it (both intervals within the
//   margin), or undecided. Equal and undecided candidates form the tie set,
//   and one deterministic rule (TieBreak) picks the winner among them, so
//   the same landscape gives the same winner whatever the order of
//   measurement, as irace's racing and CLBlast users' reports suggest.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "generator/variant.h"  // PaletteStorage

namespace skintune::internal {

struct Interval {
  double median = 0.0;
  double low = 0.0, high = 0.0;  // the 95% interval of the median
  std::size_t samples = 0;
  // The smallest positive difference between two samples: the timer's
  // resolution as the samples show it (CUPTI and NVIDIA's OpenCL stamp in
  // steps of 32 ns, 1% of a 3 us kernel); 0 when every sample is equal.
  double resolution = 0.0;
  double HalfWidthRatio() const { return median > 0.0 ? (high - low) / 2.0 / median : 0.0; }
};

// The median of `samples` (>= 1) and its 95% distribution-free interval: the
// order statistics x(j) and x(k), j and k the ranks where the binomial
// (n, 1/2) distribution puts 2.5% below and above (exact sums, n <= 100000).
// With fewer than 6 samples no order statistics cover 95%: the interval is
// then the whole range [min, max]. Throws Error for no samples or a sample
// that is not a positive finite number.
Interval MedianInterval(std::vector<double> samples);

// The mean of `samples` without the `trim` fraction (in [0, 0.5)) of them at
// each end, rounded down (0.1 of 100: the lowest ten and the highest ten):
// finer than their median where a timer's steps make many samples equal, as
// CUPTI's 32 ns steps do at a few microseconds. Throws Error for no samples
// or a trim outside [0, 0.5).
double TrimmedMean(std::vector<double> samples, double trim);

// When to stop sampling one kernel time.
struct StopRule {
  double interval = 0.01;        // stop once the interval's half-width <= this x the median
  std::size_t min_samples = 10;  // never before
  std::size_t max_samples = 200; // never after
  std::size_t batch = 10;        // samples per device submission (the sampling's unit)
  double max_ms = 100.0;         // host wall time of one variant's sampling, at most (then stop at the next batch)
};
// Why `rule` is impossible ("'timing.interval' is 0: ..."), or "" when it is
// possible: interval in (0, 0.5], min_samples >= 1, batch >= 1, max_samples
// >= min_samples and >= batch (a cap below one burst), max_ms > 0; every
// number finite. `prefix` names the config element ("timing.").
std::string BadStopRule(const StopRule& rule, const std::string& prefix);
// Whether sampling stops with `samples` taken over `elapsed_ms`; `tight`:
// the interval met the rule: its half-width at most `interval` x the median,
// or at most one step of the timer's resolution (no more samples can narrow
// an interval of one step).
bool ShouldStop(const StopRule& rule, const Interval& interval, double elapsed_ms, bool* tight = nullptr);

// One candidate of a race: its samples (taken interleaved with the others')
// and what the tie-break reads.
struct RaceEntry {
  std::string key;             // the variant key: the last tie-break
  std::vector<double> samples;
  double bytes_per_frame = 0;  // fewer bytes first
  double error = 0;            // the error against the source (SourceError::position_rel): lower first
  int limits = 0;              // how limited its palette storage is (StorageLimits): fewer first
};
// How limited a palette storage is, for the tie-break: global memory holds
// any palette; constant memory a device's 64 KB or so; local memory a
// work-group's 48 KB; an image needs image support and its size limit. Among
// tied candidates moving the same bytes, the one with fewer limits is the
// winner that applies to the most meshes and crowds (and the GPU's storage
// pairs that moved from run to run were a global one and a constant one, the
// constant first by key).
inline int StorageLimits(PaletteStorage storage) {
  switch (storage) {
    case PaletteStorage::kGlobal: return 0;
    case PaletteStorage::kConstant: return 1;
    case PaletteStorage::kLocal: return 2;
    case PaletteStorage::kImage: return 3;
  }
  return 3;
}
// The entry of a measured candidate, its samples left empty: what the
// tie-break reads of a Measurement (tuner/measurement.h) or a Winner
// (tuner/report.h), which carry the same fields.
template <typename Measured>
RaceEntry RaceEntryOf(const Measured& m) {
  return {m.variant.Key(), {}, m.bytes_per_frame, m.source_error.known ? m.source_error.position_rel : 0.0,
          StorageLimits(m.variant.storage)};
}
enum class RaceVerdict { kLeader, kEqual, kUndecided, kSeparated };
const char* Name(RaceVerdict);
struct RaceOutcome {
  std::vector<Interval> intervals;       // per entry, in entry order
  std::vector<RaceVerdict> verdicts;     // per entry, against the fastest
  std::size_t fastest = 0;               // the entry with the lowest median
  std::vector<std::size_t> contenders;   // the leader, the equal, and the undecided whose median is within the margin
  std::vector<std::size_t> tied;         // the tie set: the contenders judged at the margin plus the spread (below)
  std::size_t winner = 0;                // TieBreak among the contenders, or the whole tie set (Choice)
  bool decided = false;                  // no entry undecided
  // Sampling may stop: decided, or no undecided entry can become the winner
  // whatever its errors, because each moves more bytes than some entry
  // already proven the fastest or equal to it (TieBreak's first rule: the
  // undecided then decide only the tie set, not the choice). On a CPU
  // device, whose wide margin leaves candidates near its edge for as long
  // as they are sampled, races ran to their cap: on the 2-core machine
  // (2026-11-28) 25 of 30 of a default run's races ended undecided, and 22
  // of those 25 had their winner settled this way at the end.
  bool settled = false;
  bool all_within_noise = false;         // every entry is in the tie set
};
// Judges the entries (>= 1, each with >= 1 sample) at tie margin `margin`
// (> 0): entry e against the fastest f, their intervals E and F, is
// separated when E.low > F.high x (1 + margin), equal when E.high <=
// F.low x (1 + margin) (both within the margin), else undecided. The tie
// set holds the fastest, the equal, and the undecided whose median is
// within the margin of the fastest's: an undecided candidate 9% slower at a
// 5% margin is most likely slower, and letting the tie-break pick it would
// let the race's cap decide the winner. These are the contenders, among
// which TieBreak picks the winner.
//
// The tie set is the same judgement at `margin + spread`, where `spread`
// (>= 0) is how far the difference between two candidates moves from one
// process to the next (the p95 of its change between three cold runs: 3.4%
// on an H200's APIs, 8% on PoCL, 25% on skintune's cpu device on its host,
// 2026-11-28). A pair judged 4.9% apart in one run (both contenders) and
// 5.1% in the next (one separated) cannot be told apart across runs: the
// tie set says so.
//
// `choice` says where TieBreak picks the winner: among the contenders, or
// among the whole tie set, so that the order of the candidates within the
// spread, which moves from process to process, does not decide the winner
// (TimingOptions::choose_in_tie_set: a GPU's default); or among the tie set
// less the entries this judgement separated, whose whole interval lies
// beyond the margin of the fastest's (TimingOptions::choose_unseparated: the
// host's CPU's default). At the host's wide tie set (a quarter plus a
// quarter) a candidate steadily 1.3x slower with a tight interval is in it,
// and would be picked were it to move fewer bytes; one whose interval reaches
// down to the fastest's is the host's noise, and stays a choice.
enum class Choice { kContenders, kTieSet, kTieSetUnseparated };
RaceOutcome JudgeRace(const std::vector<RaceEntry>& entries, double margin, double spread = 0.0,
                      Choice choice = Choice::kContenders);
// The same judgement from intervals already computed (one per entry; the
// entries' samples are not read): a search's own measurements, where no race ran.
RaceOutcome JudgeIntervals(const std::vector<Interval>& intervals, const std::vector<RaceEntry>& entries, double margin,
                           double spread = 0.0, Choice choice = Choice::kContenders);
// The deterministic rule among tied candidates: fewest bytes moved, then the
// lower error against the source, then the fewer storage limits, then the
// variant key. Returns the index
// into `entries` of the chosen one among `tied` (indices, non-empty).
std::size_t TieBreak(const std::vector<RaceEntry>& entries, const std::vector<std::size_t>& tied);

}  // namespace skintune::internal
