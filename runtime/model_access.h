// skintune (internal): what the library reads of a public Model beyond its
// API (Skinner::CreateAnimated packs its skeleton and animations).
#pragma once

#include "model/asset.h"
#include "skintune/skintune.h"

namespace skintune::internal {

struct ModelAccess {
  // The model's asset (mesh, skeleton, skin, animations); null for an empty Model.
  static const SkinnedAsset* Asset(const Model& model);
};

}  // namespace skintune::internal
