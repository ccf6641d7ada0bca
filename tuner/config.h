// skintune: a tuning config (configs/*.json: space, datasets, timing,
// strategy, limits, baselines), read and checked before anything is measured.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/space.h"
#include "generator/variant.h"
#include "runtime/source_error.h"  // kDefaultBudget
#include "tuner/strategy.h"
#include "tuner/timing_options.h"

namespace skintune::internal {

// The largest search budget (evaluations per device, language and dataset)
// a config or --budget may ask for; 0 means every candidate for exhaustive.
inline constexpr std::size_t kMaxBudget = 1000000000;
// The largest variant_timeout_s of a config: a day (one variant's build,
// verification and timing; the worker's poll takes milliseconds in an int).
inline constexpr double kMaxVariantTimeoutS = 86400.0;

struct TuneConfig {
  std::string name;                     // file name or "default"
  TuningSpace space;
  std::vector<std::string> datasets;    // dataset keys or glTF paths
  TimingOptions timing;
  StrategyOptions strategy;
  double variant_timeout_s = 60.0;      // per variant, in the child process
  // The error budget (config "max_error", `tune --max-error`): a variant whose
  // weight format costs more than this, relative to the bounding-box diagonal
  // (SourceError::quantisation_rel), is too_imprecise (docs/TUNING.md "Precision").
  double max_error = kDefaultBudget;
  // Variants measured on every device x language x dataset of their language
  // before the search, with B set to the dataset's (the paper's own kernels):
  // recorded like any measurement (invalid ones with their constraints), so a
  // baseline can win and the search's best is compared with it. Need not be
  // points of `space`.
  std::vector<Variant> baselines;
};

// Parses a config (configs/*.json). Throws Error("<context>: <element>: ...").
TuneConfig ConfigFromJson(const nlohmann::json& json, const std::string& context);
// The embedded configs (configs/default.json as "default", ...; tuner/CMakeLists.txt lists them).
std::string EmbeddedConfig(const std::string& name);
// Their names, ", "-separated, in the list's order.
std::string EmbeddedConfigNames();

// How a run is asked to go (the command line's part): which devices and
// languages, the cache, the worker, progress, devices side by side or not.
struct TuneOptions {
  std::string device_pattern;           // MatchesDevice (runtime/device_identity.h), the one --device rule; empty: all
                                        // but software rasterizers (IsSoftwareRasterizer)
  bool software_rasterizers = false;    // with an empty device_pattern, tune llvmpipe and lavapipe too
  std::vector<Lang> languages;          // empty: every language of every device
  std::string cache_path;               // the resumable measurement cache (JSON lines)
  std::string worker_executable;        // the skintune binary (runs `skintune tune-worker`)
  // Called from one thread at a time (devices are tuned on several).
  std::function<void(std::size_t done, std::size_t total, const std::string& what)> progress;
  // Devices that share no hardware (tuner/schedule.h) are tuned at the same
  // time; false: one device after another, as before.
  bool parallel_devices = true;
};

// Throws Error naming the field for a config a run cannot use, whoever built
// it (ConfigFromJson checks the same while reading): an unknown strategy or
// a random one without a budget, an invalid space, a variant_timeout_s
// outside (0, kMaxVariantTimeoutS], a tolerance outside (0, kMaxTolerance],
// a max_error that is no budget.
void ValidateConfig(const TuneConfig& config);

}  // namespace skintune::internal
