// Fuzz target for the tuning config reader (ConfigFromJson: `skintune tune
// --config FILE`, configs/*.json). Built like gltf_import_fuzz
// (tests/fuzz/CMakeLists.txt); its corpus is replayed by ctest.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "base/input_file.h"
#include "tests/fuzz/fuzz_support.h"
#include "tuner/tune.h"

using namespace skintune::internal;  // the readers under test and fuzz_support.h's helpers

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    // The bytes as `tune --config` reads them: invalid JSON and numbers beyond
    // double (1e400) are ParseJson's errors, named like the reader's own.
    const nlohmann::json json = ParseJson(std::string(reinterpret_cast<const char*>(data), size), "config.json");
    const TuneConfig config = ConfigFromJson(json, "config.json");
    // An accepted config is a valid one: the checks RunTuning repeats pass.
    config.space.Validate(config.name);
    if (config.datasets.empty()) fuzz::Die("config_fuzz", "accepted a config without datasets");
    if (!(config.variant_timeout_s > 0.0 && config.variant_timeout_s <= kMaxVariantTimeoutS))
      fuzz::Die("config_fuzz", "accepted a time limit out of bounds");
    if (!(config.timing.tolerance > 0.0 && config.timing.tolerance <= kMaxTolerance))
      fuzz::Die("config_fuzz", "accepted a tolerance out of bounds");
    if (config.strategy.budget > kMaxBudget) fuzz::Die("config_fuzz", "accepted a budget above the limit");
  } catch (const Error& e) {
    fuzz::ExpectNamed("config_fuzz", e, "config.json");
  }
  return 0;
}
