// Every glsl-compute and glsl-vertex variant axis value, run through EGL on
// the machine's GL driver (Mesa llvmpipe in CI) against the float64 gold, on a
// fresh random synthetic mesh each run (the seed is printed;
// SKINTUNE_TEST_SEED=<n> reproduces a run) and on CesiumMan for the bucketed
// launches. Each language's 27 padded cases cross every layout with every
// index and every weight format, and between them reach every value of the
// other axes (every storage, both blends, both palettes, both position
// formats, normals on and off, every N/assignment and several work-group
// sizes for compute). Plus: both templates compile alone, their shared part
// is identical, the poisoned output catches vertices never written, the guard
// catches writes past the end, a build error carries its log, and a failed
// context gives a reason instead of crashing. Every test skips, with the
// reason, only when no EGL / GL 4.3 core context can be made.
#include <gtest/gtest.h>

#include <epoxy/gl.h>

#include <algorithm>
#include <cstring>
#include <iostream>

#include "generator/constraints.h"
#include "generator/copy_kernel.h"
#include "generator/covering.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "base/error.h"
#include "runner_test_support.h"
#include "runtime/backends/gl/gl_context.h"
#include "runtime/backends/gl/gl_runner.h"
#include "runtime/output_check.h"
#include "runtime/run_shape.h"

namespace skintune::internal {
namespace {

using testing::Asset;
using testing::Case;
using testing::CaseName;
using testing::ExpectCaseMatchesGold;
using testing::ExpectCoveringSetMatchesGold;
using testing::ExpectHalfPoisoned;
using testing::ExpectMatchesGold;
using testing::ExpectRunFails;
using testing::Faulty;
using testing::LaunchTimes;
using testing::Palette;
using testing::Seed;
using testing::WithFault;

// One runner (one GL context) for the whole test program, or null with the
// reason when no EGL / GL 4.3 core context can be made on this machine.
GlRunner* Runner(std::string& why) {
  static std::string reason;
  static std::unique_ptr<GlRunner> runner = []() -> std::unique_ptr<GlRunner> {
    try {
      auto r = std::make_unique<GlRunner>();
      const GlContextInfo& i = r->info();
      std::cout << "[ GL       ] " << i.renderer << " (" << i.vendor << "), " << i.version << ", EGL platform "
                << i.egl_platform << (i.egl_device.empty() ? "" : ", " + i.egl_device)
                << (i.reset_notification ? ", reset notification" : ", no reset notification") << "\n";
      return r;
    } catch (const Error& e) {
      reason = e.what();
      return nullptr;
    }
  }();
  why = reason;
  return runner.get();
}

#define REQUIRE_GL(runner)        \
  std::string why;                \
  GlRunner* runner = Runner(why); \
  if (!runner) GTEST_SKIP() << why

int MaxInfluences(const SkinnedMesh& mesh) {
  int most = 0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) most = std::max(most, mesh.InfluencesOf(v));
  return most;
}

void RunCase(const Case& c) {
  REQUIRE_GL(runner);
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + ", seed " + std::to_string(Seed()) +
               " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name());
  const SkinnedMesh& mesh = Asset(c.mesh).mesh;
  const Variant variant = ParseVariantKey(c.key);
  const ProblemShape shape{mesh.joint_count, MaxInfluences(mesh), mesh.has_normals()};
  const std::vector<Violation> violations = CheckVariant(variant, LimitsOf(runner->info()), shape);
  for (const Violation& v : violations) {
    // Only a device limit may rule a case out; the shape-related ones are mistakes in the table.
    ASSERT_TRUE(v.constraint == Constraint::kWgSizeDevice || v.constraint == Constraint::kLocalMemory ||
                v.constraint == Constraint::kConstantMemory || v.constraint == Constraint::kImageSize ||
                v.constraint == Constraint::kStorageBlocks)
        << v.message;
  }
  if (!violations.empty()) GTEST_SKIP() << "this device cannot run it: " << violations.front().message;
  ExpectCaseMatchesGold(*runner, c, variant, LaunchTimes::kNonNegative);
}

class GlslComputeVariant : public ::testing::TestWithParam<Case> {};
TEST_P(GlslComputeVariant, MatchesTheGold) { RunCase(GetParam()); }

class GlslVertexVariant : public ::testing::TestWithParam<Case> {};
TEST_P(GlslVertexVariant, MatchesTheGold) { RunCase(GetParam()); }

// layout x index x weight (27), every storage, blend, palette, position format,
// N and assignment, work-group sizes 32..1024, normals on and off, padding
// (more slots than the mesh uses: b8 on b7, b4 on b3), then bucketed launches.
const Case kComputeCases[] = {
    {"glsl-compute.b1.padded.aos.float4.i32.f32.mat3x4.constant.matrix.v1c.wg32.normals", "b1"},
    {"glsl-compute.b4.padded.aos.float4.i32.unorm16.mat3x4.local.matrix.v2c.wg32.nonormals", "b4-random"},
    {"glsl-compute.b7.padded.aos.float4.i32.unorm8.mat3x4.global.point.v4s.wg64.nonormals", "b7"},
    {"glsl-compute.b2.padded.aos.float3.u16.f32.mat4.image.matrix.v8c.wg64.nonormals", "b2"},
    {"glsl-compute.b5.padded.aos.float3.u16.unorm16.mat4.constant.point.v2s.wg256.nonormals", "b5"},
    {"glsl-compute.b8.padded.aos.float3.u16.unorm8.mat4.local.point.v4c.wg256.normals", "b7"},
    {"glsl-compute.b3.padded.aos.float4.u8.f32.mat3x4.global.point.v8s.wg128.nonormals", "b3"},
    {"glsl-compute.b6.padded.aos.float4.u8.unorm16.mat3x4.image.point.v1c.wg128.normals", "b6"},
    {"glsl-compute.b1.padded.aos.float4.u8.unorm8.mat3x4.constant.matrix.v2c.wg512.normals", "b1"},
    {"glsl-compute.b5.padded.soa.float3.i32.f32.mat3x4.global.matrix.v4s.wg1024.nonormals", "b5-random"},
    {"glsl-compute.b8.padded.soa.float3.i32.unorm16.mat3x4.image.point.v8c.wg32.nonormals", "b8"},
    {"glsl-compute.b3.padded.soa.float3.i32.unorm8.mat3x4.constant.point.v2s.wg32.normals", "b3"},
    {"glsl-compute.b6.padded.soa.float4.u16.f32.mat4.local.point.v4c.wg64.nonormals", "b6"},
    {"glsl-compute.b1.padded.soa.float4.u16.unorm16.mat4.global.point.v8s.wg64.normals", "b1-random"},
    {"glsl-compute.b4.padded.soa.float4.u16.unorm8.mat4.image.matrix.v1c.wg256.normals", "b3"},
    {"glsl-compute.b7.padded.soa.float3.u8.f32.mat3x4.constant.point.v2c.wg256.normals", "b7"},
    {"glsl-compute.b2.padded.soa.float3.u8.unorm16.mat3x4.local.matrix.v4s.wg128.normals", "b2"},
    {"glsl-compute.b5.padded.soa.float3.u8.unorm8.mat3x4.global.matrix.v8c.wg128.nonormals", "b5-random"},
    {"glsl-compute.b1.padded.soa-split.float4.i32.f32.mat3x4.constant.point.v2s.wg1024.nonormals", "b1"},
    {"glsl-compute.b4.padded.soa-split.float4.i32.unorm16.mat3x4.local.point.v4c.wg1024.normals", "b4"},
    {"glsl-compute.b7.padded.soa-split.float4.i32.unorm8.mat3x4.global.matrix.v8s.wg32.normals", "b7"},
    {"glsl-compute.b2.padded.soa-split.float3.u16.f32.mat4.image.point.v1c.wg32.normals", "b2-random"},
    {"glsl-compute.b5.padded.soa-split.float3.u16.unorm16.mat4.constant.matrix.v2c.wg64.normals", "b5"},
    {"glsl-compute.b8.padded.soa-split.float3.u16.unorm8.mat4.local.matrix.v4s.wg64.nonormals", "b7"},
    {"glsl-compute.b3.padded.soa-split.float4.u8.f32.mat3x4.global.matrix.v8c.wg256.normals", "b3"},
    {"glsl-compute.b6.padded.soa-split.float4.u8.unorm16.mat3x4.image.matrix.v2s.wg256.nonormals", "b6-random"},
    {"glsl-compute.b1.padded.soa-split.float4.u8.unorm8.mat3x4.constant.point.v4c.wg128.nonormals", "b1"},
    // bucketed: one launch (own kernel, own inputs, first > 0) per influence count
    {"glsl-compute.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.normals", "cesium"},
    {"glsl-compute.b4.bucketed.aos.float3.u8.unorm8.mat4.local.point.v2s.wg64.normals", "cesium"},
    {"glsl-compute.b4.bucketed.soa-split.float4.u16.unorm16.mat3x4.image.matrix.v4c.wg32.nonormals", "cesium"},
};
INSTANTIATE_TEST_SUITE_P(EveryAxis, GlslComputeVariant, ::testing::ValuesIn(kComputeCases), CaseName);

// The same crossing for the vertex shader (v1c.wg0; storage local does not exist there).
const Case kVertexCases[] = {
    {"glsl-vertex.b1.padded.aos.float4.i32.f32.mat3x4.constant.matrix.v1c.wg0.normals", "b1"},
    {"glsl-vertex.b4.padded.aos.float4.i32.unorm16.mat3x4.global.matrix.v1c.wg0.nonormals", "b4-random"},
    {"glsl-vertex.b7.padded.aos.float4.i32.unorm8.mat3x4.image.point.v1c.wg0.nonormals", "b7"},
    {"glsl-vertex.b2.padded.aos.float3.u16.f32.mat4.constant.matrix.v1c.wg0.nonormals", "b2"},
    {"glsl-vertex.b5.padded.aos.float3.u16.unorm16.mat4.global.point.v1c.wg0.nonormals", "b5"},
    {"glsl-vertex.b8.padded.aos.float3.u16.unorm8.mat4.image.point.v1c.wg0.normals", "b7"},
    {"glsl-vertex.b3.padded.aos.float4.u8.f32.mat3x4.constant.point.v1c.wg0.nonormals", "b3"},
    {"glsl-vertex.b6.padded.aos.float4.u8.unorm16.mat3x4.global.point.v1c.wg0.normals", "b6"},
    {"glsl-vertex.b1.padded.aos.float4.u8.unorm8.mat3x4.image.matrix.v1c.wg0.normals", "b1"},
    {"glsl-vertex.b5.padded.soa.float3.i32.f32.mat3x4.global.matrix.v1c.wg0.nonormals", "b5-random"},
    {"glsl-vertex.b8.padded.soa.float3.i32.unorm16.mat3x4.image.point.v1c.wg0.nonormals", "b8"},
    {"glsl-vertex.b3.padded.soa.float3.i32.unorm8.mat3x4.constant.point.v1c.wg0.normals", "b3"},
    {"glsl-vertex.b6.padded.soa.float4.u16.f32.mat4.global.point.v1c.wg0.nonormals", "b6"},
    {"glsl-vertex.b1.padded.soa.float4.u16.unorm16.mat4.image.point.v1c.wg0.normals", "b1-random"},
    {"glsl-vertex.b4.padded.soa.float4.u16.unorm8.mat4.constant.matrix.v1c.wg0.normals", "b3"},
    {"glsl-vertex.b7.padded.soa.float3.u8.f32.mat3x4.global.point.v1c.wg0.normals", "b7"},
    {"glsl-vertex.b2.padded.soa.float3.u8.unorm16.mat3x4.image.matrix.v1c.wg0.normals", "b2"},
    {"glsl-vertex.b5.padded.soa.float3.u8.unorm8.mat3x4.constant.matrix.v1c.wg0.nonormals", "b5-random"},
    {"glsl-vertex.b1.padded.soa-split.float4.i32.f32.mat3x4.image.point.v1c.wg0.nonormals", "b1"},
    {"glsl-vertex.b4.padded.soa-split.float4.i32.unorm16.mat3x4.constant.point.v1c.wg0.normals", "b4"},
    {"glsl-vertex.b7.padded.soa-split.float4.i32.unorm8.mat3x4.global.matrix.v1c.wg0.normals", "b7"},
    {"glsl-vertex.b2.padded.soa-split.float3.u16.f32.mat4.image.point.v1c.wg0.normals", "b2-random"},
    {"glsl-vertex.b5.padded.soa-split.float3.u16.unorm16.mat4.constant.matrix.v1c.wg0.normals", "b5"},
    {"glsl-vertex.b8.padded.soa-split.float3.u16.unorm8.mat4.global.matrix.v1c.wg0.nonormals", "b7"},
    {"glsl-vertex.b3.padded.soa-split.float4.u8.f32.mat3x4.image.matrix.v1c.wg0.normals", "b3"},
    {"glsl-vertex.b6.padded.soa-split.float4.u8.unorm16.mat3x4.constant.matrix.v1c.wg0.nonormals", "b6-random"},
    {"glsl-vertex.b1.padded.soa-split.float4.u8.unorm8.mat3x4.global.point.v1c.wg0.nonormals", "b1"},
    // bucketed: one draw per influence count, each captured at its own range
    {"glsl-vertex.b4.bucketed.soa.float4.u16.f32.mat3x4.constant.matrix.v1c.wg0.normals", "cesium"},
    {"glsl-vertex.b4.bucketed.aos.float3.u8.unorm8.mat4.image.point.v1c.wg0.normals", "cesium"},
    {"glsl-vertex.b4.bucketed.soa-split.float4.u16.unorm16.mat3x4.global.matrix.v1c.wg0.nonormals", "cesium"},
};
INSTANTIATE_TEST_SUITE_P(EveryAxis, GlslVertexVariant, ::testing::ValuesIn(kVertexCases), CaseName);

// ------------------------------------------------------------------ templates

// A template with its preludes expanded, with no defines at all.
KernelSource Bare(const char* file, Lang lang) {
  KernelSource s;
  s.lang = lang;
  s.entry_point = "main";
  s.text = ExpandedTemplate(file);
  s.source_hash = SourceHash(s.text);
  return s;
}

// The generated covering sets (generator/covering.h) for this context's
// limits: every value of every axis and every pair of layout x index x weight
// x palette x storage x blend that the language can hold, each variant on a
// fresh mesh with its own influence count.
void RunCoveringSet(Lang lang) {
  REQUIRE_GL(runner);
  const CoveringSet set = BuildCoveringSet(lang, LimitsOf(runner->info()), testing::CoveringShape());
  for (const std::string& pair : set.uncoverable) {
    EXPECT_NE(pair.find("storage=local"), std::string::npos) << "only local storage may be uncoverable: " << pair;
  }
  ExpectCoveringSetMatchesGold(*runner, set, LaunchTimes::kNonNegative);
  std::cout << "[ covering ] " << set.variants.size() << " " << Name(lang) << " variants verified on "
            << runner->device_name() << "\n";
}

TEST(GlslCoveringSet, EveryComputeVariantMatchesTheGold) { RunCoveringSet(Lang::kGlslCompute); }
TEST(GlslCoveringSet, EveryVertexVariantMatchesTheGold) { RunCoveringSet(Lang::kGlslVertex); }

TEST(GlslTemplates, ComputeTemplateCompilesAlone) {
  REQUIRE_GL(runner);
  EXPECT_NO_THROW(runner->Build(Bare("skin.comp", Lang::kGlslCompute)));
}

TEST(GlslTemplates, VertexTemplateCompilesAlone) {
  REQUIRE_GL(runner);
  EXPECT_NO_THROW(runner->Build(Bare("skin.vert", Lang::kGlslVertex)));
}

TEST(GlslTemplates, StartWithTheirVersionLineAndIncludeOneSkinningBody) {
  // The body is included, not copied: tests/generator/template_includes_test.cpp
  // checks that neither stage repeats a line of it.
  for (const char* file : {"skin.comp", "skin.vert"}) {
    const std::string text = TemplateText(file);
    EXPECT_EQ(text.rfind("#version 430 core\n", 0), 0u) << file;
    EXPECT_NE(text.find("\n#include \"skin_body.glsl\"\n"), std::string::npos) << file;
    EXPECT_EQ(ExpandedTemplate(file).rfind("#version 430 core\n", 0), 0u) << file;
  }
}

// GLSL's #line takes no file name: an emitted shader numbers its files as
// source strings (0 the template, 1 skin_params.h, 2 skin_body.glsl), so a
// build log points at the prelude's own line, in the driver's own form (Mesa
// "2:48(3): error", NVIDIA "2(48) : error"), and the error names the files.
TEST(GlslTemplates, BuildLogsGiveThePreludeAndLineOfAnError) {
  REQUIRE_GL(runner);
  const std::string line = "uniform uint n;      // vertices of this launch";
  const std::string body = TemplateText("skin_body.glsl");
  ASSERT_NE(body.find(line), std::string::npos) << "update the test: the body changed";
  const long number = std::count(body.begin(), body.begin() + static_cast<long>(body.find(line)), '\n') + 1;
  for (const char* key : {"glsl-compute.b2", "glsl-vertex.b2.v1c.wg0"}) {
    KernelSource s = Emit(ParseVariantKey(key), 0, 20);
    testing::EditKernel(s, line, "#error skintune injected fault");
    try {
      runner->Build(s);
      ADD_FAILURE() << key << ": a shader with #error built";
    } catch (const Error& e) {
      const std::string what = e.what();
      const bool mesa = what.find("2:" + std::to_string(number) + "(") != std::string::npos;
      const bool nvidia = what.find("2(" + std::to_string(number) + ")") != std::string::npos;
      EXPECT_TRUE(mesa || nvidia) << "no source string 2, line " << number << " in: " << what;
      EXPECT_NE(what.find("(source strings: 0 "), std::string::npos) << what;
      // The vertex stage makes no palette: it includes no animation records.
      const bool vertex = std::string(key).starts_with("glsl-vertex");
      EXPECT_NE(what.find(vertex ? ", 1 skin_params.h, 2 skin_body.glsl)" : ", 1 skin_params.h, 2 skin_body.glsl, 3 anim_records.glsl)"),
                std::string::npos)
          << what;
    }
  }
}

TEST(GlslTemplates, EmittedVertexKernelRejectsLocalStorage) {
  REQUIRE_GL(runner);
  const KernelSource s = Emit(ParseVariantKey("glsl-vertex.b2.soa.local.v1c.wg0"), 0, 20);
  try {
    runner->Build(s);
    ADD_FAILURE() << "a vertex shader with a shared-memory palette built";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("GL build"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no shared memory"), std::string::npos) << e.what();
  }
}

// ------------------------------------------------------------------ faults

// The faulty kernels (WithFault): one padded soa launch, compute or vertex.
constexpr const char* kComputeKey = "glsl-compute.b2.soa.float4.u16.f32.wg64";
constexpr const char* kVertexKey = "glsl-vertex.b2.soa.float4.u16.f32";

TEST(GlRunner, PoisonedOutputCatchesAComputeKernelThatSkipsVertices) {
  REQUIRE_GL(runner);
  Faulty f = WithFault(kComputeKey, "if (v >= n) break;", "if (v >= n / 2u) break;");
  ExpectHalfPoisoned(f, runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant)));
}

// A vertex shader writes every vertex it is drawn for, so what poison catches
// there is a draw that covers too few vertices: here a launch of half the count.
TEST(GlRunner, PoisonedOutputCatchesADrawThatSkipsVertices) {
  REQUIRE_GL(runner);
  Faulty f = WithFault(kVertexKey, "", "");
  f.packed.launches.front().count = static_cast<std::uint32_t>(f.packed.vertex_count / 2);
  ExpectHalfPoisoned(f, runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant)));
}

void ExpectGuardError(GlRunner* runner, const Faulty& f) {
  ExpectRunFails(*runner, f, "writing 64 vertices past the output was not caught",
                 {"GL guard", "out_positions", "wrote past the end"});
}

TEST(GlRunner, GuardCatchesAComputeKernelThatWritesPastTheEnd) {
  REQUIRE_GL(runner);
  ExpectGuardError(runner, WithFault(kComputeKey, "STORE_POSITION(out_first + v, skinned_position);",
                                     "STORE_POSITION(out_first + v + 64u, skinned_position);"));
}

// Transform feedback cannot write outside its bound range, so the guard after
// the captured range catches a capture range placed past the end: here the
// launch's first vertex moved by 64.
TEST(GlRunner, GuardCatchesACaptureThatWritesPastTheEnd) {
  REQUIRE_GL(runner);
  Faulty f = WithFault(kVertexKey, "", "");
  f.packed.launches.front().first += 64;
  ExpectGuardError(runner, f);
}

TEST(GlRunner, BuildFailureCarriesTheLog) {
  REQUIRE_GL(runner);
  for (const char* key : {kComputeKey, kVertexKey}) {
    Faulty f = WithFault(key, "float weight_of(uint raw) {", "float weight_of(uint raw) {\n  undeclared_name_xyz = 1;");
    ExpectRunFails(*runner, f, std::string(key) + ": a kernel with an undeclared name built",
                   {"GL build", "undeclared_name_xyz"});
  }
}

TEST(GlRunner, RejectsAPaletteOfTheWrongSize) {
  REQUIRE_GL(runner);
  const PackedMesh packed = Pack(Asset("b2").mesh, ParseVariantKey(kComputeKey));
  const std::vector<std::uint8_t> short_palette(16);
  try {
    runner->Run(packed, short_palette);
    ADD_FAILURE() << "a 16-byte palette was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("palette has 16 bytes"), std::string::npos) << e.what();
  }
}

// ------------------------------------------------------------------ instances

// K instances per launch (docs/VARIANTS.md "Instancing"), each with its own
// random palette, each instance against the gold of that palette: every
// layout and storage, padded and bucketed (CesiumMan: 4 launches; the vertex
// shader's bucketed captures go through a staging buffer), several vertices
// per invocation contiguous and strided, float3 and float4, normals.
class GlslInstanced : public ::testing::TestWithParam<testing::InstanceCase> {};

TEST_P(GlslInstanced, EveryInstanceMatchesTheGoldOfItsPalette) {
  REQUIRE_GL(runner);
  const testing::InstanceCase& c = GetParam();
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + " x" + std::to_string(c.instances) + ", seed " +
               std::to_string(Seed()) + " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name());
  testing::ExpectInstanceCaseMatchesGold(*runner, c, LimitsOf(runner->info()));
}

const Case kInstancedComputeCases[] = {
    {"glsl-compute.b4.padded.aos.float4.u16.f32.mat4.constant.matrix.v1c.wg64.normals", "b4"},
    {"glsl-compute.b3.padded.soa.float3.u8.unorm8.mat3x4.local.point.v2s.wg128.nonormals", "b3-random"},
    {"glsl-compute.b2.padded.soa-split.float4.i32.unorm16.mat3x4.image.matrix.v4c.wg32.normals", "b2"},
    {"glsl-compute.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v8s.wg256.normals", "cesium"},
    {"glsl-compute.b4.bucketed.aos.float3.u8.unorm8.mat4.local.matrix.v2c.wg64.nonormals", "cesium"},
    {"glsl-compute.b4.bucketed.soa-split.float3.u16.f32.mat3x4.constant.point.v4s.wg128.normals", "cesium"},
};
const Case kInstancedVertexCases[] = {
    {"glsl-vertex.b4.padded.aos.float4.u16.f32.mat4.constant.matrix.v1c.wg0.normals", "b4"},
    {"glsl-vertex.b3.padded.soa.float3.u8.unorm8.mat3x4.global.point.v1c.wg0.nonormals", "b3-random"},
    {"glsl-vertex.b2.padded.soa-split.float4.i32.unorm16.mat3x4.image.matrix.v1c.wg0.normals", "b2"},
    {"glsl-vertex.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg0.normals", "cesium"},
    {"glsl-vertex.b4.bucketed.aos.float3.u8.unorm8.mat4.image.point.v1c.wg0.nonormals", "cesium"},
    {"glsl-vertex.b4.bucketed.soa-split.float3.u16.f32.mat3x4.constant.matrix.v1c.wg0.normals", "cesium"},
};

// Live frames on the runner's own context end with no barrier; the next read
// issues the one that makes their outputs readable (GlApi::RunLive), and the
// frames' writes are ordered among themselves: eight frames queued with a
// palette each, one barrier for the read after them, and the read is the
// gold of the last frame's palettes.
TEST(GlRunner, LiveFramesOnItsOwnContextLeaveTheirBarrierToTheNextRead) {
  REQUIRE_GL(runner);
  constexpr int kInstances = 2, kFrames = 8;
  const char* key = "glsl-compute.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.nonormals";
  const Variant variant = ParseVariantKey(key);
  const SkinnedAsset& asset = testing::SmallAsset("cesium");
  const PackedMesh packed = Pack(asset.mesh, variant);
  const auto palettes = [&](int f) {
    std::vector<std::uint8_t> bytes;
    for (int k = 0; k < kInstances; ++k) {
      const std::vector<std::uint8_t> p = PackPalette(testing::InstancePalette(asset, f * kInstances + k), variant);
      bytes.insert(bytes.end(), p.begin(), p.end());
    }
    return bytes;
  };
  Prepared live = runner->Prepare(packed, EmitLaunchKernels(packed, kInstances),
                                  std::vector<std::vector<std::uint8_t>>{palettes(0)}, kInstances, kPaletteSlots);
  runner->WritePalette(live, 0, palettes(0));
  runner->LaunchSet(live, 0);
  (void)runner->ReadOutput(live, 0, Output::kPositions);
  const std::uint64_t before = runner->read_barriers();
  for (int f = 1; f <= kFrames; ++f) {
    runner->WritePalette(live, 0, palettes(f));
    runner->LaunchSet(live, 0);
  }
  EXPECT_EQ(runner->read_barriers(), before) << "a frame issued the barrier for reads";
  const std::span<const std::uint8_t> positions = runner->ReadOutput(live, 0, Output::kPositions);
  EXPECT_EQ(runner->read_barriers(), before + 1) << "the read after the frames issued no barrier";
  const SkinnedMesh quantised = QuantisedMesh(asset.mesh, variant);
  for (int k = 0; k < kInstances; ++k) {
    const GoldResult gold = SkinGold(quantised, testing::InstancePalette(asset, kFrames * kInstances + k), false);
    const GoldComparison c = CompareToGold(gold.positions, testing::UnpackInstance(packed, positions, k));
    EXPECT_EQ(c.non_finite, 0u) << "instance " << k;
    EXPECT_LT(c.max_relative, testing::kTolerance) << "instance " << k << ", worst vertex " << c.worst_vertex;
  }
}

INSTANTIATE_TEST_SUITE_P(Compute, GlslInstanced,
                         ::testing::ValuesIn(testing::WithInstanceCounts(kInstancedComputeCases)),
                         testing::InstanceCaseName);
INSTANTIATE_TEST_SUITE_P(Vertex, GlslInstanced, ::testing::ValuesIn(testing::WithInstanceCounts(kInstancedVertexCases)),
                         testing::InstanceCaseName);

TEST(GlslTemplates, BothTemplatesCompileAloneWithJustTheInstancedDefine) {
  REQUIRE_GL(runner);
  for (const auto& [file, lang] : {std::pair{"skin.comp", Lang::kGlslCompute}, std::pair{"skin.vert", Lang::kGlslVertex}}) {
    KernelSource s = Bare(file, lang);
    s.text.insert(s.text.find('\n') + 1, "#define INSTANCED 1\n");
    s.source_hash = SourceHash(s.text);
    EXPECT_NO_THROW(runner->Build(s)) << file;
  }
}

TEST(GlInstancedRunner, GoldCatchesAVertexShaderThatReadsOnePaletteForEveryInstance) {
  REQUIRE_GL(runner);
  std::vector<KernelSource> kernels;
  const testing::InstancedRun run = testing::WithInstancedFault(
      kVertexKey, 3, "joint[i] += INSTANCE * uint(JOINTS);", "joint[i] += 0u * uint(JOINTS);", kernels);
  const GlRunResult result = runner->Run(run.packed, kernels, run.palette_bytes, 3);
  EXPECT_EQ(result.poisoned_vertices, 0u);
  testing::ExpectOnlyInstanceZeroMatches(run, result);
}

TEST(GlInstancedRunner, PoisonCatchesAComputeKernelThatWritesEveryInstanceOverTheFirst) {
  REQUIRE_GL(runner);
  std::vector<KernelSource> kernels;
  const testing::InstancedRun run =
      testing::WithInstancedFault(kComputeKey, 7, "uint out_first = INSTANCE * vertex_count + first;",
                                  "uint out_first = first + 0u * vertex_count;", kernels);
  EXPECT_EQ(runner->Run(run.packed, kernels, run.palette_bytes, 7).poisoned_vertices, 6 * run.packed.vertex_count);
}

TEST(GlInstancedRunner, RejectsPalettesOfTheWrongCountAndMoreInstancesThanTheUniformBlockHolds) {
  REQUIRE_GL(runner);
  const testing::InstancedRun run = testing::InstancedInputs(ParseVariantKey(kComputeKey), "b2", 7);
  try {
    runner->RunInstanced(run.packed, 6, run.palette_bytes);
    ADD_FAILURE() << "7 palettes were accepted for 6 instances";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("expected 6 instances x 12 joints"), std::string::npos) << e.what();
  }
  const testing::InstancedRun constant =
      testing::InstancedInputs(ParseVariantKey("glsl-vertex.b2.soa.constant.v1c.wg0"), "b2", 7);
  const std::vector<KernelSource> small = EmitLaunchKernels(constant.packed, 3);  // a uniform block for 3 palettes
  try {
    runner->Run(constant.packed, small, constant.palette_bytes, 7);
    ADD_FAILURE() << "7 palettes were bound to a uniform block for 3";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the kernel's constant palette holds 3"), std::string::npos) << e.what();
  }
}

// Timing an instanced frame, compute and vertex (bucketed: staged captures).
TEST(GlInstancedRunner, TimesKInstancesPerFrame) {
  REQUIRE_GL(runner);
  for (const auto& [key, mesh] : {std::pair{"glsl-compute.b2.soa.local.wg64", "b2"},
                                  std::pair{"glsl-vertex.b4.bucketed.soa.global.v1c.wg0", "cesium"}}) {
    const testing::InstancedRun run = testing::InstancedInputs(ParseVariantKey(key), mesh, 5);
    const std::vector<KernelSource> kernels = EmitLaunchKernels(run.packed, 5);
    const std::vector<std::vector<std::uint8_t>> sets = {run.palette_bytes, run.palette_bytes};
    const GlPrepared prepared = runner->Prepare(run.packed, kernels, sets, 5);
    EXPECT_EQ(prepared.input_sets(), 2) << key;
    EXPECT_GE(prepared.bytes_per_set(), 5 * run.packed.vertex_count * run.packed.output_stride_bytes) << key;
    const std::vector<double> ms = runner->Time(prepared, 1, 2);
    EXPECT_EQ(ms.size(), 2u) << key;
  }
}

// ------------------------------------------------------------------ kernel time

// The kernel time's frames (FrameUse::kCold) of an instanced bucketed vertex
// variant: each launch's draw captures its K instances into a staging buffer
// whose copies into place belong to the launch (as Run and Time count them):
// after TimeCold every vertex of every instance has left the poison.
TEST(GlKernelTime, StagedCapturesAreCopiedIntoPlaceInEveryFrame) {
  REQUIRE_GL(runner);
  const testing::InstancedRun run =
      testing::InstancedInputs(ParseVariantKey("glsl-vertex.b4.bucketed.soa.global.v1c.wg0"), "cesium", 5);
  const std::vector<KernelSource> kernels = EmitLaunchKernels(run.packed, 5);
  const std::vector<std::vector<std::uint8_t>> sets = {run.palette_bytes};
  const GlPrepared prepared = runner->Prepare(run.packed, kernels, sets, 5);
  const GlPrepared flush = runner->PrepareFlush(Lang::kGlslVertex, 8u << 20);
  std::vector<std::vector<double>> launch_ms;
  const std::vector<double> ms = runner->TimeCold(prepared, flush, 1, 3, &launch_ms);
  ASSERT_EQ(ms.size(), 3u);
  ASSERT_EQ(launch_ms.size(), 3u);
  for (const std::vector<double>& frame : launch_ms) EXPECT_EQ(frame.size(), run.packed.launches.size());
  const std::span<const std::uint8_t> out = runner->ReadOutput(prepared, 0, Output::kPositions);
  ASSERT_EQ(out.size(), 5 * run.packed.vertex_count * run.packed.output_stride_bytes);
  std::size_t poisoned = 0;
  for (std::size_t at = 0; at + 4 <= out.size(); at += 4) {
    std::uint32_t word = 0;
    std::memcpy(&word, out.data() + at, 4);
    poisoned += word == kPoisonWord;
  }
  EXPECT_EQ(poisoned, 0u);
}

// The flush before every frame, counted by the driver: a
// GL_COMPUTE_SHADER_INVOCATIONS_ARB query (GL 4.6 or
// GL_ARB_pipeline_statistics_query) around TimeCold counts the flush's
// invocations once per frame, untimed frames included, plus the frames'
// own (glsl-compute); a glsl-vertex frame draws with no compute at all, so
// there the count is the flushes' alone.
TEST(GlKernelTime, EveryFrameRunsAfterItsOwnFlushByTheDriversCount) {
  REQUIRE_GL(runner);
  runner->MakeCurrent();
  if (!epoxy_has_gl_extension("GL_ARB_pipeline_statistics_query") && epoxy_gl_version() < 46)
    GTEST_SKIP() << runner->info().renderer << " has no pipeline statistics queries";
  constexpr std::size_t kFlushBytes = 8u << 20;
  const CopyKernel flush_kernel = EmitFlush(Lang::kGlslCompute, kFlushBytes);
  const std::uint64_t flush_invocations = flush_kernel.kernel.launch.GlobalItems(flush_kernel.items);
  for (const char* key : {"glsl-compute.b4.bucketed.soa.global.wg64", "glsl-vertex.b4.bucketed.soa.global.v1c.wg0"}) {
    SCOPED_TRACE(key);
    const Variant variant = ParseVariantKey(key);
    const PackedMesh packed = Pack(Asset("cesium").mesh, variant);
    std::vector<KernelSource> kernels;
    std::uint64_t frame_invocations = 0;
    for (const Launch& launch : packed.launches) {
      kernels.push_back(Emit(variant, launch.influences, static_cast<int>(packed.palette_joints)));
      if (variant.lang == Lang::kGlslCompute) frame_invocations += kernels.back().launch.GlobalItems(launch.count);
    }
    const std::vector<std::vector<std::uint8_t>> sets = {PackPalette(Palette(Asset("cesium")), variant)};
    const GlPrepared prepared = runner->Prepare(packed, kernels, sets);
    const GlPrepared flush = runner->PrepareFlush(variant.lang, kFlushBytes);
    constexpr int kUntimed = 2, kSamples = 3;
    runner->MakeCurrent();
    GLuint query = 0;
    glGenQueries(1, &query);
    glBeginQuery(GL_COMPUTE_SHADER_INVOCATIONS_ARB, query);
    const std::vector<double> ms = runner->TimeCold(prepared, flush, kUntimed, kSamples);
    runner->MakeCurrent();
    glEndQuery(GL_COMPUTE_SHADER_INVOCATIONS_ARB);
    GLuint64 invocations = 0;
    glGetQueryObjectui64v(query, GL_QUERY_RESULT, &invocations);
    glDeleteQueries(1, &query);
    EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
    EXPECT_EQ(ms.size(), static_cast<std::size_t>(kSamples));
    const std::uint64_t expected = (kUntimed + kSamples) * (flush_invocations + frame_invocations);
    if (runner->api().timing_policy().warm_until_stable) {
      // A GPU: TimeCold first warms the device up (frames and the clock
      // probe's copy, runner.cpp WarmUntilStable), all counted too.
      EXPECT_GE(invocations, expected) << "one flush is " << flush_invocations << " invocations";
    } else {
      EXPECT_EQ(invocations, expected)
          << "one flush is " << flush_invocations << " invocations, one frame " << frame_invocations;
    }
  }
}

// ------------------------------------------------------------------ context

TEST(GlContext, ReportsAtLeastGl43AndTheLimitsTheConstraintsUse) {
  REQUIRE_GL(runner);
  const GlContextInfo& i = runner->info();
  std::cout << "[ GL       ] limits: compute invocations " << i.max_compute_work_group_invocations
            << ", size x " << i.max_compute_work_group_size_x << ", count x " << i.max_compute_work_group_count_x
            << ", shared " << i.max_compute_shared_memory_bytes << " B, uniform block " << i.max_uniform_block_bytes
            << " B, texture buffer " << i.max_texture_buffer_texels << " texels, vertex storage blocks "
            << i.max_vertex_shader_storage_blocks << "\n";
  EXPECT_TRUE(i.major > 4 || (i.major == 4 && i.minor >= 3)) << i.version;
  EXPECT_FALSE(i.renderer.empty());
  // GL 4.3's minimum maxima.
  EXPECT_GE(i.max_compute_work_group_invocations, 1024u);
  EXPECT_GE(i.max_compute_shared_memory_bytes, 32768u);
  EXPECT_GE(i.max_uniform_block_bytes, 16384u);
  EXPECT_GE(i.max_texture_buffer_texels, 65536u);
  EXPECT_GE(i.max_compute_work_group_count_x, 65535u);
  EXPECT_GE(i.max_compute_work_group_count_y, 65535u);
  const DeviceLimits limits = LimitsOf(i);
  EXPECT_EQ(limits.uniform_block_bytes, i.max_uniform_block_bytes);
  EXPECT_EQ(limits.local_memory_bytes, i.max_compute_shared_memory_bytes);
  EXPECT_EQ(limits.image_buffer_max_texels, i.max_texture_buffer_texels);
  EXPECT_EQ(limits.vertex_shader_storage_blocks, i.max_vertex_shader_storage_blocks > 0);
  EXPECT_EQ(limits.max_grid_y, i.max_compute_work_group_count_y);
  EXPECT_EQ(limits.max_wg_size, std::min(i.max_compute_work_group_invocations, i.max_compute_work_group_size_x));
}

TEST(GlContext, AMissingDeviceGivesAReasonInsteadOfAContext) {
  std::string why;
  GlRunner* runner = Runner(why);
  GlContext missing(1000);  // never crashes, whatever the machine has
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.reason().find("no OpenGL"), std::string::npos) << missing.reason();
  try {
    GlRunner no_runner(1000);
    ADD_FAILURE() << "EGL device 1000 exists";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("GL setup"), std::string::npos) << e.what();
  }
  if (runner) {  // the shared runner still works: it makes its context current again
    const PackedMesh packed = Pack(Asset("b2").mesh, ParseVariantKey(kComputeKey));
    const std::vector<glm::mat4> palette = Palette(Asset("b2"));
    ExpectMatchesGold(packed, runner->Run(packed, PackPalette(palette, packed.variant)), Asset("b2").mesh, palette,
                      LaunchTimes::kNonNegative);
  }
}

}  // namespace
}  // namespace skintune::internal
