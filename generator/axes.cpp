#include "generator/axes.h"

#include <algorithm>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace skintune::internal {

namespace {

constexpr bool SameText(const char* a, const char* b) {
  return std::string_view(a) == std::string_view(b);
}

// Axis i reads and writes Variant's field i, and no other: change field i
// through VariantFields and only axis i's code may move.
template <std::size_t I>
constexpr bool AxisReadsField() {
  Variant v{};
  int before[kAxisCount] = {};
  for (std::size_t a = 0; a < kAxisCount; ++a) before[a] = kAxes[a].field.get(v);
  auto& field = std::get<I>(VariantFields(v));
  using T = std::remove_cvref_t<decltype(field)>;
  if constexpr (std::is_same_v<T, bool>) field = !field;
  else field = static_cast<T>(static_cast<int>(field) + 1);
  for (std::size_t a = 0; a < kAxisCount; ++a) {
    if ((kAxes[a].field.get(v) != before[a]) != (a == I)) return false;
  }
  Variant back{};
  kAxes[I].field.set(back, kAxes[I].field.get(v));
  return back == v;
}

constexpr bool AxesFollowVariantFields() {
  if (std::tuple_size_v<VariantFieldRefs> != kAxisCount) return false;
  return []<std::size_t... I>(std::index_sequence<I...>) {
    return (AxisReadsField<I>() && ...);
  }(std::make_index_sequence<kAxisCount>{});
}
static_assert(std::tuple_size_v<VariantFieldRefs> == kAxisCount,
              "every field of Variant needs its axis in kAxes (generator/axes.h)");
static_assert(AxesFollowVariantFields(), "kAxes[i] must read Variant's field i (in declaration order)");

// The decisions an entry cannot leave to a default.
constexpr bool EveryDecisionMade() {
  for (const Axis& a : kAxes) {
    if (a.define == nullptr || a.covering == Covering::kUnset || a.chart == Chart::kUnset) return false;
    if ((a.covering == Covering::kRotated) != (a.covering_step > 0)) return false;
  }
  return true;
}
static_assert(EveryDecisionMade(), "each axis sets define (or kNoDefine), covering (a step when rotated) and chart");

// Enum axes list every enumerator in order (value i is enumerator i, so
// ForEach, Full and the coordinates follow the enum); numbers have a key
// prefix and no names; names and tokens exist for the rest.
constexpr bool ValuesAreWellFormed() {
  for (const Axis& a : kAxes) {
    if (a.values.size() == 0) return false;
    for (std::size_t i = 0; i < a.values.size(); ++i) {
      const AxisValueSpec& v = a.values[i];
      const bool number = a.field.kind == AxisKind::kNumber;
      if (number != (v.name == nullptr) || number != (*a.key_prefix != '\0')) return false;
      if (!number && (v.token == nullptr || *v.token == '\0' || v.code != static_cast<int>(i))) return false;
    }
  }
  return true;
}
static_assert(ValuesAreWellFormed(), "enum values in enum order, named; numbers with a key prefix");

// A joined axis follows a number axis (its token is the number's suffix:
// v2 + c) and is charted with it; paired axes and embedded enums are enums.
constexpr bool JoinsAndRolesFit() {
  for (std::size_t i = 0; i < kAxisCount; ++i) {
    const Axis& a = kAxes[i];
    if (a.joins_previous && (i == 0 || kAxes[i - 1].field.kind != AxisKind::kNumber ||
                             kAxes[i - 1].joins_previous || a.chart != kAxes[i - 1].chart))
      return false;
    if ((a.covering == Covering::kPaired || a.embedded_enum) && a.field.kind != AxisKind::kEnum) return false;
    if (a.covering == Covering::kPerSet && !SameText(a.name, "lang")) return false;
  }
  return true;
}
static_assert(JoinsAndRolesFit(), "joined axes follow a number axis; paired and embedded axes are enums");

const AxisValueSpec& ValueOf(const Axis& axis, int code) {
  const AxisValueSpec* value = axis.Find(code);
  if (value == nullptr) {
    throw std::out_of_range("axis " + std::string(axis.name) + " has no value " + std::to_string(code));
  }
  return *value;
}

}  // namespace

std::array<int, kAxisCount> AxisCodes(const Variant& v) {
  std::array<int, kAxisCount> codes{};
  for (std::size_t i = 0; i < kAxisCount; ++i) codes[i] = kAxes[i].Get(v);
  return codes;
}

Variant CollapseWorkGroups(Variant v) {
  if (HasWorkGroups(v.lang)) return v;
  for (const Axis& a : kAxes)
    if (a.without_work_groups) a.Set(v, *a.without_work_groups);
  return v;
}

const char* AxisValueName(std::size_t axis, int code) { return ValueOf(kAxes[axis], code).name; }

std::string KeyToken(const Axis& axis, int code) {
  if (axis.field.kind == AxisKind::kNumber) return axis.key_prefix + std::to_string(code);
  return ValueOf(axis, code).token;
}

std::string KeyFormat() {
  std::string format;
  for (std::size_t i = 0; i < kAxisCount; ++i) {
    const Axis& a = kAxes[i];
    if (i > 0 && !a.joins_previous) format += a.key_omits_default ? "[." : ".";
    if (a.key_hint != nullptr) {
      format += a.key_hint;
      continue;
    }
    std::string choices;
    for (const AxisValueSpec& v : a.values) {
      if (a.key_omits_default && v.code == a.values[0].code) continue;  // its absence
      choices += (choices.empty() ? "" : "|") + (v.token ? std::string(v.token) : std::to_string(v.code));
    }
    format += a.key_prefix + ("<" + choices + ">") + (a.key_omits_default ? "]" : "");
  }
  return format;
}

std::string ValueLabel(const Axis& axis, int code) {
  if (axis.field.kind != AxisKind::kNumber) return ValueOf(axis, code).name;
  // The no-work-group value is no size: a vertex shader has no work-group.
  if (axis.without_work_groups == code && axis.Find(code) == nullptr) return "none";
  return std::to_string(code);
}

std::optional<int> CodeNamed(const Axis& axis, std::string_view name) {
  for (const AxisValueSpec& v : axis.values)
    if (v.name != nullptr && name == v.name) return v.code;
  return std::nullopt;
}

std::string Choices(const Axis& axis) {
  std::string s;
  for (const AxisValueSpec& v : axis.values) s += (s.empty() ? "" : ", ") + std::string(v.name);
  return s;
}

std::optional<std::size_t> AxisNamed(std::string_view name) {
  for (std::size_t i = 0; i < kAxisCount; ++i)
    if (name == kAxes[i].name) return i;
  return std::nullopt;
}

int DefineValue(const Axis& axis, int code) {
  if (axis.field.kind == AxisKind::kNumber) return code;
  return ValueOf(axis, code).define;
}

nlohmann::json ValueJson(const Axis& axis, int code) {
  switch (axis.field.kind) {
    case AxisKind::kNumber: return code;
    case AxisKind::kFlag: return code != 0;
    case AxisKind::kEnum: break;
  }
  return ValueOf(axis, code).name;
}

}  // namespace skintune::internal
