// Fuzz target for the tuning config reader (ConfigFromJson: `skintune tune
// --config FILE`, configs/*.json). Built like gltf_import_fuzz
// (tests/fuzz/CMakeLists.txt); its corpus is replayed by ctest.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/fuzz/fuzz_support.h"
#include "tuner/tune.h"

using namespace skintune::internal;  // the readers under test and fuzz_support.h's helpers

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // Not JSON at all is ParseJson's one error (tools/json_file.cpp): the reader starts at a document.
  const nlohmann::json json = nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded()) return 0;
  try {
    const TuneConfig config = ConfigFromJson(json, "config.json");
    // An accepted config is a valid one: the checks RunTuning repeats pass.
    config.space.Validate(config.name);
    if (config.datasets.empty()) fuzz::Die("config_fuzz", "accepted a config without datasets");
    if (!(config.variant_timeout_s > 0.0)) fuzz::Die("config_fuzz", "accepted a non-positive time limit");
    if (config.strategy.budget > kMaxBudget) fuzz::Die("config_fuzz", "accepted a budget above the limit");
  } catch (const Error& e) {
    fuzz::ExpectNamed("config_fuzz", e, "config.json");
  }
  return 0;
}
