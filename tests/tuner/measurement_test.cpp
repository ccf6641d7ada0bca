// Measurements, their JSON form and the append-only cache (tuner/measurement.h).
#include "tuner/measurement.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "skintune/skintune.h"  // its Status beside the tuner's MeasureStatus: both in one file
#include "tests/common/scratch_dir.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

fs::path Scratch() { return skintune::internal::testing::ScratchDir("skintune_measurement_test"); }

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteAll(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

Measurement Sample(const std::string& key, MeasureStatus status) {
  Measurement m;
  m.device_id = "opencl:Portable Computing Language/cpu/3.1";
  m.dataset = "5000-b2";
  m.variant = ParseVariantKey(key);
  m.status = status;
  m.detail = status == MeasureStatus::kOk ? "" : "line 1\nline 2";
  if (status == MeasureStatus::kOk) {
    m.timing.median_ms = 1.5;
    m.timing.low_ms = 1.4;
    m.timing.high_ms = 1.6;
    m.timing.min_ms = 1.25;
    m.timing.max_ms = 2.0;
    m.timing.repetitions = 10;
    m.timing.tight = true;
    m.timing.clock = "OpenCL profiling stamps: a marker's END to the next marker's START";
    m.timing.flush_bytes = 1.0e8;
    m.timing.warmup = 3;
    m.timing.input_sets = 4;
    m.timing.burst_frames = 20;
    m.timing.footprint_bytes = 4.0e7;
    m.timing.copy_ms = 1.2;
    m.timing.frame_ms = 1.7;
    m.timing.sm_clock_mhz = 1980;
    m.timing.schedule = "2 threads x 16384-vertex chunks, streaming stores";
    m.timing.context = "the quickest of 6 contexts by launch start (a 4 KiB copy after the flush): 2.088 us";
    m.timing.launch_start_ms = 2.088e-3;
    m.gbps = 12.5;
    m.x_copy = 1.5 / 1.2;
  }
  m.bytes_per_frame = 18750000;  // 12.5 GB/s at 1.5 ms
  m.max_relative_error = status == MeasureStatus::kVerifyFailed ? std::numeric_limits<double>::infinity() : 1e-7;
  m.generator_version = "0.1.0";
  m.timestamp = "2026-11-22T13:39:17Z";
  return m;
}

void ExpectSame(const Measurement& a, const Measurement& b) {
  EXPECT_EQ(a.device_id, b.device_id);
  EXPECT_EQ(a.dataset, b.dataset);
  EXPECT_EQ(a.variant, b.variant);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.detail, b.detail);
  EXPECT_EQ(a.timing.median_ms, b.timing.median_ms);
  EXPECT_EQ(a.timing.min_ms, b.timing.min_ms);
  EXPECT_EQ(a.timing.max_ms, b.timing.max_ms);
  EXPECT_EQ(a.timing.warmup, b.timing.warmup);
  EXPECT_EQ(a.timing.repetitions, b.timing.repetitions);
  EXPECT_EQ(a.timing.input_sets, b.timing.input_sets);
  EXPECT_EQ(a.timing.burst_frames, b.timing.burst_frames);
  EXPECT_EQ(a.timing.footprint_bytes, b.timing.footprint_bytes);
  EXPECT_EQ(a.timing.copy_ms, b.timing.copy_ms);
  EXPECT_EQ(a.timing.low_ms, b.timing.low_ms);
  EXPECT_EQ(a.timing.high_ms, b.timing.high_ms);
  EXPECT_EQ(a.timing.tight, b.timing.tight);
  EXPECT_EQ(a.timing.clock, b.timing.clock);
  EXPECT_EQ(a.timing.flush_bytes, b.timing.flush_bytes);
  EXPECT_EQ(a.timing.frame_ms, b.timing.frame_ms);
  EXPECT_EQ(a.timing.sm_clock_mhz, b.timing.sm_clock_mhz);
  EXPECT_EQ(a.timing.schedule, b.timing.schedule);
  EXPECT_EQ(a.timing.context, b.timing.context);
  EXPECT_EQ(a.timing.launch_start_ms, b.timing.launch_start_ms);
  EXPECT_EQ(a.timing.version, b.timing.version);
  EXPECT_EQ(a.x_copy, b.x_copy);
  EXPECT_EQ(a.bytes_per_frame, b.bytes_per_frame);
  EXPECT_EQ(a.gbps, b.gbps);
  EXPECT_EQ(a.max_relative_error, b.max_relative_error);
  EXPECT_EQ(a.generator_version, b.generator_version);
  EXPECT_EQ(a.timestamp, b.timestamp);
  EXPECT_EQ(a.CacheKey(), b.CacheKey());
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(MeasureStatus, LivesBesideThePublicStatusInOneFile) {
  const Status public_status;  // skintune::Status, the public API's result
  EXPECT_TRUE(public_status.ok());
  EXPECT_STREQ(Name(MeasureStatus::kOk), "ok");
}

TEST(MeasureStatus, NamesRoundTrip) {
  for (MeasureStatus s : kAllMeasureStatuses) EXPECT_EQ(MeasureStatusFromName(Name(s)), s) << Name(s);
  EXPECT_STREQ(Name(MeasureStatus::kCompileFailed), "compile_failed");
  EXPECT_STREQ(Name(MeasureStatus::kTimeout), "timeout");
  EXPECT_STREQ(Name(MeasureStatus::kTooImprecise), "too_imprecise");
  EXPECT_EQ(ErrorOf([] { MeasureStatusFromName("slow"); }),
            "unknown status 'slow' (expected one of ok, invalid, compile_failed, launch_failed, verify_failed, "
            "timeout, too_imprecise)");
}

// A verified measurement with its error against the source, as the measurement job records it.
Measurement WithSourceError(double quantisation_rel) {
  Measurement m = Sample("opencl.b4.soa.unorm8.wg64", MeasureStatus::kOk);
  m.source_error.known = true;
  m.source_error.diagonal = 2.5;
  m.source_error.quantisation_rel = quantisation_rel;
  m.source_error.position_rel = quantisation_rel + 1e-7;
  m.source_error.position_abs = 2.5 * m.source_error.position_rel;
  return m;
}

TEST(Measurement, SourceErrorRoundTripsAndTheBudgetMakesTooImpreciseBothWays) {
  Measurement m = WithSourceError(1.6e-4);
  ApplyBudget(m, 1e-4);
  EXPECT_EQ(m.status, MeasureStatus::kTooImprecise);
  EXPECT_NE(m.detail.find("unorm8 weights cost 1.60e-04"), std::string::npos) << m.detail;
  const nlohmann::json j = m;
  EXPECT_EQ(j.at("status"), "too_imprecise");
  const Measurement back = nlohmann::json::parse(j.dump()).get<Measurement>();
  ExpectSame(back, m);
  EXPECT_TRUE(back.source_error.known);
  EXPECT_EQ(back.source_error.quantisation_rel, 1.6e-4);
  EXPECT_EQ(back.source_error.position_abs, m.source_error.position_abs);
  EXPECT_EQ(back.source_error.diagonal, 2.5);
  // A larger budget takes it back (a cached record judged by a later run).
  ApplyBudget(m, 1e-2);
  EXPECT_EQ(m.status, MeasureStatus::kOk);
  EXPECT_EQ(m.detail, "");
  // Exactly at the budget is within it; 0 admits exact formats only.
  Measurement exact = WithSourceError(0.0);
  ApplyBudget(exact, 0.0);
  EXPECT_EQ(exact.status, MeasureStatus::kOk);
  // Failures and records without a known error are left alone.
  Measurement failed = Sample("opencl.b2", MeasureStatus::kVerifyFailed);
  ApplyBudget(failed, 0.0);
  EXPECT_EQ(failed.status, MeasureStatus::kVerifyFailed);
  Measurement old = Sample("opencl.b2", MeasureStatus::kOk);
  ApplyBudget(old, 0.0);
  EXPECT_EQ(old.status, MeasureStatus::kOk);
  EXPECT_FALSE(nlohmann::json(old).contains("source_error"));
}

TEST(Measurement, BadSourceErrorsAreRefusedNamingTheField) {
  nlohmann::json j = WithSourceError(1e-3);
  j["source_error"].erase("diagonal");
  EXPECT_EQ(ErrorOf([&] { j.get<Measurement>(); }), "measurement: 'source_error': missing 'diagonal'");
  j = WithSourceError(1e-3);
  j["source_error"]["position_rel"] = "far";
  EXPECT_EQ(ErrorOf([&] { j.get<Measurement>(); }), "measurement: 'source_error': 'position_rel' must be a number");
  j = WithSourceError(1e-3);
  j["source_error"]["quantisation_rel"] = -1.0;
  EXPECT_NE(ErrorOf([&] { j.get<Measurement>(); }).find("'source_error.quantisation_rel' is -1"), std::string::npos);
  j = WithSourceError(1e-3);
  j["status"] = "too_imprecise";
  j.erase("source_error");
  EXPECT_EQ(ErrorOf([&] { j.get<Measurement>(); }), "measurement: status too_imprecise without 'source_error'");
}

// A kernel that passed a loose verification (or a record that claims one)
// with exact weights but an output 0.39 of the diagonal off the source: the
// budget held only the weights' error, so it was ok, won and was
// within_budget. The kernel's whole error counts, with its rounding allowed.
TEST(Measurement, TheKernelsWholeErrorAgainstTheSourceIsHeldToTheBudget) {
  Measurement wrong = WithSourceError(0.0);
  wrong.source_error.position_rel = 0.39;
  wrong.source_error.position_abs = 2.5 * 0.39;
  ApplyBudget(wrong, 1e-4);
  EXPECT_EQ(wrong.status, MeasureStatus::kTooImprecise);
  EXPECT_NE(wrong.detail.find("the kernel's output is off the source by 3.90e-01"), std::string::npos) << wrong.detail;
  // A verified kernel's own float32 rounding (~2e-7 of the diagonal) stays within even a budget of 0.
  Measurement rounded = WithSourceError(0.0);
  ApplyBudget(rounded, 0.0);
  EXPECT_EQ(rounded.status, MeasureStatus::kOk);
  rounded.source_error.position_rel = 2 * kKernelRoundingAllowance;
  rounded.source_error.position_abs = 2.5 * rounded.source_error.position_rel;
  ApplyBudget(rounded, 0.0);
  EXPECT_EQ(rounded.status, MeasureStatus::kTooImprecise);
}

// Counts and sizes of a timed record that no run can produce were taken from
// the cache and written into report.json: a footprint of "nan", -1 frames
// per burst, 0 input sets, a warm-up of -1, bytes whose GB/s overflow, an
// integer beyond int, a relative error no tolerance admits, a position_rel
// that is not position_abs / diagonal.
// An edit of a status-ok sample that makes it impossible, and what the
// error says of it.
using ImpossibleCase = std::pair<std::function<void(nlohmann::json&)>, std::string>;

// Each edited sample is refused as ImpossibleMeasurement, naming the figure.
void ExpectImpossible(const std::vector<ImpossibleCase>& cases) {
  for (const auto& [edit, message] : cases) {
    nlohmann::json j = Sample("opencl.b2", MeasureStatus::kOk);
    edit(j);
    const std::string error = ErrorOf([&] { (void)j.get<Measurement>(); });
    EXPECT_EQ(error.rfind("measurement: impossible figures: status ok with ", 0), 0u) << error;
    EXPECT_NE(error.find(message), std::string::npos) << error;
    EXPECT_THROW((void)j.get<Measurement>(), ImpossibleMeasurement);
  }
}

TEST(Measurement, ImpossibleCountsSizesAndErrorsAreRefusedNamingTheField) {
  const std::vector<ImpossibleCase> cases = {
      {[](nlohmann::json& j) { j["timing"]["footprint_bytes"] = "nan"; },
       "'footprint_bytes' is nan: must be a finite number >= 0"},
      {[](nlohmann::json& j) { j["timing"]["footprint_bytes"] = -1; }, "'footprint_bytes' is -1"},
      {[](nlohmann::json& j) { j["timing"]["burst_frames"] = -1; }, "'burst_frames' is -1: must be at least 1"},
      {[](nlohmann::json& j) { j["timing"]["input_sets"] = 0; }, "'input_sets' is 0: must be at least 1"},
      {[](nlohmann::json& j) { j["timing"]["warmup"] = -1; }, "'warmup' is -1: must be at least 0"},
      {[](nlohmann::json& j) { j["timing"]["version"] = 0; }, "'version' is 0: must be at least 1"},
      {[](nlohmann::json& j) {
         j["bytes_per_frame"] = 1e308;
         j["timing"] = {{"median_ms", 1e-3}, {"min_ms", 1e-3}, {"max_ms", 1e-3}, {"warmup", 1}, {"repetitions", 3},
                        {"input_sets", 1}, {"burst_frames", 8}, {"footprint_bytes", 1}, {"copy_ms", 0}};
         j["x_copy"] = 0;
         j["gbps"] = 1e300;
       },
       "'bytes_per_frame' 1e+308 / 'median_ms' 0.001 overflows"},
      {[](nlohmann::json& j) { j["max_relative_error"] = 0.5; },
       "'max_relative_error' is 0.500000: over the largest verification tolerance"},
  };
  ExpectImpossible(cases);
  nlohmann::json huge = Sample("opencl.b2", MeasureStatus::kOk);
  huge["timing"]["input_sets"] = 1000000000000000000;
  EXPECT_NE(ErrorOf([&] { (void)huge.get<Measurement>(); })
                .find("'input_sets' must be an integer from -2147483648 to 2147483647 (got 1000000000000000000)"),
            std::string::npos);
  nlohmann::json far = WithSourceError(1e-3);
  far["source_error"]["position_rel"] = 1e308;
  EXPECT_NE(ErrorOf([&] { (void)far.get<Measurement>(); })
                .find("'source_error.position_rel' is 1e+308 but position_abs / diagonal is 0.001000"),
            std::string::npos)
      << ErrorOf([&] { (void)far.get<Measurement>(); });
  // A failure's figures are never used, so never checked.
  nlohmann::json failed = Sample("opencl.b2", MeasureStatus::kTimeout);
  failed["timing"]["input_sets"] = 0;
  EXPECT_EQ(failed.get<Measurement>().status, MeasureStatus::kTimeout);
}

// The cache is input: what a resumed run does not take from it.
TEST(Measurement, AResumedRunMeasuresAgainWhatItCannotTrust) {
  const Measurement good = WithSourceError(0.0);
  EXPECT_EQ(MeasuredAgainOnResume(good, 1e-5), "");
  Measurement loose = good;
  loose.max_relative_error = 5e-4;  // verified under a tolerance of 1e-3, this run's is 1e-5
  EXPECT_NE(MeasuredAgainOnResume(loose, 1e-5), "");
  EXPECT_EQ(MeasuredAgainOnResume(loose, 1e-3), "");
  EXPECT_NE(MeasuredAgainOnResume(Sample("opencl.b2", MeasureStatus::kOk), 1e-5), "");  // no source error
  Measurement killed = Sample("opencl.b2", MeasureStatus::kLaunchFailed);
  killed.detail = std::string(kInterruptedDetail) + "worker process died: signal 9 (Killed)";
  EXPECT_NE(MeasuredAgainOnResume(killed, 1e-5), "");
  Measurement crashed = Sample("opencl.b2", MeasureStatus::kLaunchFailed);
  crashed.detail = "worker process died: signal 11 (Segmentation fault)";  // the variant's own doing
  EXPECT_EQ(MeasuredAgainOnResume(crashed, 1e-5), "");
}

TEST(Measurement, BadMaxErrorSaysWhy) {
  EXPECT_EQ(BadMaxError(1e-4), "");
  EXPECT_EQ(BadMaxError(0.0), "");
  for (double bad : {-1e-9, std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()})
    EXPECT_NE(BadMaxError(bad).find("must be a finite number >= 0"), std::string::npos) << bad;
}

TEST(Measurement, CacheKeyNamesDeviceGeneratorDatasetAndVariant) {
  const Measurement m = Sample("opencl.b2.soa.global.wg64", MeasureStatus::kOk);
  EXPECT_EQ(m.CacheKey(), "opencl:Portable Computing Language/cpu/3.1|0.1.0|timing 13|5000-b2|" + m.variant.Key());
  Measurement other = m;
  other.generator_version = "0.2.0";
  EXPECT_NE(other.CacheKey(), m.CacheKey());
  other = m;
  other.dataset = "5000-b2-random";
  EXPECT_NE(other.CacheKey(), m.CacheKey());
  other = m;
  other.timing.version = 1;
  EXPECT_NE(other.CacheKey(), m.CacheKey());
}

// A change of timing method measures everything again: a line written before
// timing versions (the old per-launch method) reads as version 1, and the
// current key never finds it.
TEST(MeasurementCache, FiguresOfTheOldTimingMethodAreNeverReused) {
  const fs::path dir = Scratch();
  const fs::path path = dir / "cache.jsonl";
  Measurement old = Sample("opencl.b2.soa.global.wg64", MeasureStatus::kOk);
  nlohmann::json line = old;
  line["timing"].erase("version");
  line["timing"].erase("burst_frames");
  line["timing"].erase("copy_ms");
  line["timing"].erase("footprint_bytes");
  line.erase("x_copy");
  WriteAll(path, line.dump() + "\n");
  MeasurementCache cache(path.string());
  ASSERT_EQ(cache.all().size(), 1u);
  EXPECT_EQ(cache.all().front().timing.version, 1);
  const Measurement fresh = Sample("opencl.b2.soa.global.wg64", MeasureStatus::kOk);
  EXPECT_EQ(fresh.timing.version, kTimingVersion);
  EXPECT_EQ(cache.Find(fresh.CacheKey()), nullptr);
  EXPECT_NE(cache.Find(cache.all().front().CacheKey()), nullptr);
}

// x_copy is the time over the same-size copy's, or 0 without a copy time.
TEST(Measurement, XCopyMustBeTheTimeOverTheCopyTime) {
  Measurement m = Sample("opencl.b2.soa.global.wg64", MeasureStatus::kOk);
  m.timing.copy_ms = 1.2;
  m.x_copy = 1.5 / 1.2;
  EXPECT_EQ(ImpossibleFigures(m), "");
  const nlohmann::json j = m;
  EXPECT_DOUBLE_EQ(j.get<Measurement>().x_copy, 1.25);
  m.x_copy = 0.9;
  EXPECT_NE(ImpossibleFigures(m).find("x_copy"), std::string::npos);
  m.timing.copy_ms = 0.0;
  EXPECT_NE(ImpossibleFigures(m).find("without a copy time"), std::string::npos);
  m.x_copy = 0.0;
  m.timing.copy_ms = -1.0;
  EXPECT_NE(ImpossibleFigures(m).find("copy_ms"), std::string::npos);
}

TEST(Measurement, JsonRoundTripKeepsEveryFieldIncludingInfinity) {
  for (MeasureStatus s : {MeasureStatus::kOk, MeasureStatus::kVerifyFailed, MeasureStatus::kTimeout}) {
    const Measurement m = Sample("cuda.b4.aos.local.v2s.wg256", s);
    const nlohmann::json j = m;
    EXPECT_EQ(j.at("status"), Name(s));
    ExpectSame(nlohmann::json::parse(j.dump()).get<Measurement>(), m);
  }
}

TEST(Measurement, FromJsonNamesTheBadField) {
  nlohmann::json j = Sample("opencl.b2", MeasureStatus::kOk);
  j["status"] = "fast";
  EXPECT_EQ(ErrorOf([&] { (void)j.get<Measurement>(); }).rfind("measurement: 'status': unknown status 'fast'", 0), 0u);
  j = Sample("opencl.b2", MeasureStatus::kOk);
  j.erase("device_id");
  EXPECT_EQ(ErrorOf([&] { (void)j.get<Measurement>(); }), "measurement: missing field 'device_id'");
  j = Sample("opencl.b2", MeasureStatus::kOk);
  j["timing"]["median_ms"] = "quick";
  EXPECT_EQ(ErrorOf([&] { (void)j.get<Measurement>(); }), "measurement: 'timing': 'median_ms' must be a number");
}

// docs/INPUTS.md "Measurements: one rule for every time": a status-ok measurement's figures obey physics
// wherever it is read; from_json (used by the cache, reports, replay and the
// worker's answers) refuses anything else, naming the field.
TEST(Measurement, OkWithoutTimingIsRefused) {
  nlohmann::json j = Sample("opencl.b2", MeasureStatus::kOk);
  j.erase("timing");
  EXPECT_EQ(ErrorOf([&] { (void)j.get<Measurement>(); }), "measurement: status ok without 'timing'");
  // A failure has no time to check: its timing may be absent.
  j = Sample("opencl.b2", MeasureStatus::kTimeout);
  j.erase("timing");
  EXPECT_EQ(j.get<Measurement>().status, MeasureStatus::kTimeout);
}

TEST(Measurement, ImpossibleTimesAreRefusedNamingTheField) {
  const std::vector<ImpossibleCase> cases = {
      {[](nlohmann::json& j) { j["timing"]["median_ms"] = 0; },
       "'median_ms' is 0: a time must be a positive, finite number"},
      {[](nlohmann::json& j) { j["timing"]["median_ms"] = -5; },
       "'median_ms' is -5: a time must be a positive, finite number"},
      {[](nlohmann::json& j) { j["timing"]["median_ms"] = "nan"; },
       "'median_ms' is nan: a time must be a positive, finite number"},
      {[](nlohmann::json& j) { j["timing"]["median_ms"] = "inf"; },
       "'median_ms' is inf: a time must be a positive, finite number"},
      {[](nlohmann::json& j) { j["timing"]["min_ms"] = 0; }, "'min_ms' is 0: a time must be"},
      {[](nlohmann::json& j) { j["timing"]["min_ms"] = 1.75; },
       "'min_ms' 1.75, 'median_ms' 1.5, 'max_ms' 2: must be in order (min <= median <= max)"},
      {[](nlohmann::json& j) { j["timing"]["max_ms"] = 1.25; }, "must be in order (min <= median <= max)"},
      {[](nlohmann::json& j) { j["timing"]["repetitions"] = 0; }, "'repetitions' is 0"},
      {[](nlohmann::json& j) { j["bytes_per_frame"] = 0; }, "'bytes_per_frame' is 0: a frame's bytes must be"},
      {[](nlohmann::json& j) { j["gbps"] = 125.0; },
       "'gbps' is 125 but 'bytes_per_frame' / 'median_ms' is 12.5 GB/s: they must agree"},
      {[](nlohmann::json& j) { j["gbps"] = "nan"; }, "'gbps' is nan: a bandwidth must be"},
      {[](nlohmann::json& j) { j["max_relative_error"] = "inf"; },
       "'max_relative_error' is inf: must be a finite number >= 0"},
  };
  ExpectImpossible(cases);
  // The writer's own output always reads back.
  EXPECT_NO_THROW((void)nlohmann::json(Sample("opencl.b2", MeasureStatus::kOk)).get<Measurement>());
}

TEST(MeasurementCache, ImpossibleLineIsAnErrorNamingFileAndLineAndTheFileIsKept) {
  const fs::path path = Scratch() / "cache.jsonl";
  const std::string good = nlohmann::json(Sample("opencl.b2.soa.global", MeasureStatus::kOk)).dump() + "\n";
  nlohmann::json no_timing = Sample("opencl.b2.soa.local", MeasureStatus::kOk);
  no_timing.erase("timing");
  nlohmann::json zero = Sample("opencl.b2.soa.constant", MeasureStatus::kOk);
  zero["timing"]["median_ms"] = 0.0;
  for (const auto& [bad, message] : {std::pair{no_timing, std::string("status ok without 'timing'")},
                                     std::pair{zero, std::string("'median_ms' is 0")}}) {
    const std::string text = good + bad.dump() + "\n" + good;
    WriteAll(path, text);
    const std::string error = ErrorOf([&] { MeasurementCache cache(path.string()); });
    EXPECT_EQ(error.rfind(path.string() + ":2: ", 0), 0u) << error;
    EXPECT_NE(error.find(message), std::string::npos) << error;
    EXPECT_EQ(ReadAll(path), text);
  }
}

TEST(MeasurementCache, AppendedMeasurementsAreThereWhenReopened) {
  const fs::path path = Scratch() / "cache.jsonl";
  const std::vector<Measurement> written = {Sample("opencl.b2.soa.global.wg64", MeasureStatus::kOk),
                                            Sample("opencl.b2.soa.local.wg64", MeasureStatus::kCompileFailed),
                                            Sample("opencl.b2.soa.constant.wg64", MeasureStatus::kVerifyFailed)};
  {
    MeasurementCache cache(path.string());
    EXPECT_TRUE(cache.all().empty());
    for (const Measurement& m : written) cache.Append(m);
    ASSERT_NE(cache.Find(written[1].CacheKey()), nullptr);
  }
  const std::string text = ReadAll(path);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 3);
  MeasurementCache cache(path.string());
  ASSERT_EQ(cache.all().size(), 3u);
  for (std::size_t i = 0; i < written.size(); ++i) {
    ExpectSame(cache.all()[i], written[i]);
    const Measurement* found = cache.Find(written[i].CacheKey());
    ASSERT_NE(found, nullptr);
    ExpectSame(*found, written[i]);
  }
  EXPECT_EQ(cache.Find("nothing|0.1.0|5000-b2|opencl.b1"), nullptr);
}

TEST(MeasurementCache, RacesAreKeptBesideTheMeasurementsAndFoundWhenReopened) {
  const fs::path path = Scratch() / "cache.jsonl";
  RaceRecord race;
  race.device_id = "opencl:p/d/1";
  race.lang = Lang::kOpenCl;
  race.dataset = "5000-b2";
  race.decided = true;
  RaceRecord::Entry fastest;
  fastest.variant = ParseVariantKey("opencl.b2.soa.global.wg64");
  fastest.interval = {0.010, 0.009, 0.011, 30};
  fastest.verdict = RaceVerdict::kLeader;
  RaceRecord::Entry slower = fastest;
  slower.variant = ParseVariantKey("opencl.b2.soa.local.wg64");
  slower.interval = {0.020, 0.019, 0.021, 30};
  slower.verdict = RaceVerdict::kSeparated;
  race.entries = {fastest, slower};
  const Measurement m = Sample("opencl.b2.soa.global.wg64", MeasureStatus::kOk);
  {
    MeasurementCache cache(path.string());
    cache.Append(m);
    cache.AppendRace("the key", race);
    ASSERT_NE(cache.FindRace("the key"), nullptr);
  }
  MeasurementCache cache(path.string());
  EXPECT_EQ(cache.all().size(), 1u);  // a race is no measurement
  const RaceRecord* found = cache.FindRace("the key");
  ASSERT_NE(found, nullptr);
  EXPECT_EQ(RaceJson(*found), RaceJson(race));
  EXPECT_EQ(cache.FindRace("another key"), nullptr);
}

TEST(MeasurementCache, MalformedRaceLineIsAnErrorNamingFileAndLine) {
  const fs::path path = Scratch() / "cache.jsonl";
  const std::string good = nlohmann::json(Sample("opencl.b2", MeasureStatus::kOk)).dump() + "\n";
  const std::string bad = R"({"race_key": "k", "race": {"device_id": "d", "lang": "opencl", "dataset": "x", )"
                          R"("decided": true, "detail": "", "entries": [{"variant": "opencl.b2", "median_ms": 1, )"
                          R"("low_ms": 2, "high_ms": 3, "samples": 5, "verdict": "fastest"}]}})";
  WriteAll(path, good + bad + "\n");
  const std::string error = ErrorOf([&] { MeasurementCache cache(path.string()); });
  EXPECT_EQ(error.rfind(path.string() + ":2: malformed race (", 0), 0u) << error;
  EXPECT_NE(error.find("low_ms <= median_ms"), std::string::npos) << error;
  EXPECT_EQ(ReadAll(path), good + bad + "\n");  // never modified
}

TEST(MeasurementCache, TornLastLineIsCutOffAndIgnored) {
  const fs::path path = Scratch() / "cache.jsonl";
  const Measurement a = Sample("opencl.b2.soa.global.wg64", MeasureStatus::kOk);
  const Measurement b = Sample("opencl.b2.soa.local.wg64", MeasureStatus::kOk);
  const std::string good = nlohmann::json(a).dump() + "\n";
  const std::string torn = nlohmann::json(b).dump().substr(0, 57);  // killed mid-write
  WriteAll(path, good + torn);
  {
    MeasurementCache cache(path.string());
    ASSERT_EQ(cache.all().size(), 1u);
    ExpectSame(cache.all()[0], a);
    EXPECT_EQ(cache.Find(b.CacheKey()), nullptr);
    EXPECT_EQ(ReadAll(path), good);  // cut off, so the next record starts on its own line
    cache.Append(b);
  }
  EXPECT_EQ(ReadAll(path), good + nlohmann::json(b).dump() + "\n");
  MeasurementCache cache(path.string());
  EXPECT_EQ(cache.all().size(), 2u);
}

TEST(MeasurementCache, MalformedCompleteLineIsAnErrorNamingFileAndLine) {
  const fs::path path = Scratch() / "cache.jsonl";
  const std::string good = nlohmann::json(Sample("opencl.b2", MeasureStatus::kOk)).dump() + "\n";
  WriteAll(path, good + "{\"device_id\": oops}\n" + good);
  const std::string error = ErrorOf([&] { MeasurementCache cache(path.string()); });
  EXPECT_EQ(error.rfind(path.string() + ":2: malformed measurement", 0), 0u) << error;

  nlohmann::json bad = Sample("opencl.b2", MeasureStatus::kOk);
  bad["status"] = "fast";
  WriteAll(path, bad.dump() + "\n");
  const std::string status_error = ErrorOf([&] { MeasurementCache cache(path.string()); });
  EXPECT_EQ(status_error.rfind(path.string() + ":1: malformed measurement: 'status': unknown status 'fast'", 0), 0u)
      << status_error;
  const std::string before = ReadAll(path);
  EXPECT_EQ(before, bad.dump() + "\n");  // never modified
}

TEST(MeasurementCache, UnwritablePathIsAnErrorNamingTheFile) {
  const fs::path dir = Scratch();
  WriteAll(dir / "file", "not a directory");
  const std::string path = (dir / "file" / "cache.jsonl").string();
  const std::string error = ErrorOf([&] { MeasurementCache cache(path); });
  EXPECT_EQ(error.rfind(path + ": cannot open the measurement cache for appending (", 0), 0u) << error;
  const std::string dir_error = ErrorOf([&] { MeasurementCache cache(dir.string()); });
  EXPECT_EQ(dir_error.rfind(dir.string() + ": ", 0), 0u) << dir_error;
}

TEST(MeasurementCache, OnlyOneWriterAtATime) {
  const fs::path path = Scratch() / "cache.jsonl";
  MeasurementCache first(path.string());
  EXPECT_EQ(ErrorOf([&] { MeasurementCache second(path.string()); }),
            path.string() + ": in use by another skintune tune (locked)");
}

}  // namespace
}  // namespace skintune::internal
