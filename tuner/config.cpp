// skintune: reading and checking a tuning config (tuner/config.h).
#include "tuner/config.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "model/scene.h"
#include "model/synthetic.h"
#include "tuner/measurement.h"  // kMaxTolerance

namespace skintune::internal {

struct EmbeddedConfigFile {
  const char* name;
  const unsigned char* data;
  std::size_t size;
};
extern const EmbeddedConfigFile kEmbeddedConfigs[];
extern const std::size_t kEmbeddedConfigCount;

namespace {

// A positive number at most `most` (a bound stated in the error).
double PositiveNumber(const nlohmann::json& value, const std::string& where,
                      double most = std::numeric_limits<double>::max()) {
  if (!value.is_number()) throw Error(where + ": expected a number (got " + Excerpt(value.dump()) + ")");
  const double v = value.get<double>();
  if (!(v > 0.0) || v == std::numeric_limits<double>::infinity()) {
    throw Error(where + ": must be a positive number (got " + value.dump() + ")");
  }
  if (v > most) {  // absurd: a setting that cannot work (exit 2)
    std::ostringstream bound;
    bound << most;
    throw UsageError(where + ": must be a positive number at most " + bound.str() + " (got " + value.dump() + ")");
  }
  return v;
}

void CheckFields(const nlohmann::json& object, const std::string& where, const std::set<std::string>& known) {
  if (!object.is_object()) throw Error(where + ": expected an object");
  for (const auto& [field, value] : object.items()) {
    if (known.count(field)) continue;
    std::string list;
    for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
    throw Error(where + "." + field + ": unknown field (expected one of " + list + ")");
  }
}

TimingOptions TimingFromConfig(const nlohmann::json& in, const std::string& context) {
  return TimingOptionsFromJson(in, context + ": timing");
}

void ValidateStrategy(const StrategyOptions& s, const std::string& where) {
  if (s.name != "exhaustive" && s.name != "random" && s.name != "coordinate") {
    throw Error(where + ".name: unknown strategy '" + s.name + "' (expected one of exhaustive, random, coordinate)");
  }
  if (s.name == "random" && s.budget == 0) {
    throw Error(where + ".budget: the random strategy needs a budget (evaluations per device, language and dataset)");
  }
}

StrategyOptions StrategyFromConfig(const nlohmann::json& in, const std::string& context) {
  const std::string where = context + ": strategy";
  CheckFields(in, where, {"name", "budget", "seed"});
  StrategyOptions s;
  if (in.contains("name")) {
    if (!in["name"].is_string()) throw Error(where + ".name: expected a string");
    s.name = in["name"].get<std::string>();
  }
  if (in.contains("budget")) {
    if (!in["budget"].is_number_unsigned() || in["budget"].get<std::uint64_t>() > kMaxBudget)
      throw Error(where + ".budget: must be a whole number from 0 to " + std::to_string(kMaxBudget) + " (got " +
                  in["budget"].dump() + ")");
    s.budget = in["budget"].get<std::size_t>();
  }
  if (in.contains("seed")) {
    if (!in["seed"].is_number_unsigned()) throw Error(where + ".seed: must be an integer >= 0");
    s.seed = in["seed"].get<std::uint64_t>();
  }
  ValidateStrategy(s, where);
  return s;
}

std::vector<std::string> DatasetsFromConfig(const nlohmann::json& in, const std::string& context) {
  const std::string where = context + ": datasets";
  if (!in.is_array()) throw Error(where + ": expected a list of dataset keys");
  if (in.empty()) throw Error(where + ": is empty");
  std::vector<std::string> keys;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const std::string item = where + "[" + std::to_string(i) + "]";
    const nlohmann::json& d = in[i];
    std::string key;
    if (d.is_string()) {
      key = d.get<std::string>();
    } else if (d.is_object()) {
      // {"key": ..., "name", "vertices", "influences", "bones", "description"}: the
      // numbers, when given, must agree with the key.
      CheckFields(d, item, {"key", "name", "vertices", "influences", "bones", "description"});
      if (!d.contains("key") || !d["key"].is_string()) throw Error(item + ".key: missing (a dataset key or glTF path)");
      key = d["key"].get<std::string>();
    } else {
      throw Error(item + ": expected a dataset key (string) or an object with \"key\"");
    }
    SceneSpec scene;
    try {
      scene = ParseSceneKey(key);  // a dataset key, a glTF path, instances or a batch (model/scene.h)
    } catch (const Error& e) {
      throw Error(item + ": " + e.what());
    }
    if (d.is_object()) {
      const bool synthetic = !scene.batch && scene.instances == 1 && !IsGltfFile(key);
      const DatasetSpec spec = synthetic ? ParseDatasetKey(key) : DatasetSpec{};
      auto check = [&](const char* field, long long expected) {
        if (!d.contains(field)) return;
        if (!synthetic)
          throw Error(item + "." + field + ": only a synthetic dataset of one mesh states its numbers ('" + key +
                      "' is not one)");
        if (!d[field].is_number_integer() || d[field].get<long long>() != expected) {
          throw Error(item + "." + field + ": " + d[field].dump() + " does not match the key '" + key + "' (" +
                      std::to_string(expected) + ")");
        }
      };
      check("vertices", static_cast<long long>(spec.vertices));
      check("influences", spec.influences);
      check("bones", spec.bones);
    }
    if (std::find(keys.begin(), keys.end(), key) != keys.end()) throw Error(item + ": '" + key + "' is listed twice");
    keys.push_back(key);
  }
  return keys;
}

}  // namespace

TuneConfig ConfigFromJson(const nlohmann::json& json, const std::string& context) {
  if (!json.is_object()) throw Error(context + ": a tune config must be a JSON object");
  // "paper", "figure1", "paper_kernels" and "reported" are fields of configs/paper.json
  // read by `skintune paper` (report/paper_result.h).
  static const std::set<std::string> kKnown = {"description", "space",    "datasets", "timing",
                                               "strategy",    "variant_timeout_s", "max_error", "paper", "figure1",
                                               "paper_kernels", "reported"};
  for (const auto& [field, value] : json.items()) {
    if (kKnown.count(field)) continue;
    throw Error(context + ": " + field +
                ": unknown field (expected description, space, datasets, timing, strategy, variant_timeout_s, "
                "max_error)");
  }
  if (json.contains("description") && !json["description"].is_string()) {
    throw Error(context + ": description: expected a string");
  }
  if (!json.contains("space")) throw Error(context + ": space: missing (an object of axis -> list of values)");
  if (!json.contains("datasets")) throw Error(context + ": datasets: missing (a list of dataset keys)");
  TuneConfig c;
  c.name = context;
  c.space = SpaceFromJson(json["space"], context);
  c.space.Validate(context);
  c.datasets = DatasetsFromConfig(json["datasets"], context);
  if (json.contains("timing")) c.timing = TimingFromConfig(json["timing"], context);
  if (json.contains("strategy")) c.strategy = StrategyFromConfig(json["strategy"], context);
  if (json.contains("variant_timeout_s")) {
    c.variant_timeout_s = PositiveNumber(json["variant_timeout_s"], context + ": variant_timeout_s", kMaxVariantTimeoutS);
  }
  if (json.contains("max_error")) {
    const nlohmann::json& value = json["max_error"];
    if (!value.is_number()) throw Error(context + ": max_error: expected a number (got " + value.dump() + ")");
    c.max_error = value.get<double>();
    if (const std::string bad = BadMaxError(c.max_error); !bad.empty()) throw Error(context + ": max_error: " + bad);
  }
  return c;
}

std::string EmbeddedConfigNames() {
  std::string names;
  for (std::size_t i = 0; i < kEmbeddedConfigCount; ++i)
    names += (names.empty() ? "" : ", ") + std::string(kEmbeddedConfigs[i].name);
  return names;
}

std::string EmbeddedConfig(const std::string& name) {
  for (std::size_t i = 0; i < kEmbeddedConfigCount; ++i) {
    if (name == kEmbeddedConfigs[i].name) {
      return std::string(reinterpret_cast<const char*>(kEmbeddedConfigs[i].data), kEmbeddedConfigs[i].size);
    }
  }
  throw Error("no built-in config '" + name + "' (built in: " + EmbeddedConfigNames() + ")");
}

void ValidateConfig(const TuneConfig& config) {
  ValidateStrategy(config.strategy, "strategy");
  config.space.Validate(config.name);
  if (!(config.variant_timeout_s > 0.0 && config.variant_timeout_s <= kMaxVariantTimeoutS))
    throw Error("variant_timeout_s: must be a positive number at most " + std::to_string(kMaxVariantTimeoutS));
  if (!(config.timing.tolerance > 0.0 && config.timing.tolerance <= kMaxTolerance))
    throw Error("timing.tolerance: must be a positive number at most " + std::to_string(kMaxTolerance));
  if (const std::string bad = BadMaxError(config.max_error); !bad.empty()) throw Error("max_error: " + bad);
}

}  // namespace skintune::internal
