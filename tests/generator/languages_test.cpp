// The language table (generator/languages.h) against what reads it: the lang
// axis, the embedded templates, Emit's text and sidecar, and the copy kernel.
// The tests go through the table, so a new row is tested without editing them;
// the compile-time checks (one row per enumerator, no column unset) are the
// static_asserts in languages.h.
#include "generator/languages.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "generator/copy_kernel.h"
#include "generator/emit.h"

namespace skintune::internal {
namespace {

// A variant of `lang` every language emits: its work-group axes collapsed.
Variant Of(Lang lang) {
  Variant v;
  v.lang = lang;
  return CollapseWorkGroups(v);
}

bool Embedded(const std::string& name) {
  const std::vector<std::string> names = TemplateNames();
  return std::find(names.begin(), names.end(), name) != names.end();
}

TEST(Languages, TheLangAxisListsTheTablesNamesInEnumOrder) {
  const Axis& axis = AxisOf<&Variant::lang>();
  ASSERT_EQ(axis.values.size(), kLangCount);
  for (std::size_t i = 0; i < kLangCount; ++i) {
    const Language& language = kLanguages[i];
    EXPECT_EQ(axis.values[i].code, static_cast<int>(language.lang));
    EXPECT_STREQ(Name(language.lang), language.name);
    EXPECT_EQ(ParseVariantKey(language.name).lang, language.lang) << language.name;
    EXPECT_EQ(&LanguageOf(language.lang), &language);
  }
  EXPECT_EQ(Choices(axis), "opencl, cuda, glsl-compute, glsl-vertex, vulkan, cpu");
}

TEST(Languages, EveryTemplateIsEmbeddedAndEmitExpandsTheRowsOne) {
  for (const Language& language : kLanguages) {
    EXPECT_TRUE(Embedded(language.kernel_template)) << language.name << ": " << language.kernel_template;
    EXPECT_TRUE(Embedded(language.copy_template)) << language.name << ": " << language.copy_template;
    const KernelSource source = Emit(Of(language.lang), 0, 77);
    EXPECT_EQ(source.lang, language.lang);
    // OpenCL C, CUDA and the cpu parameters name the template in #line; GLSL's #line takes no name.
    const std::string line = language.glsl_text ? "#line 2\n" : std::string("#line 1 \"") + language.kernel_template + "\"\n";
    EXPECT_NE(source.text.find(line), std::string::npos) << language.name;
    EXPECT_EQ(source.text.rfind("#version", 0) == 0, language.glsl_text) << language.name;
    EXPECT_EQ(source.entry_point, language.glsl_text ? "main" : "skin") << language.name;
    // The body after the generated lines is the template's expansion (without its #version line).
    const std::string expanded = ExpandedTemplate(language.kernel_template);
    const std::string body = language.glsl_text ? expanded.substr(expanded.find('\n') + 1) : expanded;
    EXPECT_TRUE(source.text.ends_with(body)) << language.name;
  }
}

TEST(Languages, AnInstancedSidecarAndLaunchRuleSayTheRowsInstance) {
  EmitOptions options;
  options.instanced = true;
  options.max_instances = 4;
  for (const Language& language : kLanguages) {
    const Variant v = Of(language.lang);
    const KernelSource source = Emit(v, 0, 77, options);
    const nlohmann::json sidecar = SidecarJson(source, v);
    EXPECT_EQ(sidecar["instancing"]["instance"], language.instance) << language.name;
    EXPECT_EQ(sidecar["instancing"]["rule"], language.instance_rule) << language.name;
    EXPECT_TRUE(source.launch.rule.ends_with(std::string("; ") + language.instance_rule)) << language.name;
  }
}

TEST(Languages, TheCopyIsEmittedInTheRowsCopyLanguageFromItsTemplate) {
  for (const Language& language : kLanguages) {
    const CopyKernel copy = EmitCopy(language.lang, 1 << 20);
    EXPECT_EQ(copy.kernel.lang, language.copy_lang) << language.name;
    EXPECT_EQ(copy.mesh.variant.lang, language.copy_lang) << language.name;
    EXPECT_EQ(copy.kernel.entry_point, language.glsl_text ? "main" : "skintune_copy") << language.name;
    const std::string expanded = ExpandedTemplate(language.copy_template);
    const std::string body = language.glsl_text ? expanded.substr(expanded.find('\n') + 1) : expanded;
    EXPECT_TRUE(copy.kernel.text.ends_with(body)) << language.name;
  }
  // GL runs both stages; its copy is a compute shader.
  EXPECT_EQ(LanguageOf(Lang::kGlslVertex).copy_lang, Lang::kGlslCompute);
}

TEST(Languages, WorkGroupsAndGlslTextAreTheColumns) {
  for (const Language& language : kLanguages) {
    EXPECT_EQ(HasWorkGroups(language.lang), language.work_groups) << language.name;
    EXPECT_EQ(IsGlslText(language.lang), language.glsl_text) << language.name;
    // A language without work-groups takes wg0 / v1c.
    EXPECT_EQ(Of(language.lang).wg_size == 0, !language.work_groups) << language.name;
  }
  EXPECT_FALSE(HasWorkGroups(Lang::kGlslVertex));
  EXPECT_FALSE(HasWorkGroups(Lang::kCpu));
  EXPECT_TRUE(IsGlslText(Lang::kVulkan));
}

TEST(Languages, ApisAreNumberedInTheOrderTheyFirstAppear) {
  std::vector<std::string> apis;
  for (const Language& language : kLanguages) {
    if (std::find(apis.begin(), apis.end(), language.api) == apis.end()) apis.push_back(language.api);
    EXPECT_STREQ(ApiRow(ApiIndex(language.lang)).api, language.api) << language.name;
    EXPECT_STREQ(ApiRow(ApiIndex(language.lang)).api_title, language.api_title) << language.name;
  }
  ASSERT_EQ(kApiCount, apis.size());
  for (std::size_t i = 0; i < kApiCount; ++i) EXPECT_EQ(ApiRow(i).api, apis[i]);
  EXPECT_EQ(apis, (std::vector<std::string>{"opencl", "cuda", "glsl", "vulkan", "cpu"}));
  EXPECT_EQ(ApiIndex(Lang::kGlslCompute), ApiIndex(Lang::kGlslVertex));
}

}  // namespace
}  // namespace skintune::internal
