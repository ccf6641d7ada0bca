#include "tuner/report.h"

#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "generator/axes.h"
#include "tests/tuner/sample_report.h"

namespace skintune::internal {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Report, VertexBucketBoundaries) {
  EXPECT_EQ(VertexBucket(0), "25k");
  EXPECT_EQ(VertexBucket(25000), "25k");
  EXPECT_EQ(VertexBucket(49999), "25k");
  EXPECT_EQ(VertexBucket(50000), "100k");
  EXPECT_EQ(VertexBucket(199999), "100k");
  EXPECT_EQ(VertexBucket(200000), "400k");
  EXPECT_EQ(VertexBucket(799999), "400k");
  EXPECT_EQ(VertexBucket(800000), "1600k");
  EXPECT_EQ(VertexBucket(1600000), "1600k");
  EXPECT_EQ(VertexBucket(100000000), "1600k");
}

TEST(Report, JsonRoundTrip) {
  const TuningReport r = testing::SampleReport();
  const nlohmann::json j = ReportToJson(r);
  EXPECT_EQ(j["schema_version"], kReportSchemaVersion);
  EXPECT_EQ(j["kind"], "skintune-report");
  EXPECT_EQ(j["devices"][0]["id"], r.devices[0].Id());
  // Through text, as a file would.
  const TuningReport back = ReportFromJson(nlohmann::json::parse(j.dump(2)), "report.json");
  EXPECT_EQ(back.created, r.created);
  EXPECT_EQ(back.config, r.config);
  EXPECT_EQ(back.strategy, r.strategy);
  EXPECT_EQ(back.machine, r.machine);
  ASSERT_EQ(back.devices.size(), r.devices.size());
  for (std::size_t i = 0; i < r.devices.size(); ++i) EXPECT_EQ(back.devices[i].Id(), r.devices[i].Id());
  EXPECT_EQ(back.copy_bandwidth_gbps, r.copy_bandwidth_gbps);
  EXPECT_EQ(back.skipped, r.skipped);
  ASSERT_EQ(back.datasets.size(), r.datasets.size());
  EXPECT_EQ(back.datasets[2].vertices, 1600000u);
  ASSERT_EQ(back.measurements.size(), r.measurements.size());
  for (std::size_t i = 0; i < r.measurements.size(); ++i) {
    EXPECT_EQ(back.measurements[i].variant, r.measurements[i].variant);
    EXPECT_EQ(back.measurements[i].status, r.measurements[i].status);
    EXPECT_EQ(back.measurements[i].timing.median_ms, r.measurements[i].timing.median_ms);
  }
  EXPECT_EQ(ReportToJson(back), j);
}

TEST(Report, WinnersAreTheFastestOkPerDeviceLanguageInfluencesAndVertexCount) {
  const TuningReport r = testing::SampleReport();
  const std::vector<Winner> classes = ComputeWinners(r);
  // Every precision class (weight format) keeps the fastest of its own.
  for (const Winner& w : classes) {
    double fastest = 1e300;
    for (const Measurement& m : r.measurements) {
      if (m.status != MeasureStatus::kOk || m.device_id != w.device_id || m.variant.lang != w.lang ||
          m.variant.influences != w.influences || m.variant.weight != w.variant.weight)
        continue;
      for (const DatasetInfo& d : r.datasets)
        if (d.key == m.dataset && d.vertices == w.vertices) fastest = std::min(fastest, m.timing.median_ms);
    }
    // The winner ties with the fastest (the sample's measurements have no
    // interval: within the tie margin of it) and is in its own tie set.
    EXPECT_LE(w.median_ms, fastest * (1.0 + r.tie_margin)) << w.variant.Key();
    EXPECT_NE(std::find(w.tie_set.begin(), w.tie_set.end(), w.variant.Key()), w.tie_set.end());
    EXPECT_EQ(w.judged_by, "intervals");
    EXPECT_TRUE(w.within_budget);  // the sample records no error: every class is within
  }
  // The run's winners: the fastest within budget per key.
  const std::vector<Winner> winners = BudgetWinners(classes, 0.02);
  EXPECT_GT(classes.size(), winners.size());
  // opencl 100k b4, opencl 25k b4, cuda 100k b4, opencl 1600k b1 (1600k b2 only failed).
  ASSERT_EQ(winners.size(), 4u);
  std::map<std::string, const Winner*> by_key;
  for (const Winner& w : winners) {
    by_key[w.device_id + "|" + Name(w.lang) + "|" + std::to_string(w.influences) + "|" + VertexCountName(w.vertices)] = &w;
    EXPECT_EQ(w.vertex_bucket, VertexBucket(w.vertices));
  }
  const std::string gpu = testing::SampleGpu().Id();
  const std::string cuda = testing::SampleCuda().Id();
  ASSERT_TRUE(by_key.count(gpu + "|opencl|4|100k"));
  ASSERT_TRUE(by_key.count(gpu + "|opencl|4|25k"));
  ASSERT_TRUE(by_key.count(cuda + "|cuda|4|100k"));
  ASSERT_TRUE(by_key.count(gpu + "|opencl|1|1600k"));
  for (const Winner& w : winners) {
    double fastest = 1e300;
    for (const Measurement& m : r.measurements) {
      if (m.status != MeasureStatus::kOk || m.device_id != w.device_id || m.variant.lang != w.lang ||
          m.variant.influences != w.influences)
        continue;
      for (const DatasetInfo& d : r.datasets)
        if (d.key == m.dataset && d.vertices == w.vertices) fastest = std::min(fastest, m.timing.median_ms);
    }
    EXPECT_LE(w.median_ms, fastest * (1.0 + r.tie_margin)) << w.variant.Key();  // within the tie margin of the fastest
  }
  const Winner& g = *by_key[gpu + "|opencl|4|100k"];
  EXPECT_EQ(g.backend, "opencl");
  EXPECT_EQ(g.dataset, "100k-b4");
  EXPECT_DOUBLE_EQ(g.copy_fraction, g.gbps / 2000.0);
  EXPECT_EQ(by_key[cuda + "|cuda|4|100k"]->copy_fraction, 0.0);  // copy bandwidth unknown
  EXPECT_EQ(by_key[cuda + "|cuda|4|100k"]->backend, "cuda");
}

// `m`'s kernel time made `ms` with a tight interval, its other figures consistent.
void SetTime(Measurement& m, double ms) {
  const double scale = ms / m.timing.median_ms;
  m.timing.median_ms = ms;
  m.timing.min_ms *= scale;
  m.timing.max_ms *= scale;
  m.timing.low_ms = ms * 0.995;
  m.timing.high_ms = ms * 1.005;
  m.gbps /= scale;
  m.x_copy *= scale;
  m.timing.copy_ms = m.x_copy > 0.0 ? ms / m.x_copy : 0.0;
}

// Two ok measurements of one row, `slower` x apart, each with a tight interval.
TuningReport TwoCandidates(const DeviceIdentity& device, double slower) {
  TuningReport r;
  r.created = "2026-11-28T12:00:00Z";
  r.devices = {device};
  r.datasets = {{"100k-b4", 100000, 4, 77}};
  // Two f32 candidates of one precision class, so that one row judges them.
  std::vector<Variant> f32;
  for (Variant v : testing::SyntheticCandidates()) {
    v.weight = WeightFormat::kF32;
    if (v.influences == 4 && (f32.empty() || v.Key() != f32.back().Key())) f32.push_back(v);
  }
  for (const auto& [v, ms] : {std::pair{f32.at(0), 1.0}, {f32.at(1), slower}}) {
    Measurement m = testing::SyntheticMeasurement(v, device.Id(), "100k-b4", 100000);
    m.status = MeasureStatus::kOk;
    m.variant = v;
    SetTime(m, ms);
    r.measurements.push_back(m);
  }
  return r;
}

// A device that is the host's CPU ties at host_tie_margin (its times move
// between runs by tens of percent), a GPU at tie_margin; a report before
// host_tie_margin was recorded reads it as tie_margin.
TEST(Report, ACpuDevicesCandidatesTieAtTheHostMarginAGpusAtTheTieMargin) {
  DeviceIdentity cpu = testing::SampleGpu();
  cpu.type = "cpu";
  const DeviceIdentity gpu = testing::SampleGpu();
  for (const auto& [device, ties] : {std::pair{cpu, true}, {gpu, false}}) {
    TuningReport r = TwoCandidates(device, 1.15);  // 15% apart
    r.tie_margin = 0.05;
    r.host_tie_margin = 0.25;
    const std::vector<Winner> winners = ComputeWinners(r);
    ASSERT_EQ(winners.size(), 1u) << device.type;
    EXPECT_EQ(winners[0].tie_set.size(), ties ? 2u : 1u) << device.type;
    EXPECT_DOUBLE_EQ(winners[0].tie_margin, ties ? 0.25 : 0.05);
    EXPECT_DOUBLE_EQ(r.TieMarginOf(device.Id()), ties ? 0.25 : 0.05);
  }
  nlohmann::json old = ReportToJson(TwoCandidates(cpu, 1.15));
  old["tie_margin"] = 0.03;
  old.erase("host_tie_margin");
  EXPECT_DOUBLE_EQ(ReportFromJson(old, "old.json").TieMarginOf(cpu.Id()), 0.03);
  old["host_tie_margin"] = 0.0;
  EXPECT_NE(ErrorOf([&] { ReportFromJson(old, "bad.json"); }).find("host_tie_margin"), std::string::npos);
}

// A tie set spans the spread between processes: a GPU candidate 7% slower is
// no contender at a 5% margin (the winner stays the fastest) but is in the tie
// set with pairs moving 3.4% between processes. A report from before the
// spreads were recorded keeps its tie sets as they were; the spreads survive
// the round trip, and an impossible one is an error naming it.
TEST(Report, ATieSetSpansTheSpreadBetweenProcessesNotTheChoice) {
  const DeviceIdentity gpu = testing::SampleGpu();
  TuningReport r = TwoCandidates(gpu, 1.07);
  r.tie_margin = 0.05;
  r.process_spread = 0.034;
  r.choose_in_tie_set = false;
  std::vector<Winner> winners = ComputeWinners(r);
  ASSERT_EQ(winners.size(), 1u);
  EXPECT_EQ(winners[0].variant.Key(), r.measurements[0].variant.Key());
  EXPECT_EQ(winners[0].tie_set.size(), 2u);
  r.process_spread = 0.0;
  EXPECT_EQ(ComputeWinners(r)[0].tie_set.size(), 1u);
  r.process_spread = 0.034;
  nlohmann::json json = ReportToJson(r);
  EXPECT_DOUBLE_EQ(ReportFromJson(json, "r.json").TieSpreadOf(gpu.Id()), 0.034);
  json.erase("process_spread");
  json.erase("host_process_spread");
  const TuningReport old = ReportFromJson(json, "old.json");
  EXPECT_DOUBLE_EQ(old.TieSpreadOf(gpu.Id()), 0.0);
  EXPECT_EQ(ComputeWinners(old)[0].tie_set.size(), 1u);
  json["host_process_spread"] = -0.1;
  EXPECT_NE(ErrorOf([&] { ReportFromJson(json, "bad.json"); }).find("host_process_spread"), std::string::npos);
}

// A GPU's winner is picked among its whole tie set by default (1.8.0): of two
// candidates 7% apart, within the margin plus the spread, the one moving
// fewer bytes wins whichever ran faster; a report before 1.8.0 picked among
// its contenders and keeps its winners; the host's CPU picks among its tie
// set too (since 2026-12-02), less the candidates its race separated (1.20.0),
// unless asked otherwise; a choice that is not true or false is an error
// naming it.
TEST(Report, AGpusWinnerIsPickedAmongItsTieSet) {
  const DeviceIdentity gpu = testing::SampleGpu();
  TuningReport r = TwoCandidates(gpu, 1.07);
  r.tie_margin = 0.05;
  r.process_spread = 0.034;
  for (const auto& [m, bytes] : {std::pair{&r.measurements[0], 2e6}, {&r.measurements[1], 1e6}}) {
    m->gbps *= bytes / m->bytes_per_frame;  // the same time
    m->bytes_per_frame = bytes;
  }
  ASSERT_TRUE(r.choose_in_tie_set) << "the default";
  ASSERT_EQ(r.ChoiceOf(gpu.Id()), Choice::kTieSet);
  EXPECT_EQ(ComputeWinners(r).at(0).variant.Key(), r.measurements[1].variant.Key()) << "fewer bytes, 7% slower";
  nlohmann::json json = ReportToJson(r);
  EXPECT_EQ(json.at("choose_in_tie_set"), true);
  EXPECT_EQ(json.at("host_choose_in_tie_set"), true);
  EXPECT_EQ(ComputeWinners(ReportFromJson(json, "r.json")).at(0).variant.Key(), r.measurements[1].variant.Key());
  json.erase("choose_in_tie_set");
  json.erase("host_choose_in_tie_set");
  const TuningReport old = ReportFromJson(json, "old.json");
  EXPECT_EQ(old.ChoiceOf(gpu.Id()), Choice::kContenders);
  EXPECT_EQ(ComputeWinners(old).at(0).variant.Key(), r.measurements[0].variant.Key()) << "an older report's winner";
  DeviceIdentity cpu = gpu;
  cpu.backend = "cpu";
  cpu.type = "cpu";
  r.devices = {cpu};
  EXPECT_EQ(r.ChoiceOf(cpu.Id()), Choice::kTieSetUnseparated)
      << "the default on the host's CPU: its tie set less the candidates its race separated";
  EXPECT_EQ(json.at("choose_unseparated"), false);
  EXPECT_EQ(json.at("host_choose_unseparated"), true);
  nlohmann::json before_unseparated = ReportToJson(r);
  before_unseparated.erase("choose_unseparated");
  before_unseparated.erase("host_choose_unseparated");
  EXPECT_EQ(ReportFromJson(before_unseparated, "old.json").ChoiceOf(cpu.Id()), Choice::kTieSet)
      << "a report before 1.20.0 picked among the whole tie set";
  r.host_choose_unseparated = false;
  EXPECT_EQ(r.ChoiceOf(cpu.Id()), Choice::kTieSet);
  r.host_choose_in_tie_set = false;
  EXPECT_EQ(r.ChoiceOf(cpu.Id()), Choice::kContenders);
  r.host_choose_unseparated = true;
  EXPECT_EQ(r.ChoiceOf(cpu.Id()), Choice::kContenders) << "the unseparated choice is within the tie set's";
  json["choose_in_tie_set"] = "yes";
  EXPECT_NE(ErrorOf([&] { ReportFromJson(json, "bad.json"); }).find("choose_in_tie_set"), std::string::npos);
}

// Where a race measured a row, the race alone judges it: a candidate the
// race left out does not win on a search figure from minutes before.
TEST(Report, ARacedRowIsJudgedByTheRacesCandidatesOnly) {
  TuningReport r = TwoCandidates(testing::SampleGpu(), 1.30);
  SetTime(r.measurements[1], 0.5);  // the search's figure, fastest by far
  RaceRecord race;
  race.device_id = r.devices[0].Id();
  race.lang = r.measurements[0].variant.lang;
  race.dataset = "100k-b4";
  RaceRecord::Entry raced;
  raced.variant = r.measurements[0].variant;
  raced.interval = {1.0, 0.99, 1.01, 40};
  raced.verdict = RaceVerdict::kLeader;
  RaceRecord::Entry second = raced;
  second.variant = r.measurements[0].variant;
  second.variant.wg_size = 512;  // raced, not among the measurements here
  race.entries = {raced, second};
  r.races = {race};
  std::vector<Winner> winners = ComputeWinners(r);
  ASSERT_EQ(winners.size(), 1u);
  EXPECT_EQ(winners[0].variant.Key(), r.measurements[0].variant.Key());
  EXPECT_EQ(winners[0].judged_by, "race");
  EXPECT_EQ(winners[0].tie_set, std::vector<std::string>{r.measurements[0].variant.Key()});
  r.races.clear();  // without the race, the search's figures judge
  winners = ComputeWinners(r);
  EXPECT_EQ(winners[0].variant.Key(), r.measurements[1].variant.Key());
}

TEST(Report, EveryMeasuredVertexCountKeepsItsWinnerInTheReportAndTheDatabase) {
  // 1600k and 6400k share the 1600k bucket; until database 1.2.0 only one of them was kept.
  TuningReport r = testing::SampleReport();
  const Winner at1600k = [&] {
    for (const Winner& w : ComputeWinners(r))
      if (w.vertices == 1600000) return w;
    ADD_FAILURE() << "the sample has no 1600k winner";
    return Winner{};
  }();
  r.datasets.push_back({"6400k-b1", 6400000, 1, 77});
  for (Measurement m : std::vector<Measurement>(r.measurements)) {
    if (m.dataset != at1600k.dataset) continue;
    m.dataset = "6400k-b1";
    m.timing.median_ms *= 4.0;
    m.timing.min_ms *= 4.0;
    m.timing.max_ms *= 4.0;
    m.bytes_per_frame *= 4.0;  // four times the vertices: the same GB/s
    r.measurements.push_back(m);
  }
  std::map<std::size_t, int> per_count;
  for (const Winner& w : ComputeWinners(r))
    if (w.device_id == at1600k.device_id && w.lang == at1600k.lang && w.influences == at1600k.influences) ++per_count[w.vertices];
  EXPECT_EQ(per_count[1600000], 1);
  EXPECT_EQ(per_count[6400000], 1);
  const std::vector<WinnersEntry> db = WinnersDbFromJson(WinnersDatabase(r), "db.json");
  int entries = 0;
  for (const WinnersEntry& e : db) {
    if (e.device_id != at1600k.device_id || e.lang != at1600k.lang || e.influences != at1600k.influences) continue;
    ++entries;
    EXPECT_EQ(e.vertex_bucket, "1600k");
    EXPECT_TRUE(e.vertices == 1600000 || e.vertices == 6400000) << e.vertices;
  }
  EXPECT_EQ(entries, 2);
  // Merging the database with itself keeps both.
  const nlohmann::json merged = MergeWinnersDatabases({WinnersDatabase(r), WinnersDatabase(r)}, {"a.json", "b.json"});
  EXPECT_EQ(merged["entries"].size(), WinnersDatabase(r)["entries"].size());
}

// One class per weight format on one device: a measurement of `weight`
// taking `ms` (its interval 1% either side), within the budget or not.
Measurement ClassMeasurement(const std::string& dataset, std::size_t vertices, const char* weight, double ms,
                             bool within_budget) {
  Measurement m = testing::SyntheticMeasurement(ParseVariantKey(std::string("opencl.b4.soa.") + weight + ".wg64"),
                                                testing::SampleGpu().Id(), dataset, vertices);
  m.status = within_budget ? MeasureStatus::kOk : MeasureStatus::kTooImprecise;
  m.timing = {ms, ms * 0.99, ms * 1.01, 3, 30, 4, 8};
  m.timing.low_ms = ms * 0.99;
  m.timing.high_ms = ms * 1.01;
  m.gbps = m.bytes_per_frame / (ms * 1e6);
  return m;
}

// An f32 measurement within budget of `key` on a 100k-vertex `dataset`.
Measurement Measured(const std::string& dataset, const char* key, double ms) {
  Measurement m = ClassMeasurement(dataset, 100000, "f32", ms, true);
  m.variant = ParseVariantKey(key);
  return m;
}

// A precision class is judged against the others by its fastest candidate,
// not by the winner its tie-break picked: an f32 class whose pick (fewer
// bytes) is 1.12x behind its fastest, and a unorm8 class 1.30x behind that
// fastest, at a 25% margin: the unorm8 class is separated, so the f32 pick
// is the run's. Judged by the pick (1.16x), unorm8 tied and won by its bytes,
// the margin let in twice over (PoCL on the 2-core machine, 2026-12-01).
TEST(Report, APrecisionClassIsJudgedByItsFastestCandidateNotByItsPick) {
  TuningReport r;
  r.created = "2026-12-01T00:00:00Z";
  r.devices = {testing::SampleGpu()};
  r.datasets = {DatasetInfo{"100k-b4", 100000, 4, 77}};
  r.tie_margin = 0.25;
  Measurement fastest = Measured("100k-b4", "opencl.b4.soa-split.f32.wg64", 0.212);
  Measurement picked = Measured("100k-b4", "opencl.b4.soa.f32.wg64", 0.237);
  Measurement narrow = ClassMeasurement("100k-b4", 100000, "unorm8", 0.276, true);
  for (auto [m, bytes] : {std::pair{&fastest, 6e6}, std::pair{&picked, 5e6}, std::pair{&narrow, 4e6}}) {
    m->bytes_per_frame = bytes;
    m->gbps = bytes / (m->timing.median_ms * 1e6);
  }
  r.measurements = {fastest, picked, narrow};
  const std::vector<Winner> winners = ComputeWinners(r);
  ASSERT_EQ(winners.size(), 2u);
  const auto f32 = std::find_if(winners.begin(), winners.end(), [](const Winner& w) { return w.variant.weight == WeightFormat::kF32; });
  ASSERT_NE(f32, winners.end());
  EXPECT_EQ(f32->variant.Key(), picked.variant.Key()) << "the f32 class's tie-break picks the fewer bytes";
  EXPECT_DOUBLE_EQ(f32->fastest_ms, 0.212);
  const std::vector<Winner> chosen = BudgetWinners(winners, r.tie_margin);
  ASSERT_EQ(chosen.size(), 1u);
  EXPECT_EQ(chosen.front().variant.Key(), picked.variant.Key()) << "unorm8 is 1.30x behind the f32 class's fastest";
}

// Meshes of one vertex count with 8, 32 and no morph targets are three rows
// (a faster mesh without morph targets is no rival of a mesh with them), and
// half offsets a class of their own within a row; the database keeps each.
TEST(Report, MorphTargetCountsAreRowsAndHalfOffsetsAClassOfTheirOwn) {
  TuningReport r;
  r.created = "2026-11-30T00:00:00Z";
  r.devices = {testing::SampleGpu()};
  DatasetInfo plain{"100k-b4", 100000, 4, 77}, few{"100k-b4-morph8", 100000, 4, 77}, many{"100k-b4-morph32", 100000, 4, 77};
  few.morph_targets = 8;
  many.morph_targets = 32;
  r.datasets = {plain, few, many};
  r.measurements = {Measured("100k-b4", "opencl.b4.soa.wg64", 1.0),
                    Measured("100k-b4-morph8", "opencl.b4.soa.wg64.morph-sparse", 1.4),
                    Measured("100k-b4-morph8", "opencl.b4.soa.wg64.morph-sparse-half", 1.2),
                    Measured("100k-b4-morph32", "opencl.b4.soa.wg64.morph-dense", 3.0),
                    Measured("100k-b4-morph32", "opencl.b4.soa.wg64.morph-sparse", 1.5)};
  const std::vector<Winner> winners = ComputeWinners(r);
  std::map<std::pair<int, std::string>, int> per_row_class;  // (morph targets, morph value) -> winners
  for (const Winner& w : winners) ++per_row_class[{w.morph_targets, Name(w.variant.morph)}];
  EXPECT_EQ(winners.size(), 4u);  // plain; 8: float32 and half classes; 32: one (sparse beats dense)
  EXPECT_EQ((per_row_class[{0, "none"}]), 1);
  EXPECT_EQ((per_row_class[{8, "sparse"}]), 1);
  EXPECT_EQ((per_row_class[{8, "sparse-half"}]), 1);
  EXPECT_EQ((per_row_class[{32, "sparse"}]), 1);
  const std::vector<Winner> chosen = BudgetWinners(winners, 0.05);
  ASSERT_EQ(chosen.size(), 3u) << "one per row: the plain mesh's 1.0 ms decides none of the morph rows";
  for (const Winner& w : chosen)
    if (w.morph_targets == 8) {
      EXPECT_EQ(w.variant.morph, Morph::kSparseHalf);
    }
  const std::vector<WinnersEntry> db = WinnersDbFromJson(WinnersDatabase(r), "db.json");
  EXPECT_EQ(db.size(), 4u);
  const nlohmann::json merged = MergeWinnersDatabases({WinnersDatabase(r), WinnersDatabase(r)}, {"a.json", "b.json"});
  EXPECT_EQ(merged["entries"].size(), 4u);
}

// Two crowds of one size animated on the device, one cross-fading clips
// ("-animblend") and one not, are two rows: the steady crowd's baked palette
// records, faster, decide nothing for the crowd in transition, and the
// database keeps each with its cross_fades; the reports' datasets say which.
TEST(Report, ACrossFadingCrowdIsARowApartFromASteadyOneOfTheSameSize) {
  TuningReport r;
  r.created = "2026-11-30T00:00:00Z";
  r.devices = {testing::SampleGpu()};
  DatasetInfo steady{"1k-b4-x100-anim", 100000, 4, 77, SceneKind::kInstances, 100},
      fading{"1k-b4-x100-animblend", 100000, 4, 77, SceneKind::kInstances, 100};
  fading.cross_fades = true;
  r.datasets = {steady, fading};
  r.measurements = {Measured("1k-b4-x100-anim", "opencl.b4.soa.wg64.anim-baked120", 1.0),
                    Measured("1k-b4-x100-animblend", "opencl.b4.soa.wg64.anim-local120", 1.2)};
  const std::vector<Winner> winners = ComputeWinners(r);
  ASSERT_EQ(winners.size(), 2u);
  for (const Winner& w : winners) EXPECT_EQ(w.cross_fades, w.dataset == "1k-b4-x100-animblend") << w.dataset;
  const std::vector<WinnersEntry> db = WinnersDbFromJson(WinnersDatabase(r), "db.json");
  ASSERT_EQ(db.size(), 2u);
  EXPECT_NE(RowName(db[0]), RowName(db[1]));
  const nlohmann::json json = ReportToJson(r);
  EXPECT_EQ(json["datasets"][1]["cross_fades"], true);
  EXPECT_TRUE(ReportFromJson(json, "report.json").datasets[1].cross_fades);
}

// In one row and weight format, a faster form the budget rules out (palette
// records on a crowd in transition: a third of the diagonal off) does not hide
// the form it admits: the row's winner is the admitted one, and the run's
// choice takes it. With nothing admitted, the fastest stands, over the budget.
TEST(Report, AFasterFormOverTheBudgetNeverHidesOneWithinItInTheSameRow) {
  TuningReport r;
  r.created = "2026-11-30T00:00:00Z";
  r.devices = {testing::SampleGpu()};
  DatasetInfo fading{"1k-b4-x100-animblend", 100000, 4, 77, SceneKind::kInstances, 100};
  fading.cross_fades = true;
  r.datasets = {fading};
  Measurement fused = Measured("1k-b4-x100-animblend", "opencl.b4.soa.local.v8s.wg256.anim-fused240", 0.9);
  fused.status = MeasureStatus::kTooImprecise;
  r.measurements = {fused, Measured("1k-b4-x100-animblend", "opencl.b4.soa.wg64.anim-local240", 1.2)};
  std::vector<Winner> winners = ComputeWinners(r);
  ASSERT_EQ(winners.size(), 1u);
  EXPECT_EQ(winners[0].variant.animation, Animation::kLocal240);
  EXPECT_TRUE(winners[0].within_budget);
  ASSERT_EQ(BudgetWinners(winners, r.tie_margin).size(), 1u);
  r.measurements.pop_back();
  winners = ComputeWinners(r);
  ASSERT_EQ(winners.size(), 1u);
  EXPECT_EQ(winners[0].variant.animation, Animation::kFused240);
  EXPECT_FALSE(winners[0].within_budget);
  EXPECT_TRUE(BudgetWinners(winners, r.tie_margin).empty());
}

// The classes over the budget named under a device's winners (skintune run):
// only those faster than the chosen class of their own row, beyond the tie
// margin; not one that ties with it, is slower, or is of another row.
TEST(Report, OnlyClassesOverTheBudgetFasterThanTheirRowsWinnerBeyondTheTieMarginAreNamed) {
  TuningReport r = testing::SampleReport();
  r.datasets = {{"100k-b4", 100000, 4, 77}, {"25k-b4", 25000, 4, 77}};
  r.measurements = {ClassMeasurement("100k-b4", 100000, "f32", 0.30, true),
                    ClassMeasurement("100k-b4", 100000, "unorm8", 0.15, false),     // faster
                    ClassMeasurement("100k-b4", 100000, "unorm16", 0.298, false),   // a tie
                    ClassMeasurement("25k-b4", 25000, "f32", 0.10, true),
                    ClassMeasurement("25k-b4", 25000, "unorm8", 0.12, false)};      // slower
  const std::vector<Winner> all = ComputeWinners(r);
  ASSERT_EQ(all.size(), 5u);
  const std::vector<FasterOverBudget> faster = FasterClassesOverBudget(all, r.tie_margin);
  ASSERT_EQ(faster.size(), 1u);
  EXPECT_EQ(faster[0].over.variant.weight, WeightFormat::kUnorm8);
  EXPECT_EQ(faster[0].chosen.variant.weight, WeightFormat::kF32);
  EXPECT_EQ(Describe(faster[0]), "opencl 100k-b4 unorm8 0.15 ms against f32 0.3 ms");
  // Slower than its row's winner's interval by less than the margin: a tie, not faster.
  r.measurements[1] = ClassMeasurement("100k-b4", 100000, "unorm8", 0.30 * (1.0 - r.tie_margin / 4.0), false);
  EXPECT_TRUE(FasterClassesOverBudget(ComputeWinners(r), r.tie_margin).empty());
}

TEST(Report, FailedVariantsAreNeverWinners) {
  const TuningReport r = testing::SampleReport();
  for (const Winner& w : ComputeWinners(r)) {
    EXPECT_GT(w.median_ms, 1e-3) << w.variant.Key();  // the failed ones claim 1e-6 ms
    for (const Measurement& m : r.measurements) {
      if (m.device_id == w.device_id && m.dataset == w.dataset && m.variant == w.variant) {
        EXPECT_EQ(m.status, MeasureStatus::kOk) << w.variant.Key();
      }
    }
  }
  // Only failures: no winner at all.
  TuningReport failed = r;
  for (Measurement& m : failed.measurements) m.status = MeasureStatus::kVerifyFailed;
  EXPECT_TRUE(ComputeWinners(failed).empty());
  EXPECT_TRUE(ReportToJson(failed)["winners"].empty());
}

TEST(Report, MalformedReportsNameTheElement) {
  const nlohmann::json good = ReportToJson(testing::SampleReport());
  nlohmann::json j = good;
  j["measurements"][1]["status"] = "fast";
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("r.json: measurements[1]:"), std::string::npos)
      << ErrorOf([&] { ReportFromJson(j, "r.json"); });
  j = good;
  j["measurements"][2]["dataset"] = "3k-b1";
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("measurements[2]: dataset '3k-b1'"),
            std::string::npos);
  j = good;
  j["schema_version"] = "2.0.0";
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("schema_version '2.0.0'"), std::string::npos);
  j = good;
  j["measurements"][2]["device_id"] = "no backend or parts";  // found by report_fuzz: merges failed later, unnamed
  EXPECT_EQ(ErrorOf([&] { ReportFromJson(j, "r.json"); }).rfind("r.json: measurements[2]: device id 'no backend", 0), 0u)
      << ErrorOf([&] { ReportFromJson(j, "r.json"); });
  j = good;
  j["measurements"][2]["device_id"] = "metal:Apple/M3/1.0";  // found by winners_db_fuzz: merged into an unreadable database
  EXPECT_EQ(ErrorOf([&] { ReportFromJson(j, "r.json"); }),
            "r.json: measurements[2]: device id 'metal:Apple/M3/1.0' has unknown backend 'metal' (expected opencl, cuda, "
            "gl, vulkan or cpu)");
  j = good;
  j["kind"] = "something";
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("kind"), std::string::npos);
  j = good;
  j["created"] = "yesterday";
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("r.json: created:"), std::string::npos);
  j = good;
  j.erase("datasets");
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("r.json: datasets: missing"), std::string::npos);
  j = good;
  j["datasets"][0]["vertices"] = "many";
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("datasets[0]: 'vertices'"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { ReportFromJson(nlohmann::json::array(), "r.json"); }).find("r.json:"), std::string::npos);
}

// The first status-ok measurement of the report (its figures obey docs/INPUTS.md's rule).
std::size_t FirstOk(const nlohmann::json& report) {
  const nlohmann::json& list = report.at("measurements");
  for (std::size_t i = 0; i < list.size(); ++i)
    if (list[i].at("status") == "ok") return i;
  ADD_FAILURE() << "no ok measurement";
  return 0;
}

TEST(Report, ImpossibleMeasurementsAreRefusedNamingTheElement) {
  const nlohmann::json good = ReportToJson(testing::SampleReport());
  const std::size_t i = FirstOk(good);
  const std::string element = "r.json: measurements[" + std::to_string(i) + "]: measurement: ";
  nlohmann::json j = good;
  j["measurements"][i].erase("timing");
  EXPECT_EQ(ErrorOf([&] { ReportFromJson(j, "r.json"); }), element + "status ok without 'timing'");
  for (const nlohmann::json& median : {nlohmann::json(0), nlohmann::json(-5), nlohmann::json("nan")}) {
    j = good;
    j["measurements"][i]["timing"]["median_ms"] = median;
    const std::string error = ErrorOf([&] { ReportFromJson(j, "r.json"); });
    EXPECT_EQ(error.rfind(element + "impossible figures: status ok with 'median_ms' is ", 0), 0u) << error;
  }
  j = good;
  j["copy_bandwidth_gbps"].begin().value() = 0;
  EXPECT_NE(ErrorOf([&] { ReportFromJson(j, "r.json"); }).find("must be a positive, finite GB/s"), std::string::npos);
}

TEST(Report, ImpossibleMeasurementsNeverWinOrMerge) {
  TuningReport r = testing::SampleReport();
  const std::vector<Winner> before = ComputeWinners(r);
  ASSERT_FALSE(before.empty());
  // A report built in memory with a 0 ms "winner": it is never one.
  for (Measurement& m : r.measurements) {
    if (m.device_id == before[0].device_id && m.dataset == before[0].dataset && m.variant != before[0].variant &&
        m.status == MeasureStatus::kOk) {
      m.timing.median_ms = 0.0;
      break;
    }
  }
  const std::vector<Winner> after = ComputeWinners(r);
  ASSERT_EQ(after.size(), before.size());
  for (std::size_t k = 0; k < after.size(); ++k) {
    EXPECT_EQ(after[k].variant, before[k].variant);
    EXPECT_GT(after[k].median_ms, 0.0);
  }
  // Merging a report or database with an impossible time fails naming the input and the element.
  nlohmann::json report = ReportToJson(testing::SampleReport());
  report["measurements"][FirstOk(report)]["timing"]["median_ms"] = -5;
  EXPECT_EQ(ErrorOf([&] { MergeWinnersDatabases({report}, {"a.json"}); })
                .rfind("a.json: measurements[" + std::to_string(FirstOk(report)) + "]: measurement: impossible figures", 0),
            0u);
  nlohmann::json db = WinnersDatabase(testing::SampleReport());
  db["entries"][0]["median_ms"] = 0;
  EXPECT_EQ(ErrorOf([&] { MergeWinnersDatabases({db}, {"db.json"}); }),
            "db.json: entries[0]: impossible figures: 'median_ms' is 0: a time must be a positive, finite number");
}

TEST(Report, T4ExportMapsStatusesAndAxes) {
  const TuningReport r = testing::SampleReport();
  const nlohmann::json t4 = ReportToT4(r);
  EXPECT_EQ(t4["schema_version"], "1.0.0");
  ASSERT_EQ(t4["results"].size(), r.measurements.size());
  std::map<std::string, int> invalidity;
  for (std::size_t i = 0; i < r.measurements.size(); ++i) {
    const Measurement& m = r.measurements[i];
    const nlohmann::json& res = t4["results"][i];
    ++invalidity[res["invalidity"].get<std::string>()];
    EXPECT_EQ(res["configuration"]["layout"], Name(m.variant.layout));
    EXPECT_EQ(res["configuration"]["wg_size"], m.variant.wg_size);
    EXPECT_EQ(res["configuration"].size(), kAxisCount);  // the variant axes
    EXPECT_EQ(res["correctness"], m.status == MeasureStatus::kOk ? 1 : 0);
    if (m.status == MeasureStatus::kOk) {
      EXPECT_EQ(res["times"]["runtimes"], nlohmann::json::array({m.timing.median_ms}));
    } else {
      EXPECT_TRUE(res["times"]["runtimes"].empty());
    }
    for (const nlohmann::json& x : res["measurements"]) EXPECT_TRUE(x["value"].is_number()) << x.dump();
  }
  EXPECT_GT(invalidity["correct"], 0);
  EXPECT_GT(invalidity["constraints"], 0);
  EXPECT_GT(invalidity["compile"], 0);
  EXPECT_GT(invalidity["runtime"], 0);
  EXPECT_GT(invalidity["correctness"], 0);
  EXPECT_GT(invalidity["timeout"], 0);
}

TEST(Report, WinnersDatabaseHasOneEntryPerWinner) {
  const TuningReport r = testing::SampleReport();
  const nlohmann::json db = WinnersDatabase(r);
  EXPECT_EQ(db["kind"], "skintune-winners-db");
  EXPECT_EQ(db["schema_version"], kWinnersDbSchemaVersion);
  ASSERT_EQ(db["entries"].size(), ComputeWinners(r).size());
  for (const nlohmann::json& e : db["entries"]) EXPECT_EQ(e["created"], r.created);
}

TEST(Report, WinnersDatabaseEntriesNameTheDevicesVendorTypeAndDriver) {
  const TuningReport r = testing::SampleReport();
  const nlohmann::json db = WinnersDatabase(r);
  ASSERT_FALSE(db["entries"].empty());
  for (const nlohmann::json& e : db["entries"]) {
    const DeviceIdentity& d = e["backend"] == "cuda" ? testing::SampleCuda() : r.devices[0];
    EXPECT_EQ(e["device_id"], d.Id()) << e.dump();
    EXPECT_EQ(e["platform"], d.platform);
    EXPECT_EQ(e["vendor"], d.vendor);
    EXPECT_EQ(e["device_name"], d.name);
    EXPECT_EQ(e["driver_version"], d.driver_version);
    EXPECT_EQ(e["device_type"], d.type);
  }
}

TEST(Report, MergeKeepsDatabaseEntriesWithoutVendorAndType) {
  // A 1.0.0 database (written before entries named the device) merges; its
  // entries keep what the id says and no vendor or type.
  nlohmann::json old = WinnersDatabase(testing::SampleReport());
  old["schema_version"] = "1.0.0";
  for (nlohmann::json& e : old["entries"]) {
    for (const char* field : {"platform", "vendor", "device_name", "driver_version", "device_type"}) e.erase(field);
  }
  const nlohmann::json merged = MergeWinnersDatabases({old}, {"old.json"});
  ASSERT_EQ(merged["entries"].size(), old["entries"].size());
  for (const nlohmann::json& e : merged["entries"]) {
    EXPECT_FALSE(e.contains("vendor")) << e.dump();
    EXPECT_FALSE(e.contains("device_type")) << e.dump();
    EXPECT_EQ(e["device_name"], "Model GPU");
  }
}

TEST(Report, MergeNewestReportWinsPerDeviceLanguageInfluencesAndBucket) {
  // Older: faster times. Newer: slower, but newest wins (a driver update, a fix).
  TuningReport older = testing::SampleReport("2025-01-01T00:00:00Z", 1.0);
  TuningReport newer = testing::SampleReport("2025-02-01T00:00:00Z", 2.0);
  // The newer report did not measure 25k: the older 25k winner stays.
  std::erase_if(newer.measurements, [](const Measurement& m) { return m.dataset == "25k-b4"; });
  const nlohmann::json a = ReportToJson(older);
  const nlohmann::json b = ReportToJson(newer);
  for (const auto& inputs : {std::vector<nlohmann::json>{a, b}, std::vector<nlohmann::json>{b, a}}) {
    const nlohmann::json db = MergeWinnersDatabases(inputs, {"x.json", "y.json"});
    // One entry per precision class of every key; the newer report lacks 25k only.
    ASSERT_EQ(db["entries"].size(), ComputeWinners(older).size());
    for (const nlohmann::json& e : db["entries"]) {
      const bool small = e["vertex_bucket"] == "25k";
      EXPECT_EQ(e["created"], small ? "2025-01-01T00:00:00Z" : "2025-02-01T00:00:00Z") << e.dump();
    }
  }
  // Databases merge like reports, and a merged database merges again unchanged.
  const nlohmann::json merged = MergeWinnersDatabases({WinnersDatabase(older), b}, {"old-db.json", "new.json"});
  EXPECT_EQ(MergeWinnersDatabases({merged}, {"merged.json"}), merged);
  EXPECT_EQ(merged, MergeWinnersDatabases({a, b}, {"x.json", "y.json"}));
  // Another driver is another device id: both kept.
  const nlohmann::json other_driver = ReportToJson(testing::SampleReport("2025-03-01T00:00:00Z", 1.0, "2.0"));
  std::size_t gpu_classes = 0;
  for (const Winner& w : ComputeWinners(older)) gpu_classes += w.device_id == testing::SampleGpu().Id();
  EXPECT_EQ(MergeWinnersDatabases({a, other_driver}, {"a", "b"})["entries"].size(),
            ComputeWinners(older).size() + gpu_classes);
  // Fractional seconds order correctly.
  const nlohmann::json early = ReportToJson(testing::SampleReport("2025-01-01T00:00:00.5Z", 3.0));
  const nlohmann::json late = ReportToJson(testing::SampleReport("2025-01-01T00:00:00.25Z", 1.0));
  EXPECT_EQ(MergeWinnersDatabases({late, early}, {"a", "b"})["entries"][0]["created"], "2025-01-01T00:00:00.5Z");
}

TEST(Report, MergeErrorsNameTheInputFile) {
  const nlohmann::json good = ReportToJson(testing::SampleReport());
  EXPECT_EQ(ErrorOf([&] { MergeWinnersDatabases({good, nlohmann::json::array()}, {"good.json", "bad.json"}); })
                .rfind("bad.json: ", 0),
            0u);
  nlohmann::json wrong_kind = good;
  wrong_kind["kind"] = "kernel-tuner-cache";
  const std::string kind_error = ErrorOf([&] { MergeWinnersDatabases({wrong_kind}, {"kt.json"}); });
  EXPECT_EQ(kind_error.rfind("kt.json: ", 0), 0u) << kind_error;
  EXPECT_NE(kind_error.find("kernel-tuner-cache"), std::string::npos) << kind_error;
  nlohmann::json broken_report = good;
  broken_report["measurements"][0].erase("device_id");
  EXPECT_EQ(ErrorOf([&] { MergeWinnersDatabases({broken_report}, {"r.json"}); }).rfind("r.json: measurements[0]: ", 0),
            0u);
  nlohmann::json broken_db = WinnersDatabase(testing::SampleReport());
  broken_db["entries"][1]["vertex_bucket"] = "3k";
  const std::string db_error = ErrorOf([&] { MergeWinnersDatabases({good, broken_db}, {"a.json", "db.json"}); });
  EXPECT_EQ(db_error.rfind("db.json: entries[1]: ", 0), 0u) << db_error;
  EXPECT_THROW(MergeWinnersDatabases({good}, {}), Error);
}

}  // namespace
}  // namespace skintune::internal
