#include "tuner/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <tuple>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "runtime/backend_table.h"
#include "runtime/json_fields.h"
#include "runtime/winners_db.h"

namespace skintune::internal {

namespace {

using namespace json_fields;

constexpr const char* kReportKind = "skintune-report";

void CheckReportHeader(const nlohmann::json& json, const std::string& context) {
  CheckHeader(json, context, kReportKind, kReportSchemaVersion);
}

std::string BackendOf(const TuningReport& report, const std::string& device_id) {
  for (const DeviceIdentity& d : report.devices)
    if (d.Id() == device_id) return d.backend;
  return device_id.substr(0, device_id.find(':'));  // "<backend>:<platform>/<name>/<driver>"
}

nlohmann::json WinnerJson(const Winner& w) {
  nlohmann::json j = {{"device_id", w.device_id},   {"backend", w.backend},
                      {"lang", Name(w.lang)},       {"influences", w.influences},
                      {"vertices", w.vertices},     {"vertex_bucket", w.vertex_bucket}, {"dataset", w.dataset},
                      {"variant", w.variant},       {"median_ms", w.median_ms},
                      {"gbps", w.gbps},             {"copy_fraction", w.copy_fraction},
                      {"precision_class", Name(w.variant.weight)}, {"within_budget", w.within_budget},
                      {"max_relative_error", w.max_relative_error}, {"x_copy", w.x_copy},
                      {"shape", SceneKindName(w.shape)}, {"instances", w.instances}, {"meshes", w.meshes},
                      {"morph_targets", w.morph_targets}, {"cross_fades", w.cross_fades}};
  if (w.source_error.known) j["source_error"] = SourceErrorJson(w.source_error);
  j["low_ms"] = w.low_ms;
  j["high_ms"] = w.high_ms;
  j["frame_ms"] = w.frame_ms;
  j["tie_set"] = w.tie_set;
  j["within_noise"] = w.within_noise;
  j["judged_by"] = w.judged_by;
  return j;
}

// The merge key of a winner / database entry: every measured vertex count,
// scene shape (with its instance or mesh count), precision class (weight
// format, and the morph offsets' format: float32 or half), skinning method
// (linear, or dual quaternions: a different result, never one entry's rival)
// and whether it applies morph targets (a mesh with them takes only such
// entries) keeps its own, as does the format of the skinned normals (what the
// user's consumer reads, not a choice of the tuner's).
// A row (WinnerRow, runtime/winners_db.h); then the precision class: weight
// format, half morph offsets.
using RowKey = WinnerRow;
using EntryKey = std::tuple<RowKey, int, bool>;

template <typename W>  // Winner or WinnersEntry
EntryKey KeyOf(const W& w) {
  return {RowOf(w), static_cast<int>(w.variant.weight), MorphHalf(w.variant)};
}

nlohmann::json DatasetJson(const DatasetInfo& d) {
  return {{"key", d.key},       {"vertices", d.vertices},         {"influences", d.influences},
          {"joints", d.joints}, {"shape", SceneKindName(d.shape)}, {"instances", d.instances},
          {"meshes", d.meshes}, {"morph_targets", d.morph_targets}, {"cross_fades", d.cross_fades}};
}

// The report's winners as database entries, with the device's identity (the
// runtime's fallback chain matches on vendor and type).
std::vector<WinnersEntry> EntriesOf(const TuningReport& report) {
  std::vector<WinnersEntry> entries;
  for (Winner& w : ComputeWinners(report)) {
    WinnersEntry e;
    e.device_id = w.device_id;
    const DeviceIdParts parts = SplitDeviceId(w.device_id);
    e.backend = w.backend;
    e.platform = parts.platform;
    e.device_name = parts.name;
    e.driver_version = parts.driver_version;
    for (const DeviceIdentity& d : report.devices) {
      if (d.Id() != w.device_id) continue;
      e.vendor = d.vendor;
      e.device_type = d.type;
    }
    e.lang = w.lang;
    e.influences = w.influences;
    e.vertices = w.vertices;
    e.vertex_bucket = w.vertex_bucket;
    e.shape = w.shape;
    e.instances = w.instances;
    e.meshes = w.meshes;
    e.morph_targets = w.morph_targets;
    e.cross_fades = w.cross_fades;
    e.dataset = w.dataset;
    e.variant = w.variant;
    e.median_ms = w.median_ms;
    e.gbps = w.gbps;
    e.copy_fraction = w.copy_fraction;
    e.x_copy = w.x_copy;
    e.source_error = w.source_error;
    e.max_relative_error = w.max_relative_error;
    e.created = report.created;
    e.source = report.config + " (" + report.strategy + ")";
    entries.push_back(std::move(e));
  }
  return entries;
}

}  // namespace

namespace {

// The race interval of `m` where a race of its device, language and dataset measured it.
const Interval* RacedInterval(const TuningReport& report, const Measurement& m) {
  for (const RaceRecord& r : report.races) {
    if (r.device_id != m.device_id || r.lang != m.variant.lang || r.dataset != m.dataset || !r.detail.empty()) continue;
    for (const RaceRecord::Entry& e : r.entries)
      if (e.variant.Key() == m.variant.Key()) return &e.interval;
  }
  return nullptr;
}

// The interval of `m`'s kernel time: the race's, else its own (a report
// before timing version 5 has none: its median alone).
Interval IntervalOf(const TuningReport& report, const Measurement& m) {
  if (const Interval* raced = RacedInterval(report, m)) return *raced;
  Interval i;
  i.median = m.timing.median_ms;
  const bool has = m.timing.low_ms > 0.0 && m.timing.high_ms >= m.timing.low_ms;
  i.low = has ? m.timing.low_ms : m.timing.median_ms;
  i.high = has ? m.timing.high_ms : m.timing.median_ms;
  i.samples = static_cast<std::size_t>(std::max(m.timing.repetitions, 1));
  return i;
}

}  // namespace

double TuningReport::TieMarginOf(const std::string& device_id) const {
  TimingOptions margins;
  if (tie_margin > 0.0) margins.tie_margin = tie_margin;
  margins.host_tie_margin = host_tie_margin > 0.0 ? host_tie_margin : margins.tie_margin;
  for (const DeviceIdentity& d : devices)
    if (d.Id() == device_id) return margins.MarginFor(d);
  return margins.tie_margin;
}

double TuningReport::TieSpreadOf(const std::string& device_id) const {
  TimingOptions spreads;
  spreads.process_spread = process_spread;
  spreads.host_process_spread = host_process_spread;
  for (const DeviceIdentity& d : devices)
    if (d.Id() == device_id) return spreads.SpreadFor(d);
  return process_spread;
}

Choice TuningReport::ChoiceOf(const std::string& device_id) const {
  TimingOptions choices;
  choices.choose_in_tie_set = choose_in_tie_set;
  choices.host_choose_in_tie_set = host_choose_in_tie_set;
  choices.choose_unseparated = choose_unseparated;
  choices.host_choose_unseparated = host_choose_unseparated;
  for (const DeviceIdentity& d : devices)
    if (d.Id() == device_id) return choices.ChoiceFor(d);
  return choices.OwnChoice();
}

namespace {

// A report is input: an ok the kernel's own error belies is not within budget.
bool WithinBudget(const Measurement& m) {
  return m.status == MeasureStatus::kOk && KernelAddsOnlyRounding(m.source_error);
}

// Keeps the measurements of a row's class that decide its winner; whether the
// race measured them.
bool KeepDeciders(const TuningReport& report, std::vector<const Measurement*>& members) {
  // Within the budget where any of them is: a faster variant the budget rules
  // out (a baked form whose blends lose a third of the diagonal, in the same
  // weight format) never hides one it admits from the run's choice, which
  // takes only winners within it.
  const auto within = [](const Measurement* m) { return WithinBudget(*m); };
  if (std::any_of(members.begin(), members.end(), within))
    std::erase_if(members, [&](const Measurement* m) { return !within(m); });
  // Where the race measured some of them, it alone decides: the search's
  // figures of the others came minutes earlier, under other conditions,
  // and the race left them out as separated or beyond the neighbourhood.
  const auto raced = [&](const Measurement* m) { return RacedInterval(report, *m) != nullptr; };
  if (!std::any_of(members.begin(), members.end(), raced)) return false;
  std::erase_if(members, [&](const Measurement* m) { return !raced(m); });
  return true;
}

}  // namespace

std::vector<Winner> ComputeWinners(const TuningReport& report) {
  std::map<std::string, const DatasetInfo*> datasets;
  for (const DatasetInfo& d : report.datasets) datasets[d.key] = &d;
  std::map<EntryKey, std::vector<const Measurement*>> groups;
  std::map<EntryKey, Winner> shape;  // each key's fields but the variant's
  for (const Measurement& m : report.measurements) {
    if (!IsTimed(m.status)) continue;  // a failed variant is never a winner
    if (!ImpossibleFigures(m).empty()) continue;   // nor an impossible time (readers refuse one anyway)
    const auto dataset = datasets.find(m.dataset);
    if (dataset == datasets.end()) {
      throw Error("report: a measurement is of dataset '" + m.dataset + "', which is not in its datasets");
    }
    Winner w;
    w.device_id = m.device_id;
    w.lang = m.variant.lang;
    w.influences = m.variant.influences;
    w.vertices = dataset->second->vertices;
    w.vertex_bucket = VertexBucket(w.vertices);
    w.shape = dataset->second->shape;
    w.instances = dataset->second->instances;
    w.meshes = dataset->second->meshes;
    w.morph_targets = dataset->second->morph_targets;
    w.cross_fades = dataset->second->cross_fades;
    w.variant = m.variant;
    const EntryKey key = KeyOf(w);
    groups[key].push_back(&m);
    shape.emplace(key, std::move(w));
  }
  std::vector<Winner> out;
  for (auto& [key, members] : groups) {
    const bool raced = KeepDeciders(report, members);
    std::vector<RaceEntry> entries;
    std::vector<Interval> intervals;
    for (const Measurement* m : members) {
      entries.push_back(RaceEntryOf(*m));
      intervals.push_back(IntervalOf(report, *m));
    }
    const double margin = report.TieMarginOf(members.front()->device_id);
    const std::string& device = members.front()->device_id;
    const RaceOutcome outcome =
        JudgeIntervals(intervals, entries, margin, report.TieSpreadOf(device), report.ChoiceOf(device));
    const Measurement& m = *members[outcome.winner];
    Winner w = shape.at(key);
    w.tie_margin = margin;
    w.backend = BackendOf(report, m.device_id);
    w.dataset = m.dataset;
    w.variant = m.variant;
    w.median_ms = outcome.intervals[outcome.winner].median;
    w.low_ms = outcome.intervals[outcome.winner].low;
    w.high_ms = outcome.intervals[outcome.winner].high;
    w.fastest_ms = outcome.intervals[outcome.fastest].median;
    w.fastest_low_ms = outcome.intervals[outcome.fastest].low;
    w.fastest_high_ms = outcome.intervals[outcome.fastest].high;
    w.frame_ms = m.timing.frame_ms;
    for (const std::size_t i : outcome.tied) w.tie_set.push_back(entries[i].key);
    std::sort(w.tie_set.begin(), w.tie_set.end());
    w.within_noise = outcome.all_within_noise;
    w.judged_by = raced ? "race" : "intervals";
    w.gbps = m.gbps;
    w.bytes_per_frame = m.bytes_per_frame;
    const auto copy = report.copy_bandwidth_gbps.find(m.device_id);
    w.copy_fraction = copy != report.copy_bandwidth_gbps.end() && copy->second > 0.0 ? m.gbps / copy->second : 0.0;
    w.x_copy = m.x_copy;
    w.within_budget = WithinBudget(m);
    w.source_error = m.source_error;
    w.max_relative_error = m.max_relative_error;
    out.push_back(std::move(w));
  }
  return out;
}

namespace {

// A precision class as JudgeIntervals takes it (BudgetWinners): its fastest
// candidate's interval (the winner's own where that is unknown), and what
// the tie-break reads of its winner.
Interval IntervalOf(const Winner& w) {
  const bool fastest = w.fastest_ms > 0.0;
  Interval i;
  i.median = fastest ? w.fastest_ms : w.median_ms;
  const double low = fastest ? w.fastest_low_ms : w.low_ms, high = fastest ? w.fastest_high_ms : w.high_ms;
  i.low = low > 0.0 ? low : i.median;
  i.high = high >= i.median ? high : i.median;
  i.samples = 1;
  return i;
}

RaceOutcome JudgeWinners(const std::vector<const Winner*>& members, double tie_margin) {
  std::vector<RaceEntry> entries;
  std::vector<Interval> intervals;
  for (const Winner* w : members) {
    entries.push_back(RaceEntryOf(*w));
    intervals.push_back(IntervalOf(*w));
  }
  // The winners' own margin (their device's) where they carry one.
  const double own = members.front()->tie_margin > 0.0 ? members.front()->tie_margin : tie_margin;
  return JudgeIntervals(intervals, entries, own > 0.0 ? own : TimingOptions{}.tie_margin);
}

std::string Milliseconds(double ms) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4g ms", ms);
  return text;
}

}  // namespace

std::vector<Winner> BudgetWinners(const std::vector<Winner>& winners, double tie_margin) {
  std::map<RowKey, std::vector<const Winner*>> classes;
  for (const Winner& w : winners) {
    if (w.within_budget) classes[RowOf(w)].push_back(&w);
  }
  // The precision classes' winners judged as one landscape: a class within
  // the margin of the fastest ties with it, and the tie-break decides.
  std::vector<Winner> out;
  for (const auto& [key, members] : classes) out.push_back(*members[JudgeWinners(members, tie_margin).winner]);
  return out;
}

std::vector<FasterOverBudget> FasterClassesOverBudget(const std::vector<Winner>& winners, double tie_margin) {
  const std::vector<Winner> chosen = BudgetWinners(winners, tie_margin);
  std::map<RowKey, const Winner*> chosen_of_row;
  for (const Winner& w : chosen) chosen_of_row[RowOf(w)] = &w;
  std::vector<FasterOverBudget> out;
  for (const Winner& w : winners) {
    const auto row = chosen_of_row.find(RowOf(w));
    if (w.within_budget || row == chosen_of_row.end()) continue;
    const RaceOutcome outcome = JudgeWinners({row->second, &w}, tie_margin);
    if (outcome.fastest == 1 && outcome.verdicts[0] == RaceVerdict::kSeparated) out.push_back({w, *row->second});
  }
  return out;
}

std::string Describe(const FasterOverBudget& f) {
  return std::string(Name(f.over.lang)) + " " + f.over.dataset + " " + Name(f.over.variant.weight) + " " +
         Milliseconds(f.over.median_ms) + " against " + Name(f.chosen.variant.weight) + " " +
         Milliseconds(f.chosen.median_ms);
}

nlohmann::json ReportToJson(const TuningReport& report) {
  nlohmann::json out;
  out["schema_version"] = kReportSchemaVersion;
  out["kind"] = kReportKind;
  out["created"] = report.created;
  out["config"] = report.config;
  out["strategy"] = report.strategy;
  out["max_error"] = report.max_error;
  out["machine"] = report.machine.is_null() ? nlohmann::json::object() : report.machine;
  out["devices"] = nlohmann::json::array();
  for (const DeviceIdentity& d : report.devices) {
    nlohmann::json dj = d;
    dj["id"] = d.Id();
    out["devices"].push_back(std::move(dj));
  }
  out["copy_bandwidth_gbps"] = nlohmann::json::object();
  for (const auto& [id, gbps] : report.copy_bandwidth_gbps) out["copy_bandwidth_gbps"][id] = gbps;
  out["skipped"] = report.skipped;
  out["datasets"] = nlohmann::json::array();
  for (const DatasetInfo& d : report.datasets) out["datasets"].push_back(DatasetJson(d));
  out["measurements"] = nlohmann::json::array();
  for (const Measurement& m : report.measurements) out["measurements"].push_back(m);
  out["winners"] = nlohmann::json::array();
  const std::vector<Winner> winners = ComputeWinners(report);
  std::set<std::pair<std::string, std::string>> chosen;  // (device, variant key) of the budget winners
  for (const Winner& w : BudgetWinners(winners, report.tie_margin)) chosen.insert({w.device_id, w.variant.Key() + "|" + w.dataset});
  for (const Winner& w : winners) {
    nlohmann::json j = WinnerJson(w);
    j["chosen"] = chosen.count({w.device_id, w.variant.Key() + "|" + w.dataset}) > 0;
    out["winners"].push_back(std::move(j));
  }
  out["tie_margin"] = report.tie_margin;
  out["host_tie_margin"] = report.host_tie_margin;
  out["process_spread"] = report.process_spread;
  out["host_process_spread"] = report.host_process_spread;
  out["choose_in_tie_set"] = report.choose_in_tie_set;
  out["host_choose_in_tie_set"] = report.host_choose_in_tie_set;
  out["choose_unseparated"] = report.choose_unseparated;
  out["host_choose_unseparated"] = report.host_choose_unseparated;
  out["races"] = nlohmann::json::array();
  for (const RaceRecord& r : report.races) out["races"].push_back(RaceJson(r));
  return out;
}

namespace {

// The report's sections, each read into `r` with its errors naming the
// element ("<context>: devices[2]: ...").

void ReadDevices(const nlohmann::json& json, const std::string& context, TuningReport& r) {
  const nlohmann::json& devices = At(context, "devices", [&]() -> const nlohmann::json& { return Array(json, "devices"); });
  for (std::size_t i = 0; i < devices.size(); ++i) {
    r.devices.push_back(At(context, "devices[" + std::to_string(i) + "]", [&] {
      DeviceIdentity d = devices[i].get<DeviceIdentity>();
      if (devices[i].contains("id") && devices[i]["id"] != d.Id()) {
        throw Error("'id' " + devices[i]["id"].dump() + " does not match the identity (" + d.Id() + ")");
      }
      return d;
    }));
  }
}

void ReadCopyBandwidths(const nlohmann::json& json, const std::string& context, TuningReport& r) {
  const nlohmann::json& copy = At(context, "copy_bandwidth_gbps", [&]() -> const nlohmann::json& {
    const nlohmann::json& c = Field(json, "copy_bandwidth_gbps");
    if (!c.is_object()) throw Error("must be an object");
    return c;
  });
  for (const auto& item : copy.items()) {
    const std::string& id = item.key();
    const nlohmann::json& gbps = item.value();  // not a structured binding: clang 14 cannot capture one
    r.copy_bandwidth_gbps[id] = At(context, "copy_bandwidth_gbps[\"" + id + "\"]", [&] {
      if (!gbps.is_number()) throw Error("must be a number");
      const double value = gbps.get<double>();
      if (!(std::isfinite(value) && value > 0.0)) throw Error("is " + gbps.dump() + ": must be a positive, finite GB/s");
      return value;
    });
  }
}

void ReadSkipped(const nlohmann::json& json, const std::string& context, TuningReport& r) {
  const nlohmann::json& skipped = At(context, "skipped", [&]() -> const nlohmann::json& { return Array(json, "skipped"); });
  for (std::size_t i = 0; i < skipped.size(); ++i) {
    r.skipped.push_back(At(context, "skipped[" + std::to_string(i) + "]", [&] {
      if (!skipped[i].is_string()) throw Error("must be a string");
      return skipped[i].get<std::string>();
    }));
  }
}

DatasetInfo DatasetInfoFromJson(const nlohmann::json& d) {
  if (!d.is_object()) throw Error("expected an object");
  DatasetInfo info;
  info.key = String(d, "key");
  const std::int64_t vertices = Integer(d, "vertices");
  if (vertices < 0) throw Error("'vertices' must not be negative");
  info.vertices = static_cast<std::size_t>(vertices);
  info.influences = static_cast<int>(Integer(d, "influences"));
  info.joints = static_cast<int>(Integer(d, "joints"));
  if (d.contains("shape")) {  // 1.3.0; older reports tuned single meshes
    info.shape = SceneKindFromName(String(d, "shape"));
    info.instances = static_cast<int>(Integer(d, "instances"));
    info.meshes = static_cast<int>(Integer(d, "meshes"));
    if (info.instances < 1 || info.meshes < 1) throw Error("'instances' and 'meshes' must be at least 1");
  }
  if (d.contains("morph_targets")) {  // 1.11.0
    info.morph_targets = static_cast<int>(Integer(d, "morph_targets"));
    if (info.morph_targets < 0) throw Error("'morph_targets' must not be negative");
  }
  if (d.contains("cross_fades")) info.cross_fades = Boolean(d, "cross_fades");  // 1.14.0
  return info;
}

void ReadDatasets(const nlohmann::json& json, const std::string& context, TuningReport& r) {
  const nlohmann::json& datasets = At(context, "datasets", [&]() -> const nlohmann::json& { return Array(json, "datasets"); });
  for (std::size_t i = 0; i < datasets.size(); ++i)
    r.datasets.push_back(At(context, "datasets[" + std::to_string(i) + "]", [&] { return DatasetInfoFromJson(datasets[i]); }));
}

// After the datasets: each measurement must name one of them.
void ReadMeasurements(const nlohmann::json& json, const std::string& context, TuningReport& r) {
  const nlohmann::json& measurements =
      At(context, "measurements", [&]() -> const nlohmann::json& { return Array(json, "measurements"); });
  for (std::size_t i = 0; i < measurements.size(); ++i) {
    r.measurements.push_back(At(context, "measurements[" + std::to_string(i) + "]", [&] {
      Measurement m = measurements[i].get<Measurement>();
      // Winners and databases are keyed by the id's parts and name its backend.
      const std::string backend = SplitDeviceId(m.device_id).backend;
      if (!FindBackend(backend))
        throw Error("device id '" + m.device_id + "' has unknown backend '" + backend + "' (expected " +
                    JoinedBackendNames() + ")");
      if (std::none_of(r.datasets.begin(), r.datasets.end(), [&](const DatasetInfo& d) { return d.key == m.dataset; })) {
        throw Error("dataset '" + m.dataset + "' is not in 'datasets'");
      }
      return m;
    }));
  }
}

// tie_margin since 1.4.0, host_tie_margin since 1.5.0 (before it, a CPU device's was tie_margin too).
void ReadMargins(const nlohmann::json& json, const std::string& context, TuningReport& r) {
  // Each field, its range ((0, 0.5] for a margin, [0, 0.5] for a spread) and its value in a
  // report without it: the default margin, the tie margin for the host's, and no spread
  // before 1.6.0 (an older report's tie sets were its contenders).
  static constexpr double kNoSpread = 0.0;
  const struct {
    const char* name;
    double* value;
    bool may_be_zero;
    const double* absent;
  } fields[] = {
      {"tie_margin", &r.tie_margin, false, &r.tie_margin},
      {"host_tie_margin", &r.host_tie_margin, false, &r.tie_margin},
      {"process_spread", &r.process_spread, true, &kNoSpread},
      {"host_process_spread", &r.host_process_spread, true, &kNoSpread},
  };
  for (const auto& f : fields) {
    if (!json.contains(f.name)) {
      *f.value = *f.absent;
      continue;
    }
    *f.value = At(context, f.name, [&] {
      const double value = Number(json, f.name);
      const bool in_range = (f.may_be_zero ? value >= 0.0 : value > 0.0) && value <= 0.5;
      if (!in_range) throw Error(f.may_be_zero ? "must be in [0, 0.5]" : "must be in (0, 0.5]");
      return value;
    });
  }
  // Where the winner is picked, since 1.8.0 (before it, among the contenders)
  // and 1.20.0 (before it, among the whole tie set).
  for (const auto& [name, value] : {std::pair<const char*, bool*>{"choose_in_tie_set", &r.choose_in_tie_set},
                                    {"host_choose_in_tie_set", &r.host_choose_in_tie_set},
                                    {"choose_unseparated", &r.choose_unseparated},
                                    {"host_choose_unseparated", &r.host_choose_unseparated}}) {
    *value = json.contains(name) && At(context, name, [&] {
      if (!json.at(name).is_boolean()) throw Error("must be true or false");
      return json.at(name).get<bool>();
    });
  }
}

}  // namespace

TuningReport ReportFromJson(const nlohmann::json& json, const std::string& context) {
  CheckReportHeader(json, context);
  TuningReport r;
  r.created = At(context, "created", [&] { return CheckedCreated(String(json, "created")); });
  r.config = At(context, "config", [&] { return String(json, "config"); });
  r.strategy = At(context, "strategy", [&] { return String(json, "strategy"); });
  if (json.contains("max_error")) {  // since 1.2.0
    r.max_error = At(context, "max_error", [&] {
      const double value = Number(json, "max_error");
      if (const std::string bad = BadMaxError(value); !bad.empty()) throw Error(bad);
      return value;
    });
  }
  r.machine = At(context, "machine", [&] {
    const nlohmann::json& m = Field(json, "machine");
    if (!m.is_object()) throw Error("must be an object");
    return m;
  });
  ReadDevices(json, context, r);
  ReadCopyBandwidths(json, context, r);
  ReadSkipped(json, context, r);
  ReadDatasets(json, context, r);
  ReadMeasurements(json, context, r);
  ReadMargins(json, context, r);
  if (json.contains("races")) {  // since 1.4.0
    const nlohmann::json& races = At(context, "races", [&]() -> const nlohmann::json& { return Array(json, "races"); });
    for (std::size_t i = 0; i < races.size(); ++i)
      r.races.push_back(At(context, "races[" + std::to_string(i) + "]", [&] { return RaceFromJson(races[i]); }));
  }
  // "winners" is derived from the measurements and races: recomputed, never trusted.
  return r;
}

nlohmann::json ReportToT4(const TuningReport& report) {
  nlohmann::json metadata = {{"generator", "skintune"},
                             {"skintune_report_schema_version", kReportSchemaVersion},
                             {"created", report.created},
                             {"config", report.config},
                             {"strategy", report.strategy},
                             {"machine", report.machine.is_null() ? nlohmann::json::object() : report.machine},
                             {"devices", nlohmann::json::array()},
                             {"copy_bandwidth_gbps", nlohmann::json::object()},
                             {"datasets", nlohmann::json::array()}};
  for (const DeviceIdentity& d : report.devices) {
    nlohmann::json dj = d;
    dj["id"] = d.Id();
    metadata["devices"].push_back(std::move(dj));
  }
  for (const auto& [id, gbps] : report.copy_bandwidth_gbps) metadata["copy_bandwidth_gbps"][id] = gbps;
  for (const DatasetInfo& d : report.datasets) metadata["datasets"].push_back(DatasetJson(d));

  nlohmann::json results = nlohmann::json::array();
  for (const Measurement& m : report.measurements) {
    nlohmann::json configuration = m.variant;  // the tuning parameters: one entry per variant axis
    configuration.erase("key");
    nlohmann::json r;
    r["timestamp"] = m.timestamp;
    r["configuration"] = std::move(configuration);
    r["objectives"] = nlohmann::json::array({"time"});
    // Only the summary of the timed repetitions is recorded, not each run:
    // "runtimes" holds the median (the time skintune ranks variants by).
    nlohmann::json times = {{"runtimes", nlohmann::json::array()}};
    nlohmann::json measurements = nlohmann::json::array();
    // T4 measurement values are numbers: a non-finite one (the relative error
    // of a kernel that wrote NaN) is left out; the status says why it failed.
    auto measure = [&](const char* name, double value, const char* unit) {
      if (std::isfinite(value)) measurements.push_back({{"name", name}, {"value", value}, {"unit", unit}});
    };
    auto count = [&](const char* name, int value) {
      measurements.push_back({{"name", name}, {"value", value}, {"unit", ""}});
    };
    if (IsTimed(m.status)) {
      times["runtimes"].push_back(m.timing.median_ms);
      measure("time", m.timing.median_ms, "ms");
      measure("time_min", m.timing.min_ms, "ms");
      measure("time_max", m.timing.max_ms, "ms");
      count("repetitions", m.timing.repetitions);
      count("warmup", m.timing.warmup);
      count("input_sets", m.timing.input_sets);
      measure("bandwidth", m.gbps, "GB/s");
    }
    measure("bytes_per_frame", m.bytes_per_frame, "B");
    if (IsTimed(m.status) || m.status == MeasureStatus::kVerifyFailed) {
      measure("max_relative_error", m.max_relative_error, "");
    }
    if (m.source_error.known) {
      measure("source_error_position", m.source_error.position_abs, "");
      measure("source_error_position_relative", m.source_error.position_rel, "");
      measure("quantisation_error_relative", m.source_error.quantisation_rel, "");
    }
    r["times"] = std::move(times);
    switch (m.status) {
      case MeasureStatus::kOk: r["invalidity"] = "correct"; break;
      case MeasureStatus::kInvalid: r["invalidity"] = "constraints"; break;
      case MeasureStatus::kCompileFailed: r["invalidity"] = "compile"; break;
      case MeasureStatus::kLaunchFailed: r["invalidity"] = "runtime"; break;
      case MeasureStatus::kVerifyFailed: r["invalidity"] = "correctness"; break;
      case MeasureStatus::kTimeout: r["invalidity"] = "timeout"; break;
      // Correct and timed, but over the error budget: T4 has no invalidity for precision.
      case MeasureStatus::kTooImprecise: r["invalidity"] = "correct"; break;
    }
    // 1: the output matched the float64 gold within tolerance; 0: it did not, or was never checked.
    r["correctness"] = IsTimed(m.status) ? 1 : 0;
    r["measurements"] = std::move(measurements);
    // skintune extensions (the T4 schema allows further properties): where it ran, on what, and why it failed.
    r["device_id"] = m.device_id;
    r["dataset"] = m.dataset;
    r["status"] = Name(m.status);
    if (!m.detail.empty()) r["detail"] = m.detail;
    results.push_back(std::move(r));
  }
  return {{"schema_version", "1.0.0"}, {"metadata", std::move(metadata)}, {"results", std::move(results)}};
}

nlohmann::json WinnersDatabase(const TuningReport& report) { return WinnersDbJson(EntriesOf(report)); }

nlohmann::json MergeWinnersDatabases(const std::vector<nlohmann::json>& reports_or_databases,
                                     const std::vector<std::string>& names_for_errors) {
  if (names_for_errors.size() != reports_or_databases.size()) {
    throw Error("winners database merge: " + std::to_string(reports_or_databases.size()) + " inputs but " +
                std::to_string(names_for_errors.size()) + " names");
  }
  std::map<EntryKey, WinnersEntry> merged;
  for (std::size_t i = 0; i < reports_or_databases.size(); ++i) {
    const nlohmann::json& input = reports_or_databases[i];
    const std::string& name = names_for_errors[i];
    if (!input.is_object()) throw Error(name + ": expected a JSON object (a skintune report or winners database)");
    const std::string kind = input.contains("kind") && input["kind"].is_string() ? input["kind"].get<std::string>() : "";
    std::vector<WinnersEntry> entries;
    if (kind == kReportKind) {
      entries = EntriesOf(ReportFromJson(input, name));
    } else if (kind == kWinnersDbKind) {
      entries = WinnersDbFromJson(input, name);
    } else {
      throw Error(name + ": not a skintune report or winners database (\"kind\" is " +
                  (kind.empty() ? std::string("missing") : "'" + kind + "'") + ", expected '" + kReportKind +
                  "' or '" + kWinnersDbKind + "')");
    }
    // Newest `created` wins per key; on equal `created`, the later input.
    for (WinnersEntry& e : entries) {
      const EntryKey key = KeyOf(e);
      const auto it = merged.find(key);
      if (it == merged.end() || !CreatedBefore(e.created, it->second.created)) merged.insert_or_assign(key, std::move(e));
    }
  }
  std::vector<WinnersEntry> out;
  for (auto& [key, e] : merged) out.push_back(std::move(e));
  return WinnersDbJson(out);
}

}  // namespace skintune::internal
