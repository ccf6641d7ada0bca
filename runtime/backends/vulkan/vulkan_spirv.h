// skintune (internal): GLSL compute shaders to SPIR-V for Vulkan, with
// glslang (Debian's glslang-dev: its C interface, its default resource
// limits and SPIRV-Tools' optimiser, static libraries held once in
// libskintune_glslang.so: glslang_compile.h). Not shaderc: Debian's libshaderc.so.1 is linked without
// its glslang dependency (undefined glslang symbols that the program would
// have to export). Used by the Vulkan runner (vulkan_runner.cpp) and by
// `skintune emit`, which writes the SPIR-V beside the GLSL it came from.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace skintune::internal::vk {

// The SPIR-V words of `text` (a compute shader, entry point main, Vulkan 1.1
// target, SPIR-V 1.3, optimised); throws Error("Vulkan build: <what> failed
// to compile (glslang); log: <its first lines>").
std::vector<std::uint32_t> CompileSpirv(const std::string& text, const std::string& what);

}  // namespace skintune::internal::vk
