// skintune: the kernel languages, each declared once.
//
// A language is one row of kLanguages: the `lang` axis value (generator/axes.h
// takes its values from here), the template Emit expands, the instancing text
// of its sidecar, its same-size copy (copy_kernel.cpp), the file extension of
// `skintune emit`, whether its text is GLSL and whether it has work-groups, and
// the API reports name it under (report/paper_result.h's PaperApi). What a language
// does differently in code (its sidecar bindings, its constraints, fault
// injection) stays code; this table holds what is data.
//
// Row i is enumerator i of Lang, and a row leaves no column unset: the
// static_asserts below fail the build otherwise. Which API runs a language is
// the table of APIs' (runtime/backend_table.h, BackendEntry::languages).
// docs/ARCHITECTURE.md says what a new language or backend edits.
#pragma once

#include <cstddef>
#include <iterator>
#include <string_view>

namespace skintune::internal {

// kCpu: the fast CPU path's kernels (cpu_kernels/cpu_kernels.h), compiled into
// skintune and selected by the parameters of the kernel text (templates/skin.cpu).
enum class Lang { kOpenCl, kCuda, kGlslCompute, kGlslVertex, kVulkan, kCpu };
// Lang's enumerators: a new language goes last and moves this, and the
// static_asserts below then ask for its row.
inline constexpr std::size_t kLangCount = static_cast<std::size_t>(Lang::kCpu) + 1;

struct Language {
  Lang lang;                        // row i is Lang's enumerator i
  const char* name;                 // the `lang` axis value: keys, JSON, configs, --lang, sidecars
  const char* kernel_template;      // the templates/ file Emit expands (GLSL: starting with #version)
  const char* extension;            // `skintune emit`'s kernel file: KEY + extension (unique per language)
  bool glsl_text;                   // GLSL: entry point main, GLSL #line, bindings and uniforms in the sidecar
  bool work_groups;                 // false: one vertex per invocation or host-chosen chunks: wg0, v1c
  const char* instance;             // an instanced kernel's instance i, as the kernel reads it (sidecar)
  const char* instance_rule;        // where an instanced launch puts instance i, in words (sidecar, launch rule)
  const char* copy_template;        // the same-size copy's template (generator/copy_kernel.h)
  Lang copy_lang;                   // the language that copy is emitted in: its API's (glsl-vertex: glsl-compute)
  const char* palette_template;     // the palette kernel's template (generator/palette_kernel.h), emitted in copy_lang
  const char* api;                  // the API reports compare it as ("glsl": both GL stages): PaperApi's name
  const char* api_title;            // that API in tables and charts: "GLSL"
};

inline constexpr Language kLanguages[] = {
    {.lang = Lang::kOpenCl,
     .name = "opencl",
     .kernel_template = "skin.cl",
     .extension = ".cl",
     .glsl_text = false,
     .work_groups = true,
     .instance = "get_global_id(1)",
     .instance_rule = "K instances: global size (items, K), instance i = get_global_id(1)",
     .copy_template = "copy.cl",
     .copy_lang = Lang::kOpenCl,
     .palette_template = "palette.cl",
     .api = "opencl",
     .api_title = "OpenCL"},
    {.lang = Lang::kCuda,
     .name = "cuda",
     .kernel_template = "skin.cu",
     .extension = ".cu",
     .glsl_text = false,
     .work_groups = true,
     .instance = "blockIdx.y",
     .instance_rule = "K instances: grid (items / wg_size, K), instance i = blockIdx.y",
     .copy_template = "copy.cu",
     .copy_lang = Lang::kCuda,
     .palette_template = "palette.cu",
     .api = "cuda",
     .api_title = "CUDA"},
    {.lang = Lang::kGlslCompute,
     .name = "glsl-compute",
     .kernel_template = "skin.comp",
     .extension = ".comp",
     .glsl_text = true,
     .work_groups = true,
     .instance = "gl_WorkGroupID.y",
     .instance_rule = "K instances: glDispatchCompute(items / wg_size, K, 1), instance i = gl_WorkGroupID.y",
     .copy_template = "copy.comp",
     .copy_lang = Lang::kGlslCompute,
     .palette_template = "palette.comp",
     .api = "glsl",
     .api_title = "GLSL"},
    // Transform feedback of a vertex shader; GL's copy is a compute shader.
    {.lang = Lang::kGlslVertex,
     .name = "glsl-vertex",
     .kernel_template = "skin.vert",
     .extension = ".vert",
     .glsl_text = true,
     .work_groups = false,
     .instance = "gl_InstanceID",
     .instance_rule = "K instances: glDrawArraysInstanced(GL_POINTS, 0, n, K), instance i = gl_InstanceID; the "
                      "capture holds the K instances' n vertices one instance after another",
     .copy_template = "copy.comp",
     .copy_lang = Lang::kGlslCompute,
     .palette_template = "palette.comp",
     .api = "glsl",
     .api_title = "GLSL"},
    // The GL compute stage's text compiled to SPIR-V: VULKAN (predefined by
    // glslang, GL_KHR_vulkan_glsl) selects its push constants, in the copy too.
    {.lang = Lang::kVulkan,
     .name = "vulkan",
     .kernel_template = "skin.comp",
     .extension = ".vk.comp",
     .glsl_text = true,
     .work_groups = true,
     .instance = "gl_WorkGroupID.y",
     .instance_rule = "K instances: vkCmdDispatch(items / wg_size, K, 1), instance i = gl_WorkGroupID.y",
     .copy_template = "copy.comp",
     .copy_lang = Lang::kVulkan,
     .palette_template = "palette.comp",
     .api = "vulkan",
     .api_title = "Vulkan"},
    // Parameters only: the kernels and the all-thread memcpy copy are compiled
    // into skintune; threads and chunks are chosen per machine by measurement
    // (runtime/backends/cpu/cpu_runner.h), not by work-groups.
    {.lang = Lang::kCpu,
     .name = "cpu",
     .kernel_template = "skin.cpu",
     .extension = ".cpu",
     .glsl_text = false,
     .work_groups = false,
     .instance = "the host's instance loop",
     .instance_rule = "K instances: the host loops over the instances; instance i = the loop's index",
     .copy_template = "copy.cpu",
     .copy_lang = Lang::kCpu,
     .palette_template = "palette.cpu",
     .api = "cpu",
     .api_title = "CPU"},
};

namespace languages_detail {

constexpr bool Set(const char* text) { return text != nullptr && *text != '\0'; }
constexpr bool Same(const char* a, const char* b) { return std::string_view(a) == std::string_view(b); }

// Row i is enumerator i and sets every text column.
constexpr bool RowsFollowTheEnum() {
  for (std::size_t i = 0; i < std::size(kLanguages); ++i) {
    const Language& l = kLanguages[i];
    if (static_cast<std::size_t>(l.lang) != i) return false;
    for (const char* text : {l.name, l.kernel_template, l.extension, l.instance, l.instance_rule, l.copy_template,
                             l.palette_template,
                             l.api, l.api_title})
      if (!Set(text)) return false;
  }
  return true;
}

// Names and extensions tell the languages apart; a copy language copies in
// its own language with the same template; an API has one title.
constexpr bool RowsAgree() {
  for (const Language& a : kLanguages) {
    const Language& copy = kLanguages[static_cast<std::size_t>(a.copy_lang)];
    if (copy.copy_lang != copy.lang || !Same(copy.copy_template, a.copy_template)) return false;
    for (const Language& b : kLanguages) {
      if (&a == &b) continue;
      if (Same(a.name, b.name) || Same(a.extension, b.extension)) return false;
      if (Same(a.api, b.api) != Same(a.api_title, b.api_title)) return false;
    }
  }
  return true;
}

}  // namespace languages_detail

static_assert(std::size(kLanguages) == kLangCount, "every Lang enumerator needs its row in kLanguages");
static_assert(languages_detail::RowsFollowTheEnum(), "kLanguages[i] is Lang's enumerator i and sets every column");
static_assert(languages_detail::RowsAgree(),
              "names and extensions are unique, a copy language copies in itself, an API has one title");

constexpr const Language& LanguageOf(Lang lang) { return kLanguages[static_cast<std::size_t>(lang)]; }

// Whether the kernel text is GLSL: glsl-compute, glsl-vertex, and vulkan.
constexpr bool IsGlslText(Lang lang) { return LanguageOf(lang).glsl_text; }
// glsl-vertex and cpu have no work-groups: their wg_size, vertices_per_item and
// assignment are wg0 / v1c.
constexpr bool HasWorkGroups(Lang lang) { return LanguageOf(lang).work_groups; }

// The APIs of the rows, each once, in the order they first appear (opencl,
// cuda, glsl, vulkan, cpu): report/paper_result.h's PaperApi takes its values from
// ApiIndex, so the report derives which API a language counts under.
constexpr std::size_t FirstRowOfApi(const char* api) {
  std::size_t row = 0;
  while (!languages_detail::Same(kLanguages[row].api, api)) ++row;
  return row;
}
constexpr std::size_t ApiIndex(Lang lang) {
  std::size_t index = 0;
  for (std::size_t row = 0; row < FirstRowOfApi(LanguageOf(lang).api); ++row)
    if (FirstRowOfApi(kLanguages[row].api) == row) ++index;
  return index;
}
inline constexpr std::size_t kApiCount = [] {
  std::size_t count = 0;
  for (std::size_t row = 0; row < kLangCount; ++row)
    if (FirstRowOfApi(kLanguages[row].api) == row) ++count;
  return count;
}();
// The first row of API `index` (< kApiCount): its name and title.
constexpr const Language& ApiRow(std::size_t index) {
  std::size_t row = 0;
  while (row + 1 < kLangCount && ApiIndex(kLanguages[row].lang) != index) ++row;
  return kLanguages[row];
}

}  // namespace skintune::internal
