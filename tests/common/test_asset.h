// A test's skinned asset by key, loaded once per test program: a glTF file of
// tests/data ("CesiumMan.gltf") or a synthetic dataset key ("1500-b2-bones40-seed3").
#pragma once

#include <map>
#include <string>

#include "model/gltf_import.h"
#include "model/synthetic.h"

namespace skintune::internal::testing {

inline const SkinnedAsset& TestAsset(const std::string& key) {
  static std::map<std::string, SkinnedAsset> cache;
  auto found = cache.find(key);
  if (found != cache.end()) return found->second;
  SkinnedAsset asset = key.ends_with(".gltf") ? ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/" + key).asset
                                              : GenerateDataset(ParseDatasetKey(key));
  return cache.emplace(key, std::move(asset)).first->second;
}

}  // namespace skintune::internal::testing
