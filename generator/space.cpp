#include "generator/space.h"

#include <nlohmann/json.hpp>

#include "reference/error.h"

namespace skintune {

namespace {

template <typename E, std::size_t N>
std::vector<E> All() {
  std::vector<E> values;
  for (std::size_t i = 0; i < N; ++i) values.push_back(static_cast<E>(i));
  return values;
}

// Parses one enum axis: a list of value names.
template <typename E, std::size_t N>
std::vector<E> EnumAxis(const nlohmann::json& list, const std::string& where) {
  std::vector<E> values;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string item_where = where + "[" + std::to_string(i) + "]";
    if (!list[i].is_string()) throw Error(item_where + ": expected a string");
    bool found = false;
    for (E e : All<E, N>()) {
      if (list[i].get<std::string>() == Name(e)) {
        values.push_back(e);
        found = true;
      }
    }
    if (!found) {
      std::string choices;
      for (E e : All<E, N>()) choices += (choices.empty() ? "" : ", ") + std::string(Name(e));
      throw Error(item_where + ": unknown value '" + list[i].get<std::string>() + "' (expected one of " + choices +
                  ")");
    }
  }
  return values;
}

std::vector<int> IntAxis(const nlohmann::json& list, const std::string& where) {
  std::vector<int> values;
  for (std::size_t i = 0; i < list.size(); ++i) {
    if (!list[i].is_number_integer()) throw Error(where + "[" + std::to_string(i) + "]: expected an integer");
    values.push_back(list[i].get<int>());
  }
  return values;
}

template <typename E>
nlohmann::json Names(const std::vector<E>& values) {
  nlohmann::json list = nlohmann::json::array();
  for (E e : values) list.push_back(Name(e));
  return list;
}

}  // namespace

TuningSpace TuningSpace::Full() {
  TuningSpace s;
  s.langs = All<Lang, 4>();
  s.influences = {1, 2, 3, 4, 5, 6, 7, 8};
  s.mixed = All<MixedCounts, 2>();
  s.layouts = All<Layout, 3>();
  s.positions = All<PositionFormat, 2>();
  s.indices = All<IndexFormat, 3>();
  s.weights = All<WeightFormat, 3>();
  s.palettes = All<PaletteFormat, 2>();
  s.storages = All<PaletteStorage, 4>();
  s.blends = All<Blend, 2>();
  s.vertices_per_item = {1, 2, 4, 8};
  s.assignments = All<Assignment, 2>();
  s.wg_sizes = {32, 64, 128, 256, 512, 1024};
  s.normals = {false, true};
  return s;
}

void TuningSpace::Validate(const std::string& context) const {
  const std::pair<const char*, std::size_t> axes[] = {
      {"lang", langs.size()},         {"influences", influences.size()},
      {"mixed", mixed.size()},        {"layout", layouts.size()},
      {"position", positions.size()}, {"index", indices.size()},
      {"weight", weights.size()},     {"palette", palettes.size()},
      {"storage", storages.size()},   {"blend", blends.size()},
      {"vertices_per_item", vertices_per_item.size()},
      {"assignment", assignments.size()}, {"wg_size", wg_sizes.size()},
      {"normals", normals.size()}};
  for (const auto& [name, size] : axes) {
    if (size == 0) throw Error(context + ": space." + name + " is empty");
  }
}

void TuningSpace::ForEach(const std::function<void(const Variant&)>& visit) const {
  Variant v;
  for (Lang lang : langs) {
    v.lang = lang;
    const bool no_groups = lang == Lang::kGlslVertex;
    const std::vector<int> wgs = no_groups ? std::vector<int>{0} : wg_sizes;
    const std::vector<int> vpis = no_groups ? std::vector<int>{1} : vertices_per_item;
    const std::vector<Assignment> assigns = no_groups ? std::vector<Assignment>{Assignment::kContiguous} : assignments;
    for (int b : influences) for (MixedCounts m : mixed) for (Layout l : layouts) for (PositionFormat p : positions)
    for (IndexFormat i : indices) for (WeightFormat w : weights) for (PaletteFormat pf : palettes)
    for (PaletteStorage st : storages) for (Blend bl : blends) for (int vpi : vpis) for (Assignment a : assigns)
    for (int wg : wgs) for (bool n : normals) {
      v.influences = b; v.mixed = m; v.layout = l; v.position = p; v.index = i; v.weight = w; v.palette = pf;
      v.storage = st; v.blend = bl; v.vertices_per_item = vpi; v.assignment = a; v.wg_size = wg; v.normals = n;
      visit(v);
    }
  }
}

std::uint64_t TuningSpace::Size() const {
  const std::uint64_t shared = influences.size() * mixed.size() * layouts.size() * positions.size() *
                               indices.size() * weights.size() * palettes.size() * storages.size() *
                               blends.size() * normals.size();
  std::uint64_t total = 0;
  for (Lang lang : langs) {
    total += lang == Lang::kGlslVertex ? shared
                                       : shared * vertices_per_item.size() * assignments.size() * wg_sizes.size();
  }
  return total;
}

TuningSpace SpaceFromJson(const nlohmann::json& in, const std::string& context) {
  if (!in.is_object()) throw Error(context + ": space must be an object of axis -> list of values");
  TuningSpace s = TuningSpace::Full();
  for (const auto& [axis, list] : in.items()) {
    const std::string where = context + ": space." + axis;
    if (!list.is_array()) throw Error(where + ": expected a list of values");
    if (axis == "lang") s.langs = EnumAxis<Lang, 4>(list, where);
    else if (axis == "influences") s.influences = IntAxis(list, where);
    else if (axis == "mixed") s.mixed = EnumAxis<MixedCounts, 2>(list, where);
    else if (axis == "layout") s.layouts = EnumAxis<Layout, 3>(list, where);
    else if (axis == "position") s.positions = EnumAxis<PositionFormat, 2>(list, where);
    else if (axis == "index") s.indices = EnumAxis<IndexFormat, 3>(list, where);
    else if (axis == "weight") s.weights = EnumAxis<WeightFormat, 3>(list, where);
    else if (axis == "palette") s.palettes = EnumAxis<PaletteFormat, 2>(list, where);
    else if (axis == "storage") s.storages = EnumAxis<PaletteStorage, 4>(list, where);
    else if (axis == "blend") s.blends = EnumAxis<Blend, 2>(list, where);
    else if (axis == "vertices_per_item") s.vertices_per_item = IntAxis(list, where);
    else if (axis == "assignment") s.assignments = EnumAxis<Assignment, 2>(list, where);
    else if (axis == "wg_size") s.wg_sizes = IntAxis(list, where);
    else if (axis == "normals") {
      s.normals.clear();
      for (std::size_t i = 0; i < list.size(); ++i) {
        if (!list[i].is_boolean()) throw Error(where + "[" + std::to_string(i) + "]: expected true or false");
        s.normals.push_back(list[i].get<bool>());
      }
    } else {
      throw Error(where + ": unknown axis (expected lang, influences, mixed, layout, position, index, weight, "
                          "palette, storage, blend, vertices_per_item, assignment, wg_size, normals)");
    }
  }
  s.Validate(context);
  return s;
}

void to_json(nlohmann::json& out, const TuningSpace& s) {
  out = {{"lang", Names(s.langs)},           {"influences", s.influences},
         {"mixed", Names(s.mixed)},          {"layout", Names(s.layouts)},
         {"position", Names(s.positions)},   {"index", Names(s.indices)},
         {"weight", Names(s.weights)},       {"palette", Names(s.palettes)},
         {"storage", Names(s.storages)},     {"blend", Names(s.blends)},
         {"vertices_per_item", s.vertices_per_item}, {"assignment", Names(s.assignments)},
         {"wg_size", s.wg_sizes},            {"normals", s.normals}};
}

SpaceCount Enumerate(const TuningSpace& space, const DeviceLimits& device, const ProblemShape& shape,
                     const std::function<void(const Variant&)>& valid) {
  SpaceCount count;
  space.ForEach([&](const Variant& v) {
    ++count.total;
    const std::vector<Violation> broken = CheckVariant(v, device, shape);
    if (broken.empty()) {
      ++count.valid;
      if (valid) valid(v);
    } else {
      ++count.invalid_by[broken.front().constraint];
    }
  });
  return count;
}

}  // namespace skintune
