#include "generator/variant.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <optional>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "base/error.h"

namespace skintune::internal {

namespace {

std::optional<int> Number(std::string_view text) {
  int value = 0;
  auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

// Sets axis i (and the axis glued to it) from `token`; false when it is not one of axis i's tokens.
bool MatchAxis(std::size_t i, std::string_view token, Variant& v) {
  const Axis& a = kAxes[i];
  if (a.field.kind != AxisKind::kNumber) {
    for (const AxisValueSpec& value : a.values) {
      if (token == value.token) {
        a.Set(v, value.code);
        return true;
      }
    }
    return false;
  }
  const std::string_view prefix = a.key_prefix;
  if (token.size() <= prefix.size() || !token.starts_with(prefix)) return false;
  const std::string_view rest = token.substr(prefix.size());
  if (!JoinsNext(i)) {
    const std::optional<int> n = Number(rest);
    if (n) a.Set(v, *n);
    return n.has_value();
  }
  for (const AxisValueSpec& suffix : kAxes[i + 1].values) {
    const std::string_view s = suffix.token;
    if (rest.size() <= s.size() || !rest.ends_with(s)) continue;
    if (const std::optional<int> n = Number(rest.substr(0, rest.size() - s.size()))) {
      a.Set(v, *n);
      kAxes[i + 1].Set(v, suffix.code);
      return true;
    }
  }
  return false;
}

// The axis whose token this is (a glued pair answers its first axis).
std::optional<std::size_t> MatchToken(std::string_view token, Variant& v) {
  for (std::size_t i = 0; i < kAxisCount; ++i) {
    if (!kAxes[i].joins_previous && MatchAxis(i, token, v)) return i;
  }
  return std::nullopt;
}

}  // namespace

std::size_t BytesOf(PositionFormat f) { return f == PositionFormat::kFloat4 ? 16 : 12; }
std::size_t BytesOf(IndexFormat f) { return f == IndexFormat::kI32 ? 4 : f == IndexFormat::kU16 ? 2 : 1; }
std::size_t BytesOf(WeightFormat f) { return f == WeightFormat::kF32 ? 4 : f == WeightFormat::kUnorm16 ? 2 : 1; }
std::size_t BytesOf(PaletteFormat f) { return f == PaletteFormat::kMat4 ? 64 : f == PaletteFormat::kMat3x4 ? 48 : 32; }

std::string Variant::Key() const {
  std::string key;
  for (std::size_t i = 0; i < kAxisCount; ++i) {
    const int code = kAxes[i].Get(*this);
    if (kAxes[i].key_omits_default && code == kAxes[i].values[0].code) continue;
    if (i > 0 && !kAxes[i].joins_previous) key += ".";
    key += KeyToken(kAxes[i], code);
  }
  return key;
}

std::size_t Variant::Hash() const {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : Key()) h = (h ^ c) * 1099511628211ull;
  return static_cast<std::size_t>(h);
}

Variant ParseVariantKey(std::string_view key) {
  Variant v;
  std::array<bool, kAxisCount> seen{};
  const std::string quoted = "variant '" + std::string(key) + "': ";
  if (key.empty()) throw Error(quoted + "empty key (expected " + KeyFormat() + ")");
  std::size_t start = 0;
  while (start <= key.size()) {
    const std::size_t dot = std::min(key.find('.', start), key.size());
    const std::string_view token = key.substr(start, dot - start);
    const std::optional<std::size_t> axis = MatchToken(token, v);
    if (!axis) {
      throw Error(quoted + "unknown token '" + std::string(token) + "' (expected " + KeyFormat() + ")");
    }
    if (seen[*axis]) throw Error(quoted + "axis '" + kAxes[*axis].name + "' given twice");
    seen[*axis] = true;
    if (JoinsNext(*axis)) seen[*axis + 1] = true;
    start = dot + 1;
  }
  // A vertex shader has no work-groups: the axes it lacks default to wg0, v1c.
  if (!HasWorkGroups(v.lang)) {
    for (std::size_t i = 0; i < kAxisCount; ++i)
      if (kAxes[i].without_work_groups && !seen[i]) kAxes[i].Set(v, *kAxes[i].without_work_groups);
  }
  return v;
}

void to_json(nlohmann::json& out, const Variant& v) {
  out = {{"key", v.Key()}};
  for (const Axis& a : kAxes) out[a.name] = ValueJson(a, a.Get(v));
}

namespace {

int ReadValue(const Axis& a, const nlohmann::json& j) {
  const std::string field = std::string("variant JSON: '") + a.name + "' ";
  switch (a.field.kind) {
    case AxisKind::kNumber:
      if (!j.is_number_integer()) throw Error(field + "must be an integer");
      return j.get<int>();
    case AxisKind::kFlag:
      if (!j.is_boolean()) throw Error(field + "must be true or false");
      return j.get<bool>() ? 1 : 0;
    case AxisKind::kEnum: break;
  }
  if (a.reads_flags && j.is_boolean()) return j.get<bool>() ? 1 : 0;
  if (!j.is_string()) throw Error(field + "must be a string");
  const std::optional<int> code = CodeNamed(a, j.get<std::string>());
  if (!code) {
    throw Error(field + "has unknown value '" + j.get<std::string>() + "' (expected one of " + Choices(a) + ")");
  }
  return *code;
}

}  // namespace

void from_json(const nlohmann::json& in, Variant& v) {
  if (!in.is_object()) throw Error("variant JSON: expected an object");
  v = Variant{};
  for (const Axis& a : kAxes) {
    if (in.contains(a.name)) a.Set(v, ReadValue(a, in[a.name]));
  }
  if (!HasWorkGroups(v.lang)) {
    for (const Axis& a : kAxes)
      if (a.without_work_groups && !in.contains(a.name)) a.Set(v, *a.without_work_groups);
  }
  if (in.contains("key") && in["key"].is_string() && in["key"].get<std::string>() != v.Key()) {
    throw Error("variant JSON: 'key' " + in["key"].get<std::string>() + " does not match the fields (" + v.Key() + ")");
  }
}

}  // namespace skintune::internal
