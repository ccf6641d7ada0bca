#include <gtest/gtest.h>

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "generator/emit.h"
#include "generator/packer.h"
#include "base/error.h"

namespace skintune::internal {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

std::vector<std::string> ArgumentNames(const nlohmann::json& sidecar) {
  std::vector<std::string> names;
  for (const auto& a : sidecar.at("arguments")) names.push_back(a.at("name"));
  return names;
}

long long DefineOf(const KernelSource& s, const std::string& name) {
  for (const auto& [n, value] : s.defines)
    if (n == name) return value;
  return -1;
}

// Builds `text` for the first OpenCL device; "" on a clean build, else the reason (or the warnings).
// Sets `skipped` when there is no device.
std::string BuildOnFirstDevice(const std::string& text, bool& skipped) {
  skipped = false;
  cl_uint platforms = 0;
  if (clGetPlatformIDs(0, nullptr, &platforms) != CL_SUCCESS || platforms == 0) {
    skipped = true;
    return "no OpenCL platform";
  }
  std::vector<cl_platform_id> ids(platforms);
  clGetPlatformIDs(platforms, ids.data(), nullptr);
  for (cl_platform_id platform : ids) {
    cl_device_id device = nullptr;
    if (clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, 1, &device, nullptr) != CL_SUCCESS) continue;
    cl_int err = CL_SUCCESS;
    cl_context context = clCreateContext(nullptr, 1, &device, nullptr, nullptr, &err);
    if (err != CL_SUCCESS) return "clCreateContext failed: " + std::to_string(err);
    const char* source = text.c_str();
    const std::size_t length = text.size();
    cl_program program = clCreateProgramWithSource(context, 1, &source, &length, &err);
    std::string result;
    const cl_int built = clBuildProgram(program, 1, &device, "-cl-std=CL1.2", nullptr, nullptr);
    std::size_t size = 0;
    clGetProgramBuildInfo(program, device, CL_PROGRAM_BUILD_LOG, 0, nullptr, &size);
    std::string log(size, '\0');
    clGetProgramBuildInfo(program, device, CL_PROGRAM_BUILD_LOG, size, log.data(), nullptr);
    if (built != CL_SUCCESS) {
      result = "build failed: " + log;
    } else if (log.find("warning") != std::string::npos) {
      result = "built with warnings: " + log;  // our kernels build cleanly
    } else {
      cl_kernel kernel = clCreateKernel(program, "skin", &err);
      if (err != CL_SUCCESS) result = "no kernel 'skin': " + std::to_string(err);
      else clReleaseKernel(kernel);
    }
    clReleaseProgram(program);
    clReleaseContext(context);
    return result;
  }
  skipped = true;
  return "no OpenCL device";
}

TEST(EmitTemplate, EmbeddedTemplateIsTheFileInTheSourceTree) {
  std::ifstream in(std::string(SKINTUNE_SOURCE_DIR) + "/templates/skin.cl", std::ios::binary);
  ASSERT_TRUE(in) << "templates/skin.cl not found";
  std::stringstream file;
  file << in.rdbuf();
  EXPECT_EQ(TemplateText("skin.cl"), file.str());
  EXPECT_NE(ErrorOf([] { TemplateText("nope.cl"); }).find("skin.cl"), std::string::npos);
}

TEST(EmitTemplate, TemplateCompilesAloneWithNoDefines) {
  bool skipped = false;
  const std::string result = BuildOnFirstDevice(ExpandedTemplate("skin.cl"), skipped);
  if (skipped) GTEST_SKIP() << result;
  EXPECT_EQ(result, "");
}

TEST(EmitTemplate, EmittedKernelsOfEveryLayoutAndStorageCompile) {
  std::string text;
  for (const char* key : {"opencl.aos.float3.u8.unorm8.b3.normals.constant", "opencl.soa.local.point.v4s",
                          "opencl.soa-split.image.mat4.i32.unorm16.v8c.wg32.normals"}) {
    bool skipped = false;
    const std::string result = BuildOnFirstDevice(Emit(ParseVariantKey(key), 0, 77).text, skipped);
    if (skipped) GTEST_SKIP() << result;
    EXPECT_EQ(result, "") << key;
  }
}

// The preludes an emitted kernel includes keep their names and lines (#line),
// so a build log points at the prelude's own line.
TEST(EmitTemplate, BuildLogsNameThePreludeAndLineOfAnError) {
  const std::string line = "#define PALETTE_FLOAT4S (JOINTS * PALETTE_ROWS)";
  const std::string params = TemplateText("skin_params.h");
  ASSERT_NE(params.find(line), std::string::npos) << "update the test: skin_params.h changed";
  const auto number = std::count(params.begin(), params.begin() + static_cast<long>(params.find(line)), '\n') + 1;
  std::string text = Emit(ParseVariantKey("opencl.b2"), 0, 20).text;
  text.replace(text.find(line), line.size(), "#error skintune injected fault");
  bool skipped = false;
  const std::string result = BuildOnFirstDevice(text, skipped);
  if (skipped) GTEST_SKIP() << result;
  EXPECT_NE(result.find("skin_params.h:" + std::to_string(number) + ":"), std::string::npos) << result;
}

TEST(Emit, SidecarListsArgumentsInTheDocumentedOrderForEachLayout) {
  using Names = std::vector<std::string>;
  const auto names = [](const char* key) {
    const Variant v = ParseVariantKey(key);
    return ArgumentNames(SidecarJson(Emit(v, 0, 77), v));
  };
  EXPECT_EQ(names("opencl.aos"), (Names{"n", "first", "records", "palette", "out_positions"}));
  EXPECT_EQ(names("opencl.aos.normals"), (Names{"n", "first", "records", "palette", "out_positions", "out_normals"}));
  for (const char* key : {"opencl.soa", "opencl.soa-split"}) {
    EXPECT_EQ(names(key), (Names{"n", "first", "positions", "indices", "weights", "palette", "out_positions"})) << key;
  }
  for (const char* key : {"opencl.soa.normals", "opencl.soa-split.normals"}) {
    EXPECT_EQ(names(key), (Names{"n", "first", "positions", "indices", "weights", "normals", "palette",
                                 "out_positions", "out_normals"}))
        << key;
  }
}

TEST(Emit, SidecarDescribesFormatsStridesAndKinds) {
  const Variant v = ParseVariantKey("opencl.b3.soa-split.float3.u8.unorm16.mat4.image.v2s.wg64");
  const KernelSource s = Emit(v, 0, 20);
  const nlohmann::json j = SidecarJson(s, v);
  EXPECT_EQ(j.at("generator_version"), kGeneratorVersion);
  EXPECT_EQ(j.at("source_hash"), s.source_hash);
  EXPECT_EQ(j.at("entry_point"), "skin");
  EXPECT_EQ(j.at("variant"), v.Key());
  const auto& args = j.at("arguments");
  EXPECT_EQ(args[0].at("kind"), "scalar");
  EXPECT_EQ(args[0].at("format"), "u32");
  EXPECT_EQ(args[2].at("format"), "float3");
  EXPECT_EQ(args[2].at("stride_bytes"), 12);
  EXPECT_EQ(args[3].at("format"), "u8");
  EXPECT_EQ(args[3].at("indexing"), "i*S+v");
  EXPECT_EQ(args[4].at("format"), "unorm16");
  EXPECT_EQ(args[5].at("name"), "palette");
  EXPECT_EQ(args[5].at("kind"), "image");
  EXPECT_EQ(args[5].at("stride_bytes"), 64);
  EXPECT_EQ(args[6].at("direction"), "out");
  EXPECT_EQ(args[6].at("indexing"), "first+v");
  EXPECT_EQ(j.at("launch").at("assignment"), "strided");
  EXPECT_EQ(j.at("launch").at("wg_size"), 64);
  EXPECT_EQ(DefineOf(s, "SLOT_STRIDE_MULTIPLE"), static_cast<long long>(SoaSplitSlotStride(1, v)));
  EXPECT_EQ(s.launch.GlobalItems(1000), 512u);  // ceil(1000 / 2) = 500 -> 512
  EXPECT_EQ(s.launch.GlobalItems(0), 0u);

  const Variant soa = ParseVariantKey("opencl.b4.soa.u16.f32");
  const nlohmann::json js = SidecarJson(Emit(soa), soa);
  EXPECT_EQ(js.at("arguments")[3].at("stride_bytes"), 8);  // 4 x u16 per vertex
  EXPECT_EQ(js.at("arguments")[3].at("indexing"), "v*B+i");
}

TEST(Emit, AosOffsetsAreThePackersRecordLayout) {
  for (const char* key : {"opencl.aos.b3.float3.u8.f32.normals", "opencl.aos.b4.float4.u16.unorm8",
                          "opencl.aos.b1.float3.u8.unorm8", "opencl.aos.b7.float4.i32.unorm16.normals"}) {
    const Variant v = ParseVariantKey(key);
    const KernelSource s = Emit(v);
    const RecordLayout r = AosRecordLayout(v, v.influences);
    EXPECT_EQ(DefineOf(s, "AOS_INDICES_OFFSET"), static_cast<long long>(r.indices)) << key;
    EXPECT_EQ(DefineOf(s, "AOS_WEIGHTS_OFFSET"), static_cast<long long>(r.weights)) << key;
    EXPECT_EQ(DefineOf(s, "AOS_RECORD_WORDS") * 4, static_cast<long long>(r.size)) << key;
    if (SkinsNormals(v)) {
      EXPECT_EQ(DefineOf(s, "AOS_NORMAL_OFFSET"), static_cast<long long>(r.normal)) << key;
    }
    if (SkinsTangents(v)) {
      EXPECT_EQ(DefineOf(s, "AOS_TANGENT_OFFSET"), static_cast<long long>(r.tangent)) << key;
    }
    EXPECT_EQ(SidecarJson(s, v).at("aos_record").at("size"), r.size) << key;
  }
}

TEST(Emit, SourceHashFollowsTheTextAndChangesWithAnyDefine) {
  const Variant v = ParseVariantKey("opencl.b4.soa.wg128");
  const KernelSource a = Emit(v);
  EXPECT_EQ(a.source_hash, Emit(v).source_hash);
  EXPECT_EQ(a.source_hash, SourceHash(a.text));
  EXPECT_EQ(a.source_hash.size(), 16u);
  EXPECT_EQ(SourceHash(""), "cbf29ce484222325");  // FNV-1a 64 offset basis
  EXPECT_EQ(SourceHash("a"), "af63dc4c8601ec8c");
  Variant w = v;
  w.wg_size = 256;
  EXPECT_NE(Emit(w).source_hash, a.source_hash);
  EXPECT_NE(Emit(v, 2).source_hash, a.source_hash);
  EXPECT_NE(Emit(v, 0, 77).source_hash, a.source_hash);
  EXPECT_NE(a.text.find("#define WG_SIZE 128\n"), std::string::npos);
  EXPECT_NE(Emit(w).text.find("#define WG_SIZE 256\n"), std::string::npos);
}

TEST(Emit, InfluencesOverrideSpecialisesOneBucket) {
  const Variant v = ParseVariantKey("opencl.b4.bucketed");
  const KernelSource s = Emit(v, 2);
  EXPECT_EQ(s.influences, 2);
  EXPECT_EQ(DefineOf(s, "INFLUENCES"), 2);
  EXPECT_EQ(SidecarJson(s, v).at("influences"), 2);
}

TEST(Emit, EveryLanguageEmitsFromItsOwnTemplateWithTheSameParameters) {
  const std::pair<const char*, const char*> languages[] = {
      {"opencl", "skin.cl"}, {"cuda", "skin.cu"}, {"glsl-compute", "skin.comp"}, {"glsl-vertex", "skin.vert"}};
  const KernelSource reference = Emit(ParseVariantKey("opencl.b3.u8.unorm8.constant"), 0, 77);
  for (const auto& [lang, file] : languages) {
    const KernelSource k = Emit(ParseVariantKey(std::string(lang) + ".b3.u8.unorm8.constant"), 0, 77);
    EXPECT_FALSE(TemplateText(file).empty()) << file;
    // GLSL's BINDING_* are its interface (each buffer's binding), not parameters.
    const auto parameters = std::count_if(k.defines.begin(), k.defines.end(),
                                          [](const auto& d) { return !d.first.starts_with("BINDING_"); });
    EXPECT_EQ(static_cast<std::size_t>(parameters), reference.defines.size()) << lang;
    for (const auto& [name, value] : reference.defines) {
      if (name != "WG_SIZE" && name != "VERTICES_PER_ITEM") {
        EXPECT_EQ(DefineOf(k, name), value) << lang << " " << name;
      }
    }
    const bool glsl = std::string(lang).rfind("glsl", 0) == 0;
    if (glsl) {
      EXPECT_EQ(k.text.rfind("#version", 0), 0u) << lang << ": #version must stay the first line";
      EXPECT_EQ(k.entry_point, "main");
    } else {
      EXPECT_EQ(k.entry_point, "skin");
    }
  }
}

TEST(Emit, LocalStorageNeedsTheJointCount) {
  EXPECT_NE(ErrorOf([] { Emit(ParseVariantKey("opencl.local")); }).find("storage local needs the joint count"),
            std::string::npos);
  EXPECT_EQ(DefineOf(Emit(ParseVariantKey("opencl.local"), 0, 40), "JOINTS"), 40);
  EXPECT_NE(ErrorOf([] { Emit(ParseVariantKey("cuda.constant")); }).find("sizes the __constant__ palette symbol"),
            std::string::npos);
  const nlohmann::json sidecar = SidecarJson(Emit(ParseVariantKey("cuda.constant"), 0, 40), ParseVariantKey("cuda.constant"));
  for (const auto& a : sidecar.at("arguments"))
    if (a.at("name") == "palette") {
      EXPECT_EQ(a.at("symbol"), "skintune_palette");
    }
}

// ---------------------------------------------------------------- instancing

EmitOptions Instanced(int max_instances = 0) { return EmitOptions{true, max_instances}; }

TEST(EmitInstanced, AddsTheInstancedDefineAndNothingWhenNotInstanced) {
  const Variant v = ParseVariantKey("opencl.b4.soa.global");
  const KernelSource plain = Emit(v, 0, 77);
  const KernelSource instanced = Emit(v, 0, 77, Instanced());
  EXPECT_EQ(DefineOf(plain, "INSTANCED"), -1);
  EXPECT_EQ(plain.text.find("#define INSTANCED 1"), std::string::npos);
  EXPECT_FALSE(plain.instanced);
  EXPECT_EQ(SidecarJson(plain, v).count("instancing"), 0u);
  EXPECT_EQ(DefineOf(instanced, "INSTANCED"), 1);
  EXPECT_TRUE(instanced.instanced);
  EXPECT_TRUE(instanced.launch.instanced);
  EXPECT_NE(instanced.source_hash, plain.source_hash);
  // Every parameter define of the plain kernel, with the same value.
  for (const auto& [name, value] : plain.defines) EXPECT_EQ(DefineOf(instanced, name), value) << name;
  EXPECT_EQ(instanced.defines.size(), plain.defines.size() + 1);
  EXPECT_NE(instanced.launch.rule.find("get_global_id(1)"), std::string::npos) << instanced.launch.rule;
}

TEST(EmitInstanced, VertexCountFollowsFirstExceptInTheVertexShader) {
  using Names = std::vector<std::string>;
  const auto names = [](const char* key) {
    const Variant v = ParseVariantKey(key);
    return ArgumentNames(SidecarJson(Emit(v, 0, 77, Instanced(4)), v));
  };
  for (const char* key : {"opencl.aos", "cuda.aos", "glsl-compute.aos"}) {
    EXPECT_EQ(names(key), (Names{"n", "first", "vertex_count", "records", "palette", "out_positions"})) << key;
  }
  EXPECT_EQ(names("opencl.soa.normals"), (Names{"n", "first", "vertex_count", "positions", "indices", "weights",
                                                "normals", "palette", "out_positions", "out_normals"}));
  // The vertex shader's capture places the instances: no vertex_count.
  EXPECT_EQ(names("glsl-vertex.aos.v1c.wg0"), (Names{"n", "first", "records", "palette", "out_positions"}));
}

TEST(EmitInstanced, SidecarSaysWhereEachInstanceReadsAndWrites) {
  const Variant v = ParseVariantKey("opencl.b2.soa.image.normals");
  const nlohmann::json j = SidecarJson(Emit(v, 0, 30, Instanced()), v);
  const auto& args = j.at("arguments");
  EXPECT_EQ(args[2].at("name"), "vertex_count");
  EXPECT_EQ(args[2].at("kind"), "scalar");
  EXPECT_EQ(args[2].at("format"), "u32");
  for (const auto& a : args) {
    if (a.at("name") == "palette") {
      EXPECT_EQ(a.at("indexing"), "(i*J+j)*R+r");
    }
    if (a.at("direction") == "out") {
      EXPECT_EQ(a.at("indexing"), "i*vertex_count+first+v") << a.at("name");
    }
  }
  const auto& inst = j.at("instancing");
  EXPECT_EQ(inst.at("instance"), "get_global_id(1)");
  EXPECT_NE(inst.at("palette").get<std::string>().find("(i*30+j)*R+r"), std::string::npos) << inst;
  EXPECT_EQ(inst.at("max_instances"), 0);

  const Variant vertex = ParseVariantKey("glsl-vertex.b2.soa.image.v1c.wg0.normals");
  const nlohmann::json jv = SidecarJson(Emit(vertex, 0, 30, Instanced()), vertex);
  EXPECT_EQ(jv.at("instancing").at("instance"), "gl_InstanceID");
  for (const auto& a : jv.at("arguments"))
    if (a.at("direction") == "out") {
      EXPECT_EQ(a.at("indexing"), "i*n+v") << a.at("name");
    }
  EXPECT_EQ(SidecarJson(Emit(ParseVariantKey("cuda.b2"), 0, 30, Instanced()), ParseVariantKey("cuda.b2"))
                .at("instancing").at("instance"),
            "blockIdx.y");
}

// Contract item 3: the image's width in texels wherever the joint count is
// known: one palette's rows, and for an instanced kernel per instance and
// for the K it was emitted for.
TEST(EmitInstanced, ImageSidecarGivesTheWidthInTexelsPerInstanceAndForItsK) {
  const Variant v = ParseVariantKey("opencl.b2.soa.mat3x4.image");
  auto image_of = [&v](const KernelSource& source) {
    const nlohmann::json sidecar = SidecarJson(source, v);
    for (const auto& a : sidecar.at("arguments"))
      if (a.at("name") == "palette") return a.at("image");
    return nlohmann::json();
  };
  EXPECT_EQ(image_of(Emit(v, 0, 77)).at("width_texels"), 231);
  const nlohmann::json instanced = image_of(Emit(v, 0, 77, Instanced(4)));
  EXPECT_EQ(instanced.at("width_texels_per_instance"), 231) << instanced;
  EXPECT_EQ(instanced.at("instances"), 4) << instanced;
  EXPECT_EQ(instanced.at("width_texels"), 924) << instanced;
  EXPECT_EQ(instanced.at("read"), "read_imagef(palette, (i*J + j)*R + r)");
  // Emitted for no particular K: the width per instance only.
  const nlohmann::json any = image_of(Emit(v, 0, 77, Instanced()));
  EXPECT_EQ(any.at("width_texels_per_instance"), 231) << any;
  EXPECT_FALSE(any.contains("width_texels")) << any;
}

TEST(EmitInstanced, NeedsTheJointCount) {
  EXPECT_NE(ErrorOf([] { Emit(ParseVariantKey("opencl.global"), 0, 0, Instanced()); })
                .find("an instanced kernel needs the joint count"),
            std::string::npos);
}

TEST(EmitInstanced, ConstantStorageInCudaAndGlslIsSizedForMaxInstances) {
  for (const char* key : {"cuda.constant", "glsl-compute.constant", "glsl-vertex.constant.v1c.wg0"}) {
    const Variant v = ParseVariantKey(key);
    EXPECT_NE(ErrorOf([&] { Emit(v, 0, 77, Instanced()); }).find("needs max_instances >= 1"), std::string::npos)
        << key;
    const KernelSource s = Emit(v, 0, 77, Instanced(9));
    EXPECT_EQ(DefineOf(s, "PALETTE_INSTANCES"), 9) << key;
    EXPECT_EQ(s.max_instances, 9) << key;
    EXPECT_EQ(SidecarJson(s, v).at("instancing").at("max_instances"), 9) << key;
    EXPECT_TRUE(InstancesBoundAtCompileTime(v)) << key;
  }
  // OpenCL's __constant pointer and every other storage take any K: no define, max_instances 0.
  for (const char* key : {"opencl.constant", "cuda.global", "cuda.local", "glsl-compute.image"}) {
    const Variant v = ParseVariantKey(key);
    const KernelSource s = Emit(v, 0, 77, Instanced(9));
    EXPECT_EQ(DefineOf(s, "PALETTE_INSTANCES"), -1) << key;
    EXPECT_EQ(s.max_instances, 0) << key;
    EXPECT_FALSE(InstancesBoundAtCompileTime(v)) << key;
  }
}

TEST(EmitInstanced, TemplateCompilesAloneWithJustTheInstancedDefine) {
  bool skipped = false;
  const std::string result = BuildOnFirstDevice("#define INSTANCED 1\n" + ExpandedTemplate("skin.cl"), skipped);
  if (skipped) GTEST_SKIP() << result;
  EXPECT_EQ(result, "");
}

TEST(EmitInstanced, KernelsOfEveryLayoutAndStorageCompileCleanly) {
  for (const char* key : {"opencl.aos.float3.u8.unorm8.b3.normals.constant", "opencl.soa.local.point.v4s",
                          "opencl.soa-split.image.mat4.i32.unorm16.v8c.wg32.normals", "opencl.aos.global.v2s"}) {
    bool skipped = false;
    const std::string result = BuildOnFirstDevice(Emit(ParseVariantKey(key), 0, 77, Instanced()).text, skipped);
    if (skipped) GTEST_SKIP() << result;
    EXPECT_EQ(result, "") << key;
  }
}

TEST(Emit, InfluencesOutsideTheRangeThrow) {
  EXPECT_NE(ErrorOf([] { Emit(ParseVariantKey("opencl.b4"), 9); }).find("influences 9 outside 1..8"),
            std::string::npos);
}

}  // namespace
}  // namespace skintune::internal
