// GLSL to SPIR-V (vulkan_spirv.h): glslang in libskintune_glslang.so
// (glslang_compile.h), its failures as skintune's build errors.
#include "runtime/backends/vulkan/vulkan_spirv.h"

#include "generator/template_includes.h"
#include "runtime/backends/vulkan/glslang_compile.h"
#include "runtime/backends/vulkan/vulkan_loader.h"
#include "runtime/output_check.h"

namespace skintune::internal::vk {

std::vector<std::uint32_t> CompileSpirv(const std::string& text, const std::string& what) {
  GlslangResult r = CompileWithGlslang(text);
  if (r.failed.empty()) return std::move(r.spirv);
  if (r.failed == "start") Fail("build", what + ": glslang could not start");
  if (r.failed == "compile")
    Fail("build", what + " failed to compile (glslang)" + GlslSourceStrings(text) + "; log:" + FirstLines(r.log, 20));
  if (r.failed == "link") Fail("build", what + " failed to link (glslang); log:" + FirstLines(r.log, 20));
  if (r.failed == "generate") Fail("build", what + ": SPIR-V generation: " + FirstLines(r.log, 20));
  Fail("build", what + ": glslang produced no SPIR-V");
}

}  // namespace skintune::internal::vk
