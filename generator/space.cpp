#include "generator/space.h"

#include <algorithm>
#include <array>
#include <optional>
#include <utility>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "base/error.h"

namespace skintune::internal {

namespace {

// Each list as axis codes (generator/axes.h), in table order.
using Codes = std::vector<int>;
using SpaceCodes = std::array<Codes, kAxisCount>;

using SpaceListRefs = decltype(SpaceLists(std::declval<TuningSpace&>()));
static_assert(std::tuple_size_v<SpaceListRefs> == kAxisCount, "TuningSpace needs one list per axis");
static_assert([]<std::size_t... I>(std::index_sequence<I...>) {
  return (std::is_same_v<typename std::remove_reference_t<std::tuple_element_t<I, SpaceListRefs>>::value_type,
                         std::remove_reference_t<std::tuple_element_t<I, VariantFieldRefs>>> && ...);
}(std::make_index_sequence<kAxisCount>{}), "TuningSpace's list i holds values of Variant's field i");

// Calls visit(i, list i) for every list.
template <typename Space, typename Visit>
void ForEachList(Space& s, Visit&& visit) {
  std::apply([&](auto&... lists) {
    std::size_t i = 0;
    (visit(i++, lists), ...);
  }, SpaceLists(s));
}

SpaceCodes CodesOf(const TuningSpace& s) {
  SpaceCodes codes;
  ForEachList(s, [&](std::size_t i, const auto& list) {
    for (auto value : list) codes[i].push_back(static_cast<int>(value));
  });
  return codes;
}

void SetList(TuningSpace& s, std::size_t axis, const Codes& codes) {
  ForEachList(s, [&](std::size_t i, auto& list) {
    if (i != axis) return;
    using T = typename std::remove_reference_t<decltype(list)>::value_type;
    list.clear();
    for (int code : codes) list.push_back(static_cast<T>(code));
  });
}

// The lists one language enumerates: without work-groups, those axes take their one value.
SpaceCodes ForLanguage(SpaceCodes codes, int lang) {
  constexpr std::size_t kLang = AxisIndex<&Variant::lang>();
  codes[kLang] = {lang};
  if (HasWorkGroups(static_cast<Lang>(lang))) return codes;
  for (std::size_t i = 0; i < kAxisCount; ++i)
    if (kAxes[i].without_work_groups) codes[i] = {*kAxes[i].without_work_groups};
  return codes;
}

// Every combination, the last axis fastest.
void Odometer(const SpaceCodes& lists, const std::function<void(const Variant&)>& visit) {
  for (const Codes& list : lists)
    if (list.empty()) return;
  std::array<std::size_t, kAxisCount> at{};
  Variant v;
  for (std::size_t i = 0; i < kAxisCount; ++i) kAxes[i].Set(v, lists[i][0]);
  for (;;) {
    visit(v);
    std::size_t a = kAxisCount;
    do {
      if (a == 0) return;
      --a;
      at[a] = (at[a] + 1) % lists[a].size();
      kAxes[a].Set(v, lists[a][at[a]]);
    } while (at[a] == 0);
  }
}

// One axis's list from a config: value names, integers, or true / false.
Codes ReadList(const Axis& axis, const nlohmann::json& list, const std::string& where) {
  Codes codes;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string item_where = where + "[" + std::to_string(i) + "]";
    const nlohmann::json& item = list[i];
    if (axis.field.kind == AxisKind::kNumber) {
      if (!item.is_number_integer()) throw Error(item_where + ": expected an integer");
      codes.push_back(item.get<int>());
    } else if (axis.field.kind == AxisKind::kFlag || (axis.reads_flags && item.is_boolean())) {
      if (!item.is_boolean()) throw Error(item_where + ": expected true or false");
      codes.push_back(item.get<bool>() ? 1 : 0);
    } else {
      if (!item.is_string()) throw Error(item_where + ": expected a string");
      const std::optional<int> code = CodeNamed(axis, item.get<std::string>());
      if (!code) {
        throw Error(item_where + ": unknown value '" + item.get<std::string>() + "' (expected one of " +
                    Choices(axis) + ")");
      }
      codes.push_back(*code);
    }
  }
  return codes;
}

std::string AxisNames() {
  std::string names;
  for (const Axis& a : kAxes) names += (names.empty() ? "" : ", ") + std::string(a.name);
  return names;
}

}  // namespace

TuningSpace TuningSpace::Full() {
  TuningSpace s;
  for (std::size_t i = 0; i < kAxisCount; ++i) {
    Codes codes;
    for (const AxisValueSpec& value : kAxes[i].values) codes.push_back(value.code);
    SetList(s, i, codes);
  }
  return s;
}

void TuningSpace::Validate(const std::string& context) const {
  ForEachList(*this, [&](std::size_t i, const auto& list) {
    if (list.empty()) throw Error(context + ": space." + kAxes[i].name + " is empty");
  });
}

void TuningSpace::ForEach(const std::function<void(const Variant&)>& visit) const {
  const SpaceCodes codes = CodesOf(*this);
  for (int lang : codes[AxisIndex<&Variant::lang>()]) Odometer(ForLanguage(codes, lang), visit);
}

std::uint64_t TuningSpace::Size() const {
  const SpaceCodes codes = CodesOf(*this);
  std::uint64_t total = 0;
  for (int lang : codes[AxisIndex<&Variant::lang>()]) {
    std::uint64_t points = 1;
    for (const Codes& list : ForLanguage(codes, lang)) points *= list.size();
    total += points;
  }
  return total;
}

TuningSpace SpaceFromJson(const nlohmann::json& in, const std::string& context) {
  if (!in.is_object()) throw Error(context + ": space must be an object of axis -> list of values");
  TuningSpace s = TuningSpace::Full();
  bool blend_given = false, palette_given = false, normal_format_given = false;
  for (const auto& [name, list] : in.items()) {
    const std::string where = context + ": space." + name;
    if (!list.is_array()) throw Error(where + ": expected a list of values");
    const std::optional<std::size_t> axis = AxisNamed(name);
    if (!axis) throw Error(where + ": unknown axis (expected " + AxisNames() + ")");
    SetList(s, *axis, ReadList(kAxes[*axis], list, where));
    blend_given = blend_given || *axis == AxisIndex<&Variant::blend>();
    palette_given = palette_given || *axis == AxisIndex<&Variant::palette>();
    normal_format_given = normal_format_given || *axis == AxisIndex<&Variant::normal_format>();
  }
  // The format of the skinned normals is what the user's consumer reads, not
  // a choice the tuner makes: left out, it is float32. Listed formats are
  // tuned as rows of their own (tuner/report.cpp), never raced.
  if (!normal_format_given) s.normal_formats = {NormalFormat::kF32};
  // Dual quaternions skin differently from the linear blends (they keep
  // volume at twisting joints): a user's choice, tuned in a space of its own,
  // never raced against matrix and point blending. Left out, the blend axis
  // is the linear two, and the palette axis the formats the blends read.
  const auto dq = [](Blend b) { return b == Blend::kDualQuaternion; };
  if (!blend_given) std::erase_if(s.blends, dq);
  if (std::any_of(s.blends.begin(), s.blends.end(), dq) && !std::all_of(s.blends.begin(), s.blends.end(), dq))
    throw Error(context + ": space.blend: \"dq\" (dual quaternions) skins differently from \"matrix\" and \"point\" "
                "(linear blending), so the two are not raced: tune [\"dq\"] in a space of its own");
  if (!palette_given) {
    const bool dq_blend = !s.blends.empty() && dq(s.blends.front());
    std::erase_if(s.palettes, [&](PaletteFormat p) { return (p == PaletteFormat::kDualQuaternion) != dq_blend; });
  }
  s.Validate(context);
  return s;
}

void to_json(nlohmann::json& out, const TuningSpace& s) {
  const SpaceCodes codes = CodesOf(s);
  out = nlohmann::json::object();
  for (std::size_t i = 0; i < kAxisCount; ++i) {
    nlohmann::json list = nlohmann::json::array();
    for (int code : codes[i]) list.push_back(ValueJson(kAxes[i], code));
    out[kAxes[i].name] = list;
  }
}

TuningSpace ForDataSet(TuningSpace space, const ProblemShape& shape) {
  std::erase_if(space.morphs, [&](Morph m) {
    return m == Morph::kNone ? shape.morph_moves : shape.morph_targets == 0;
  });
  if (!shape.has_normals) std::erase_if(space.normal_formats, [](NormalFormat f) { return f != NormalFormat::kF32; });
  std::erase_if(space.animations, [&](Animation a) { return (a != Animation::kHost) != shape.animated; });
  return space;
}

SpaceCount Enumerate(const TuningSpace& space, const DeviceLimits& device, const ProblemShape& shape,
                     const std::function<void(const Variant&)>& valid) {
  SpaceCount count;
  ForDataSet(space, shape).ForEach([&](const Variant& v) {
    const std::vector<Violation> broken = CheckVariant(v, device, shape);
    ++count.total;
    if (broken.empty()) {
      ++count.valid;
      if (valid) valid(v);
    } else {
      ++count.invalid_by[broken.front().constraint];
    }
  });
  return count;
}

}  // namespace skintune::internal
