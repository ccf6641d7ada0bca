// skintune: a small set of variants that covers a language's space: every
// value of every axis appears at least once, and every pair of values of the
// axes layout x index x weight x palette x storage x blend appears together at
// least once (a pairwise covering array, built greedily). Only variants valid
// for the device and problem are chosen; a pair no valid variant can hold
// (e.g. local storage in a vertex shader) is left out and reported.
#pragma once

#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"

namespace skintune::internal {

struct CoveringSet {
  std::vector<Variant> variants;
  std::vector<std::string> uncoverable;  // "storage=local & blend=point" pairs no valid variant holds
};

// Deterministic for the same inputs. `wg_sizes` lists the work-group sizes to
// rotate through (those above the device limit are skipped).
CoveringSet BuildCoveringSet(Lang lang, const DeviceLimits& device, const ProblemShape& shape,
                             const std::vector<int>& wg_sizes = {32, 64, 128, 256, 512, 1024});

}  // namespace skintune::internal
