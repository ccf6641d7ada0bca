#include "tuner/statistics.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "base/error.h"

namespace skintune::internal {

namespace {

// P(Binomial(n, 1/2) <= j - 1) <= 2.5% for the largest rank j >= 1; 0 when
// even j = 1 misses (n < 6).
std::size_t LowerRank(std::size_t n) {
  const double log_half_n = -static_cast<double>(n) * std::log(2.0);
  const double lg_n1 = std::lgamma(static_cast<double>(n) + 1.0);
  double cdf = 0.0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    cdf += std::exp(lg_n1 - std::lgamma(static_cast<double>(i) + 1.0) - std::lgamma(static_cast<double>(n - i) + 1.0) +
                    log_half_n);
    if (cdf > 0.025) break;
    j = i + 1;  // P(B <= i) <= 2.5%: x(i + 1) is a lower bound
  }
  return j;
}

std::string NumberText(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

}  // namespace

double TrimmedMean(std::vector<double> samples, double trim) {
  if (samples.empty()) throw Error("TrimmedMean: no samples");
  if (!(trim >= 0.0 && trim < 0.5)) throw Error("TrimmedMean: trim " + std::to_string(trim) + " is outside [0, 0.5)");
  std::sort(samples.begin(), samples.end());
  const auto cut = static_cast<std::size_t>(trim * static_cast<double>(samples.size()));
  double sum = 0.0;
  for (std::size_t i = cut; i < samples.size() - cut; ++i) sum += samples[i];
  return sum / static_cast<double>(samples.size() - 2 * cut);
}

Interval MedianInterval(std::vector<double> samples) {
  if (samples.empty()) throw Error("MedianInterval: no samples");
  if (samples.size() > 100000) throw Error("MedianInterval: more than 100000 samples");
  for (const double s : samples)
    if (!(s > 0.0) || !std::isfinite(s)) throw Error("MedianInterval: a sample of " + NumberText(s) + " ms");
  std::sort(samples.begin(), samples.end());
  const std::size_t n = samples.size();
  Interval interval;
  interval.samples = n;
  interval.median = n % 2 ? samples[n / 2] : (samples[n / 2 - 1] + samples[n / 2]) / 2.0;
  for (std::size_t i = 1; i < n; ++i) {
    const double step = samples[i] - samples[i - 1];
    if (step > 0.0 && (interval.resolution == 0.0 || step < interval.resolution)) interval.resolution = step;
  }
  const std::size_t j = std::max<std::size_t>(LowerRank(n), 1);
  interval.low = samples[j - 1];
  interval.high = samples[n - j];
  return interval;
}

std::string BadStopRule(const StopRule& rule, const std::string& prefix) {
  const auto field = [&](const char* name) { return "'" + prefix + name + "' "; };
  if (!(rule.interval > 0.0) || !(rule.interval <= 0.5))
    return field("interval") + "is " + NumberText(rule.interval) +
           ": the interval's half-width, relative to the median, must be in (0, 0.5] (0.01: 1%)";
  if (rule.batch < 1) return field("sample_batch") + "is 0: at least one sample per submission";
  if (rule.min_samples < 1) return field("min_samples") + "is 0: at least one sample";
  if (rule.max_samples < rule.batch)
    return field("max_samples") + "is " + std::to_string(rule.max_samples) + ": below one batch of " +
           std::to_string(rule.batch) + " samples";
  if (rule.max_samples < rule.min_samples)
    return field("max_samples") + "is " + std::to_string(rule.max_samples) + ": below min_samples (" +
           std::to_string(rule.min_samples) + ")";
  if (rule.max_samples > 100000) return field("max_samples") + "is " + std::to_string(rule.max_samples) + ": at most 100000";
  if (!(rule.max_ms > 0.0) || !std::isfinite(rule.max_ms) || rule.max_ms > 3.6e6)
    return field("sample_ms") + "is " + NumberText(rule.max_ms) + ": a positive number of ms, at most an hour";
  return "";
}

bool ShouldStop(const StopRule& rule, const Interval& interval, double elapsed_ms, bool* tight) {
  const double half = (interval.high - interval.low) / 2.0;
  const bool met = interval.samples >= rule.min_samples &&
                   (interval.HalfWidthRatio() <= rule.interval || (interval.resolution > 0.0 && half <= interval.resolution));
  if (tight) *tight = met;
  return met || interval.samples >= rule.max_samples || (elapsed_ms >= rule.max_ms && interval.samples >= 1);
}

const char* Name(RaceVerdict v) {
  switch (v) {
    case RaceVerdict::kLeader: return "fastest";
    case RaceVerdict::kEqual: return "equal";
    case RaceVerdict::kUndecided: return "undecided";
    case RaceVerdict::kSeparated: return "slower";
  }
  return "?";
}

std::size_t TieBreak(const std::vector<RaceEntry>& entries, const std::vector<std::size_t>& tied) {
  if (tied.empty()) throw Error("TieBreak: no candidate");
  return *std::min_element(tied.begin(), tied.end(), [&](std::size_t a, std::size_t b) {
    const RaceEntry& x = entries[a];
    const RaceEntry& y = entries[b];
    if (x.bytes_per_frame != y.bytes_per_frame) return x.bytes_per_frame < y.bytes_per_frame;
    if (x.error != y.error) return x.error < y.error;
    if (x.limits != y.limits) return x.limits < y.limits;
    return x.key < y.key;
  });
}

RaceOutcome JudgeRace(const std::vector<RaceEntry>& entries, double margin, double spread, Choice choice) {
  std::vector<Interval> intervals;
  for (const RaceEntry& e : entries) intervals.push_back(MedianInterval(e.samples));
  return JudgeIntervals(intervals, entries, margin, spread, choice);
}

namespace {

// The entries that tie with the fastest `f` at `margin`: the leader, the
// equal, and the undecided whose median is within the margin.
std::vector<std::size_t> TiedAt(const std::vector<Interval>& intervals, std::size_t f, double margin) {
  std::vector<std::size_t> tied;
  for (std::size_t e = 0; e < intervals.size(); ++e) {
    const Interval& i = intervals[e];
    if (e == f || i.median <= intervals[f].median * (1.0 + margin) || i.high <= intervals[f].low * (1.0 + margin))
      tied.push_back(e);
  }
  return tied;
}

}  // namespace

RaceOutcome JudgeIntervals(const std::vector<Interval>& intervals, const std::vector<RaceEntry>& entries, double margin,
                           double spread, Choice choice) {
  if (entries.empty() || intervals.size() != entries.size()) throw Error("JudgeRace: no candidate, or not one interval each");
  if (!(margin > 0.0)) throw Error("JudgeRace: the tie margin must be positive");
  if (!(spread >= 0.0) || !std::isfinite(spread)) throw Error("JudgeRace: the spread must be 0 or more");
  RaceOutcome out;
  out.intervals = intervals;
  for (std::size_t e = 1; e < entries.size(); ++e) {
    const Interval& a = out.intervals[e];
    const Interval& b = out.intervals[out.fastest];
    // Ties in the median go to the key order, so that the fastest does not
    // depend on the order the entries came in.
    if (a.median < b.median || (a.median == b.median && entries[e].key < entries[out.fastest].key)) out.fastest = e;
  }
  const Interval& f = out.intervals[out.fastest];
  out.decided = true;
  for (std::size_t e = 0; e < entries.size(); ++e) {
    const Interval& i = out.intervals[e];
    RaceVerdict v = RaceVerdict::kUndecided;
    if (e == out.fastest) {
      v = RaceVerdict::kLeader;
    } else if (i.low > f.high * (1.0 + margin)) {
      v = RaceVerdict::kSeparated;
    } else if (i.high <= f.low * (1.0 + margin)) {
      v = RaceVerdict::kEqual;
    }
    if (v == RaceVerdict::kUndecided) out.decided = false;
    out.verdicts.push_back(v);
  }
  // A separated entry's median is beyond the margin and its high end too, so
  // TiedAt takes exactly the leader, the equal and the undecided within it.
  out.contenders = TiedAt(out.intervals, out.fastest, margin);
  out.tied = spread > 0.0 ? TiedAt(out.intervals, out.fastest, margin + spread) : out.contenders;
  std::vector<std::size_t> pool = choice == Choice::kContenders ? out.contenders : out.tied;
  if (choice == Choice::kTieSetUnseparated)  // the fastest is never separated: the pool keeps it
    pool.erase(std::remove_if(pool.begin(), pool.end(),
                              [&](std::size_t e) { return out.verdicts[e] == RaceVerdict::kSeparated; }),
               pool.end());
  out.winner = TieBreak(entries, pool);
  out.settled = true;
  for (std::size_t u = 0; u < entries.size(); ++u) {
    if (out.verdicts[u] != RaceVerdict::kUndecided) continue;
    bool outranked = false;  // by a decided contender moving fewer bytes
    for (std::size_t c = 0; c < entries.size() && !outranked; ++c)
      outranked = (out.verdicts[c] == RaceVerdict::kLeader || out.verdicts[c] == RaceVerdict::kEqual) &&
                  entries[c].bytes_per_frame < entries[u].bytes_per_frame;
    out.settled = out.settled && outranked;
  }
  out.all_within_noise = out.tied.size() == entries.size() && entries.size() > 1;
  return out;
}

}  // namespace skintune::internal
