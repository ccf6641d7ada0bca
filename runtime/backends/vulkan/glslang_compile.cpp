// glslang's C interface behind glslang_compile.h (libskintune_glslang.so).
#include "runtime/backends/vulkan/glslang_compile.h"

#include <glslang/Include/glslang_c_interface.h>
#include <glslang/Public/resource_limits_c.h>

#include <mutex>

namespace skintune::internal::vk {

GlslangResult CompileWithGlslang(const std::string& text) {
  static std::once_flag initialised;
  std::call_once(initialised, [] { glslang_initialize_process(); });  // once per process, never finalised
  glslang_input_t input{};
  input.language = GLSLANG_SOURCE_GLSL;
  input.stage = GLSLANG_STAGE_COMPUTE;
  input.client = GLSLANG_CLIENT_VULKAN;
  input.client_version = GLSLANG_TARGET_VULKAN_1_1;
  input.target_language = GLSLANG_TARGET_SPV;
  input.target_language_version = GLSLANG_TARGET_SPV_1_3;
  input.code = text.c_str();
  input.default_version = 450;
  input.default_profile = GLSLANG_NO_PROFILE;
  input.messages = static_cast<glslang_messages_t>(GLSLANG_MSG_SPV_RULES_BIT | GLSLANG_MSG_VULKAN_RULES_BIT);
  input.resource = glslang_default_resource();

  struct Owned {
    glslang_shader_t* shader = nullptr;
    glslang_program_t* program = nullptr;
    ~Owned() {
      if (program) glslang_program_delete(program);
      if (shader) glslang_shader_delete(shader);
    }
  } o;
  GlslangResult result;
  o.shader = glslang_shader_create(&input);
  if (!o.shader) {
    result.failed = "start";
    return result;
  }
  if (!glslang_shader_preprocess(o.shader, &input) || !glslang_shader_parse(o.shader, &input)) {
    result.failed = "compile";
    result.log = std::string(glslang_shader_get_info_log(o.shader)) + glslang_shader_get_info_debug_log(o.shader);
    return result;
  }
  o.program = glslang_program_create();
  glslang_program_add_shader(o.program, o.shader);
  if (!glslang_program_link(o.program, GLSLANG_MSG_SPV_RULES_BIT | GLSLANG_MSG_VULKAN_RULES_BIT)) {
    result.failed = "link";
    result.log = glslang_program_get_info_log(o.program);
    return result;
  }
  glslang_spv_options_t options{};
  options.disable_optimizer = false;  // glslang's SPIR-V optimiser (SPIRV-Tools) on
  options.validate = true;
  glslang_program_SPIRV_generate_with_options(o.program, GLSLANG_STAGE_COMPUTE, &options);
  if (const char* messages = glslang_program_SPIRV_get_messages(o.program); messages && *messages) {
    result.failed = "generate";
    result.log = messages;
    return result;
  }
  result.spirv.resize(glslang_program_SPIRV_get_size(o.program));
  glslang_program_SPIRV_get(o.program, result.spirv.data());
  if (result.spirv.empty()) result.failed = "empty";
  return result;
}

}  // namespace skintune::internal::vk
