// skintune: the variant axes, each declared once.
//
// Every list of axes in skintune is this table, as ozz-animation keeps one
// table of skinning functions and CLBlast one list of parameters per kernel:
// keys and JSON (variant.cpp), tuning spaces and configs (space.cpp), covering
// sets (covering.cpp), the kernels' #defines (emit.cpp), search coordinates
// (tuner/strategy.cpp, tuner/replay.cpp), the report's axis charts
// (report/paper_report.cpp) and the embedded header's enums
// (tools/emit/embed_header.cpp) iterate it instead of naming axes.
//
// Axis i is Variant's field i (VariantFields in variant.h). The static_asserts
// in axes.cpp fail the build when a field has no axis, an axis reads another
// field, or an entry leaves one of its decisions (define, covering, chart)
// unset; tests/generator/axes_test.cpp checks configs/*.schema.json list the
// same values. docs/ARCHITECTURE.md says how to add an axis. The lang axis's
// values are the rows of the language table (generator/languages.h).
#pragma once

#include <array>
#include <cstddef>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>

#include <nlohmann/json_fwd.hpp>

#include "generator/variant.h"

namespace skintune::internal {

// How a field holds its value, and so how keys, JSON and configs spell it.
enum class AxisKind {
  kEnum,    // a name: "soa-split"
  kNumber,  // an integer: 256 (in keys after a prefix: "wg256")
  kFlag,    // true / false in JSON and configs, a name in keys ("normals" / "nonormals")
};

// One value of an axis.
struct AxisValueSpec {
  int code = 0;                // the field's value as an int: the enumerator, the number, 0 / 1
  const char* name = nullptr;  // in keys, JSON, configs and reports (numbers: none, written as digits)
  const char* token = nullptr;  // in keys, when not `name`
  int define = 0;              // the value of the axis's #define in kernels
};

// An enumerator (or flag) value. `define` defaults to the enumerator's value.
template <typename E>
constexpr AxisValueSpec V(E value, const char* name) {
  return {static_cast<int>(value), name, name, static_cast<int>(value)};
}
template <typename E>
constexpr AxisValueSpec V(E value, const char* name, int define) {
  return {static_cast<int>(value), name, name, define};
}
template <typename E>
constexpr AxisValueSpec V(E value, const char* name, const char* token) {
  return {static_cast<int>(value), name, token, static_cast<int>(value)};
}
template <typename E>
constexpr AxisValueSpec V(E value, const char* name, const char* token, int define) {
  return {static_cast<int>(value), name, token, define};
}

// The values of the full space, in order (enum axes: every enumerator, in the enum's order).
class AxisValueList {
 public:
  static constexpr std::size_t kCapacity = 26;
  constexpr AxisValueList() = default;
  constexpr AxisValueList(std::initializer_list<AxisValueSpec> values) {
    for (const AxisValueSpec& v : values) Add(v);
  }
  constexpr AxisValueList(std::initializer_list<int> numbers) {
    for (int n : numbers) Add({n, nullptr, nullptr, n});
  }
  constexpr const AxisValueSpec* begin() const { return items_.data(); }
  constexpr const AxisValueSpec* end() const { return items_.data() + size_; }
  constexpr std::size_t size() const { return size_; }
  constexpr const AxisValueSpec& operator[](std::size_t i) const { return items_[i]; }
  constexpr void Add(const AxisValueSpec& v) {
    if (size_ == kCapacity) throw "an axis lists more than AxisValueList::kCapacity values";
    items_[size_++] = v;
  }

 private:
  std::array<AxisValueSpec, kCapacity> items_{};
  std::size_t size_ = 0;
};

// Reads and writes one field of Variant as an int code.
struct AxisField {
  AxisKind kind;
  int (*get)(const Variant&);
  void (*set)(Variant&, int);
};

template <auto Member>
constexpr int GetField(const Variant& v) {
  return static_cast<int>(v.*Member);
}
template <auto Member>
constexpr void SetField(Variant& v, int code) {
  v.*Member = static_cast<std::remove_cvref_t<decltype(v.*Member)>>(code);
}
template <auto Member>
constexpr AxisField FieldOf() {
  using T = std::remove_cvref_t<decltype(std::declval<Variant>().*Member)>;
  const AxisKind kind = std::is_same_v<T, bool> ? AxisKind::kFlag
                        : std::is_enum_v<T>      ? AxisKind::kEnum
                                                 : AxisKind::kNumber;
  return {kind, &GetField<Member>, &SetField<Member>};
}

// The decisions every axis must make (kUnset fails the build, axes.cpp).
inline constexpr const char* kNoDefine = "";
enum class Covering {
  kUnset,
  kPerSet,   // each covering set has one value (lang: a set per language)
  kPaired,   // every pair of values of two paired axes appears in the set
  kRotated,  // row i takes value (i / covering_step) % count
};
enum class Chart {
  kUnset,
  kNo,   // not charted (fixed by the chart's language or data set, or not tuned there)
  kYes,  // a bar per value in the report's "what each variant axis costs" chart
};

struct Axis {
  const char* name;      // Variant's field, the JSON field, the config axis, the report's label
  AxisField field;       // FieldOf<&Variant::name>()
  AxisValueList values;  // the full space (TuningSpace::Full)
  // Key: enum and flag values by their token; numbers as key_prefix + digits.
  const char* key_prefix = "";
  // The token is glued to the previous axis's ("v2" + "c" = v2c), and the
  // report charts the two axes as one ("2 contiguous").
  bool joins_previous = false;
  const char* key_hint = nullptr;  // in "expected ..." messages; default "<a|b|c>" or prefix"<1|2>"
  const char* define = nullptr;    // the kernels' #define (kNoDefine: none); value: AxisValueSpec::define or the number
  // The value a language without work-groups (glsl-vertex) takes: wg0, v1c.
  std::optional<int> without_work_groups = std::nullopt;
  Covering covering = Covering::kUnset;
  int covering_step = 0;                // kRotated: values change every `step` rows
  Chart chart = Chart::kUnset;
  const char* embedded_enum = nullptr;  // the enum type of the embedded header's Kernel field, if any
  // Keys leave the axis out while it has its first value, and files may
  // leave it out (the schemas do not require it): an axis added after keys
  // and files were recorded, so that every earlier variant's key and file
  // stay as they were.
  bool key_omits_default = false;
  // An enum axis that was a flag in earlier files (reports, winners
  // databases, configs): JSON's false / true read as the values of code 0 / 1.
  bool reads_flags = false;

  int Get(const Variant& v) const { return field.get(v); }
  void Set(Variant& v, int code) const { field.set(v, code); }
  // The listed value with this code, or nullptr (numbers outside the full space, wg0).
  constexpr const AxisValueSpec* Find(int code) const {
    for (const AxisValueSpec& value : values)
      if (value.code == code) return &value;
    return nullptr;
  }
};

// The lang axis's values: the language table's names (generator/languages.h).
consteval AxisValueList LanguageValues() {
  AxisValueList values;
  for (const Language& language : kLanguages) values.Add(V(language.lang, language.name));
  return values;
}

// The table. Order: Variant's fields = key order = ForEach nesting (last fastest).
inline constexpr Axis kAxes[] = {
    {.name = "lang",
     .field = FieldOf<&Variant::lang>(),
     .values = LanguageValues(),
     .key_hint = "<lang>",
     .define = kNoDefine,  // a template per language
     .covering = Covering::kPerSet,
     .chart = Chart::kNo},  // a chart per language
    {.name = "influences",
     .field = FieldOf<&Variant::influences>(),
     .values = {1, 2, 3, 4, 5, 6, 7, 8},
     .key_prefix = "b",
     .key_hint = "b<B>",
     .define = "INFLUENCES",
     .covering = Covering::kRotated,
     .covering_step = 1,
     .chart = Chart::kNo},  // set by the data set
    {.name = "mixed",
     .field = FieldOf<&Variant::mixed>(),
     .values = {V(MixedCounts::kPadded, "padded"), V(MixedCounts::kBucketed, "bucketed")},
     .define = kNoDefine,  // a bucketed launch runs a kernel specialised for its count
     .covering = Covering::kRotated,
     .covering_step = 1,
     .chart = Chart::kNo},  // configs/default.json and paper.json tune padded only
    {.name = "layout",
     .field = FieldOf<&Variant::layout>(),
     .values = {V(Layout::kAos, "aos"), V(Layout::kSoa, "soa"), V(Layout::kSoaSplit, "soa-split")},
     .define = "LAYOUT",
     .covering = Covering::kPaired,
     .chart = Chart::kYes,
     .embedded_enum = "Layout"},
    {.name = "position",
     .field = FieldOf<&Variant::position>(),
     .values = {V(PositionFormat::kFloat4, "float4", 1), V(PositionFormat::kFloat3, "float3", 0)},
     .define = "POSITION_FLOAT4",
     .covering = Covering::kRotated,
     .covering_step = 2,
     .chart = Chart::kYes,
     .embedded_enum = "PositionFormat"},
    {.name = "index",
     .field = FieldOf<&Variant::index>(),
     .values = {V(IndexFormat::kI32, "i32"), V(IndexFormat::kU16, "u16"), V(IndexFormat::kU8, "u8")},
     .define = "INDEX_FORMAT",
     .covering = Covering::kPaired,
     .chart = Chart::kYes,
     .embedded_enum = "IndexFormat"},
    {.name = "weight",
     .field = FieldOf<&Variant::weight>(),
     .values = {V(WeightFormat::kF32, "f32"), V(WeightFormat::kUnorm16, "unorm16"),
                V(WeightFormat::kUnorm8, "unorm8")},
     .define = "WEIGHT_FORMAT",
     .covering = Covering::kPaired,
     .chart = Chart::kYes,
     .embedded_enum = "WeightFormat"},
    {.name = "palette",
     .field = FieldOf<&Variant::palette>(),
     .values = {V(PaletteFormat::kMat4, "mat4", 4), V(PaletteFormat::kMat3x4, "mat3x4", 3),
                V(PaletteFormat::kDualQuaternion, "dualquat", 2)},
     .define = "PALETTE_ROWS",
     .covering = Covering::kPaired,
     .chart = Chart::kYes,
     .embedded_enum = "PaletteFormat"},
    {.name = "storage",
     .field = FieldOf<&Variant::storage>(),
     .values = {V(PaletteStorage::kConstant, "constant"), V(PaletteStorage::kLocal, "local"),
                V(PaletteStorage::kGlobal, "global"), V(PaletteStorage::kImage, "image")},
     .define = "STORAGE",
     .covering = Covering::kPaired,
     .chart = Chart::kYes,
     .embedded_enum = "PaletteStorage"},
    {.name = "blend",
     .field = FieldOf<&Variant::blend>(),
     .values = {V(Blend::kMatrix, "matrix"), V(Blend::kPoint, "point"), V(Blend::kDualQuaternion, "dq")},
     .define = "BLEND",  // 0 matrix, 1 point, 2 dual quaternion
     .covering = Covering::kPaired,
     .chart = Chart::kYes},
    {.name = "vertices_per_item",
     .field = FieldOf<&Variant::vertices_per_item>(),
     .values = {1, 2, 4, 8},
     .key_prefix = "v",
     .define = "VERTICES_PER_ITEM",
     .without_work_groups = 1,
     .covering = Covering::kRotated,
     .covering_step = 1,
     .chart = Chart::kYes},
    {.name = "assignment",
     .field = FieldOf<&Variant::assignment>(),
     .values = {V(Assignment::kContiguous, "contiguous", "c"), V(Assignment::kStrided, "strided", "s")},
     .joins_previous = true,
     .define = "STRIDED",
     .without_work_groups = static_cast<int>(Assignment::kContiguous),
     .covering = Covering::kRotated,
     .covering_step = 4,
     .chart = Chart::kYes},
    {.name = "wg_size",
     .field = FieldOf<&Variant::wg_size>(),
     .values = {32, 64, 128, 256, 512, 1024},
     .key_prefix = "wg",
     .key_hint = "wg<N>",
     .define = "WG_SIZE",
     .without_work_groups = 0,
     .covering = Covering::kRotated,
     .covering_step = 1,
     .chart = Chart::kYes},
    {.name = "normals",
     .field = FieldOf<&Variant::normals>(),
     .values = {V(Normals::kNone, "none", "nonormals"), V(Normals::kNormals, "normals"),
                V(Normals::kTangents, "tangents")},
     .define = "NORMALS",  // 0, 1, 2: 2 skins normals and tangents
     .covering = Covering::kRotated,
     .covering_step = 3,
     .chart = Chart::kNo,  // set by the data set
     .reads_flags = true},  // a flag before tangents: older files say false / true
    {.name = "morph",
     .field = FieldOf<&Variant::morph>(),
     .values = {V(Morph::kNone, "none", "nomorph", 0), V(Morph::kDense, "dense", "morph-dense", 1),
                V(Morph::kSparse, "sparse", "morph-sparse", 2), V(Morph::kDenseHalf, "dense-half", "morph-dense-half", 5),
                V(Morph::kSparseHalf, "sparse-half", "morph-sparse-half", 6)},
     .define = "MORPH",  // bits 0-1 the layout (1 dense, 2 sparse), bit 2 half offsets; 0 none
     .covering = Covering::kRotated,
     .covering_step = 1,
     .chart = Chart::kNo,  // none or not is set by the data set; the report's rows name the layout
     .embedded_enum = "Morph",
     .key_omits_default = true},
    {.name = "normal_format",
     .field = FieldOf<&Variant::normal_format>(),
     .values = {V(NormalFormat::kF32, "f32", "normals-f32"), V(NormalFormat::kOct16, "oct16", "normals-oct16"),
                V(NormalFormat::kSnorm8, "snorm8", "normals-snorm8")},
     .define = "NORMAL_FORMAT",  // 0 float32, 1 octahedral 2 x unorm16, 2 4 x snorm8
     .covering = Covering::kRotated,
     .covering_step = 2,
     .chart = Chart::kNo,  // the consumer's format, not a tuning choice: rows of their own
     .embedded_enum = "NormalFormat",
     .key_omits_default = true},
    {.name = "animation",
     .field = FieldOf<&Variant::animation>(),
     .values = {V(Animation::kHost, "host", "anim-host"), V(Animation::kSampled, "sampled", "anim-sampled"),
                V(Animation::kBaked30, "baked30", "anim-baked30"), V(Animation::kBaked60, "baked60", "anim-baked60"),
                V(Animation::kBaked120, "baked120", "anim-baked120"), V(Animation::kBaked240, "baked240", "anim-baked240"),
                V(Animation::kLocal30, "local30", "anim-local30"), V(Animation::kLocal60, "local60", "anim-local60"),
                V(Animation::kLocal120, "local120", "anim-local120"), V(Animation::kLocal240, "local240", "anim-local240"),
                V(Animation::kHybrid30, "hybrid30", "anim-hybrid30"), V(Animation::kHybrid60, "hybrid60", "anim-hybrid60"),
                V(Animation::kHybrid120, "hybrid120", "anim-hybrid120"),
                V(Animation::kHybrid240, "hybrid240", "anim-hybrid240"), V(Animation::kFused30, "fused30", "anim-fused30"),
                V(Animation::kFused60, "fused60", "anim-fused60"), V(Animation::kFused120, "fused120", "anim-fused120"),
                V(Animation::kFused240, "fused240", "anim-fused240"),
                V(Animation::kFusedLocal30, "fusedlocal30", "anim-fusedlocal30"),
                V(Animation::kFusedLocal60, "fusedlocal60", "anim-fusedlocal60"),
                V(Animation::kFusedLocal120, "fusedlocal120", "anim-fusedlocal120"),
                V(Animation::kFusedLocal240, "fusedlocal240", "anim-fusedlocal240"),
                V(Animation::kFusedHybrid30, "fusedhybrid30", "anim-fusedhybrid30"),
                V(Animation::kFusedHybrid60, "fusedhybrid60", "anim-fusedhybrid60"),
                V(Animation::kFusedHybrid120, "fusedhybrid120", "anim-fusedhybrid120"),
                V(Animation::kFusedHybrid240, "fusedhybrid240", "anim-fusedhybrid240")},
     // The forms by family and rate, where the 25 tokens one by one would pass a message's length.
     .key_hint = "anim-<sampled|<baked|local|hybrid|fused|fusedlocal|fusedhybrid><30|60|120|240>>]",
     .define = kNoDefine,  // the skin kernel is the same: the runner runs the palette kernel before it
     .covering = Covering::kRotated,
     .covering_step = 1,
     .chart = Chart::kNo,  // host or not is set by the scene; the report's rows name the form
     .key_omits_default = true},
};
inline constexpr std::size_t kAxisCount = std::size(kAxes);

// The index of the axis reading `Member`: consumers that must name one axis
// (emit's JOINTS after STORAGE, covering's fix-ups) name it through the table.
template <auto Member>
consteval std::size_t AxisIndex() {
  for (std::size_t i = 0; i < kAxisCount; ++i)
    if (kAxes[i].field.get == &GetField<Member>) return i;
  throw "no axis reads this field";
}
template <auto Member>
constexpr const Axis& AxisOf() {
  return kAxes[AxisIndex<Member>()];
}

// Whether axis i + 1 is glued to axis i (vertices_per_item + assignment).
constexpr bool JoinsNext(std::size_t i) { return i + 1 < kAxisCount && kAxes[i + 1].joins_previous; }

// Every axis's code, in table order: the search coordinates of a variant.
std::array<int, kAxisCount> AxisCodes(const Variant& v);

// `v` with the no-work-group values when its language has no work-groups.
Variant CollapseWorkGroups(Variant v);

// A value as keys spell it: "soa-split", "wg256", "c".
std::string KeyToken(const Axis& axis, int code);
// The key's grammar, for "expected ..." messages:
// "<lang>.b<B>.<padded|bucketed>. ... .v<1|2|4|8><c|s>.wg<N>.<normals|nonormals>".
std::string KeyFormat();
// A value as reports show it: its name or digits; "none" for wg0.
std::string ValueLabel(const Axis& axis, int code);
// The code of an enum or flag axis's value named `name`.
std::optional<int> CodeNamed(const Axis& axis, std::string_view name);
// The value names joined by ", " ("aos, soa, soa-split").
std::string Choices(const Axis& axis);
// The index of the axis called `name` ("wg_size").
std::optional<std::size_t> AxisNamed(std::string_view name);
// The kernels' #define value for `code`.
int DefineValue(const Axis& axis, int code);
// A value in JSON and configs: a name, a number or true / false.
nlohmann::json ValueJson(const Axis& axis, int code);

}  // namespace skintune::internal
