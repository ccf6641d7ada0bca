// skintune: the tuning report (versioned JSON, schema in
// configs/report.schema.json), its winners, the T4 export, and the winners
// database merged from many machines.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>  // TuningReport holds a json by value (json_fwd.hpp is not enough)

#include "runtime/winners_db.h"
#include "tuner/timing_options.h"
#include "tuner/measurement.h"
#include "tuner/race_record.h"

namespace skintune::internal {

// 1.1.0: winners name their measured vertex count; 1.2.0: max_error, too_imprecise,
// source_error, a winner per precision class; timing version 2 (bursts, the physical
// cache, the same-size copy: x_copy); 1.3.0: datasets and winners name their scene shape
// (shape, instances, meshes), and winners are kept per shape; 1.4.0: timing
// version 5 (kernel time with its interval, frame time), the races of each
// search, tie_margin, and each winner's interval and tie set.
inline constexpr const char* kReportSchemaVersion = "1.20.0";

struct DatasetInfo {
  std::string key;          // a scene key (model/scene.h): a dataset, a glTF path, instances, a batch
  std::size_t vertices = 0;  // the scene's total (K x the mesh's; the sum of a batch's meshes)
  int influences = 0;   // the mesh's slots per vertex (a batch's: the largest of its meshes')
  int joints = 0;       // per instance (a batch's: every mesh's)
  SceneKind shape = SceneKind::kSingle;
  int instances = 1;
  int meshes = 1;
  int morph_targets = 0;  // the mesh's morph targets (0: none; 1.11.0)
  bool cross_fades = false;  // "-animblend": its instances cross-fade two clips (1.14.0)
};

struct TuningReport {
  std::string created;                        // UTC ISO 8601
  std::string config;                         // config file or "default"
  std::string strategy;                       // "exhaustive", "random", "coordinate"
  double max_error = kDefaultBudget;        // the run's error budget (TuneConfig::max_error)
  nlohmann::json machine;                     // hostname, os, cpu model, logical cpus, memory
  std::vector<DeviceIdentity> devices;
  std::map<std::string, double> copy_bandwidth_gbps;  // by DeviceIdentity::Id()
  std::vector<std::string> skipped;           // APIs and devices not measured, with the reason
  std::vector<DatasetInfo> datasets;
  std::vector<Measurement> measurements;
  // Timing version 5: the margin within which kernel times tie (TimingOptions::tie_margin), and the races.
  double tie_margin = TimingOptions{}.tie_margin;
  // The margin of a device that is the host's CPU (TimingOptions::host_tie_margin; 1.5.0).
  double host_tie_margin = TimingOptions{}.host_tie_margin;
  // The margin `device_id`'s candidates are judged at (host_tie_margin for a CPU device).
  double TieMarginOf(const std::string& device_id) const;
  // The spreads that widen the tie sets (TimingOptions::process_spread; 1.6.0:
  // an older report's are 0, its tie sets as it had them).
  double process_spread = TimingOptions{}.process_spread;
  double host_process_spread = TimingOptions{}.host_process_spread;
  double TieSpreadOf(const std::string& device_id) const;
  // Where the winner is picked (TimingOptions::choose_in_tie_set; 1.8.0: an
  // older report's among its contenders, its winners as it had them).
  bool choose_in_tie_set = TimingOptions{}.choose_in_tie_set;
  bool host_choose_in_tie_set = TimingOptions{}.host_choose_in_tie_set;
  // Within the tie set, only among the unseparated (TimingOptions::
  // choose_unseparated; 1.20.0: an older report's among its whole tie set).
  bool choose_unseparated = TimingOptions{}.choose_unseparated;
  bool host_choose_unseparated = TimingOptions{}.host_choose_unseparated;
  Choice ChoiceOf(const std::string& device_id) const;
  std::vector<RaceRecord> races;
};

// VertexBucket (the paper's vertex counts as buckets) and the database format
// itself live in runtime/winners_db.h: the runtime reads what this writes.

struct Winner {
  std::string device_id;
  std::string backend;       // "opencl", "cuda", "gl"
  Lang lang = Lang::kOpenCl;
  int influences = 0;
  std::size_t vertices = 0;   // the dataset's vertex count: every measured count keeps its winner
  std::string vertex_bucket;  // VertexBucket(vertices)
  SceneKind shape = SceneKind::kSingle;  // the dataset's scene: every shape keeps its winner
  int instances = 1;
  int meshes = 1;
  int morph_targets = 0;      // the dataset's morph targets: every count keeps its winner
  bool cross_fades = false;   // the dataset's crowd cross-fades clips: kept apart from one that does not
  std::string dataset;
  Variant variant;
  double tie_margin = 0.0;    // the margin it was judged at (TuningReport::TieMarginOf; 0: unknown)
  double median_ms = 0.0;     // its kernel time
  double low_ms = 0.0, high_ms = 0.0;  // its 95% interval (the race's, where it was raced)
  // The fastest candidate of its key, as it was judged (the winner's own
  // figures where the tie-break picked the fastest): what a precision class
  // is judged by against the others (BudgetWinners). Not written to reports;
  // 0: unknown, the winner's own figures stand in.
  double fastest_ms = 0.0, fastest_low_ms = 0.0, fastest_high_ms = 0.0;
  double frame_ms = 0.0;      // its frame time (0: not measured)
  // The candidates that cannot be told from the fastest (the fastest among
  // them, the winner too), in key order; the rule that picked the winner
  // among them: fewest bytes moved, then lower error against the source, then
  // fewer storage limits (StorageLimits), then key.
  std::vector<std::string> tie_set;
  bool within_noise = false;  // every candidate of the key is in the tie set
  std::string judged_by;      // "race" or "intervals" (no race covered it)
  double gbps = 0.0;
  double bytes_per_frame = 0.0;  // what its frame moves (the tie-break's first key)
  double copy_fraction = 0.0;  // gbps / the device's copy bandwidth (0 when unknown)
  double x_copy = 0.0;         // median_ms / the same-size copy's (Measurement::x_copy; 0 when unknown)
  // The precision class is variant.weight, and half morph offsets: one winner per class.
  bool within_budget = true;      // status ok (not too_imprecise) under the report's max_error
  SourceError source_error;       // against the unquantised source
  double max_relative_error = 0.0;  // against the gold of its quantised weights
};

// The winning verified (ok or too_imprecise) measurement per (device,
// language, influences, measured vertex count, scene shape with its instance
// and mesh counts, precision class = weight format), in that key order: the
// candidates of a key are judged against the fastest at the report's
// tie_margin (JudgeIntervals, on the race's intervals where the race
// covered them), and TieBreak picks among the tie set, so the same
// landscape gives the same winner whatever the measurement order. A variant
// that failed verification is never a winner. The run's winner of a key is
// the fastest one within_budget (BudgetWinners); the others stay for callers
// with a larger budget.
std::vector<Winner> ComputeWinners(const TuningReport& report);
// Of `winners`, the one within budget per (device, language, influences,
// measured vertex count, shape): the precision classes judged against the
// fastest at `tie_margin`, each by its own fastest candidate, and TieBreak
// among the tied classes' winners (so a class a hair faster by noise does
// not win by it): what the tuning chose at its budget. A class's winner may
// be picked among its tie set, up to the margin behind its class's fastest;
// judged by that pick, a class would be let in at the margin twice over
// (PoCL on the 2-core machine, 2026-12-01: a unorm8 class 1.17x behind the
// f32 class's pick and 1.30x behind its fastest was chosen, at a 25%
// margin, in one run of three).
// A winner's own tie_margin is used where it has one, else `tie_margin`.
std::vector<Winner> BudgetWinners(const std::vector<Winner>& winners, double tie_margin);
// A precision class over the budget that is faster than the winner within it
// of the same row (device, language, influences, measured vertex count,
// shape): its kernel time below the chosen one's and outside the tie margin
// (the two judged as BudgetWinners judges classes: the chosen one separated
// from it). The winners database keeps it for callers with a larger budget.
struct FasterOverBudget {
  Winner over;    // the class over the budget
  Winner chosen;  // the row's winner within the budget (BudgetWinners)
};
// Of `winners` (ComputeWinners), every class over the budget faster than its
// row's chosen winner beyond `tie_margin`, in the order of `winners`; a row
// with no winner within the budget has none.
std::vector<FasterOverBudget> FasterClassesOverBudget(const std::vector<Winner>& winners, double tie_margin);
// "opencl 100k-b4 unorm8 0.15 ms against f32 0.3 ms": the language, dataset,
// precision class and kernel time of both.
std::string Describe(const FasterOverBudget& faster);

nlohmann::json ReportToJson(const TuningReport& report);
// Throws Error("<context>: ...") naming the element for a malformed report.
TuningReport ReportFromJson(const nlohmann::json& json, const std::string& context);

// The T4 autotuning results format (github.com/odgaard/TuningSchema, T4 branch):
// schema_version, metadata, results[] with configuration, times, invalidity, correctness.
nlohmann::json ReportToT4(const TuningReport& report);

// Winners database (runtime/winners_db.h): {"schema_version", "kind": "skintune-winners-db",
// "entries": [...]}, one entry per (device id with driver, language, influences, measured vertex count,
// precision class: every class's winner, within the run's budget or not, with its error),
// each naming the device's platform, vendor, name, driver and type. Merging takes reports and/or
// databases; for the same device+driver the newest report wins (by `created`).
nlohmann::json WinnersDatabase(const TuningReport& report);
nlohmann::json MergeWinnersDatabases(const std::vector<nlohmann::json>& reports_or_databases,
                                     const std::vector<std::string>& names_for_errors);

}  // namespace skintune::internal
