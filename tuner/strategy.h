// skintune: search strategies over the valid variants of a tuning space.
//
// A strategy asks an Evaluator for the time of variants (a device run, or a
// recorded cache in replay mode) and returns the best it found. Failed
// variants (any status but ok) have no time and are never the best.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "generator/variant.h"

namespace skintune::internal {

// Median time in ms, or nullopt when the variant failed (any status but ok).
using Evaluator = std::function<std::optional<double>(const Variant&)>;

struct StrategyOptions {
  std::string name = "exhaustive";  // "exhaustive", "random", "coordinate"
  std::size_t budget = 0;           // evaluations allowed (0: all for exhaustive; required for random)
  std::uint64_t seed = 1;
  // Coordinate descent moves only to a point faster by more than this
  // fraction (the run's tie margin, TimingOptions::tie_margin): a move
  // decided by noise would send two runs of one landscape down different
  // paths to different candidates. 0: any faster point.
  double margin = 0.0;
};

struct SearchResult {
  std::optional<Variant> best;
  double best_ms = 0.0;
  std::size_t evaluations = 0;  // distinct variants evaluated
};

// Throws Error for an unknown strategy name or a missing budget.
// Told, before a strategy evaluates them one by one, the variants it will
// evaluate next (not evaluated yet, within the budget): exhaustive and random
// search announce all of theirs at once, coordinate descent each set of moves.
// The tuner builds them in parallel meanwhile (Worker::CompileAhead); a search
// is the same with or without it.
using LookAhead = std::function<void(const std::vector<Variant>&)>;

SearchResult Search(const std::vector<Variant>& candidates, const Evaluator& evaluate,
                    const StrategyOptions& options, const LookAhead& ahead = {});

// The candidates that differ from `of` along exactly one axis
// (generator/axes.h), in candidate order, each once: the neighbourhood of a
// search's leader, which the race settles (tuner/race.h SettleSearch).
std::vector<Variant> Neighbours(const std::vector<Variant>& candidates, const Variant& of);

}  // namespace skintune::internal
