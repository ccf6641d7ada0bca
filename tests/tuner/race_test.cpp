// The settling of a search (tuner/race.h): which candidates race, who wins
// a race, and that two runs whose searches stopped at different points of
// one plateau of near-equal variants name the same winner.
#include "tuner/race.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "tuner/strategy.h"

namespace skintune::internal {
namespace {

// 3 storages x 2 index formats x 2 work-group sizes: 12 OpenCL variants.
std::vector<Variant> SmallSpace() {
  std::vector<Variant> out;
  for (PaletteStorage s : {PaletteStorage::kConstant, PaletteStorage::kLocal, PaletteStorage::kGlobal})
    for (IndexFormat i : {IndexFormat::kU16, IndexFormat::kU8})
      for (int wg : {64, 256}) {
        Variant v;
        v.storage = s;
        v.index = i;
        v.wg_size = wg;
        out.push_back(v);
      }
  return out;
}

double BytesOf(const Variant& v) { return v.index == IndexFormat::kU8 ? 40.0e6 : 48.0e6; }

// A landscape: local storage is a plateau at 1.00 ms whatever the index and
// group size; global 1.30, constant 1.60.
double TrueMs(const Variant& v) {
  switch (v.storage) {
    case PaletteStorage::kLocal: return 1.00;
    case PaletteStorage::kGlobal: return 1.30;
    default: return 1.60;
  }
}

Measurement Measured(const Variant& v, double ms, double spread = 0.005) {
  Measurement m;
  m.variant = v;
  m.dataset = "100k-b4";
  m.status = MeasureStatus::kOk;
  m.timing.median_ms = ms;
  m.timing.low_ms = ms * (1.0 - spread);
  m.timing.high_ms = ms * (1.0 + spread);
  m.bytes_per_frame = BytesOf(v);
  return m;
}

// A run: measurements with its own noise (a seed), and a racer whose samples
// carry the run's noise too: up to +-2% on each variant, differently in
// each run, so that two plateau points are at most about 4% apart, within
// the 5% margin.
class NoisyRun {
 public:
  explicit NoisyRun(std::uint64_t seed, double (*landscape)(const Variant&) = TrueMs) : seed_(seed), true_ms_(landscape) {}

  double Noise(const Variant& v) const {
    std::uint64_t h = seed_ * 0x9E3779B97F4A7C15ull;
    for (char c : v.Key()) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
    return 1.0 + 0.02 * (static_cast<double>(h % 2001) / 1000.0 - 1.0);
  }
  std::optional<double> Evaluate(const Variant& v) {
    if (!seen_.insert(v.Key()).second) return measured_.at(index_.at(v.Key())).timing.median_ms;
    index_[v.Key()] = measured_.size();
    measured_.push_back(Measured(v, true_ms_(v) * Noise(v)));
    ++evaluations_;
    return measured_.back().timing.median_ms;
  }
  std::optional<std::vector<RaceSamples>> Race(const std::vector<Variant>& variants, std::string*) {
    ++races_;
    std::vector<std::vector<double>> samples;
    for (const Variant& v : variants) {
      std::vector<double> s;
      for (int i = 0; i < 40; ++i) s.push_back(true_ms_(v) * Noise(v) * (1.0 + 0.001 * ((i % 5) - 2)));
      samples.push_back(s);
    }
    return std::vector<RaceSamples>{samples};
  }
  RaceRecord Settle(const std::vector<Variant>& space, std::size_t walk_evaluations = 0) {
    const std::function<std::optional<double>(const Variant&)> evaluate = [this](const Variant& v) { return Evaluate(v); };
    const SearchToSettle search{space, evaluate, [this] { return measured_; }, {}, walk_evaluations};
    const Racer racer = [this](const std::vector<Variant>& v, std::string* why) { return Race(v, why); };
    TimingOptions options;
    return SettleSearch(racer, search, "opencl:p/d/1", Lang::kOpenCl, "100k-b4", options);
  }
  const std::vector<Measurement>& measured() const { return measured_; }
  int races() const { return races_; }
  int evaluations() const { return evaluations_; }

 private:
  std::uint64_t seed_;
  double (*true_ms_)(const Variant&);
  std::vector<Measurement> measured_;
  std::map<std::string, std::size_t> index_;
  std::set<std::string> seen_;
  int races_ = 0;
  int evaluations_ = 0;
};

Variant At(PaletteStorage s, IndexFormat i, int wg) {
  Variant v;
  v.storage = s;
  v.index = i;
  v.wg_size = wg;
  return v;
}

TEST(Neighbours, AreTheCandidatesOneAxisAwayEachOnce) {
  const std::vector<Variant> space = SmallSpace();
  const Variant centre = At(PaletteStorage::kGlobal, IndexFormat::kU16, 64);
  std::vector<Variant> twice = space;
  twice.insert(twice.end(), space.begin(), space.end());
  std::set<std::string> keys;
  for (const Variant& v : Neighbours(twice, centre)) EXPECT_TRUE(keys.insert(v.Key()).second) << v.Key();
  // Two other storages, the other index format, the other group size.
  EXPECT_EQ(keys, (std::set<std::string>{At(PaletteStorage::kConstant, IndexFormat::kU16, 64).Key(),
                                         At(PaletteStorage::kLocal, IndexFormat::kU16, 64).Key(),
                                         At(PaletteStorage::kGlobal, IndexFormat::kU8, 64).Key(),
                                         At(PaletteStorage::kGlobal, IndexFormat::kU16, 256).Key()}));
}

// The leader's neighbours race whatever their search figures (a neighbour
// measured 20% slower by noise still races); the rest only within reach.
TEST(RaceCandidates, TheLeaderAndItsWholeNeighbourhoodRaceOthersOnlyWithinReach) {
  const Variant leader = At(PaletteStorage::kLocal, IndexFormat::kU16, 64);
  const Variant far_neighbour = At(PaletteStorage::kConstant, IndexFormat::kU16, 64);
  const Variant near_stranger = At(PaletteStorage::kGlobal, IndexFormat::kU8, 256);
  const Variant far_stranger = At(PaletteStorage::kConstant, IndexFormat::kU8, 256);
  const std::vector<Measurement> measured = {Measured(leader, 1.0), Measured(far_neighbour, 1.2),
                                             Measured(near_stranger, 1.03), Measured(far_stranger, 1.2)};
  TimingOptions options;
  std::vector<std::string> keys;
  for (const Measurement* m : RaceCandidates(measured, options, &leader, Neighbours(SmallSpace(), leader)))
    keys.push_back(m->variant.Key());
  EXPECT_EQ(keys, (std::vector<std::string>{leader.Key(), near_stranger.Key(), far_neighbour.Key()}));  // fastest first

  // At most options.race: the leader first, then its neighbours, then the others.
  options.race = 2;
  keys.clear();
  for (const Measurement* m : RaceCandidates(measured, options, &leader, Neighbours(SmallSpace(), leader)))
    keys.push_back(m->variant.Key());
  EXPECT_EQ(keys, (std::vector<std::string>{leader.Key(), far_neighbour.Key()}));
}

TEST(RaceWinner, IsTheTieBreakAmongTheTiedOnTheRacesOwnIntervals) {
  const Variant a = At(PaletteStorage::kLocal, IndexFormat::kU16, 64);  // fastest, more bytes
  const Variant b = At(PaletteStorage::kLocal, IndexFormat::kU8, 64);   // 3% slower: tied, fewer bytes
  const Variant c = At(PaletteStorage::kGlobal, IndexFormat::kU8, 64);  // 30% slower: separated
  RaceRecord race;
  for (const auto& [v, ms] : {std::pair{a, 1.0}, {b, 1.03}, {c, 1.3}}) {
    RaceRecord::Entry e;
    e.variant = v;
    e.interval.median = ms;
    e.interval.low = ms * 0.995;
    e.interval.high = ms * 1.005;
    race.entries.push_back(e);
  }
  const std::vector<Measurement> measured = {Measured(a, 1.0), Measured(b, 1.03), Measured(c, 1.3)};
  ASSERT_TRUE(RaceWinner(race, measured, 0.05).has_value());
  EXPECT_EQ(RaceWinner(race, measured, 0.05)->Key(), b.Key());
  EXPECT_EQ(RaceWinner(race, measured, 0.01)->Key(), a.Key());  // 3% apart is no tie at a 1% margin
  race.detail = "race failed: the worker died";
  EXPECT_FALSE(RaceWinner(race, measured, 0.05).has_value());
}

// The point of settling: searches stopped at different points of the local
// plateau (each run's own noise ranks its points differently) end at one
// winner, the plateau's point of fewest bytes then key order, in every run.
TEST(SettleSearch, RunsWhoseSearchesStoppedAtDifferentPointsOfAPlateauNameTheSameWinner) {
  const std::vector<Variant> space = SmallSpace();
  const std::vector<std::vector<Variant>> search_paths = {
      {At(PaletteStorage::kGlobal, IndexFormat::kU16, 64), At(PaletteStorage::kLocal, IndexFormat::kU16, 64)},
      {At(PaletteStorage::kConstant, IndexFormat::kU16, 256), At(PaletteStorage::kLocal, IndexFormat::kU16, 256)},
      {At(PaletteStorage::kGlobal, IndexFormat::kU8, 256), At(PaletteStorage::kLocal, IndexFormat::kU8, 256)},
      {At(PaletteStorage::kLocal, IndexFormat::kU8, 64)}};
  std::set<std::string> winners;
  std::uint64_t seed = 1;
  for (const std::vector<Variant>& path : search_paths) {
    for (int repeat = 0; repeat < 8; ++repeat) {
      NoisyRun run(seed++);
      for (const Variant& v : path) run.Evaluate(v);
      const RaceRecord race = run.Settle(space);
      ASSERT_TRUE(race.detail.empty()) << race.detail;
      const std::optional<Variant> winner = RaceWinner(race, run.measured(), TimingOptions{}.tie_margin);
      ASSERT_TRUE(winner.has_value());
      winners.insert(winner->Key());
      EXPECT_LE(run.races(), kSettleRounds);
      EXPECT_LE(run.evaluations(), 12);
    }
  }
  // Local (the plateau), u8 (fewest bytes), wg256 before wg64 in key order.
  EXPECT_EQ(winners, (std::set<std::string>{At(PaletteStorage::kLocal, IndexFormat::kU8, 256).Key()}));
}

// The walk spends at most its allowance after the first neighbourhood; a
// step that would need more is not taken, and the last race stands.
TEST(SettleSearch, TheWalkStopsWhereItsAllowanceEnds) {
  const Variant start = At(PaletteStorage::kLocal, IndexFormat::kU16, 64);
  NoisyRun free_walk(3), short_walk(3);
  free_walk.Evaluate(start);
  short_walk.Evaluate(start);
  free_walk.Settle(SmallSpace());
  short_walk.Settle(SmallSpace(), 1);
  // From local-u16-64 the walk goes to local-u8-64 (fewer bytes), whose
  // neighbourhood needs 3 more (constant, global, wg256 at u8): over 1.
  EXPECT_GT(free_walk.races(), 1);
  EXPECT_EQ(short_walk.races(), 1);
  EXPECT_EQ(short_walk.evaluations(), 1 + 4);  // the start and its first neighbourhood
  EXPECT_GT(free_walk.evaluations(), short_walk.evaluations());
}

// Where the allowance cannot pay for a whole neighbourhood, the walk still
// measures the neighbours the tie-break would prefer on a tie (the same
// bytes, fewer storage limits, then a lower key) and reaches the plateau's
// preferred point, as a walk without a cap does. Constant and global
// storage are one plateau here; from constant-u8-64 the first race goes to
// global-u8-64 (global storage has fewer limits), whose neighbourhood needs
// global-u16-64 and global-u8-256: over an allowance of 1, but
// global-u8-256 alone (wg256 before wg64) fits.
double StoragePlateauMs(const Variant& v) { return v.storage == PaletteStorage::kLocal ? 1.30 : 1.00; }
TEST(SettleSearch, WhereTheAllowanceEndsTheWalkStillMeasuresWhatTheTieBreakPrefers) {
  const Variant start = At(PaletteStorage::kConstant, IndexFormat::kU8, 64);
  const Variant preferred = At(PaletteStorage::kGlobal, IndexFormat::kU8, 256);
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    NoisyRun free_walk(seed, StoragePlateauMs), short_walk(seed, StoragePlateauMs);
    free_walk.Evaluate(start);
    short_walk.Evaluate(start);
    const RaceRecord free_race = free_walk.Settle(SmallSpace());
    const RaceRecord short_race = short_walk.Settle(SmallSpace(), 1);
    const std::optional<Variant> free_winner = RaceWinner(free_race, free_walk.measured(), TimingOptions{}.tie_margin);
    const std::optional<Variant> short_winner = RaceWinner(short_race, short_walk.measured(), TimingOptions{}.tie_margin);
    ASSERT_TRUE(free_winner && short_winner);
    EXPECT_EQ(free_winner->Key(), preferred.Key());
    EXPECT_EQ(short_winner->Key(), preferred.Key());
    EXPECT_EQ(short_walk.evaluations(), 1 + 4 + 1) << "the start, its neighbourhood, and the one preferred neighbour";
  }
}

// Without settling (the leader's own race only, as before) the same runs
// disagree: the test above would fail without the neighbourhood and the
// walk to the race's winner.
TEST(SettleSearch, WithoutTheNeighbourhoodTheSameRunsWouldDisagree) {
  std::set<std::string> fastest;
  for (std::uint64_t seed = 1; seed <= 16; ++seed) {
    NoisyRun run(seed);
    for (const Variant& v : {At(PaletteStorage::kLocal, IndexFormat::kU16, 64), At(PaletteStorage::kLocal, IndexFormat::kU16, 256)})
      run.Evaluate(v);
    const std::vector<const Measurement*> raced = RaceCandidates(run.measured(), TimingOptions{});
    ASSERT_FALSE(raced.empty());
    fastest.insert(raced.front()->variant.Key());
  }
  EXPECT_GT(fastest.size(), 1u);
}

// A race in two worker processes (a CPU device): a variant's interval spans
// both legs', so a variant fast in one process and slow in the other is
// not told apart from one steady in both.
TEST(LegsInterval, SpansEveryLegsIntervalAroundThePooledMedian) {
  const std::vector<double> fast(41, 1.0), slow(41, 1.3);
  const Interval one = LegsInterval({fast});
  EXPECT_DOUBLE_EQ(one.low, 1.0);
  EXPECT_DOUBLE_EQ(one.high, 1.0);
  const Interval both = LegsInterval({fast, slow});
  EXPECT_DOUBLE_EQ(both.low, 1.0);
  EXPECT_DOUBLE_EQ(both.high, 1.3);
  EXPECT_EQ(both.samples, 82u);
  EXPECT_GE(both.median, 1.0);
  EXPECT_LE(both.median, 1.3);
  DeviceIdentity cpu, pocl, gpu;
  cpu.backend = "cpu";
  cpu.type = pocl.type = "cpu";
  pocl.backend = "opencl";
  gpu.backend = "opencl";
  gpu.type = "gpu";
  EXPECT_EQ(RaceLegsFor(cpu), 2);
  EXPECT_EQ(RaceLegsFor(pocl), 1);
  EXPECT_EQ(RaceLegsFor(gpu), 1);
}

// A race answer is input: a leg without samples, or of other candidates,
// fails the race (the winners are then judged on the search's intervals)
// and never the run.
TEST(SettleSearch, ARaceAnswerWithoutSamplesFailsTheRaceNotTheRun) {
  const std::vector<Variant> space = SmallSpace();
  std::vector<Measurement> measured = {Measured(space[0], 1.0), Measured(space[1], 1.01)};
  const std::function<std::optional<double>(const Variant&)> evaluate = [](const Variant&) { return std::nullopt; };
  const SearchToSettle search{space, evaluate, [&] { return measured; }, {}};
  for (const std::vector<RaceSamples>& answer :
       {std::vector<RaceSamples>{}, std::vector<RaceSamples>{RaceSamples{{1.0}, {}}}, std::vector<RaceSamples>{RaceSamples{{1.0}}}}) {
    const Racer racer = [&](const std::vector<Variant>&, std::string*) { return std::optional<std::vector<RaceSamples>>(answer); };
    RaceRecord race;
    EXPECT_NO_THROW(race = SettleSearch(racer, search, "opencl:p/d/1", Lang::kOpenCl, "100k-b4", TimingOptions{}));
    EXPECT_EQ(race.detail.rfind("race failed: ", 0), 0u) << race.detail;
  }
}

TEST(SettleSearch, NothingVerifiedIsNoRaceSayingSo) {
  NoisyRun run(1);
  const RaceRecord race = run.Settle(SmallSpace());
  EXPECT_EQ(race.detail, "no race: no candidate was verified");
  EXPECT_EQ(run.races(), 0);
}


// The physical ceiling against the highest copy bandwidth measured: a copy
// measured low (the host loaded at the device's start) is measured again
// before a figure above it is rejected, at most kCopyRemeasures times a
// device; a figure above every copy measured is still rejected, and a figure
// within the ceiling costs no copy.
TEST(Ceiling, AFigureOverALowCopyIsJudgedAgainstTheCopyMeasuredAgain) {
  const auto at_gbps = [](double gbps) {
    Measurement m;
    m.status = MeasureStatus::kOk;
    m.bytes_per_frame = 1e6;
    m.timing.median_ms = m.bytes_per_frame / (gbps * 1e6);
    m.gbps = gbps;
    return m;
  };
  std::vector<double> copies = {12.0, 40.0};  // measured again: still low, then as fast as it is
  int copies_measured = 0;
  const auto measure_copy = [&]() -> std::optional<double> {
    return copies_measured < static_cast<int>(copies.size()) ? std::optional<double>(copies[copies_measured++])
                                                             : std::nullopt;
  };
  double copy_gbps = 16.0;  // at the device's start, under load
  int left = kCopyRemeasures;
  Measurement fast = at_gbps(36.0);
  EXPECT_FALSE(RejectOverCeilingMeasuringAgain(fast, copy_gbps, 1.0, left, measure_copy));
  EXPECT_EQ(fast.status, MeasureStatus::kOk);
  EXPECT_EQ(copy_gbps, 40.0);
  EXPECT_EQ(copies_measured, 2);
  EXPECT_EQ(left, kCopyRemeasures - 2);
  Measurement within = at_gbps(41.0);  // within 1.05x: no copy measured
  EXPECT_FALSE(RejectOverCeilingMeasuringAgain(within, copy_gbps, 1.0, left, measure_copy));
  EXPECT_EQ(left, kCopyRemeasures - 2);
  // Impossible against every copy: measured again until the allowance ends, then rejected.
  copies = {30.0, 41.0, 39.0};
  copies_measured = 0;
  Measurement impossible = at_gbps(90.0);
  EXPECT_TRUE(RejectOverCeilingMeasuringAgain(impossible, copy_gbps, 1.0, left, measure_copy));
  EXPECT_EQ(impossible.status, MeasureStatus::kInvalid);
  EXPECT_NE(impossible.detail.find("41 GB/s"), std::string::npos) << impossible.detail;
  EXPECT_EQ(left, 0);
  Measurement later = at_gbps(60.0);  // the allowance spent: judged against the highest copy, none measured
  EXPECT_TRUE(RejectOverCeilingMeasuringAgain(later, copy_gbps, 1.0, left, measure_copy));
  EXPECT_EQ(copies_measured, 2);
}


// On the host's CPU a copy's stores read their lines first, so the ceiling
// is 1.5 times further: a mostly-reading kernel at 1.49x the copy's figure
// is possible there (the cpu device on the 2-core machine), not on a GPU.
TEST(Ceiling, OnTheHostsCpuTheCopysWriteAllocateTrafficCounts) {
  Measurement m;
  m.status = MeasureStatus::kOk;
  m.bytes_per_frame = 1105984;
  m.timing.median_ms = 0.03508;
  m.gbps = 31.5;
  Measurement on_gpu = m;
  EXPECT_FALSE(RejectOverCeiling(m, 21.1, kHostCopyTraffic));
  EXPECT_EQ(m.status, MeasureStatus::kOk);
  EXPECT_TRUE(RejectOverCeiling(on_gpu, 21.1));
  Measurement impossible = m;
  impossible.gbps = 1.6 * 21.1;
  EXPECT_TRUE(RejectOverCeiling(impossible, 21.1, kHostCopyTraffic));
  EXPECT_NE(impossible.detail.find("at most 1.58x is possible, its copy's stores reading their lines first"),
            std::string::npos)
      << impossible.detail;
}

// An instanced crowd reads its one mesh once: the ceiling judges the bytes
// the frame must move at least (each instance's outputs and palette, the
// mesh once), not K copies' (the H200's 1024 x 5k-b4 crowd with f32 weights:
// 0.0601 ms for 290.5 MB of K copies, 4.8 TB/s against a 4.3 TB/s copy,
// 2026-11-30). A record without the least bytes is judged on all of them.
TEST(Ceiling, AnInstancedCrowdIsJudgedOnTheBytesItMustMoveNotOnKCopiesOfItsMesh) {
  Measurement crowd;
  crowd.status = MeasureStatus::kOk;
  crowd.bytes_per_frame = 290504704;
  crowd.least_bytes_per_frame = 86e6;
  crowd.timing.median_ms = 0.06011;
  crowd.gbps = crowd.bytes_per_frame / crowd.timing.median_ms / 1e6;
  Measurement old_record = crowd;
  old_record.least_bytes_per_frame = 0.0;
  EXPECT_FALSE(RejectOverCeiling(crowd, 4286.0));
  EXPECT_EQ(crowd.status, MeasureStatus::kOk);
  EXPECT_TRUE(RejectOverCeiling(old_record, 4286.0));
  EXPECT_NE(old_record.detail.find("for 290504704 bytes is 4833 GB/s"), std::string::npos) << old_record.detail;
  Measurement too_fast = crowd;  // even its least bytes faster than the copy: impossible
  too_fast.timing.median_ms = 0.015;
  too_fast.gbps = too_fast.bytes_per_frame / too_fast.timing.median_ms / 1e6;
  EXPECT_TRUE(RejectOverCeiling(too_fast, 4286.0));
  EXPECT_NE(too_fast.detail.find("for 86000000 bytes is 5733 GB/s"), std::string::npos) << too_fast.detail;
}

}  // namespace
}  // namespace skintune::internal
