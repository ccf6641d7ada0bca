// A tuning config of a few variants for the command-line tests: the given
// languages, layouts, index formats, palette storages and work-group sizes
// at `influences`, every other axis at one value (float4, f32, mat3x4,
// matrix, v1c), on one dataset, timed briefly.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace skintune::internal::testing {

struct TinyTuneConfig {
  std::vector<std::string> langs = {"opencl"};
  std::vector<std::string> layouts = {"soa"};
  std::vector<std::string> indices = {"u16"};
  std::vector<std::string> storages = {"global"};
  std::vector<int> wg_sizes = {64};
  std::string dataset = "5000-b2";
  int influences = 2;
  int max_input_sets = 1;
  double variant_timeout_s = 30;
  std::string description;  // "": none

  nlohmann::json Json() const {
    nlohmann::json config = {{"space",
             {{"lang", langs},
              {"influences", {influences}},
              {"mixed", {"padded"}},
              {"layout", layouts},
              {"position", {"float4"}},
              {"index", indices},
              {"weight", {"f32"}},
              {"palette", {"mat3x4"}},
              {"storage", storages},
              {"blend", {"matrix"}},
              {"vertices_per_item", {1}},
              {"assignment", {"contiguous"}},
              {"wg_size", wg_sizes},
              {"normals", {false}}}},
            {"datasets", {dataset}},
            // A few samples: the tests check what is recorded, never the figures.
            {"timing", {{"warmup", 1}, {"repetitions", 3}, {"max_input_sets", max_input_sets}, {"min_samples", 3},
                        {"sample_batch", 3}, {"max_samples", 6}, {"sample_ms", 20}}},
            {"variant_timeout_s", variant_timeout_s}};
    if (!description.empty()) config["description"] = description;
    return config;
  }
};

}  // namespace skintune::internal::testing
