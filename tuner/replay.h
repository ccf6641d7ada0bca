// skintune: replay mode. Search strategies run against recorded measurements
// (a MeasurementCache file or a report) instead of a device, so strategies can
// be compared on real data in seconds and without the hardware.
//
// A ReplayEvaluator serves one (device id, dataset): a recorded status-ok
// variant gives its median time, any other recorded status gives nullopt (a
// failed variant), and a variant that was never recorded gives nullopt and is
// counted as missing. Every lookup is counted.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/variant.h"
#include "tuner/measurement.h"
#include "tuner/report.h"
#include "tuner/strategy.h"

namespace skintune::internal {

// The measurements of a MeasurementCache file (JSON lines), read without
// modifying the file: a torn last line (no newline: the writer was killed) is
// ignored, as the cache itself does. Throws Error("<path>: ...") when the file
// cannot be read and Error("<path>:<line>: ...") for a malformed line.
std::vector<Measurement> ReadMeasurementLines(const std::string& path);

// A hash of a Variant's fields (std::hash<Variant> hashes its key string:
// the same value everywhere, but slow for the millions of lookups of a comparison).
struct VariantFieldHash {
  std::size_t operator()(const Variant& v) const;
};

class ReplayEvaluator {
 public:
  // Keeps the measurements of `device_id` on `dataset` (for the same variant
  // recorded more than once, the last one). Throws Error("<context>: ...")
  // when none match, listing the (device, dataset) pairs that were recorded.
  ReplayEvaluator(const std::vector<Measurement>& measurements, const std::string& device_id,
                  const std::string& dataset, const std::string& context);
  static ReplayEvaluator FromCacheFile(const std::string& path, const std::string& device_id,
                                       const std::string& dataset);
  static ReplayEvaluator FromReport(const TuningReport& report, const std::string& device_id,
                                    const std::string& dataset, const std::string& context);

  // The median time of a status-ok variant; nullopt for a failed or unknown one.
  std::optional<double> Lookup(const Variant& v);
  // An Evaluator calling Lookup on this object (which must outlive it).
  Evaluator AsEvaluator();

  // Every recorded variant of this (device, dataset), in recorded order: the
  // candidates of a replayed search (failed ones included: a strategy must
  // pay for trying them).
  const std::vector<Variant>& variants() const { return variants_; }
  std::size_t ok_count() const;
  std::size_t lookups() const { return lookups_; }
  std::size_t missing() const { return missing_; }
  void ResetCounters() { lookups_ = missing_ = 0; }

 private:
  std::vector<Variant> variants_;
  std::unordered_map<Variant, std::optional<double>, VariantFieldHash> times_;
  std::size_t lookups_ = 0;
  std::size_t missing_ = 0;
};

// One row of the comparison: a strategy at one budget (a fraction of the candidates).
struct StrategyComparisonRow {
  std::string strategy;            // "exhaustive", "random", "coordinate"
  double budget_fraction = 0.0;
  std::size_t budget = 0;          // evaluations allowed: ceil(fraction x candidates), at least 1
  double mean_ratio = 0.0;         // mean over seeds of best_found_ms / optimum_ms (+inf: found nothing)
  double worst_ratio = 0.0;        // the largest ratio over seeds
  double mean_evaluations = 0.0;   // distinct variants actually evaluated, mean over seeds
  int found_optimum = 0;           // seeds whose best was the optimum (ratio exactly 1)
};

struct StrategyComparison {
  std::size_t candidates = 0;      // distinct candidates
  std::size_t ok = 0;              // of which status ok
  double optimum_ms = 0.0;         // the exhaustive optimum
  std::optional<Variant> optimum;
  int seeds = 0;
  std::vector<StrategyComparisonRow> rows;  // by strategy (exhaustive, random, coordinate), then budget
};

// Runs every strategy at every budget fraction with seeds 1..`seeds` (the
// exhaustive strategy's order does not depend on the seed: it runs once per
// budget) and compares each best with the exhaustive optimum. Throws Error
// when no candidate is status ok (there is no optimum to compare with).
StrategyComparison CompareStrategies(const std::vector<Variant>& candidates, const Evaluator& evaluate,
                                     const std::vector<double>& budget_fractions = {0.05, 0.1, 0.25, 0.5},
                                     int seeds = 10);

// A Markdown table of the comparison (docs/TUNING.md shows one).
std::string FormatComparison(const StrategyComparison& comparison);
void to_json(nlohmann::json& out, const StrategyComparison& comparison);

}  // namespace skintune::internal
