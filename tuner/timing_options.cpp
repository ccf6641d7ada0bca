// skintune: the timing options and their JSON form (tuner/timing_options.h).
#include "tuner/timing_options.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "tuner/measurement.h"  // kMaxTolerance
#include "tuner/schedule.h"     // IsHostCpu

namespace skintune::internal {

namespace {

// The fields of TimingOptions, declared once for the reader and the writer.
struct TimingField {
  const char* name;
  enum Kind { kInt, kCount, kNumber, kBool } kind;
  int* as_int;
  std::size_t* as_count;
  double* as_number;
  bool* as_bool = nullptr;
};

std::vector<TimingField> Fields(TimingOptions& t) {
  return {{"warmup", TimingField::kInt, &t.warmup, nullptr, nullptr},
          {"repetitions", TimingField::kInt, &t.repetitions, nullptr, nullptr},
          {"max_input_sets", TimingField::kInt, &t.max_input_sets, nullptr, nullptr},
          {"tolerance", TimingField::kNumber, nullptr, nullptr, &t.tolerance},
          {"burst_ms", TimingField::kNumber, nullptr, nullptr, &t.burst_ms},
          {"interval", TimingField::kNumber, nullptr, nullptr, &t.stop.interval},
          {"min_samples", TimingField::kCount, nullptr, &t.stop.min_samples, nullptr},
          {"max_samples", TimingField::kCount, nullptr, &t.stop.max_samples, nullptr},
          {"sample_batch", TimingField::kCount, nullptr, &t.stop.batch, nullptr},
          {"sample_ms", TimingField::kNumber, nullptr, nullptr, &t.stop.max_ms},
          {"race", TimingField::kInt, &t.race, nullptr, nullptr},
          {"tie_margin", TimingField::kNumber, nullptr, nullptr, &t.tie_margin},
          {"host_tie_margin", TimingField::kNumber, nullptr, nullptr, &t.host_tie_margin},
          {"process_spread", TimingField::kNumber, nullptr, nullptr, &t.process_spread},
          {"host_process_spread", TimingField::kNumber, nullptr, nullptr, &t.host_process_spread},
          {"frames_per_sample", TimingField::kInt, &t.frames_per_sample, nullptr, nullptr},
          {"host_frames_per_sample", TimingField::kInt, &t.host_frames_per_sample, nullptr, nullptr},
          {"choose_in_tie_set", TimingField::kBool, nullptr, nullptr, nullptr, &t.choose_in_tie_set},
          {"host_choose_in_tie_set", TimingField::kBool, nullptr, nullptr, nullptr, &t.host_choose_in_tie_set},
          {"choose_unseparated", TimingField::kBool, nullptr, nullptr, nullptr, &t.choose_unseparated},
          {"host_choose_unseparated", TimingField::kBool, nullptr, nullptr, nullptr, &t.host_choose_unseparated}};
}

std::string Dumped(const nlohmann::json& v) {
  std::string text = v.dump();
  return text.size() > 40 ? text.substr(0, 40) + "..." : text;
}

}  // namespace

TimingOptions TimingOptionsFromJson(const nlohmann::json& in, const std::string& where) {
  if (!in.is_object()) throw Error(where + ": expected an object");
  TimingOptions t;
  std::vector<TimingField> fields = Fields(t);
  for (const auto& [name, value] : in.items()) {
    const auto field = std::find_if(fields.begin(), fields.end(), [&key = name](const TimingField& f) { return key == f.name; });
    if (field == fields.end()) {
      std::string list;
      for (const TimingField& f : fields) list += (list.empty() ? "" : ", ") + std::string(f.name);
      throw Error(where + "." + name + ": unknown field (expected one of " + list + ")");
    }
    const std::string at = where + "." + name;
    if (field->kind == TimingField::kBool) {
      if (!value.is_boolean()) throw Error(at + ": expected true or false (got " + Dumped(value) + ")");
      *field->as_bool = value.get<bool>();
      continue;
    }
    if (field->kind == TimingField::kNumber) {
      if (!value.is_number()) throw Error(at + ": expected a number (got " + Dumped(value) + ")");
      *field->as_number = value.get<double>();
      if (!std::isfinite(*field->as_number)) throw Error(at + ": must be finite (got " + Dumped(value) + ")");
      continue;
    }
    if (!value.is_number_integer()) throw Error(at + ": expected an integer (got " + Dumped(value) + ")");
    const long long v = value.get<long long>();
    const long long least = field->kind == TimingField::kCount || name == "repetitions" || name == "max_input_sets" ? 1 : 0;
    if (v < least || v > 1000000)
      throw Error(at + ": must be an integer from " + std::to_string(least) + " to 1000000 (got " + std::to_string(v) + ")");
    if (field->as_int) *field->as_int = static_cast<int>(v);
    if (field->as_count) *field->as_count = static_cast<std::size_t>(v);
  }
  for (const auto& [name, value] : {std::pair<const char*, double>{"burst_ms", t.burst_ms}, {"tolerance", t.tolerance}})
    if (!(value > 0.0)) throw Error(where + "." + name + ": must be a positive number (got " + Dumped(in.at(name)) + ")");
  // A verification that passes any output would let a wrong kernel win: a setting that cannot work.
  if (t.tolerance > kMaxTolerance)
    throw UsageError(where + ".tolerance: must be a positive number at most 0.001 (got " + Dumped(in.at("tolerance")) + ")");
  const std::string prefix = where.substr(where.rfind(' ') == std::string::npos ? 0 : where.rfind(' ') + 1) + ".";
  if (const std::string bad = BadStopRule(t.stop, prefix); !bad.empty()) throw UsageError(where + ": " + bad);
  for (const auto& [name, value] : {std::pair<const char*, double>{"tie_margin", t.tie_margin}, {"host_tie_margin", t.host_tie_margin}})
    if (!(value > 0.0) || value > 0.5)
      throw UsageError(where + ": '" + prefix + name + "' is " + Dumped(in.at(name)) +
                       ": a relative difference in (0, 0.5] (0.02: 2%)");
  for (const auto& [name, value] :
       {std::pair<const char*, double>{"process_spread", t.process_spread}, {"host_process_spread", t.host_process_spread}})
    if (!(value >= 0.0) || value > 0.5)
      throw UsageError(where + ": '" + prefix + name + "' is " + Dumped(in.at(name)) +
                       ": a relative difference in [0, 0.5] (0.034: 3.4%)");
  for (const auto& [name, value] :
       {std::pair<const char*, int>{"frames_per_sample", t.frames_per_sample}, {"host_frames_per_sample", t.host_frames_per_sample}})
    if (value < 1 || value > kMaxFramesPerSample)
      throw UsageError(where + ": '" + prefix + name + "' is " + Dumped(in.at(name)) + ": cold frames per sample, 1 to " +
                       std::to_string(kMaxFramesPerSample));
  return t;
}

double TimingOptions::MarginFor(const DeviceIdentity& device) const {
  return IsHostCpu(device) ? host_tie_margin : tie_margin;
}

double TimingOptions::SpreadFor(const DeviceIdentity& device) const {
  return IsHostCpu(device) ? host_process_spread : process_spread;
}

Choice TimingOptions::OwnChoice() const {
  if (!choose_in_tie_set) return Choice::kContenders;
  return choose_unseparated ? Choice::kTieSetUnseparated : Choice::kTieSet;
}

Choice TimingOptions::ChoiceFor(const DeviceIdentity& device) const { return ForDevice(device).OwnChoice(); }

TimingOptions TimingOptions::ForDevice(const DeviceIdentity& device) const {
  TimingOptions out = *this;
  out.tie_margin = MarginFor(device);
  out.process_spread = SpreadFor(device);
  out.choose_in_tie_set = IsHostCpu(device) ? host_choose_in_tie_set : choose_in_tie_set;
  out.choose_unseparated = IsHostCpu(device) ? host_choose_unseparated : choose_unseparated;
  out.frames_per_sample = IsHostCpu(device) ? host_frames_per_sample : frames_per_sample;
  out.stop.interval = std::min(stop.interval * out.tie_margin / tie_margin, 0.5);  // BadStopRule's bound
  return out;
}

nlohmann::json ToJson(const TimingOptions& t) {
  TimingOptions copy = t;
  nlohmann::json out = nlohmann::json::object();
  for (const TimingField& f : Fields(copy)) {
    if (f.as_int) out[f.name] = *f.as_int;
    if (f.as_count) out[f.name] = *f.as_count;
    if (f.as_number) out[f.name] = *f.as_number;
    if (f.as_bool) out[f.name] = *f.as_bool;
  }
  return out;
}

}  // namespace skintune::internal
