#include "generator/variant.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <optional>

#include <nlohmann/json.hpp>

#include "reference/error.h"

namespace skintune {

namespace {

// One table per enum: value names in enum order.
template <typename E>
struct Names;
template <> struct Names<Lang> { static constexpr std::array<const char*, 4> kValues{"opencl", "cuda", "glsl-compute", "glsl-vertex"}; static constexpr const char* kAxis = "lang"; };
template <> struct Names<MixedCounts> { static constexpr std::array<const char*, 2> kValues{"padded", "bucketed"}; static constexpr const char* kAxis = "mixed"; };
template <> struct Names<Layout> { static constexpr std::array<const char*, 3> kValues{"aos", "soa", "soa-split"}; static constexpr const char* kAxis = "layout"; };
template <> struct Names<PositionFormat> { static constexpr std::array<const char*, 2> kValues{"float4", "float3"}; static constexpr const char* kAxis = "position"; };
template <> struct Names<IndexFormat> { static constexpr std::array<const char*, 3> kValues{"i32", "u16", "u8"}; static constexpr const char* kAxis = "index"; };
template <> struct Names<WeightFormat> { static constexpr std::array<const char*, 3> kValues{"f32", "unorm16", "unorm8"}; static constexpr const char* kAxis = "weight"; };
template <> struct Names<PaletteFormat> { static constexpr std::array<const char*, 2> kValues{"mat4", "mat3x4"}; static constexpr const char* kAxis = "palette"; };
template <> struct Names<PaletteStorage> { static constexpr std::array<const char*, 4> kValues{"constant", "local", "global", "image"}; static constexpr const char* kAxis = "storage"; };
template <> struct Names<Blend> { static constexpr std::array<const char*, 2> kValues{"matrix", "point"}; static constexpr const char* kAxis = "blend"; };
template <> struct Names<Assignment> { static constexpr std::array<const char*, 2> kValues{"contiguous", "strided"}; static constexpr const char* kAxis = "assignment"; };

template <typename E>
const char* EnumName(E value) {
  return Names<E>::kValues.at(static_cast<std::size_t>(value));
}

template <typename E>
std::optional<E> EnumFromName(std::string_view name) {
  for (std::size_t i = 0; i < Names<E>::kValues.size(); ++i)
    if (name == Names<E>::kValues[i]) return static_cast<E>(i);
  return std::nullopt;
}

template <typename E>
std::string Choices() {
  std::string s;
  for (const char* n : Names<E>::kValues) s += (s.empty() ? "" : ", ") + std::string(n);
  return s;
}

std::optional<int> Number(std::string_view text) {
  int value = 0;
  auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

// Tries `token` against one enum axis; true when it matched.
template <typename E>
bool Match(std::string_view token, E& field, std::vector<std::string>& seen) {
  const std::optional<E> value = EnumFromName<E>(token);
  if (!value) return false;
  seen.push_back(Names<E>::kAxis);
  field = *value;
  return true;
}

const char* const kKeyFormat =
    "<lang>.b<B>.<padded|bucketed>.<aos|soa|soa-split>.<float4|float3>.<i32|u16|u8>.<f32|unorm16|unorm8>"
    ".<mat4|mat3x4>.<constant|local|global|image>.<matrix|point>.v<1|2|4|8><c|s>.wg<N>.<normals|nonormals>";

bool MatchNumeric(std::string_view token, Variant& v, std::vector<std::string>& seen) {
  if (token.size() > 1 && token[0] == 'b') {
    if (auto n = Number(token.substr(1))) {
      v.influences = *n;
      seen.push_back("influences");
      return true;
    }
  }
  if (token.size() > 2 && token.substr(0, 2) == "wg") {
    if (auto n = Number(token.substr(2))) {
      v.wg_size = *n;
      seen.push_back("wg_size");
      return true;
    }
  }
  if (token.size() > 2 && token[0] == 'v' && (token.back() == 'c' || token.back() == 's')) {
    if (auto n = Number(token.substr(1, token.size() - 2))) {
      v.vertices_per_item = *n;
      v.assignment = token.back() == 'c' ? Assignment::kContiguous : Assignment::kStrided;
      seen.push_back("vertices_per_item");
      return true;
    }
  }
  if (token == "normals" || token == "nonormals") {
    v.normals = token == "normals";
    seen.push_back("normals");
    return true;
  }
  return false;
}

}  // namespace

const char* Name(Lang v) { return EnumName(v); }
const char* Name(MixedCounts v) { return EnumName(v); }
const char* Name(Layout v) { return EnumName(v); }
const char* Name(PositionFormat v) { return EnumName(v); }
const char* Name(IndexFormat v) { return EnumName(v); }
const char* Name(WeightFormat v) { return EnumName(v); }
const char* Name(PaletteFormat v) { return EnumName(v); }
const char* Name(PaletteStorage v) { return EnumName(v); }
const char* Name(Blend v) { return EnumName(v); }
const char* Name(Assignment v) { return EnumName(v); }

std::size_t BytesOf(PositionFormat f) { return f == PositionFormat::kFloat4 ? 16 : 12; }
std::size_t BytesOf(IndexFormat f) { return f == IndexFormat::kI32 ? 4 : f == IndexFormat::kU16 ? 2 : 1; }
std::size_t BytesOf(WeightFormat f) { return f == WeightFormat::kF32 ? 4 : f == WeightFormat::kUnorm16 ? 2 : 1; }
std::size_t BytesOf(PaletteFormat f) { return f == PaletteFormat::kMat4 ? 64 : 48; }

std::string Variant::Key() const {
  std::string key = Name(lang);
  auto add = [&key](const std::string& token) { key += "." + token; };
  add("b" + std::to_string(influences));
  add(Name(mixed));
  add(Name(layout));
  add(Name(position));
  add(Name(index));
  add(Name(weight));
  add(Name(palette));
  add(Name(storage));
  add(Name(blend));
  add("v" + std::to_string(vertices_per_item) + (assignment == Assignment::kContiguous ? "c" : "s"));
  add("wg" + std::to_string(wg_size));
  add(normals ? "normals" : "nonormals");
  return key;
}

std::size_t Variant::Hash() const {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : Key()) h = (h ^ c) * 1099511628211ull;
  return static_cast<std::size_t>(h);
}

Variant ParseVariantKey(std::string_view key) {
  Variant v;
  std::vector<std::string> seen;
  const std::string quoted = "variant '" + std::string(key) + "': ";
  if (key.empty()) throw Error(quoted + "empty key (expected " + kKeyFormat + ")");
  std::size_t start = 0;
  while (start <= key.size()) {
    const std::size_t dot = std::min(key.find('.', start), key.size());
    const std::string_view token = key.substr(start, dot - start);
    const std::size_t before = seen.size();
    const bool matched = Match(token, v.lang, seen) || Match(token, v.mixed, seen) || Match(token, v.layout, seen) ||
                         Match(token, v.position, seen) || Match(token, v.index, seen) ||
                         Match(token, v.weight, seen) || Match(token, v.palette, seen) ||
                         Match(token, v.storage, seen) || Match(token, v.blend, seen) || MatchNumeric(token, v, seen);
    if (!matched) {
      throw Error(quoted + "unknown token '" + std::string(token) + "' (expected " + kKeyFormat + ")");
    }
    for (std::size_t i = 0; i < before; ++i) {
      if (seen[i] == seen.back()) throw Error(quoted + "axis '" + seen.back() + "' given twice");
    }
    start = dot + 1;
  }
  // A vertex shader has no work-groups: its canonical geometry is wg0, v1c.
  if (v.lang == Lang::kGlslVertex && std::find(seen.begin(), seen.end(), "wg_size") == seen.end()) v.wg_size = 0;
  return v;
}

void to_json(nlohmann::json& out, const Variant& v) {
  out = {{"key", v.Key()},
         {"lang", Name(v.lang)},
         {"influences", v.influences},
         {"mixed", Name(v.mixed)},
         {"layout", Name(v.layout)},
         {"position", Name(v.position)},
         {"index", Name(v.index)},
         {"weight", Name(v.weight)},
         {"palette", Name(v.palette)},
         {"storage", Name(v.storage)},
         {"blend", Name(v.blend)},
         {"vertices_per_item", v.vertices_per_item},
         {"assignment", Name(v.assignment)},
         {"wg_size", v.wg_size},
         {"normals", v.normals}};
}

namespace {

template <typename E>
void ReadEnum(const nlohmann::json& in, E& field) {
  const char* axis = Names<E>::kAxis;
  if (!in.contains(axis)) return;
  if (!in[axis].is_string()) throw Error(std::string("variant JSON: '") + axis + "' must be a string");
  const std::optional<E> value = EnumFromName<E>(in[axis].get<std::string>());
  if (!value) {
    throw Error(std::string("variant JSON: '") + axis + "' has unknown value '" + in[axis].get<std::string>() +
                "' (expected one of " + Choices<E>() + ")");
  }
  field = *value;
}

void ReadInt(const nlohmann::json& in, const char* name, int& field) {
  if (!in.contains(name)) return;
  if (!in[name].is_number_integer()) throw Error(std::string("variant JSON: '") + name + "' must be an integer");
  field = in[name].get<int>();
}

}  // namespace

void from_json(const nlohmann::json& in, Variant& v) {
  if (!in.is_object()) throw Error("variant JSON: expected an object");
  v = Variant{};
  ReadEnum(in, v.lang);
  ReadEnum(in, v.mixed);
  ReadEnum(in, v.layout);
  ReadEnum(in, v.position);
  ReadEnum(in, v.index);
  ReadEnum(in, v.weight);
  ReadEnum(in, v.palette);
  ReadEnum(in, v.storage);
  ReadEnum(in, v.blend);
  ReadEnum(in, v.assignment);
  ReadInt(in, "influences", v.influences);
  ReadInt(in, "vertices_per_item", v.vertices_per_item);
  if (v.lang == Lang::kGlslVertex) v.wg_size = 0;
  ReadInt(in, "wg_size", v.wg_size);
  if (in.contains("normals")) {
    if (!in["normals"].is_boolean()) throw Error("variant JSON: 'normals' must be true or false");
    v.normals = in["normals"].get<bool>();
  }
  if (in.contains("key") && in["key"].is_string() && in["key"].get<std::string>() != v.Key()) {
    throw Error("variant JSON: 'key' " + in["key"].get<std::string>() + " does not match the fields (" + v.Key() + ")");
  }
}

}  // namespace skintune
