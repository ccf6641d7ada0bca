// templates/palette.comp, the palette kernel as a GL 4.3 compute shader
// (docs/ANIMATION.md), run through EGL on the machine's GL driver (Mesa
// llvmpipe here) against the float64 gold, as tests/generator/
// palette_kernel_test.cpp runs the CPU and OpenCL kernels (the same bound,
// the same instances: tests/generator/palette_gold.h). Every test skips, with
// the reason, when no EGL / GL 4.3 core context can be made.
#include <gtest/gtest.h>

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "generator/clip_packer.h"
#include "generator/emit.h"
#include "generator/palette_kernel.h"
#include "runtime/backends/gl/gl_context.h"
#include "runtime/backends/vulkan/vulkan_spirv.h"
#include "tests/common/test_asset.h"
#include "tests/generator/deep_rig.h"
#include "tests/generator/palette_checks.h"
#include "tests/generator/palette_gold.h"

namespace skintune::internal {
namespace {

using testing::Blends;
using testing::ExpectBakedClipsMatchTheirFrames;
using testing::ExpectBlendsMatchTheGold;
using testing::ExpectEveryClipOfTheGltfModelsMatchesTheGold;
using testing::ExpectNanRowsForAClipOutOfRange;
using testing::ExpectTheDeepRigMatchesTheGold;
using testing::On;
using testing::PaletteInputBytes;
using testing::Compare;
using testing::DeepRig;
using testing::EveryClipAlone;
using testing::ExpectWithinBound;
using testing::Name;
using testing::TestAsset;

// palette.comp in one GL context for the program: the template alone once,
// then each packed animation's kernel (EmitPalette).
class GlPaletteKernel {
 public:
  // Null, with the reason in `why`, without a GL 4.3 context.
  static GlPaletteKernel* Get(std::string& why) {
    static std::string reason;
    static const std::unique_ptr<GlPaletteKernel> kernel = [] {
      auto context = std::make_unique<GlContext>();
      if (!context->ok()) {
        reason = "no GL 4.3 context: " + context->reason();
        return std::unique_ptr<GlPaletteKernel>();
      }
      return std::unique_ptr<GlPaletteKernel>(new GlPaletteKernel(std::move(context)));
    }();
    why = reason;
    return kernel.get();
  }

  // The palette rows of `instances`, as RunPaletteKernel writes them.
  std::vector<float> Run(const PackedAnimation& packed, const std::vector<AnimInstance>& instances) {
    const std::size_t joints = packed.joints.size();
    std::vector<float> rows(instances.size() * joints * 12);
    const PaletteKernel kernel = EmitPalette(Lang::kGlslCompute, packed.View(), 3);
    // Every buffer by its name at consecutive bindings (the palette read back
    // below); a fresh frame, so the states are the instances.
    std::vector<GLuint> buffers;
    GLuint palette = 0;
    for (const KernelArgument& a : kernel.kernel.arguments) {
      if (a.kind != ArgumentKind::kBuffer) continue;
      const std::span<const std::uint8_t> bytes = PaletteInputBytes(packed, instances, a.name);
      std::vector<std::uint8_t> padded(bytes.begin(), bytes.end());
      padded.resize(std::max<std::size_t>(a.name == kAnimOutput ? rows.size() * sizeof(float) : padded.size(), 16), 0);
      GLuint& buffer = buffers.emplace_back();
      glGenBuffers(1, &buffer);
      glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
      glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(padded.size()), padded.data(), GL_DYNAMIC_READ);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, static_cast<GLuint>(buffers.size() - 1), buffer);
      if (a.name == kAnimOutput) palette = buffer;
    }
    const GLuint program = ProgramFor(kernel.kernel.text);
    glUseProgram(program);
    glUniform1f(glGetUniformLocation(program, "delta"), 0.0f);
    glUniform1ui(glGetUniformLocation(program, "fresh"), 1u);
    glDispatchCompute(1, static_cast<GLuint>(instances.size()), 1);  // a work-group per instance
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, palette);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(rows.size() * sizeof(float)), rows.data());
    glDeleteBuffers(static_cast<GLsizei>(buffers.size()), buffers.data());
    if (const GLenum error = glGetError(); error != GL_NO_ERROR)
      throw std::runtime_error("GL error " + std::to_string(error) + " running palette.comp");
    return rows;
  }

 private:
  explicit GlPaletteKernel(std::unique_ptr<GlContext> context) : context_(std::move(context)) {
    ProgramFor(ExpandedTemplate("palette.comp"));  // the template alone, at its defaults
  }

  // `text` compiled and linked once.
  GLuint ProgramFor(const std::string& text) {
    const std::string hash = SourceHash(text);
    if (const auto found = programs_.find(hash); found != programs_.end()) return found->second;
    const char* source = text.c_str();
    const GLuint shader = glCreateShader(GL_COMPUTE_SHADER);
    glShaderSource(shader, 1, &source, nullptr);
    glCompileShader(shader);
    GLint ok = GL_FALSE;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (ok != GL_TRUE) throw std::runtime_error("palette.comp does not compile: " + Log(shader, false));
    const GLuint program = glCreateProgram();
    glAttachShader(program, shader);
    glLinkProgram(program);
    glDeleteShader(shader);
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    if (ok != GL_TRUE) throw std::runtime_error("palette.comp does not link: " + Log(program, true));
    return programs_[hash] = program;
  }

  static std::string Log(GLuint object, bool program) {
    GLint length = 0;
    program ? glGetProgramiv(object, GL_INFO_LOG_LENGTH, &length) : glGetShaderiv(object, GL_INFO_LOG_LENGTH, &length);
    std::string log(static_cast<std::size_t>(std::max(length, 1)), '\0');
    program ? glGetProgramInfoLog(object, length, nullptr, log.data())
            : glGetShaderInfoLog(object, length, nullptr, log.data());
    return log;
  }

  std::unique_ptr<GlContext> context_;
  std::map<std::string, GLuint> programs_;  // by source hash
};

#define SKIP_WITHOUT_GL(kernel)                        \
  std::string why;                                     \
  GlPaletteKernel* kernel = GlPaletteKernel::Get(why); \
  if (kernel == nullptr) GTEST_SKIP() << why

TEST(PaletteKernelGl, MatchesTheGoldForEveryClipOfTheGltfModels) {
  SKIP_WITHOUT_GL(kernel);
  ExpectEveryClipOfTheGltfModelsMatchesTheGold(On(kernel), "gl");
}

TEST(PaletteKernelGl, MatchesTheGoldOnADeepRigWithEveryInterpolation) {
  SKIP_WITHOUT_GL(kernel);
  ExpectTheDeepRigMatchesTheGold(On(kernel), "gl");
}

TEST(PaletteKernelGl, BlendsTwoClipsInLocalSpaceLikeTheGold) {
  SKIP_WITHOUT_GL(kernel);
  ExpectBlendsMatchTheGold(On(kernel), "gl");
}

TEST(PaletteKernelGl, WritesNanRowsForAClipOutOfRangeInsteadOfReadingBeyond) {
  SKIP_WITHOUT_GL(kernel);
  ExpectNanRowsForAClipOutOfRange(On(kernel));
}

TEST(PaletteKernelGl, BakedClipsMatchTheirFramesAloneAndBlended) {
  SKIP_WITHOUT_GL(kernel);
  ExpectBakedClipsMatchTheirFrames(On(kernel), "gl");
  ExpectNanRowsForAClipOutOfRange(On(kernel), Animation::kBaked30);
  ExpectNanRowsForAClipOutOfRange(On(kernel), Animation::kLocal30);
}

// The same shader is Vulkan's: it compiles to SPIR-V with glslang, as the
// skin kernels do for Vulkan (the Skinner runs it: skinner_animation_test).
TEST(PaletteKernelVulkan, CompilesToSpirvWithGlslang) {
  const std::vector<std::uint32_t> spirv = vk::CompileSpirv(ExpandedTemplate("palette.comp"), "palette.comp");
  ASSERT_GT(spirv.size(), 5u);
  EXPECT_EQ(spirv[0], 0x07230203u);  // the SPIR-V magic number
  for (const SkinnedAsset* asset : {&TestAsset("Fox.gltf"), &DeepRig()}) {  // both record forms
    const PackedAnimation baked = BakeAnimation(*asset, 30.0);
    const std::vector<std::uint32_t> baked_spirv =
        vk::CompileSpirv(EmitPalette(Lang::kVulkan, baked.View(), 3).kernel.text, "palette.comp (baked)");
    ASSERT_GT(baked_spirv.size(), 5u);
  }
}

}  // namespace
}  // namespace skintune::internal
