#include "tuner/replay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "base/error.h"
#include "base/input_file.h"

namespace skintune::internal {

std::size_t VariantFieldHash::operator()(const Variant& v) const {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a over every axis's value (generator/axes.h)
  for (int x : AxisCodes(v)) {
    h ^= static_cast<std::uint32_t>(x);
    h *= 1099511628211ull;
  }
  return static_cast<std::size_t>(h);
}

std::vector<Measurement> ReadMeasurementLines(const std::string& path) {
  const std::string text = ReadInputFile(path, kMeasurementCacheInput);
  std::vector<Measurement> out;
  std::size_t line_number = 0;
  for (std::size_t begin = 0; begin < text.size();) {
    const std::size_t end = text.find('\n', begin);
    if (end == std::string::npos) break;  // torn last line: the writer was killed mid-write
    ++line_number;
    const std::string line = text.substr(begin, end - begin);
    begin = end + 1;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    try {
      const nlohmann::json j = nlohmann::json::parse(line);
      if (CachedRaceOf(j)) continue;  // a race kept beside the measurements: checked, not replayed
      out.push_back(j.get<Measurement>());
    } catch (const nlohmann::json::exception& e) {
      throw Error(path + ":" + std::to_string(line_number) + ": malformed measurement (" + e.what() + ")");
    } catch (const Error& e) {
      throw Error(path + ":" + std::to_string(line_number) + ": " + e.what());
    }
  }
  return out;
}

ReplayEvaluator::ReplayEvaluator(const std::vector<Measurement>& measurements, const std::string& device_id,
                                 const std::string& dataset, const std::string& context) {
  std::set<std::string> recorded;
  for (const Measurement& m : measurements) {
    if (m.device_id != device_id || m.dataset != dataset) {
      recorded.insert("'" + m.device_id + "' on '" + m.dataset + "'");
      continue;
    }
    const std::optional<double> time =
        m.status == MeasureStatus::kOk ? std::optional<double>(m.timing.median_ms) : std::nullopt;
    const auto [it, inserted] = times_.insert_or_assign(m.variant, time);
    if (inserted) variants_.push_back(m.variant);
  }
  if (variants_.empty()) {
    std::string pairs;
    for (const std::string& p : recorded) pairs += (pairs.empty() ? "" : ", ") + p;
    throw Error(context + ": no measurement of device '" + device_id + "' on dataset '" + dataset + "'" +
                (pairs.empty() ? std::string(" (no measurements at all)") : " (recorded: " + pairs + ")"));
  }
}

ReplayEvaluator ReplayEvaluator::FromCacheFile(const std::string& path, const std::string& device_id,
                                               const std::string& dataset) {
  return ReplayEvaluator(ReadMeasurementLines(path), device_id, dataset, path);
}

ReplayEvaluator ReplayEvaluator::FromReport(const TuningReport& report, const std::string& device_id,
                                            const std::string& dataset, const std::string& context) {
  return ReplayEvaluator(report.measurements, device_id, dataset, context);
}

std::optional<double> ReplayEvaluator::Lookup(const Variant& v) {
  ++lookups_;
  const auto it = times_.find(v);
  if (it == times_.end()) {
    ++missing_;
    return std::nullopt;
  }
  return it->second;
}

Evaluator ReplayEvaluator::AsEvaluator() {
  return [this](const Variant& v) { return Lookup(v); };
}

std::size_t ReplayEvaluator::ok_count() const {
  return static_cast<std::size_t>(
      std::count_if(times_.begin(), times_.end(), [](const auto& entry) { return entry.second.has_value(); }));
}

StrategyComparison CompareStrategies(const std::vector<Variant>& candidates, const Evaluator& evaluate,
                                     const std::vector<double>& budget_fractions, int seeds) {
  if (seeds < 1) throw Error("strategy comparison: at least one seed is needed");
  for (double f : budget_fractions) {
    if (!(f > 0.0 && f <= 1.0)) throw Error("strategy comparison: budget fraction " + std::to_string(f) +
                                            " is not in (0, 1]");
  }
  // The reference: every candidate (each distinct one evaluated once, and
  // memoised here so the other strategies' runs can reuse the values).
  std::unordered_map<Variant, std::optional<double>, VariantFieldHash> memo;
  const Evaluator memoised = [&](const Variant& v) -> std::optional<double> {
    const auto it = memo.find(v);
    if (it != memo.end()) return it->second;
    return memo.emplace(v, evaluate(v)).first->second;
  };
  const SearchResult all = Search(candidates, memoised, {"exhaustive", 0, 1});
  StrategyComparison c;
  c.candidates = all.evaluations;
  c.seeds = seeds;
  for (const auto& entry : memo) c.ok += entry.second ? 1 : 0;
  if (!all.best) throw Error("strategy comparison: none of the " + std::to_string(c.candidates) +
                             " candidates has a time (every variant failed)");
  c.optimum = all.best;
  c.optimum_ms = all.best_ms;

  for (const char* strategy : {"exhaustive", "random", "coordinate"}) {
    const bool seeded = std::string(strategy) != "exhaustive";
    for (double fraction : budget_fractions) {
      StrategyComparisonRow row;
      row.strategy = strategy;
      row.budget_fraction = fraction;
      row.budget = std::max<std::size_t>(
          1, static_cast<std::size_t>(std::ceil(fraction * static_cast<double>(c.candidates) - 1e-9)));
      const int runs = seeded ? seeds : 1;
      double ratio_sum = 0.0;
      double evaluation_sum = 0.0;
      for (int seed = 1; seed <= runs; ++seed) {
        const SearchResult r =
            Search(candidates, memoised, {strategy, row.budget, static_cast<std::uint64_t>(seed)});
        const double ratio = r.best ? r.best_ms / c.optimum_ms : std::numeric_limits<double>::infinity();
        ratio_sum += ratio;
        evaluation_sum += static_cast<double>(r.evaluations);
        row.worst_ratio = std::max(row.worst_ratio, ratio);
        row.found_optimum += ratio == 1.0 ? 1 : 0;
      }
      row.mean_ratio = ratio_sum / runs;
      row.mean_evaluations = evaluation_sum / runs;
      if (!seeded) row.found_optimum *= seeds;  // the same result for every seed
      c.rows.push_back(row);
    }
  }
  return c;
}

namespace {

std::string Fixed(double value, int decimals) {
  if (std::isinf(value)) return "none found";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, value);
  return buffer;
}

// A percentage without trailing zeros: "10", "0.5", "0.25".
std::string Percent(double fraction) {
  std::string s = Fixed(100.0 * fraction, 2);
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s;
}

}  // namespace

std::string FormatComparison(const StrategyComparison& c) {
  std::ostringstream out;
  out << "candidates: " << c.candidates << " (" << c.ok << " ok), optimum " << Fixed(c.optimum_ms, 4) << " ms"
      << (c.optimum ? " (" + c.optimum->Key() + ")" : std::string()) << ", seeds: " << c.seeds << "\n\n";
  out << "| strategy | budget | evaluations | mean best / optimum | worst best / optimum | found the optimum |\n";
  out << "| --- | --- | --- | --- | --- | --- |\n";
  for (const StrategyComparisonRow& r : c.rows) {
    out << "| " << r.strategy << " | " << Percent(r.budget_fraction) << "% (" << r.budget << ") | "
        << Fixed(r.mean_evaluations, 1) << " | " << Fixed(r.mean_ratio, 3) << " | " << Fixed(r.worst_ratio, 3)
        << " | " << r.found_optimum << "/" << c.seeds << " |\n";
  }
  return out.str();
}

void to_json(nlohmann::json& out, const StrategyComparison& c) {
  // +inf (nothing found) has no JSON number: null.
  auto number = [](double x) { return std::isinf(x) ? nlohmann::json(nullptr) : nlohmann::json(x); };
  out = {{"candidates", c.candidates},
         {"ok", c.ok},
         {"optimum_ms", c.optimum_ms},
         {"optimum", c.optimum ? nlohmann::json(*c.optimum) : nlohmann::json(nullptr)},
         {"seeds", c.seeds},
         {"rows", nlohmann::json::array()}};
  for (const StrategyComparisonRow& r : c.rows) {
    out["rows"].push_back({{"strategy", r.strategy},
                           {"budget_fraction", r.budget_fraction},
                           {"budget", r.budget},
                           {"mean_ratio", number(r.mean_ratio)},
                           {"worst_ratio", number(r.worst_ratio)},
                           {"mean_evaluations", r.mean_evaluations},
                           {"found_optimum", r.found_optimum}});
  }
}

}  // namespace skintune::internal
