// skintune (internal): glslang's GLSL -> SPIR-V compile of one compute
// shader, in a shared library of its own (libskintune_glslang.so,
// runtime/CMakeLists.txt). glslang and SPIRV-Tools are static in Debian
// (glslang-dev) and weigh ~20 MB: linked into every program that discovers
// devices, they made 43 of the build's 81 executables 20 MB each (935 MB of
// build/bin on the 2-core development machine, 2026-11). Held once here, the
// programs and libskintune.so load it like any shared library. The interface
// names no glslang type and nothing else of skintune, so the library holds
// glslang alone; vulkan_spirv.cpp turns its result into skintune's errors.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace skintune::internal::vk {

struct GlslangResult {
  std::vector<std::uint32_t> spirv;  // the SPIR-V words when `failed` is empty
  // Empty on success, else the step that failed: "start" (glslang made no
  // shader), "compile" (preprocess or parse), "link", "generate" (SPIR-V
  // generation or its validation) or "empty" (no words).
  std::string failed;
  std::string log;  // glslang's log of the failed step
};

// `text`: a compute shader, entry point main, compiled for Vulkan 1.1 to
// SPIR-V 1.3 with glslang's optimiser and validation on. Thread-safe.
[[gnu::visibility("default")]] GlslangResult CompileWithGlslang(const std::string& text);

}  // namespace skintune::internal::vk
