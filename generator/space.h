// skintune: a tuning space (the values to try on each axis) and its enumeration.
//
// Configs (configs/*.json) give a space as an object of axis -> list of values
// (names as in variant keys; numbers for influences, vertices_per_item and
// wg_size; "none", "normals" or "tangents" for normals, where older configs
// wrote false / true); an axis left out takes every value
// (TuningSpace::Full). glsl-vertex has no work-groups: for it the wg_size and
// vertices_per_item/assignment axes collapse to wg0 / v1c.
#pragma once

#include <concepts>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/constraints.h"
#include "generator/variant.h"

namespace skintune::internal {

struct TuningSpace {
  std::vector<Lang> langs;
  std::vector<int> influences;
  std::vector<MixedCounts> mixed;
  std::vector<Layout> layouts;
  std::vector<PositionFormat> positions;
  std::vector<IndexFormat> indices;
  std::vector<WeightFormat> weights;
  std::vector<PaletteFormat> palettes;
  std::vector<PaletteStorage> storages;
  std::vector<Blend> blends;
  std::vector<int> vertices_per_item;
  std::vector<Assignment> assignments;
  std::vector<int> wg_sizes;
  std::vector<Normals> normals;
  std::vector<Morph> morphs;
  std::vector<NormalFormat> normal_formats;
  std::vector<Animation> animations;

  // Every value of every axis: wg sizes 32, 64, 128, 256, 512, 1024.
  static TuningSpace Full();
  // Throws Error("<context>: ...") naming the empty axis.
  void Validate(const std::string& context) const;
  // Number of points before constraints.
  std::uint64_t Size() const;
  // Calls `visit` for every point (before constraints), in a fixed order.
  void ForEach(const std::function<void(const Variant&)>& visit) const;
};

// The lists in field order: list i holds values of Variant's field i, so of
// axis i (generator/axes.h). A list added without its axis, or an axis
// without its list, fails the build in space.cpp.
template <typename T>
  requires std::same_as<std::remove_const_t<T>, TuningSpace>
constexpr auto SpaceLists(T& s) {
  auto& [langs, influences, mixed, layouts, positions, indices, weights, palettes, storages, blends,
         vertices_per_item, assignments, wg_sizes, normals, morphs, normal_formats, animations] = s;
  return std::tie(langs, influences, mixed, layouts, positions, indices, weights, palettes, storages, blends,
                  vertices_per_item, assignments, wg_sizes, normals, morphs, normal_formats, animations);
}

// Reads a space from JSON; unknown axes and values throw Error("<context>: space.<axis>[i]: ...").
TuningSpace SpaceFromJson(const nlohmann::json& in, const std::string& context);
void to_json(nlohmann::json& out, const TuningSpace& space);

struct SpaceCount {
  std::uint64_t total = 0;
  std::uint64_t valid = 0;
  std::map<Constraint, std::uint64_t> invalid_by;  // first broken constraint of each invalid point
};

// `space` with the values of the axes the data set decides kept to those of
// this data set: a mesh without morph targets has no morph variants, one
// whose targets move it none without them (what NotOfThisDataSet's
// constraints would refuse). May leave an axis empty (the space lists none
// of the data set's values).
TuningSpace ForDataSet(TuningSpace space, const ProblemShape& shape);

// Enumerates ForDataSet(space, shape) against a device and problem; `valid`
// (optional) receives each runnable variant.
SpaceCount Enumerate(const TuningSpace& space, const DeviceLimits& device, const ProblemShape& shape,
                     const std::function<void(const Variant&)>& valid = {});

}  // namespace skintune::internal
