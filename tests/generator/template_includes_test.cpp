// Preludes: `#include "FILE"` in kernel templates, resolved by the generator
// (generator/template_includes.h), and the rules the templates keep: every
// parameter default and the GLSL skinning are written once, in a prelude.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

#include "generator/emit.h"
#include "generator/palette_kernel.h"
#include "generator/template_includes.h"
#include "base/error.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

using Files = std::map<std::string, std::string>;

TemplateLookup LookupIn(const Files& files) {
  return [&files](const std::string& name) -> std::optional<std::string> {
    const auto at = files.find(name);
    if (at == files.end()) return std::nullopt;
    return at->second;
  };
}

std::string Expand(const Files& files, const std::string& name) {
  return ExpandIncludes(name, files.at(name), LookupIn(files));
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// ------------------------------------------------------------ resolution

TEST(ExpandIncludes, ReplacesTheLineByTheFileFramedByLineDirectives) {
  const Files files = {{"a.cl", "first\n#include \"p.h\"\nlast\n"}, {"p.h", "p1\np2\n"}};
  EXPECT_EQ(Expand(files, "a.cl"), "first\n#line 1 \"p.h\"\np1\np2\n#line 3 \"a.cl\"\nlast\n");
}

TEST(ExpandIncludes, GlslLineDirectivesNumberTheFilesInIncludeOrder) {
  // GLSL's #line takes a source-string number; the comment names the file.
  const Files files = {{"a.comp", "#version 430 core\n#include \"p.h\"\n#include \"q.glsl\"\nvoid main() {}\n"},
                       {"p.h", "p1\n"},
                       {"q.glsl", "q1\n"}};
  EXPECT_EQ(Expand(files, "a.comp"),
            "#version 430 core\n"
            "#line 1 1  // p.h\np1\n"  // no #line back into a.comp: another include follows
            "#line 1 2  // q.glsl\nq1\n#line 4 0  // a.comp\n"
            "void main() {}\n");
}

// A GLSL compiler's log names source strings by number; the legend names them.
TEST(ExpandIncludes, GlslSourceStringsNameEveryNumberedFile) {
  const Files files = {{"a.comp", "#version 430 core\n#include \"p.h\"\n#include \"q.glsl\"\nvoid main() {}\n"},
                       {"p.h", "p1\n"},
                       {"q.glsl", "q1\n"}};
  EXPECT_EQ(GlslSourceStrings(Expand(files, "a.comp")), " (source strings: 0 a.comp, 1 p.h, 2 q.glsl)");
  EXPECT_EQ(GlslSourceStrings("#version 430 core\nvoid main() {}\n"), "");
  EXPECT_EQ(GlslSourceStrings(ExpandedTemplate("skin.comp")),
            " (source strings: 0 skin.comp, 1 skin_params.h, 2 skin_body.glsl, 3 anim_records.glsl)");
}

TEST(ExpandIncludes, TextWithoutIncludesIsUnchanged) {
  const Files files = {{"a.cl", "x\n// #include \"commented-out.h\"\n#define INCLUDE 1\n#ifndef X\ny"}};
  EXPECT_EQ(Expand(files, "a.cl"), files.at("a.cl"));
}

TEST(ExpandIncludes, AcceptsBlanksAndATrailingComment) {
  const Files files = {{"a.cl", "  #  include   \"p.h\"  // why it is included\n"}, {"p.h", "p1"}};
  EXPECT_EQ(Expand(files, "a.cl"), "#line 1 \"p.h\"\np1\n")
      << "a file that does not end in a newline gets one; nothing follows, so no #line back";
}

TEST(ExpandIncludes, AnUnknownFileIsAnErrorNamingTheTemplateAndLine) {
  const Files files = {{"skin.cl", "one\ntwo\n#include \"missing.h\"\n"}};
  const std::string error = ErrorOf([&] { Expand(files, "skin.cl"); });
  EXPECT_NE(error.find("skin.cl:3"), std::string::npos) << error;
  EXPECT_NE(error.find("\"missing.h\""), std::string::npos) << error;
  EXPECT_NE(error.find("no such file in templates/"), std::string::npos) << error;
}

TEST(ExpandIncludes, OnlyQuotedFileNamesAreIncludes) {
  for (const char* line : {"#include <stdio.h>", "#include SOME_MACRO", "#include \"p.h\" trailing", "#include"}) {
    const Files files = {{"a.cl", std::string("x\n") + line + "\n"}, {"p.h", "p\n"}};
    const std::string error = ErrorOf([&] { Expand(files, "a.cl"); });
    EXPECT_NE(error.find("a.cl:2"), std::string::npos) << line << ": " << error;
    EXPECT_NE(error.find("may only #include \"FILE\""), std::string::npos) << line << ": " << error;
  }
}

TEST(ExpandIncludes, PreludesMayIncludePreludes) {
  const Files files = {{"a.cl", "a1\n#include \"b.h\"\na3\n"}, {"b.h", "b1\n#include \"c.h\"\nb3\n"}, {"c.h", "c1\n"}};
  EXPECT_EQ(Expand(files, "a.cl"),
            "a1\n#line 1 \"b.h\"\nb1\n#line 1 \"c.h\"\nc1\n#line 3 \"b.h\"\nb3\n#line 3 \"a.cl\"\na3\n");
  const Files ends_with_include = {{"a.cl", "a1\n#include \"b.h\"\na3\n"}, {"b.h", "b1\n#include \"c.h\"\n"},
                                   {"c.h", "c1\n"}};
  EXPECT_EQ(Expand(ends_with_include, "a.cl"), "a1\n#line 1 \"b.h\"\nb1\n#line 1 \"c.h\"\nc1\n#line 3 \"a.cl\"\na3\n");
}

TEST(ExpandIncludes, ANestedErrorNamesTheIncludesThatLedToIt) {
  const Files files = {{"a.cl", "a1\n#include \"b.h\"\n"}, {"b.h", "#include \"c.h\"\n"}, {"c.h", "\n\n#include \"d.h\"\n"}};
  EXPECT_EQ(ErrorOf([&] { Expand(files, "a.cl"); }),
            "c.h:3: #include \"d.h\": no such file in templates/ (included from b.h:1, from a.cl:2)");
}

TEST(ExpandIncludes, AFileIncludedTwiceIsAnError) {
  const Files twice = {{"a.cl", "#include \"p.h\"\n#include \"p.h\"\n"}, {"p.h", "p\n"}};
  EXPECT_EQ(ErrorOf([&] { Expand(twice, "a.cl"); }),
            "a.cl:2: #include \"p.h\": already included (at a.cl:1); its text would be compiled twice");
  const Files through_another = {{"a.cl", "#include \"b.h\"\n#include \"p.h\"\n"}, {"b.h", "#include \"p.h\"\n"},
                                 {"p.h", "p\n"}};
  EXPECT_NE(ErrorOf([&] { Expand(through_another, "a.cl"); }).find("a.cl:2: #include \"p.h\": already included (at b.h:1)"),
            std::string::npos);
}

TEST(ExpandIncludes, ACycleIsAnError) {
  const Files files = {{"a.cl", "#include \"b.h\"\n"}, {"b.h", "#include \"a.cl\"\n"}};
  EXPECT_EQ(ErrorOf([&] { Expand(files, "a.cl"); }),
            "b.h:1: #include \"a.cl\": already included (it is the file being expanded); its text would be compiled "
            "twice (included from a.cl:1)");
}

// ------------------------------------------------------------ the templates

const char* const kKernelTemplates[] = {"skin.cl", "skin.cu", "skin.comp", "skin.vert"};
const char* const kGlslTemplates[] = {"skin.comp", "skin.vert"};

bool IsGlsl(const std::string& name) { return name.ends_with(".comp") || name.ends_with(".vert"); }

// The lines of `text` that are exactly `#include "file"`.
int IncludesOf(const std::string& text, const std::string& file) {
  int count = 0;
  for (const std::string& line : Lines(text)) count += line == "#include \"" + file + "\"";
  return count;
}

TEST(Templates, EveryFileOfTheTemplatesFolderIsEmbeddedAsItIs) {
  // Preludes included: the build embeds every file of templates/ but *.md.
  std::set<std::string> files;
  for (const fs::directory_entry& e : fs::directory_iterator(fs::path(SKINTUNE_SOURCE_DIR) / "templates")) {
    if (!e.is_regular_file() || e.path().extension() == ".md") continue;
    const std::string name = e.path().filename().string();
    files.insert(name);
    std::ifstream in(e.path(), std::ios::binary);
    const std::string text{std::istreambuf_iterator<char>(in), {}};
    EXPECT_EQ(TemplateText(name), text) << name << ": the embedded copy is stale";
  }
  const std::vector<std::string> names = TemplateNames();
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()), files);
  EXPECT_TRUE(files.contains("skin_params.h"));
  EXPECT_TRUE(files.contains("skin_body.glsl"));
}

TEST(Templates, EveryKernelTemplateIncludesTheParametersAndGlslOnesTheSkinningBody) {
  for (const std::string name : kKernelTemplates) {
    const std::string text = TemplateText(name);
    EXPECT_EQ(IncludesOf(text, "skin_params.h"), 1) << name;
    EXPECT_EQ(IncludesOf(text, "skin_body.glsl"), IsGlsl(name) ? 1 : 0) << name;
    // The compute templates make a fused kernel's palette with the palette kernel's own record readers.
    const std::string records = name == "skin.cl" ? "anim_records.clh" : name == "skin.cu" ? "anim_records.cuh" : "anim_records.glsl";
    EXPECT_EQ(IncludesOf(text, records), name == "skin.vert" ? 0 : 1) << name;
    if (IsGlsl(name)) {
      EXPECT_LT(text.find("#include \"skin_params.h\""), text.find("#include \"skin_body.glsl\"")) << name;
      EXPECT_LT(text.find("#define SKIN_COMPUTE_STAGE"), text.find("#include \"skin_body.glsl\"")) << name;
    }
  }
}

// The NAMEs of `#ifndef NAME` blocks that `#define NAME`: parameter defaults.
std::vector<std::string> DefaultsIn(const std::string& text) {
  std::vector<std::string> names;
  const std::vector<std::string> lines = Lines(text);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (!lines[i].starts_with("#ifndef ")) continue;
    std::istringstream words(lines[i].substr(8));
    std::string name;
    words >> name;
    int depth = 0;
    for (std::size_t j = i + 1; j < lines.size() && depth >= 0; ++j) {
      if (lines[j].starts_with("#if")) ++depth;
      if (lines[j].starts_with("#endif")) --depth;
      if (lines[j].starts_with("#define " + name + " ")) {
        names.push_back(name);
        break;
      }
    }
  }
  return names;
}

// GLSL's BINDING_* defines are no parameters: each buffer's binding, which
// the generator writes from the argument list and skin_body.glsl defaults
// for a template compiled alone.
bool IsBinding(const std::string& define) { return define.starts_with("BINDING_"); }

TEST(Templates, ParameterDefaultsAreWrittenOnceInTheParameterPrelude) {
  for (const std::string& name : TemplateNames()) {
    if (name == "skin_params.h") continue;
    std::vector<std::string> defaults = DefaultsIn(TemplateText(name));
    std::erase_if(defaults, IsBinding);
    EXPECT_EQ(defaults, std::vector<std::string>{}) << name << " sets a parameter default: "
                                                    << "move it to skin_params.h";
  }
  // Every define the generator prepends, in any language, has its default there.
  const std::vector<std::string> defaults = DefaultsIn(TemplateText("skin_params.h"));
  const std::set<std::string> with_default(defaults.begin(), defaults.end());
  EXPECT_EQ(with_default.size(), defaults.size()) << "a default is set twice in skin_params.h";
  const EmitOptions instanced{.instanced = true, .max_instances = 2};
  for (const char* key : {"cuda.aos.normals.constant", "glsl-compute.soa-split.local", "opencl.aos", "glsl-vertex.v1c.wg0"}) {
    for (const EmitOptions& options : {EmitOptions{}, instanced}) {
      for (const auto& [define, value] : Emit(ParseVariantKey(key), 0, 20, options).defines)
        EXPECT_TRUE(IsBinding(define) || with_default.contains(define)) << define << " (emitted for " << key << ") has no default in skin_params.h";
    }
  }
  // The palette kernel's too (its defines are counts: any animation has them all).
  const std::vector<AnimNodeRecord> nodes(3);
  const std::vector<AnimJointRecord> joints(2);
  const AnimationView animation{.clip_count = 1, .nodes = nodes, .joints = joints};
  for (Lang lang : {Lang::kOpenCl, Lang::kCuda, Lang::kGlslCompute, Lang::kVulkan})
    for (const auto& [define, value] : EmitPalette(lang, animation, 3).kernel.defines)
      EXPECT_TRUE(with_default.contains(define)) << define << " (the palette kernel's) has no default in skin_params.h";
}

// Lines that say something: not blank, not comments, not bare #if/#else/#endif
// structure, and with at least one letter (not a lone brace).
std::vector<std::string> CodeLines(const std::string& text) {
  std::vector<std::string> code;
  for (std::string line : Lines(text)) {
    line.erase(0, line.find_first_not_of(" \t"));
    if (line.empty() || line.starts_with("//") || line.starts_with("#if") || line.starts_with("#elif") ||
        line.starts_with("#else") || line.starts_with("#endif"))
      continue;
    if (line.find_first_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ") == std::string::npos) continue;
    code.push_back(line);
  }
  return code;
}

TEST(Templates, PreludesAreIncludedNotCopied) {
  const std::pair<const char*, std::vector<const char*>> preludes[] = {
      {"skin_params.h", {"skin.cl", "skin.cu", "skin.comp", "skin.vert", "skin_body.glsl"}},
      {"skin_body.glsl", {"skin.comp", "skin.vert"}},
  };
  for (const auto& [prelude, includers] : preludes) {
    const std::vector<std::string> code = CodeLines(TemplateText(prelude));
    EXPECT_GT(code.size(), 20u) << prelude;
    for (const char* includer : includers) {
      const std::vector<std::string> theirs = CodeLines(TemplateText(includer));
      const std::set<std::string> lines(theirs.begin(), theirs.end());
      for (const std::string& line : code)
        EXPECT_FALSE(lines.contains(line)) << includer << " repeats a line of " << prelude << ": " << line;
    }
  }
}

TEST(Templates, ExpandedTemplatesAreSelfContainedWithVersionFirst) {
  for (const std::string name : kKernelTemplates) {
    const std::string text = ExpandedTemplate(name);
    for (const std::string& line : Lines(text)) EXPECT_FALSE(line.starts_with("#include")) << name << ": " << line;
    EXPECT_EQ(text.find("#version"), IsGlsl(name) ? 0u : std::string::npos) << name;
    EXPECT_EQ(text.find("#ifndef INFLUENCES "), text.rfind("#ifndef INFLUENCES ")) << name << ": the defaults once";
  }
  for (const char* prelude : {"skin_params.h", "skin_body.glsl"})
    EXPECT_EQ(TemplateText(prelude).find("#version"), std::string::npos) << prelude << ": #version is the template's";
  for (const std::string name : kGlslTemplates) {
    const std::string text = ExpandedTemplate(name);
    EXPECT_NE(text.find("void skin_vertex("), std::string::npos) << name;
    EXPECT_EQ(text.find("void skin_vertex("), text.rfind("void skin_vertex(")) << name;
  }
}

// After every #line directive of an expanded template, the next line is the
// line of the file it names: compiler messages point at the right place.
TEST(Templates, LineDirectivesPointAtTheLinesOfTheFilesTheyName) {
  for (const std::string name : kKernelTemplates) {
    std::vector<std::string> glsl_files = {name};  // GLSL source-string number -> file
    const std::vector<std::string> lines = Lines(ExpandedTemplate(name));
    int directives = 0;
    for (std::size_t i = 0; i + 1 < lines.size(); ++i) {
      if (!lines[i].starts_with("#line ")) continue;
      ++directives;
      std::istringstream words(lines[i].substr(6));
      std::size_t number = 0;
      std::string file;
      words >> number >> file;
      if (IsGlsl(name)) {
        std::string slashes;
        words >> slashes >> file;  // "#line N S  // FILE"
      } else {
        file = file.substr(1, file.size() - 2);  // "#line N \"FILE\""
      }
      const std::vector<std::string> original = Lines(TemplateText(file));
      ASSERT_LE(number, original.size()) << name << ": " << lines[i];
      EXPECT_EQ(lines[i + 1], original[number - 1]) << name << ": after " << lines[i];
    }
    // In, in (the animation records' prelude, on the next line) and back;
    // GLSL compute: in, in, in and back; the vertex stage: in, in and back.
    EXPECT_EQ(directives, name == "skin.comp" ? 4 : 3) << name;
  }
}

TEST(Templates, EmittedKernelsHoldThePreludesOnce) {
  for (const char* key : {"opencl", "cuda", "glsl-compute", "glsl-vertex.v1c.wg0"}) {
    const KernelSource s = Emit(ParseVariantKey(key), 0, 20);
    for (const std::string& line : Lines(s.text)) EXPECT_FALSE(line.starts_with("#include")) << key << ": " << line;
    const std::size_t first = s.text.find("#define PALETTE_FLOAT4S");
    EXPECT_NE(first, std::string::npos) << key;
    EXPECT_EQ(first, s.text.rfind("#define PALETTE_FLOAT4S")) << key;
  }
}

}  // namespace
}  // namespace skintune::internal
