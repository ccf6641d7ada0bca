#include "tools/emit/embed_header.h"

#include <algorithm>
#include <cctype>
#include <iterator>
#include <cstdio>
#include <map>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "base/error.h"
#include "runtime/backends/vulkan/vulkan_spirv.h"

namespace skintune::internal {

namespace {

constexpr std::string_view kTemplateFile = "embedded_support.h";
constexpr std::string_view kTemplateNamespace = "skintune_kernels";
constexpr std::string_view kTableBegin = "// skintune:kernel-table-begin\n";
constexpr std::string_view kTableEnd = "// skintune:kernel-table-end\n";

// C++17 keywords and alternative tokens (and C++20's, so the header stays valid there).
constexpr std::string_view kKeywords[] = {
    "alignas", "alignof", "and", "and_eq", "asm", "auto", "bitand", "bitor", "bool", "break", "case", "catch",
    "char", "char8_t", "char16_t", "char32_t", "class", "compl", "concept", "const", "consteval", "constexpr",
    "constinit", "const_cast", "continue", "co_await", "co_return", "co_yield", "decltype", "default", "delete",
    "do", "double", "dynamic_cast", "else", "enum", "explicit", "export", "extern", "false", "float", "for",
    "friend", "goto", "if", "inline", "int", "long", "mutable", "namespace", "new", "noexcept", "not", "not_eq",
    "nullptr", "operator", "or", "or_eq", "private", "protected", "public", "register", "reinterpret_cast",
    "requires", "return", "short", "signed", "sizeof", "static", "static_assert", "static_cast", "struct",
    "switch", "template", "this", "thread_local", "throw", "true", "try", "typedef", "typeid", "typename",
    "union", "unsigned", "using", "virtual", "void", "volatile", "wchar_t", "while", "xor", "xor_eq", "std"};

bool IsIdentifier(std::string_view s) {
  if (s.empty()) return false;
  const auto alpha = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; };
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  if (!alpha(s[0])) return false;
  if (!std::all_of(s.begin(), s.end(), [&](char c) { return alpha(c) || digit(c); })) return false;
  if (s.find("__") != std::string_view::npos) return false;
  if (s.size() > 1 && s[0] == '_' && s[1] >= 'A' && s[1] <= 'Z') return false;
  return std::find(std::begin(kKeywords), std::end(kKeywords), s) == std::end(kKeywords);
}

std::string Quoted(std::string_view text) { return "\"" + CppEscaped(text) + "\""; }

// `text` as adjacent string literal pieces, one per line of the text, each on
// its own line after `indent`.
std::string LiteralLines(std::string_view text, const std::string& indent) {
  if (text.empty()) return indent + "\"\"";
  std::string out;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t eol = text.find('\n', start);
    const std::size_t end = eol == std::string_view::npos ? text.size() : eol + 1;
    if (!out.empty()) out += "\n";
    out += indent + Quoted(text.substr(start, end - start));
    start = end;
  }
  return out;
}

std::string Number(double value) { return nlohmann::json(value).dump(); }

const char* Bool(bool value) { return value ? "true" : "false"; }

// The Kernel's enum fields, one per axis with an embedded_enum (generator/axes.h), in table order:
// "Layout::kAos, PositionFormat::kFloat4, ...".
std::string EnumFields(const Variant& v) {
  std::string fields;
  for (const Axis& a : kAxes) {
    if (a.embedded_enum != nullptr) fields += (fields.empty() ? "" : ", ") + EmbeddedEnumerator(a, a.Get(v));
  }
  return fields;
}

// Replaces the one occurrence of `from` in `text`; throws when there is not exactly one.
void ReplaceOnce(std::string& text, std::string_view from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos || text.find(from, at + 1) != std::string::npos)
    throw Error("embed header: templates/" + std::string(kTemplateFile) + " must contain '" + std::string(from) +
                "' exactly once");
  text.replace(at, from.size(), to);
}

std::string ArgumentsTable(const KernelSource& source) {
  std::string out;
  for (const KernelArgument& a : source.arguments) {
    out += "    {" + Quoted(a.name) + ", " + Quoted(a.format) + ", " + std::to_string(a.element_bytes) + "u, " +
           std::to_string(a.stride_bytes) + "u, " + Quoted(a.indexing) + ", " +
           Bool(a.direction == ArgumentDirection::kOut) + ", " + Bool(a.kind == ArgumentKind::kScalar) + ", " +
           Bool(a.kind == ArgumentKind::kImage) + "},\n";
  }
  return out;
}

// A vulkan kernel's SPIR-V words: "inline constexpr std::uint32_t kSpirv<i>[] = {...};".
std::string SpirvTable(const KernelSource& s, std::size_t index) {
  const std::vector<std::uint32_t> words = vk::CompileSpirv(s.text, "embed header: kernel " + s.source_hash);
  std::string out = "inline constexpr std::uint32_t kSpirv" + std::to_string(index) + "[] = {";
  char word[16];
  for (std::size_t w = 0; w < words.size(); ++w) {
    std::snprintf(word, sizeof word, "0x%08xu,", words[w]);
    out += (w % 8 == 0 ? "\n    " : " ") + std::string(word);
  }
  return out + "\n};\n";
}

// The Kernel's scene fields: "\"instances\", 64, 1, true, 0" (shape, instances, meshes, instanced, max_instances).
std::string SceneFields(const EmbeddedKernel& k) {
  return Quoted(SceneKindName(k.entry.shape)) + ", " + std::to_string(k.entry.instances) + ", " +
         std::to_string(k.entry.meshes) + ", " + Bool(k.source.instanced) + ", " + std::to_string(k.source.max_instances);
}

std::string KernelRow(const EmbeddedKernel& k, std::size_t index, std::size_t source_index) {
  const WinnersEntry& e = k.entry;
  const Variant& v = k.variant;
  const KernelSource& s = k.source;
  const std::string n = std::to_string(source_index);
  std::string row = "    // [" + std::to_string(index) + "] " + Name(e.lang) + " b" + std::to_string(e.influences) +
                    " " + RowName(e) + " on " + Quoted(e.device_id);
  if (e.variant.mixed != v.mixed)
    row += " (tuned " + std::string(Name(e.variant.mixed)) + ", emitted " + Name(v.mixed) + ")";
  row += "\n    {" + Quoted(e.device_id) + ",\n     " + Quoted(e.platform) + ", " + Quoted(e.vendor) + ", " +
         Quoted(e.device_name) + ", " + Quoted(e.driver_version) + ", " + Quoted(e.device_type) + ",\n     " +
         Quoted(Name(v.lang)) + ", " + std::to_string(s.influences) + ", " + Quoted(e.vertex_bucket) + ", " +
         std::to_string(e.vertices) + "u,\n     " + SceneFields(k) + ",\n     " + Quoted(v.Key()) + ",\n     " +
         EnumFields(v) + ",\n     " +
         Bool(v.blend == Blend::kPoint) + ", " + Bool(SkinsNormals(v)) + ", " + Bool(SkinsTangents(v)) + ", " + std::to_string(s.launch.vertices_per_item) +
         ", " + Bool(s.launch.strided) + ", " +
         std::to_string(s.launch.wg_size) + ", " + std::to_string(s.joints) + ", " + std::to_string(s.morph_targets) +
         ",\n     " + Quoted(s.entry_point) +
         ", generated::kSource" + n + ", " + Quoted(s.source_hash) + ", " +
         (v.lang == Lang::kVulkan ? "generated::kSpirv" + n + ", sizeof generated::kSpirv" + n + " / 4"
                                  : std::string("nullptr, 0")) +
         ", generated::kArguments" + n + ", " +
         std::to_string(s.arguments.size()) + ",\n     " + Quoted(s.launch.rule) + ",\n     " + Number(e.median_ms) +
         ", " + Number(e.gbps) + ", " + Number(e.copy_fraction) + ", " + Quoted(e.dataset) + "},\n";
  return row;
}

}  // namespace

bool IsCppNamespaceName(std::string_view name) {
  std::size_t start = 0;
  while (true) {
    const std::size_t sep = name.find("::", start);
    if (!IsIdentifier(name.substr(start, sep == std::string_view::npos ? std::string_view::npos : sep - start)))
      return false;
    if (sep == std::string_view::npos) return true;
    start = sep + 2;
  }
}

std::string EmbeddedEnumerator(const Axis& axis, int code) {
  std::string name = std::string(axis.embedded_enum) + "::k";
  bool upper = true;  // "soa-split" -> kSoaSplit, like skintune's own enumerators
  for (const char c : ValueLabel(axis, code)) {
    if (c == '-') {
      upper = true;
      continue;
    }
    name += upper ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
    upper = false;
  }
  return name;
}

std::string CppEscaped(std::string_view text) {
  std::string out;
  out.reserve(text.size() + text.size() / 16);
  char previous = '\0';
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    switch (ch) {
      case '\\': out += "\\\\"; break;
      case '"': out += "\\\""; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      case '?': out += previous == '?' ? "\\?" : "?"; break;
      default:
        if (c < 0x20 || c >= 0x7f) {
          char octal[5];
          std::snprintf(octal, sizeof octal, "\\%03o", static_cast<unsigned>(c));
          out += octal;
        } else {
          out += ch;
        }
    }
    previous = ch;
  }
  return out;
}

std::string EmbedHeader(const std::vector<EmbeddedKernel>& kernels, const EmbedHeaderOptions& options) {
  if (kernels.empty()) throw Error("embed header: no kernels");
  if (!IsCppNamespaceName(options.name_space))
    throw Error("embed header: '" + options.name_space + "' is not a C++ namespace name (identifiers joined by ::)");
  for (const EmbeddedKernel& k : kernels) {
    if (k.variant.mixed != MixedCounts::kPadded)
      throw Error("embed header: " + k.variant.Key() + " is not padded (the header's kernels skin in mesh order)");
    if (k.source.joints <= 0)
      throw Error("embed header: " + k.variant.Key() + " is not specialised for a joint count");
    if (k.source.lang != k.variant.lang || k.source.influences != k.variant.influences ||
        k.source.instanced != (k.entry.shape == SceneKind::kInstances))
      throw Error("embed header: the kernel of " + k.variant.Key() + " (" + Describe(k.entry) +
                  ") is not Emit(variant, 0, joints), instanced for a crowd's winner alone");
  }

  // One source literal and argument array per distinct kernel text.
  std::map<std::string, std::size_t> index_of_text;
  std::vector<std::size_t> source_index;
  std::vector<const EmbeddedKernel*> distinct;
  for (const EmbeddedKernel& k : kernels) {
    const auto [at, added] = index_of_text.emplace(k.source.text, distinct.size());
    if (added) distinct.push_back(&k);
    source_index.push_back(at->second);
  }

  std::string table = "// The kernel table (generated).\nnamespace generated {\n\n";
  for (std::size_t i = 0; i < distinct.size(); ++i) {
    const KernelSource& s = distinct[i]->source;
    table += "// " + distinct[i]->variant.Key() + " (" + std::to_string(s.joints) + " joints, " +
             std::to_string(s.text.size()) + " bytes, hash " + s.source_hash + ")\n";
    table += "inline constexpr char kSource" + std::to_string(i) + "[] =\n" + LiteralLines(s.text, "    ") + ";\n";
    if (s.lang == Lang::kVulkan) table += SpirvTable(s, i);
    table += "inline constexpr Argument kArguments" + std::to_string(i) + "[] = {\n" + ArgumentsTable(s) + "};\n\n";
  }
  table += "}  // namespace generated\n\n";
  table += "inline constexpr double kMaxError = " + Number(options.max_error) + ";\n";
  table += "inline constexpr int kKernelCount = " + std::to_string(kernels.size()) + ";\n";
  table += "inline constexpr Kernel kKernels[kKernelCount] = {\n";
  for (std::size_t i = 0; i < kernels.size(); ++i) table += KernelRow(kernels[i], i, source_index[i]);
  table += "};\n";

  std::string text = TemplateText(std::string(kTemplateFile));
  const std::size_t begin = text.find(kTableBegin);
  const std::size_t end = begin == std::string::npos ? std::string::npos : text.find(kTableEnd, begin);
  if (end == std::string::npos)
    throw Error("embed header: templates/" + std::string(kTemplateFile) + " has no '" +
                std::string(kTableBegin.substr(0, kTableBegin.size() - 1)) + "' ... '" +
                std::string(kTableEnd.substr(0, kTableEnd.size() - 1)) + "' section");
  text.replace(begin, end + kTableEnd.size() - begin, table);
  ReplaceOnce(text, "namespace " + std::string(kTemplateNamespace) + " {", "namespace " + options.name_space + " {");
  ReplaceOnce(text, "}  // namespace " + std::string(kTemplateNamespace), "}  // namespace " + options.name_space);
  // The comments' examples name the namespace too.
  const std::string qualified = std::string(kTemplateNamespace) + "::";
  for (std::size_t at = text.find(qualified); at != std::string::npos;) {
    text.replace(at, qualified.size(), options.name_space + "::");
    at = text.find(qualified, at + options.name_space.size() + 2);
  }

  std::string banner = "// Generated by skintune " + std::string(kGeneratorVersion) +
                       " (skintune emit --db): do not edit, regenerate instead.\n"
                       "// Winners database " + Quoted(options.database) + ", devices matching " +
                       Quoted(options.device_pattern) + ", languages: ";
  if (options.langs.empty()) banner += "all";
  for (std::size_t i = 0; i < options.langs.size(); ++i) banner += (i ? ", " : "") + CppEscaped(options.langs[i]);
  banner += ".\n// Error budget (--max-error): " + Number(options.max_error) +
            " of the bounding-box diagonal; each kernel's weight format costs at most that (kMaxError).";
  banner += "\n// " + std::to_string(kernels.size()) + " kernel(s), " + std::to_string(distinct.size()) +
            " distinct source(s), in namespace " + options.name_space + ":\n";
  for (std::size_t i = 0; i < kernels.size(); ++i) {
    const EmbeddedKernel& k = kernels[i];
    banner += "//   [" + std::to_string(i) + "] " + Quoted(k.entry.device_id) + " " + Name(k.entry.lang) + " b" +
              std::to_string(k.entry.influences) + " " + VertexCountName(k.entry.vertices) +
              SceneSuffix(k.entry.shape, k.entry.instances, k.entry.meshes) + ": " + k.variant.Key() +
              (k.source.instanced ? " instanced" : "") + ", " + std::to_string(k.source.joints) + " joints\n";
  }
  banner += "// The API is documented below (skintune's templates/embedded_support.h).\n\n";
  return banner + text;
}

}  // namespace skintune::internal
