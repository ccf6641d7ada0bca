#include "generator/emit.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <optional>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "generator/packer.h"
#include "generator/template_includes.h"
#include "base/error.h"
#include "model/mesh.h"

namespace skintune::internal {

// templates/, embedded by cmake/embed_templates.cmake (generated embedded_templates.cpp).
struct EmbeddedTemplate {
  const char* name;
  const unsigned char* data;
  std::size_t size;
};
extern const EmbeddedTemplate kEmbeddedTemplates[];
extern const std::size_t kEmbeddedTemplateCount;

namespace {

// float4 rows per joint: the PALETTE_ROWS the table gives the kernels.
int PaletteRows(PaletteFormat f) { return DefineValue(AxisOf<&Variant::palette>(), static_cast<int>(f)); }

std::vector<std::pair<std::string, long long>> ParameterDefines(const Variant& v, int b, int joints,
                                                                const EmitOptions& options) {
  std::vector<std::pair<std::string, long long>> d;
  Variant kernel = v;
  kernel.influences = b;  // a bucket's kernel is specialised for its count
  for (std::size_t i = 0; i < kAxisCount; ++i) {
    const Axis& a = kAxes[i];
    if (*a.define != '\0') d.emplace_back(a.define, DefineValue(a, a.Get(kernel)));
    // JOINTS has always followed the palette's STORAGE (the golden kernels keep that order).
    if (i == AxisIndex<&Variant::storage>() && joints > 0) d.emplace_back("JOINTS", joints);
  }
  if (SkinsMorph(v)) d.emplace_back("MORPH_TARGETS", options.morph_targets);
  if (v.layout == Layout::kSoaSplit) d.emplace_back("SLOT_STRIDE_MULTIPLE", SoaSplitSlotStride(1, v));
  if (v.layout == Layout::kAos) {
    const RecordLayout r = AosRecordLayout(v, b);
    d.emplace_back("AOS_POSITION_OFFSET", static_cast<long long>(r.position));
    d.emplace_back("AOS_INDICES_OFFSET", static_cast<long long>(r.indices));
    d.emplace_back("AOS_WEIGHTS_OFFSET", static_cast<long long>(r.weights));
    if (SkinsNormals(v)) d.emplace_back("AOS_NORMAL_OFFSET", static_cast<long long>(r.normal));
    if (SkinsTangents(v)) d.emplace_back("AOS_TANGENT_OFFSET", static_cast<long long>(r.tangent));
    d.emplace_back("AOS_RECORD_WORDS", static_cast<long long>(r.size / 4));
  }
  if (options.instanced) {
    d.emplace_back("INSTANCED", 1);
    if (InstancesBoundAtCompileTime(v)) d.emplace_back("PALETTE_INSTANCES", options.max_instances);
  }
  return d;
}

KernelArgument Scalar(const char* name) {
  return {name, "u32", 4, 0, "", ArgumentDirection::kIn, ArgumentKind::kScalar};
}

KernelArgument Vector(const std::string& name, const Variant& v, ArgumentDirection direction) {
  const std::size_t bytes = BytesOf(v.position);
  return {name, Name(v.position), bytes, bytes, direction == ArgumentDirection::kOut ? "first+v" : "v",
          direction, ArgumentKind::kBuffer};
}
// Tangents: float4 (xyz, then the handedness w) in every position format.
KernelArgument Tangents(const std::string& name, ArgumentDirection direction) {
  return {name, "float4", kTangentBytes, kTangentBytes, direction == ArgumentDirection::kOut ? "first+v" : "v",
          direction, ArgumentKind::kBuffer};
}

// The morph targets' inputs (docs/VARIANTS.md "Morph targets"): dense, per
// target t the offset of vertex v at t*n+v; sparse, vertex v's entries
// morph_offsets[v] .. morph_offsets[v+1]-1 each a target (morph_targets) and
// its offsets; and the weights, T per instance.
void MorphArguments(const Variant& v, bool instanced, std::vector<KernelArgument>& args) {
  if (!SkinsMorph(v)) return;
  const std::size_t offset_bytes = MorphHalf(v) ? kMorphHalfOffsetBytes : kMorphF32OffsetBytes;
  const char* format = MorphHalf(v) ? "half4" : "float3";
  const char* at = MorphSparse(v) ? "e" : "t*n+v";
  if (MorphSparse(v)) {
    args.push_back({"morph_offsets", "u32", 4, 4, "v (n+1 of them: vertex v's entries e in [morph_offsets[v], "
                    "morph_offsets[v+1]))", ArgumentDirection::kIn, ArgumentKind::kBuffer});
    args.push_back({"morph_targets", "u32", 4, 4, "e", ArgumentDirection::kIn, ArgumentKind::kBuffer});
  }
  args.push_back({"morph_positions", format, offset_bytes, offset_bytes, at, ArgumentDirection::kIn,
                  ArgumentKind::kBuffer});
  if (SkinsNormals(v))
    args.push_back({"morph_normals", format, offset_bytes, offset_bytes, at, ArgumentDirection::kIn,
                    ArgumentKind::kBuffer});
  if (SkinsTangents(v))
    args.push_back({"morph_tangents", format, offset_bytes, offset_bytes, at, ArgumentDirection::kIn,
                    ArgumentKind::kBuffer});
  args.push_back({kMorphWeightsArgument, "f32", 4, 4, instanced ? "i*T+t" : "t", ArgumentDirection::kIn,
                  ArgumentKind::kBuffer});
}

}  // namespace

std::vector<std::pair<std::string, long long>> BindingDefines(Lang lang, std::span<const KernelArgument> arguments) {
  std::vector<std::pair<std::string, long long>> defines;
  for (const KernelArgument& a : arguments) {
    if (!TakesBinding(lang, a)) continue;
    std::string name = "BINDING_";
    for (const char c : a.name) name += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    defines.emplace_back(name, static_cast<long long>(defines.size()));
  }
  return defines;
}

bool TakesBinding(Lang lang, const KernelArgument& a) {
  if (a.kind == ArgumentKind::kScalar) return false;
  return !(lang == Lang::kGlslVertex && a.direction == ArgumentDirection::kOut);
}

namespace {

std::vector<KernelArgument> KernelArguments(const Variant& v, int b, bool instanced) {
  const auto bb = static_cast<std::size_t>(b);
  std::vector<KernelArgument> args = {Scalar("n"), Scalar("first")};
  // glsl-vertex places instances by the capture order: no vertex_count.
  if (instanced && v.lang != Lang::kGlslVertex) args.push_back(Scalar("vertex_count"));
  if (v.layout == Layout::kAos) {
    const std::size_t size = AosRecordLayout(v, b).size;
    args.push_back({"records", "record", size, size, "v", ArgumentDirection::kIn, ArgumentKind::kBuffer});
  } else {
    const bool split = v.layout == Layout::kSoaSplit;
    const std::size_t ib = BytesOf(v.index), wb = BytesOf(v.weight);
    args.push_back(Vector("positions", v, ArgumentDirection::kIn));
    args.push_back({"indices", Name(v.index), ib, split ? ib : bb * ib, split ? "i*S+v" : "v*B+i",
                    ArgumentDirection::kIn, ArgumentKind::kBuffer});
    args.push_back({"weights", Name(v.weight), wb, split ? wb : bb * wb, split ? "i*S+v" : "v*B+i",
                    ArgumentDirection::kIn, ArgumentKind::kBuffer});
    if (SkinsNormals(v)) args.push_back(Vector("normals", v, ArgumentDirection::kIn));
    if (SkinsTangents(v)) args.push_back(Tangents("tangents", ArgumentDirection::kIn));
  }
  MorphArguments(v, instanced, args);
  const auto rows = static_cast<std::size_t>(PaletteRows(v.palette));
  args.push_back({"palette", "float4 rows", 16, rows * 16, instanced ? "(i*J+j)*R+r" : "j*R+r",
                  ArgumentDirection::kIn,
                  v.storage == PaletteStorage::kImage ? ArgumentKind::kImage : ArgumentKind::kBuffer});
  args.push_back(Vector("out_positions", v, ArgumentDirection::kOut));
  if (PacksNormals(v)) {  // one word a vector (docs/VARIANTS.md "Packed normals and tangents")
    for (const Output o : {Output::kNormals, Output::kTangents})
      if (Writes(v, o))
        args.push_back({SpecOf(o).argument, Name(v.normal_format), 4, 4, "first+v", ArgumentDirection::kOut,
                        ArgumentKind::kBuffer});
  } else {
    if (SkinsNormals(v)) args.push_back(Vector("out_normals", v, ArgumentDirection::kOut));
    if (SkinsTangents(v)) args.push_back(Tangents("out_tangents", ArgumentDirection::kOut));
  }
  if (instanced) {
    for (KernelArgument& a : args) {
      if (a.direction == ArgumentDirection::kOut)
        a.indexing = v.lang == Lang::kGlslVertex ? "i*n+v" : "i*vertex_count+first+v";
    }
  }
  return args;
}

LaunchGeometry Geometry(const Variant& v, bool instanced) {
  LaunchGeometry g;
  g.vertices_per_item = v.vertices_per_item;
  g.strided = v.assignment == Assignment::kStrided;
  g.wg_size = v.wg_size;
  g.instanced = instanced;
  const std::string n = std::to_string(v.vertices_per_item);
  g.rule = "work items = ceil(n / " + n + ") rounded up to a multiple of " + std::to_string(v.wg_size) +
           " (the work-group size); item g skins vertices " +
           (g.strided ? "g, g+G, .., g+" + std::to_string(v.vertices_per_item - 1) + "G (G = work items)"
                      : "g*" + n + " .. g*" + n + "+" + std::to_string(v.vertices_per_item - 1)) +
           " below n";
  if (instanced) g.rule += "; " + std::string(LanguageOf(v.lang).instance_rule);
  return g;
}

std::string Hex64(std::uint64_t value) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

}  // namespace

const char* Name(ArgumentKind k) {
  switch (k) {
    case ArgumentKind::kScalar: return "scalar";
    case ArgumentKind::kBuffer: return "buffer";
    case ArgumentKind::kImage: return "image";
  }
  return "?";
}

const char* Name(ArgumentDirection d) { return d == ArgumentDirection::kIn ? "in" : "out"; }

std::size_t LaunchGeometry::GlobalItems(std::size_t count) const {
  const auto n = static_cast<std::size_t>(std::max(vertices_per_item, 1));
  const auto wg = static_cast<std::size_t>(std::max(wg_size, 1));
  const std::size_t items = (count + n - 1) / n;
  return (items + wg - 1) / wg * wg;
}

std::string SourceHash(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (const char c : text) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ull;
  }
  return Hex64(h);
}

std::vector<std::string> TemplateNames() {
  std::vector<std::string> names;
  for (std::size_t i = 0; i < kEmbeddedTemplateCount; ++i) names.emplace_back(kEmbeddedTemplates[i].name);
  return names;
}

namespace {

std::optional<std::string> EmbeddedText(const std::string& name) {
  for (std::size_t i = 0; i < kEmbeddedTemplateCount; ++i) {
    const EmbeddedTemplate& t = kEmbeddedTemplates[i];
    if (name == t.name) return std::string(reinterpret_cast<const char*>(t.data), t.size);
  }
  return std::nullopt;
}

}  // namespace

std::string TemplateText(const std::string& name) {
  if (std::optional<std::string> text = EmbeddedText(name)) return *std::move(text);
  std::string known;
  for (const std::string& n : TemplateNames()) known += (known.empty() ? "" : ", ") + n;
  throw Error("no embedded template '" + name + "' (embedded: " + known + ")");
}

std::string ExpandedTemplate(const std::string& name) {
  return ExpandIncludes(name, TemplateText(name), EmbeddedText);
}

namespace {

// Splits a leading "#version ..." line off a GLSL template.
std::pair<std::string, std::string> SplitVersion(const std::string& text) {
  if (text.rfind("#version", 0) != 0) return {"", text};
  const std::size_t eol = text.find('\n');
  if (eol == std::string::npos) return {text + "\n", ""};
  return {text.substr(0, eol + 1), text.substr(eol + 1)};
}

}  // namespace

std::string SpecialisedText(const std::string& template_name, const std::string& heading,
                            const std::vector<std::pair<std::string, long long>>& defines) {
  const auto [version, body] = SplitVersion(ExpandedTemplate(template_name));
  std::string text = version + "// Generated by skintune " + kGeneratorVersion + ": " + heading + "\n";
  for (const auto& [name, value] : defines) text += "#define " + name + " " + std::to_string(value) + "\n";
  // GLSL's #line takes no file name; the template's own first line follows the #version hoisted.
  text += version.empty() ? "#line 1 \"" + template_name + "\"\n" : "#line 2\n";
  return text + body;
}

bool InstancesBoundAtCompileTime(const Variant& variant) {
  return variant.storage == PaletteStorage::kConstant && variant.lang != Lang::kOpenCl;
}

KernelSource Emit(const Variant& variant, int influences_override, int joints, const EmitOptions& options) {
  // Every template compiles alone; GLSL ones start with their #version line, which must stay first.
  const char* file = LanguageOf(variant.lang).kernel_template;
  const std::vector<std::string> embedded = TemplateNames();
  if (std::find(embedded.begin(), embedded.end(), file) == embedded.end())
    throw Error(std::string("emit: language ") + Name(variant.lang) + " not implemented yet");
  const int b = influences_override > 0 ? influences_override : variant.influences;
  if (b < 1 || b > kMaxInfluences)
    throw Error("emit " + variant.Key() + ": influences " + std::to_string(b) + " outside 1.." +
                std::to_string(kMaxInfluences));
  if (joints < 0) throw Error("emit " + variant.Key() + ": negative joint count " + std::to_string(joints));
  if (variant.storage == PaletteStorage::kLocal && joints == 0)
    throw Error("emit " + variant.Key() + ": storage local needs the joint count (it sizes the local palette copy)");
  if (variant.storage == PaletteStorage::kConstant && variant.lang == Lang::kCuda && joints == 0)
    throw Error("emit " + variant.Key() + ": CUDA constant storage needs the joint count (it sizes the __constant__ "
                "palette symbol)");
  if (options.instanced && joints == 0)
    throw Error("emit " + variant.Key() + ": an instanced kernel needs the joint count (instance i's palette starts "
                "at joint i*J)");
  if (SkinsMorph(variant) && options.morph_targets < 1)
    throw Error("emit " + variant.Key() + ": morph " + Name(variant.morph) +
                " needs the mesh's morph target count (it sizes each instance's weights)");
  if (options.instanced && InstancesBoundAtCompileTime(variant) && options.max_instances < 1)
    throw Error("emit " + variant.Key() + ": instanced constant storage in " + Name(variant.lang) +
                " needs max_instances >= 1 (it sizes the " +
                (variant.lang == Lang::kCuda ? "__constant__ palette symbol" : "palette uniform block") + ")");

  KernelSource source;
  source.lang = variant.lang;
  source.entry_point = IsGlslText(variant.lang) ? "main" : "skin";
  source.influences = b;
  source.joints = joints;
  source.instanced = options.instanced;
  source.max_instances = options.instanced && InstancesBoundAtCompileTime(variant) ? options.max_instances : 0;
  source.instances = options.instanced ? std::max(options.max_instances, 0) : 0;
  source.morph_targets = SkinsMorph(variant) ? options.morph_targets : 0;
  source.defines = ParameterDefines(variant, b, joints, options);  // the same parameters in every language
  source.arguments = KernelArguments(variant, b, options.instanced);
  source.launch = Geometry(variant, options.instanced);
  // GLSL: each buffer's binding, its place in the argument list (skin_body.glsl).
  if (IsGlslText(variant.lang)) {
    const auto bindings = BindingDefines(variant.lang, source.arguments);
    source.defines.insert(source.defines.end(), bindings.begin(), bindings.end());
  }

  std::string heading = variant.Key();
  if (b != variant.influences) heading += " (bucket of " + std::to_string(b) + " influences)";
  if (options.instanced) heading += " (instanced)";
  std::string text = SpecialisedText(file, heading, source.defines);
  source.text = std::move(text);
  source.source_hash = SourceHash(source.text);
  return source;
}

namespace {

// The sidecar's "morph" object: the morph targets' count, layout and
// offsets, in the words of docs/VARIANTS.md "Morph targets".
nlohmann::json MorphJson(const KernelSource& source, const Variant& variant) {
  const bool half = MorphHalf(variant);
  nlohmann::json j = {
      {"targets", source.morph_targets},
      {"layout", MorphSparse(variant) ? "sparse" : "dense"},
      {"offset_format", half ? "half4" : "float3"},
      {"offset_bytes", static_cast<int>(half ? kMorphHalfOffsetBytes : kMorphF32OffsetBytes)},
      {"offset_rule", half ? "IEEE 754 binary16 x, y, z rounded to nearest (ties to even) from the float32 offset, "
                             "then a zero: 8 bytes"
                           : "little-endian float32 x, y, z: 12 bytes"},
      {"rule", "before skinning, each of the vertex's position, normal and tangent xyz gains w_t * offset_t for "
               "every target t of non-zero weight, in ascending target order, in float32; normals and tangents are "
               "renormalised after skinning and the tangent's w is kept"},
      {"weights", std::string("morph_weights: float32, ") + std::to_string(source.morph_targets) +
                      " per instance (instance i's target t at i*T+t); the runtime uploads them with each frame's "
                      "palette"},
  };
  j["entries"] = MorphSparse(variant)
                     ? "launch vertex v's entries e in [morph_offsets[v], morph_offsets[v+1]) (n+1 offsets), each "
                       "a target morph_targets[e] and its offsets at element e: one entry for every target with a "
                       "non-zero offset in any stream the kernel reads, in ascending target order; every buffer "
                       "holds at least one element"
                     : "target t's offset of launch vertex v at element t*n+v (n: the launch's vertex count)";
  return j;
}

// The sidecar's "instancing" object: where an instanced kernel finds its
// instance, its palette and where its outputs go.
nlohmann::json InstancingJson(const KernelSource& source) {
  const bool vertex = source.lang == Lang::kGlslVertex;
  const Language& language = LanguageOf(source.lang);
  nlohmann::json j = {
      {"instance", language.instance},
      {"palette", "the K palettes one after another: instance i's joint j row r at float4 (i*" +
                      std::to_string(source.joints) + "+j)*R+r"},
      {"outputs", vertex ? "one capture per draw holds its K instances one after another: instance i's vertex v at "
                           "element i*n+v of the capture range (place it at i*vertex_count+first+v yourself when "
                           "the mesh takes several draws)"
                         : "instance i's vertex v at element i*vertex_count+first+v (vertex_count: the mesh's vertex "
                           "count, every launch together)"},
      {"rule", language.instance_rule},
  };
  j["max_instances"] = source.max_instances;  // 0: any K
  return j;
}

// The image's width in texels where the joint count is known: one palette's
// rows; instanced, per instance and for the K the kernel was emitted for.
void ImageWidths(const KernelSource& source, int rows, nlohmann::json& image) {
  const int one = source.joints * rows;
  if (!source.instanced) {
    image["width_texels"] = one;
    return;
  }
  image["width_texels_per_instance"] = one;
  if (source.instances > 0) {
    image["instances"] = source.instances;
    image["width_texels"] = static_cast<long long>(one) * source.instances;
  }
}

// Vulkan's descriptor type of a buffer argument (the palette's follows its storage).
const char* VulkanDescriptorType(const KernelArgument& argument, const Variant& variant) {
  if (argument.name != "palette") return "VK_DESCRIPTOR_TYPE_STORAGE_BUFFER";
  if (variant.storage == PaletteStorage::kConstant) return "VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER";
  if (variant.storage == PaletteStorage::kImage) return "VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER";
  return "VK_DESCRIPTOR_TYPE_STORAGE_BUFFER";
}

}  // namespace

std::size_t PushConstantOffset(const std::string& scalar) {
  if (scalar == "n") return 0;
  if (scalar == "first") return 4;
  if (scalar == "vertex_count") return 8;
  if (scalar == "elapsed") return 12;
  throw Error("no push constant '" + scalar + "' (n, first, vertex_count, elapsed)");
}

namespace {

constexpr const char* kWorkGroupSizesRule =
    "emit and the runtime accept any multiple of 32 from 32 to 1024 (the device's limit applies when it runs); "
    "tuning spaces and `skintune variants --list` list 32, 64, 128, 256, 512 and 1024; glsl-vertex has none (wg0)";

constexpr const char* kStrideBytesRule =
    "per argument: per-vertex inputs and outputs (positions, normals, records, out_*): bytes from vertex v's element "
    "to vertex v+1's (the element size; records: the record size); indices and weights: bytes from vertex v's first "
    "slot to vertex v+1's (soa: B elements; soa-split: one element, within a slot array); palette: bytes from joint j "
    "to joint j+1 (R float4 rows); morph offsets, morph_targets and morph_offsets: bytes from one element to the "
    "next; morph_weights: bytes from target t's weight to t+1's; scalars: 0";

// The quantisation rule in the words of docs/VARIANTS.md (the kernel
// contract's item 1) and of the generated header's QuantiseVertex
// (templates/embedded_support.h), the code generator/packer.cpp also runs.
constexpr const char* kQuantisationRule =
    "In IEEE 754 double precision (binary64), each operation rounded to nearest, ties to even: "
    "1. s = ((w_0 + w_1) + w_2) + ... + w_(B-1): the float32 weights converted to double (exactly) and added in "
    "slot order. "
    "2. t_i = (w_i / s) x M: the quotient rounded to double, then the product rounded to double. "
    "3. q_i = floor(t_i) and r_i = t_i - q_i (exact in double). "
    "4. D = M - (q_0 + ... + q_(B-1)): the quanta still missing, at most the number of non-zero weights. "
    "5. The D slots of non-zero weight with the largest r_i get one quantum more each; of equal r_i the earlier "
    "slot (smaller i) comes first. A zero weight stays 0.";

nlohmann::json WeightsJson(WeightFormat format) {
  const std::string input = "finite, non-negative, not all zero per vertex (others are an error naming the vertex)";
  if (format == WeightFormat::kF32)
    return {{"format", "f32"}, {"input", input}, {"rule", "the weights as given, as float32 (no quantisation)"}};
  const int max = format == WeightFormat::kUnorm16 ? 65535 : 255;
  const std::string m = std::to_string(max);
  return {{"format", Name(format)},
          {"max", max},
          {"input", input},
          {"rule", "per vertex, the B weights w_0 .. w_(B-1) become integers q_0 .. q_(B-1) summing to exactly M = " +
                       m + ", read by the kernel as q_i / " + m + ". " + kQuantisationRule},
          {"exact", "weights that are already multiples of 1/" + m + " summing to 1 are kept exactly (zero "
                    "quantisation error), e.g. a glTF's normalized WEIGHTS of this width"}};
}

// How a packed normal_format's words are written and read (docs/VARIANTS.md
// "Packed normals and tangents", the emitted header's PackNormal /
// PackTangent / UnpackNormal / UnpackTangent).
nlohmann::json NormalFormatJson(NormalFormat format) {
  const std::string round = "each operation in float32; unorm16(c) = floor(clamp(c, 0, 1) * 65535 + 0.5), "
                            "snorm8(c) = floor(clamp(c, -1, 1) * 127 + 0.5) as a two's-complement byte";
  if (format == NormalFormat::kOct16)
    return {{"name", "oct16"},
            {"bytes", 4},
            {"normal", "n normalised; s = |n.x| + |n.y| + |n.z|; (u, v) = (n.x / s, n.y / s); where n.z < 0: "
                       "(u, v) = ((1 - |v|) * sign(u), (1 - |u|) * sign(v)) with sign(0) = 1, both from the "
                       "unfolded u and v; then u = u * 0.5 + 0.5, v = v * 0.5 + 0.5; the word is "
                       "unorm16(u) | unorm16(v) << 16"},
            {"tangent", "t.xyz normalised and folded as a normal to (u, v) in [0, 1]; y = max(v, 1/32767) * 0.5 + "
                        "0.5, then y = 1 - y where the handedness w < 0; x16 = unorm16(u), y16 = unorm16(y), and "
                        "x16 = 65535 where x16 = 0 and y16 = 65535; the word is x16 | y16 << 16"},
            {"decode", "u = x16 / 65535, v = y16 / 65535; a tangent first: y = v * 2 - 1, w = +1 where y >= 0 "
                       "else -1, v = |y| (as Godot 4 decodes); then x = u * 2 - 1, y = v * 2 - 1, z = 1 - |x| - "
                       "|y|; k = max(-z, 0); x -= sign(x) * k, y -= sign(y) * k (sign(0) = 1); normalise (x, y, z)"},
            {"rounding", round},
            {"max_error", NormalFormatBound(format)},
            {"tangent_max_error", TangentFormatBound(format)}};
  return {{"name", "snorm8"},
          {"bytes", 4},
          {"normal", "n normalised; the word is snorm8(n.x) | snorm8(n.y) << 8 | snorm8(n.z) << 16 (byte 3 is 0)"},
          {"tangent", "t.xyz normalised; the word is snorm8(t.x) | snorm8(t.y) << 8 | snorm8(t.z) << 16 | "
                      "snorm8(w) << 24, w the handedness (+1 or -1: byte 3 is 127 or 129)"},
          {"decode", "each byte b as max(b / 127, -1), then xyz normalised; a tangent's w is +1 where byte 3 >= 0"},
          {"rounding", round},
          {"max_error", NormalFormatBound(format)},
          {"tangent_max_error", TangentFormatBound(format)}};
}

// The `skintune emit` command that writes `variant`'s kernel exactly as
// `source` was emitted (joint count, instancing), into the current folder,
// and the files it writes there.
nlohmann::json EmitCommandJson(const Variant& variant, const KernelSource& source) {
  std::string command = "skintune emit --variant " + variant.Key();
  if (source.joints > 0) command += " --joints " + std::to_string(source.joints);
  // Every K >= 1 gives the same text where K is not compiled in (max_instances 0).
  if (source.instanced) command += " --instances " + std::to_string(std::max(source.instances, 1));
  command += " --out .";
  const std::string base = variant.Key() + (source.instanced ? ".instanced" : "");
  return {{"emit", command},
          {"source_file", base + LanguageOf(variant.lang).extension},
          {"sidecar_file", base + ".json"}};
}

// A bucketed variant: one kernel per influence count, and how to split and reorder.
nlohmann::json BucketedJson(const Variant& variant, const KernelSource& source) {
  nlohmann::json kernels = nlohmann::json::array();
  for (int k = 1; k <= variant.influences; ++k) {
    Variant bucket = variant;
    bucket.influences = k;
    nlohmann::json kernel = {{"influences", k}, {"defines", "this kernel's with INFLUENCES " + std::to_string(k)}};
    kernel.update(EmitCommandJson(bucket, source));
    kernels.push_back(std::move(kernel));
  }
  return {{"bucketed", true},
          {"order", "sort the vertices by their number of non-zero weights, ascending, stable (vertices of one count "
                    "keep the mesh's order): packed position p holds mesh vertex order[p]"},
          {"split", "one launch per count k present: n = the bucket's vertices, first = its first packed position; "
                    "each launch has its own input buffers holding only its bucket, each vertex's non-zero slots "
                    "compacted to slots 0..k-1 in the mesh's slot order (weights quantised per vertex on the "
                    "compacted slots)"},
          {"kernels", kernels},
          {"kernels_rule", "kernels[k-1] is bucket k's kernel: its `emit` command, run as written, writes "
                           "`source_file` and `sidecar_file` into the current folder, specialised for this "
                           "kernel's joint count" + std::string(source.instanced ? " and instancing" : "")},
          {"outputs", "launch k writes its vertices at first + v: the outputs are in packed order; vertex "
                      "order[p]'s result is at p"}};
}

}  // namespace

nlohmann::json SidecarJson(const KernelSource& source, const Variant& variant) {
  nlohmann::json j;
  j["generator"] = "skintune";
  j["generator_version"] = source.generator_version;
  j["source_hash"] = source.source_hash;
  j["lang"] = Name(source.lang);
  j["variant"] = variant.Key();
  j["variant_axes"] = variant;
  j["entry_point"] = source.entry_point;
  j["influences"] = source.influences;
  j["joints"] = source.joints;
  nlohmann::json defines = nlohmann::json::object();
  for (const auto& [name, value] : source.defines) defines[name] = value;
  j["defines"] = defines;
  nlohmann::json args = nlohmann::json::array();
  int binding = 0;
  for (const KernelArgument& a : source.arguments) {
    nlohmann::json arg = {{"name", a.name},
                          {"format", a.format},
                          {"element_bytes", a.element_bytes},
                          {"stride_bytes", a.stride_bytes},
                          {"indexing", a.indexing},
                          {"direction", Name(a.direction)},
                          {"kind", Name(a.kind)}};
    // GLSL: buffers and the palette take consecutive bindings in argument
    // order; scalars are uniforms of the same name.
    // glsl-vertex outputs are captured by transform feedback (separate
    // attributes, one buffer each), not written to storage buffers.
    // Vulkan: scalars are members of one push-constant block (n, first,
    // vertex_count: 4 bytes each at 0, 4, 8; 12 bytes), the others descriptor
    // set 0 at the same bindings, of the type the palette storage needs.
    if (source.lang == Lang::kVulkan) {
      if (a.kind == ArgumentKind::kScalar) {
        arg["push_constant_offset"] = PushConstantOffset(a.name);
      } else {
        arg["set"] = 0;
        arg["binding"] = binding++;
        arg["descriptor_type"] = VulkanDescriptorType(a, variant);
      }
    } else if (IsGlslText(source.lang)) {
      if (a.kind == ArgumentKind::kScalar) {
        arg["uniform"] = a.name;
      } else if (!TakesBinding(source.lang, a)) {
        const OutputSpec* output = OutputOfArgument(a.name);
        arg["transform_feedback_buffer"] = static_cast<int>(output->output);
        arg["varying"] = output->varying;
      } else {
        arg["binding"] = binding++;
      }
    }
    if (a.name == "palette") {
      const int rows = PaletteRows(variant.palette);
      arg["rows_per_joint"] = rows;
      arg["elements_rule"] = "joints x R float4 rows (R = " + std::to_string(rows) + ")" +
                             std::string(source.instanced ? ", times the K instances" : "");
      if (source.joints > 0) arg["elements"] = source.joints * rows;  // float4 rows of one palette
      arg["rows"] = variant.palette == PaletteFormat::kDualQuaternion
                        ? "a unit dual quaternion a joint: row 0 the real part (x, y, z, w), the rotation's unit "
                          "quaternion; row 1 the dual part 0.5 * (t, 0) * real for the translation t; only rigid "
                          "joints (docs/VARIANTS.md \"Dual quaternions\")"
                        : "the matrix's rows (row-major); mat4's fourth row is not read";
      if (source.lang == Lang::kOpenCl && variant.storage == PaletteStorage::kImage) {
        arg["image"] = {{"type", "image1d_buffer_t"},
                        {"channel_order", "CL_RGBA"},
                        {"channel_type", "CL_FLOAT"},
                        {"width", "joints x R texels (one float4 row per texel" +
                                      std::string(source.instanced ? "), times the K instances of the launch" : ")")},
                        {"buffer", "created with clCreateImage (CL_MEM_OBJECT_IMAGE1D_BUFFER) over the palette buffer"},
                        {"read", source.instanced ? "read_imagef(palette, (i*J + j)*R + r)" : "read_imagef(palette, j*R + r)"}};
        if (source.joints > 0) ImageWidths(source, rows, arg["image"]);
      } else if (IsGlslText(source.lang) && variant.storage == PaletteStorage::kImage) {
        arg["texture"] = {{"type", "samplerBuffer"},
                          {source.lang == Lang::kVulkan ? "view_format" : "internal_format",
                           source.lang == Lang::kVulkan ? "VK_FORMAT_R32G32B32A32_SFLOAT" : "GL_RGBA32F"},
                          {"read", "texelFetch(palette_texels, j*R + r)"}};
      }
    }
    // CUDA binds two palette storages outside the argument list.
    if (source.lang == Lang::kCuda && a.name == "palette") {
      if (variant.storage == PaletteStorage::kConstant) {
        arg["symbol"] = "skintune_palette";
        arg["note"] = "copy the palette into the module's __constant__ symbol skintune_palette (cuModuleGetGlobal); "
                      "the argument is passed but not read";
      } else if (variant.storage == PaletteStorage::kImage) {
        arg["texture"] = {{"type", "cudaTextureObject_t"}, {"resource", "linear"}, {"format", "CU_AD_FORMAT_FLOAT"},
                          {"channels", 4}, {"filter", "point"}, {"read", "tex1Dfetch<float4>"}};
      }
    }
    args.push_back(arg);
  }
  j["arguments"] = args;
  j["launch"] = {{"vertices_per_item", source.launch.vertices_per_item},
                 {"assignment", source.launch.strided ? "strided" : "contiguous"},
                 {"wg_size", source.launch.wg_size},
                 {"rule", source.launch.rule},
                 {"wg_sizes", kWorkGroupSizesRule}};
  if (source.instanced) j["instancing"] = InstancingJson(source);
  if (SkinsMorph(variant)) j["morph"] = MorphJson(source, variant);
  if (PacksNormals(variant)) j["normal_format"] = NormalFormatJson(variant.normal_format);
  if (variant.layout == Layout::kAos) {
    const RecordLayout r = AosRecordLayout(variant, source.influences);
    j["aos_record"] = {{"position", r.position}, {"indices", r.indices}, {"weights", r.weights},
                       {"normal", r.normal}, {"tangent", r.tangent}, {"size", r.size},
                       {"holds_normal", SkinsNormals(variant)}, {"holds_tangent", SkinsTangents(variant)}};
    if (SkinsTangents(variant))
      j["aos_record"]["note"] = "the record holds the normal at 'normal' (w = 0 for float4) and the tangent at "
                                "'tangent' (4 floats: xyz, then the handedness w): there are no separate normals "
                                "and tangents arguments";
    else if (SkinsNormals(variant))
      j["aos_record"]["note"] = "the record holds the normal at 'normal' (w = 0 for float4): there is no separate "
                                "normals argument";
  }
  if (variant.layout == Layout::kSoaSplit) {
    j["slot_stride"] = "S = n rounded up to a multiple of " + std::to_string(SoaSplitSlotStride(1, variant)) +
                       " (every slot array starts on a 256-byte boundary)";
    j["slot_stride_multiple"] = SoaSplitSlotStride(1, variant);
  }
  j["buffers"] = {{"word_bytes", 4},
                  {"rule", "every buffer is an array of 32-bit words: its byte size is rounded up to a multiple of "
                           "4, the padding bytes are 0; narrower elements are packed little-endian"},
                  {"stride_bytes", kStrideBytesRule},
                  {"vectors", "positions and normals in the position format: float4 = x, y, z, w with w = 1 for "
                              "positions and 0 for normals; float3 = x, y, z packed"},
                  {"tangents", "tangents (inputs and outputs) are float4 in every position format: x, y, z, then "
                               "w = the handedness (+1 or -1; a skinned tangent's w is flipped where the blended "
                               "matrix mirrors)"}};
  j["weights"] = WeightsJson(variant.weight);
  if (variant.mixed == MixedCounts::kBucketed) j["bucketed"] = BucketedJson(variant, source);
  return j;
}

std::size_t OutputStrideBytes(const Variant& v, Output o) {
  if (o != Output::kPositions && PacksNormals(v)) return 4;
  return o == Output::kTangents ? kTangentBytes : BytesOf(v.position);
}

const OutputSpec* OutputOfArgument(std::string_view argument) {
  for (const OutputSpec& o : kOutputs)
    if (argument == o.argument) return &o;
  return nullptr;
}

}  // namespace skintune::internal
