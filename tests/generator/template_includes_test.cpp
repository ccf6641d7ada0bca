// Preludes: `#include "FILE"` in kernel templates, resolved by the generator
// (generator/template_includes.h).
#include <gtest/gtest.h>

#include <functional>
#include <map>

#include "generator/template_includes.h"
#include "reference/error.h"

namespace skintune {
namespace {

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

}  // namespace
}  // namespace skintune
