// The tuner's statistics (tuner/statistics.h): the median's interval, the
// stop rule, the race's verdicts and the tie-break.
#include "tuner/statistics.h"

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "base/error.h"
#include "tuner/measurement.h"  // RaceEntryOf of a Measurement

namespace skintune::internal {
namespace {

// n samples around `median` with a relative spread `spread`, from a fixed seed.
std::vector<double> Samples(double median, double spread, int n, unsigned seed) {
  std::mt19937 gen(seed);
  std::normal_distribution<double> noise(0.0, spread);
  std::vector<double> s;
  for (int i = 0; i < n; ++i) s.push_back(median * (1.0 + noise(gen)));
  return s;
}

TEST(MedianInterval, OrderStatisticsAroundTheMedian) {
  std::vector<double> s;
  for (int i = 1; i <= 100; ++i) s.push_back(i);
  std::shuffle(s.begin(), s.end(), std::mt19937(3));
  const Interval in = MedianInterval(s);
  EXPECT_DOUBLE_EQ(in.median, 50.5);
  // Binomial(100, 1/2): P(B <= 39) = 0.0176 <= 2.5% < P(B <= 40) = 0.0284: x(40) and x(61).
  EXPECT_DOUBLE_EQ(in.low, 40.0);
  EXPECT_DOUBLE_EQ(in.high, 61.0);
  EXPECT_EQ(in.samples, 100u);
  EXPECT_DOUBLE_EQ(in.resolution, 1.0);
}

TEST(MedianInterval, FewSamplesSpanTheirRange) {
  const Interval in = MedianInterval({3.0, 1.0, 2.0});
  EXPECT_DOUBLE_EQ(in.median, 2.0);
  EXPECT_DOUBLE_EQ(in.low, 1.0);
  EXPECT_DOUBLE_EQ(in.high, 3.0);
}

TEST(MedianInterval, RejectsImpossibleSamples) {
  EXPECT_THROW(MedianInterval({}), Error);
  EXPECT_THROW(MedianInterval({1.0, 0.0}), Error);
  EXPECT_THROW(MedianInterval({1.0, -2.0}), Error);
  EXPECT_THROW(MedianInterval({1.0, std::numeric_limits<double>::quiet_NaN()}), Error);
}

// A trimmed mean sees a step that a median of timer ticks hides: two
// contexts whose samples share a median of 64 ticks but not their mix.
TEST(TrimmedMean, DropsEachEndAndSeesBelowATimersStep) {
  std::vector<double> quick(45, 2.048), slow(20, 2.048);
  quick.insert(quick.end(), 55, 2.080);
  slow.insert(slow.end(), 80, 2.080);
  EXPECT_DOUBLE_EQ(MedianInterval(quick).median, MedianInterval(slow).median);
  EXPECT_LT(TrimmedMean(quick, 0.1), TrimmedMean(slow, 0.1));
  // The tenth at each end goes: 100 and -100 are not seen.
  std::vector<double> outliers(8, 5.0);
  outliers.push_back(100.0);
  outliers.push_back(-100.0);
  EXPECT_DOUBLE_EQ(TrimmedMean(outliers, 0.1), 5.0);
  EXPECT_DOUBLE_EQ(TrimmedMean(outliers, 0.0), 4.0);
  EXPECT_DOUBLE_EQ(TrimmedMean({7.0}, 0.4), 7.0);
  EXPECT_THROW(TrimmedMean({}, 0.1), Error);
  EXPECT_THROW(TrimmedMean({1.0}, 0.5), Error);
  EXPECT_THROW(TrimmedMean({1.0}, -0.1), Error);
}

// The stop rule: tight once the half-width is within `interval` of the
// median; or a cap (samples, time); never before min_samples.
TEST(StopRule, StopsWhenTightOrCapped) {
  StopRule rule;
  rule.interval = 0.01;
  rule.min_samples = 10;
  rule.max_samples = 50;
  bool tight = false;
  const Interval narrow = MedianInterval(Samples(1.0, 0.002, 20, 1));
  EXPECT_TRUE(ShouldStop(rule, narrow, 1.0, &tight));
  EXPECT_TRUE(tight);
  const Interval wide = MedianInterval(Samples(1.0, 0.2, 20, 2));
  EXPECT_FALSE(ShouldStop(rule, wide, 1.0, &tight));
  EXPECT_FALSE(tight);
  EXPECT_TRUE(ShouldStop(rule, MedianInterval(Samples(1.0, 0.2, 50, 2)), 1.0, &tight));  // the sample cap
  EXPECT_FALSE(tight);
  EXPECT_TRUE(ShouldStop(rule, wide, rule.max_ms, &tight));  // the time cap
  EXPECT_FALSE(tight);
  const Interval few = MedianInterval(Samples(1.0, 0.0001, 5, 3));
  EXPECT_FALSE(ShouldStop(rule, few, 1.0, &tight)) << "never before min_samples";
}

// A timer that stamps in steps (CUPTI, NVIDIA's OpenCL: 32 ns) cannot narrow
// an interval below one step: one step is tight.
TEST(StopRule, OneTimerStepIsTight) {
  StopRule rule;
  rule.interval = 0.001;
  std::vector<double> s;
  for (int i = 0; i < 30; ++i) s.push_back(i % 3 == 0 ? 3.072 : (i % 3 == 1 ? 3.104 : 3.136));
  bool tight = false;
  EXPECT_TRUE(ShouldStop(rule, MedianInterval(s), 1.0, &tight));
  EXPECT_TRUE(tight);
}

TEST(StopRule, ImpossibleRulesNameTheField) {
  const auto bad = [](StopRule r) { return BadStopRule(r, "timing."); };
  StopRule r;
  EXPECT_EQ(bad(r), "");
  r.interval = 0.0;
  EXPECT_NE(bad(r).find("'timing.interval' is 0"), std::string::npos) << bad(r);
  r.interval = -0.1;
  EXPECT_NE(bad(r).find("'timing.interval'"), std::string::npos);
  r = StopRule{};
  r.max_samples = r.batch - 1;
  EXPECT_NE(bad(r).find("'timing.max_samples'"), std::string::npos) << "a cap below one burst";
  r = StopRule{};
  r.max_samples = 5;
  r.batch = 5;
  r.min_samples = 6;
  EXPECT_NE(bad(r).find("below min_samples"), std::string::npos);
  r = StopRule{};
  r.max_ms = 0.0;
  EXPECT_NE(bad(r).find("'timing.sample_ms'"), std::string::npos);
}

// The race: separated, equal and undecided against the fastest.
TEST(Race, VerdictsAgainstTheFastest) {
  std::vector<RaceEntry> entries = {
      {"b.fast", Samples(1.00, 0.002, 60, 4), 100, 0},
      {"a.equal", Samples(1.002, 0.002, 60, 5), 100, 0},
      {"c.slow", Samples(1.20, 0.002, 60, 6), 100, 0},
      {"d.noisy", Samples(1.05, 0.3, 60, 7), 100, 0},
  };
  const RaceOutcome out = JudgeRace(entries, 0.02);
  EXPECT_EQ(out.fastest, 0u);
  EXPECT_EQ(out.verdicts[0], RaceVerdict::kLeader);
  EXPECT_EQ(out.verdicts[1], RaceVerdict::kEqual);
  EXPECT_EQ(out.verdicts[2], RaceVerdict::kSeparated);
  EXPECT_EQ(out.verdicts[3], RaceVerdict::kUndecided);
  EXPECT_FALSE(out.decided);
  EXPECT_FALSE(out.all_within_noise);
  // Tied: b.fast, a.equal, and d.noisy if its median is within the margin;
  // all moving the same bytes at error 0: the key decides.
  const bool noisy_within = out.intervals[3].median <= out.intervals[0].median * 1.02;
  EXPECT_EQ(out.tied, noisy_within ? (std::vector<std::size_t>{0, 1, 3}) : (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(entries[out.winner].key, "a.equal");
}

// An undecided candidate whose median is beyond the margin is not in the tie
// set: it is most likely slower, and the tie-break would otherwise pick it
// for its key whenever the race ran out of samples before separating it.
TEST(Race, AnUndecidedCandidateWhoseMedianIsBeyondTheMarginIsNoTie) {
  std::vector<RaceEntry> entries = {
      {"b.fast", Samples(1.00, 0.002, 60, 4), 100, 0},
      {"a.noisy.slower", Samples(1.09, 0.2, 60, 8), 100, 0},
  };
  const RaceOutcome out = JudgeRace(entries, 0.05);
  ASSERT_EQ(out.verdicts[1], RaceVerdict::kUndecided);
  ASSERT_GT(out.intervals[1].median, 1.05);
  EXPECT_EQ(out.tied, std::vector<std::size_t>{0});
  EXPECT_EQ(entries[out.winner].key, "b.fast");
}

// A race may stop while a candidate is undecided when it cannot be the
// winner: it moves more bytes than a candidate already proven the fastest or
// equal, so the tie-break would never pick it. An undecided candidate moving
// as few bytes as every decided contender (or fewer) keeps the race going,
// whatever its error (the worker judges bytes only).
TEST(Race, AnUndecidedCandidateThatCannotWinSettlesTheRace) {
  const auto judge = [](double noisy_bytes) {
    return JudgeRace({{"b.fast", Samples(1.00, 0.002, 60, 4), 100, 0},
                      {"a.equal", Samples(1.002, 0.002, 60, 5), 90, 0},
                      {"c.slow", Samples(1.20, 0.002, 60, 6), 10, 0},
                      {"d.noisy", Samples(1.05, 0.3, 60, 7), noisy_bytes, 0}},
                     0.02);
  };
  const RaceOutcome more = judge(95);
  ASSERT_EQ(more.verdicts[3], RaceVerdict::kUndecided);
  EXPECT_FALSE(more.decided);
  EXPECT_TRUE(more.settled) << "a.equal moves fewer bytes: d.noisy can never be picked";
  EXPECT_FALSE(judge(90).settled) << "as few bytes as a.equal: its error or key may pick it";
  EXPECT_FALSE(judge(50).settled) << "fewer bytes: it would win if proven equal";
}

TEST(Race, ADecidedRaceIsSettled) {
  const RaceOutcome out = JudgeRace({{"a", Samples(1.0, 0.001, 30, 21), 1, 0}, {"b", Samples(1.5, 0.001, 30, 22), 0, 0}}, 0.02);
  EXPECT_TRUE(out.decided);
  EXPECT_TRUE(out.settled);
}

// The tie-break: fewest bytes, then lower error, then fewer storage limits, then key.
TEST(Race, TieBreakPrefersFewerBytesThenLowerErrorThenFewerLimitsThenKey) {
  std::vector<RaceEntry> e = {{"z", {1}, 100, 1e-3}, {"y", {1}, 80, 1e-3}, {"x", {1}, 80, 1e-6}, {"w", {1}, 80, 1e-6}};
  EXPECT_EQ(TieBreak(e, {0, 1}), 1u);
  EXPECT_EQ(TieBreak(e, {0, 1, 2}), 2u);
  EXPECT_EQ(TieBreak(e, {0, 1, 2, 3}), 3u);
  // Global storage over constant, local and image, whatever the keys' order.
  const std::vector<RaceEntry> storage = {{"a.constant", {1}, 80, 0, StorageLimits(PaletteStorage::kConstant)},
                                          {"b.image", {1}, 80, 0, StorageLimits(PaletteStorage::kImage)},
                                          {"c.local", {1}, 80, 0, StorageLimits(PaletteStorage::kLocal)},
                                          {"d.global", {1}, 80, 0, StorageLimits(PaletteStorage::kGlobal)}};
  EXPECT_EQ(TieBreak(storage, {0, 1, 2, 3}), 3u);
  EXPECT_EQ(TieBreak(storage, {0, 1, 2}), 0u) << "then constant";
  EXPECT_EQ(TieBreak(storage, {1, 2}), 2u) << "local before image";
  Measurement m;
  m.variant = ParseVariantKey("cuda.b4.padded.soa.float4.u8.f32.mat3x4.constant.matrix.v1c.wg256.nonormals");
  EXPECT_EQ(RaceEntryOf(m).limits, StorageLimits(PaletteStorage::kConstant));
}

// The same landscape gives the same winner whatever the order the
// candidates were measured in.
TEST(Race, SameWinnerUnderPermutedMeasurementOrder) {
  std::vector<RaceEntry> entries = {
      {"v1", Samples(1.000, 0.004, 40, 11), 120, 1e-7}, {"v2", Samples(1.004, 0.004, 40, 12), 100, 1e-7},
      {"v3", Samples(1.006, 0.004, 40, 13), 100, 1e-5}, {"v4", Samples(1.30, 0.004, 40, 14), 60, 1e-7},
      {"v5", Samples(1.003, 0.004, 40, 15), 100, 1e-7},
  };
  const std::string first = entries[JudgeRace(entries, 0.02).winner].key;
  EXPECT_EQ(first, "v2") << "tied: v1..v3 and v5; fewest bytes among them: v2, v3, v5; lowest error: v2, v5; key: v2";
  std::vector<std::size_t> order = {0, 1, 2, 3, 4};
  do {
    std::vector<RaceEntry> permuted;
    for (std::size_t i : order) permuted.push_back(entries[i]);
    EXPECT_EQ(permuted[JudgeRace(permuted, 0.02).winner].key, first);
  } while (std::next_permutation(order.begin(), order.end()));
}

// The spread between processes widens the tie set, never the winner's
// choice: a candidate 7% slower is no contender at a 5% margin, so the
// tie-break cannot pick it for its fewer bytes; but with pairs moving 3.4%
// from one process to the next it cannot be told from the winner either, so
// it is in the tie set. With no spread the two sets are one.
TEST(Race, TheSpreadWidensTheTieSetNotTheChoice) {
  const std::vector<RaceEntry> entries = {
      {"fast", Samples(1.00, 0.002, 60, 31), 100, 0},
      {"seven.percent", Samples(1.07, 0.002, 60, 32), 80, 0},
      {"twelve.percent", Samples(1.12, 0.002, 60, 33), 60, 0},
  };
  const RaceOutcome plain = JudgeRace(entries, 0.05);
  EXPECT_EQ(plain.contenders, std::vector<std::size_t>{0});
  EXPECT_EQ(plain.tied, plain.contenders);
  const RaceOutcome spread = JudgeRace(entries, 0.05, 0.034);
  EXPECT_EQ(spread.contenders, std::vector<std::size_t>{0});
  EXPECT_EQ(spread.tied, (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(entries[spread.winner].key, "fast") << "among the contenders, the winner is not the tie set's fewest bytes";
  EXPECT_EQ(spread.verdicts, plain.verdicts) << "verdicts (and so when a race stops) are judged at the margin";
  EXPECT_FALSE(spread.all_within_noise);
  EXPECT_THROW(JudgeRace(entries, 0.05, -0.01), Error);
}

// Choice::kTieSet (a GPU's default): the tie-break picks among the whole tie
// set, so a pair whose order within the spread moves from one process to the
// next gives the same winner in both: the fewer bytes, whichever was faster.
// The tie set, the verdicts and the candidates beyond it are unchanged.
TEST(Race, ChoosingInTheTieSetPicksItsFewestBytesWhicheverRanFaster) {
  const auto race = [](double second) {
    return std::vector<RaceEntry>{
        {"fast", Samples(1.00, 0.002, 60, 31), 100, 0},
        {"seven.percent", Samples(second, 0.002, 60, 32), 80, 0},
        {"twelve.percent", Samples(1.12, 0.002, 60, 33), 60, 0},
    };
  };
  for (const double second : {1.07, 1.03, 0.97}) {  // beyond the margin, within it, faster
    const std::vector<RaceEntry> entries = race(second);
    const RaceOutcome contenders = JudgeRace(entries, 0.05, 0.034);
    const RaceOutcome tie_set = JudgeRace(entries, 0.05, 0.034, Choice::kTieSet);
    EXPECT_EQ(entries[tie_set.winner].key, "seven.percent") << second;
    EXPECT_EQ(tie_set.tied, contenders.tied) << second;
    EXPECT_EQ(tie_set.verdicts, contenders.verdicts) << second;
    EXPECT_EQ(tie_set.fastest, contenders.fastest) << second;
  }
  EXPECT_EQ(race(1.07)[JudgeRace(race(1.07), 0.05, 0.034).winner].key, "fast") << "the contenders' choice differs";
  const std::vector<RaceEntry> far = race(1.07);
  EXPECT_EQ(far[JudgeRace(far, 0.05, 0.0, Choice::kTieSet).winner].key, "fast")
      << "with no spread the tie set is the contenders";
}

// Choice::kTieSetUnseparated (the host's CPU's default): within the tie set,
// a candidate whose whole interval lies beyond the margin of the fastest's is
// not picked, however few bytes it moves: steadily slower, not noise. One
// whose interval reaches within the margin is, as in the whole tie set.
TEST(Race, ChoosingAmongTheUnseparatedRefusesASteadilySlowerCandidate) {
  const auto race = [](double spread_of_second) {
    return std::vector<RaceEntry>{
        {"fast", Samples(1.00, 0.01, 60, 41), 100, 0},
        {"slower", Samples(1.30, spread_of_second, 60, 42), 60, 0},
        {"beyond", Samples(1.70, 0.01, 60, 43), 40, 0},
    };
  };
  const std::vector<RaceEntry> steady = race(0.01);
  const RaceOutcome whole = JudgeRace(steady, 0.25, 0.25, Choice::kTieSet);
  const RaceOutcome unseparated = JudgeRace(steady, 0.25, 0.25, Choice::kTieSetUnseparated);
  ASSERT_EQ(whole.tied, (std::vector<std::size_t>{0, 1})) << "1.3x is inside a quarter plus a quarter";
  ASSERT_EQ(whole.verdicts[1], RaceVerdict::kSeparated);
  EXPECT_EQ(steady[whole.winner].key, "slower") << "the whole tie set picks the fewer bytes";
  EXPECT_EQ(steady[unseparated.winner].key, "fast");
  EXPECT_EQ(unseparated.tied, whole.tied) << "the tie set itself is unchanged";
  EXPECT_EQ(unseparated.verdicts, whole.verdicts);
  // The same median, its samples spread so wide that the interval reaches down to the fastest's.
  const std::vector<RaceEntry> noisy = race(0.3);
  const RaceOutcome noisy_out = JudgeRace(noisy, 0.25, 0.25, Choice::kTieSetUnseparated);
  ASSERT_NE(noisy_out.verdicts[1], RaceVerdict::kSeparated);
  EXPECT_EQ(noisy[noisy_out.winner].key, "slower") << "noise on the host, not a slower kernel";
  // The fastest alone unseparated: it is the pick.
  const std::vector<RaceEntry> lone = {{"only", Samples(1.0, 0.01, 30, 44), 100, 0}};
  EXPECT_EQ(JudgeRace(lone, 0.25, 0.25, Choice::kTieSetUnseparated).winner, 0u);
}

TEST(Race, AllWithinNoiseSaysSo) {
  const RaceOutcome out = JudgeRace({{"a", Samples(1.0, 0.001, 30, 21), 1, 0}, {"b", Samples(1.001, 0.001, 30, 22), 1, 0}}, 0.02);
  EXPECT_TRUE(out.all_within_noise);
  EXPECT_TRUE(out.decided);
}

}  // namespace
}  // namespace skintune::internal
