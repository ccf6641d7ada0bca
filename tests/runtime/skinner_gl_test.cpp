// The public API on GL (Mesa's llvmpipe through EGL here): a GL Device with a
// headless context of its own, Device::FromCurrentGl on the caller's
// context, compute and vertex-shader variants against the gold, K
// instances, the program binary cache, and the misuse a GL context allows
// (not current, gone). Every test skips with the reason where no GL 4.3
// context can be made.
#include <epoxy/gl.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <thread>
#include <vector>

#include "model/gltf_import.h"
#include "model/synthetic.h"
#include "runtime/backends/gl/gl_context.h"
#include "skintune/skintune.h"
#include "tests/runtime/api_test_support.h"

namespace skintune::internal {
namespace {

using testing::CacheIn;
using testing::ExpectInstancesLikeTheGold;
using testing::ExpectSkinsLikeTheGold;
using testing::Floats;
using testing::Poses;
using testing::TempDir;
using testing::View;

constexpr Backend kGl = Backend::kGl;

const SkinnedAsset& Cesium() {
  static const SkinnedAsset asset = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
  return asset;
}

const SkinnedAsset& Small() {
  static const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("500-b3-random-seed6-normals"));
  return asset;
}

std::vector<glm::mat4> Pose(const SkinnedAsset& asset, double fraction) {
  const AnimationClip& clip = asset.animations.front();
  return asset.PaletteAt(0, clip.start + fraction * (clip.end - clip.start));
}

#define CONTEXT_OR_SKIP(context)                            \
  GlContext context;                                        \
  if (!context.ok()) GTEST_SKIP() << context.reason()

Skinner MustCreate(Device& device, const MeshView& mesh, const SkinnerOptions& options = {}) {
  Result<Skinner> skinner = Skinner::Create(device, WinnersDb::Empty(), mesh, options);
  EXPECT_TRUE(skinner.ok()) << skinner.status().message();
  return skinner.ok() ? std::move(*skinner) : Skinner();
}

TEST(GlSkinner, AGlDeviceOfItsOwnSkinsWithComputeAndVertexShaders) {
  TempDir dir;
  Result<Device> device = Device::Open("", &kGl, CacheIn(dir));
  if (!device.ok()) GTEST_SKIP() << "no GL device: " << device.status().message();
  EXPECT_EQ(device->info().backend, Backend::kGl);
  EXPECT_EQ(device->info().id, "gl:" + device->info().platform + "/" + device->info().name + "/" +
                                   device->info().driver_version);
  const View view(Cesium().mesh);
  for (const std::string& key : {std::string(), std::string("glsl-vertex.b4.padded.aos.float3.u8.unorm8.mat3x4.constant"),
                                 std::string("glsl-vertex.b4.soa.image.mat4"),
                                 std::string("glsl-compute.b4.soa-split.u16.unorm16.local.point.v2s.wg128")}) {
    SCOPED_TRACE(key.empty() ? "built-in default" : key);
    SkinnerOptions options;
    options.variant = key;
    options.normals = true;
    Skinner skinner = MustCreate(*device, view.mesh, options);
    if (key.empty()) {
      EXPECT_EQ(skinner.selection().variant.rfind("glsl-compute.", 0), 0u);
    }
    ExpectSkinsLikeTheGold(skinner, Cesium().mesh, Pose(Cesium(), 0.3));
  }
}

TEST(GlSkinner, SkinsKInstancesWithComputeAndVertexShaders) {
  TempDir dir;
  Result<Device> device = Device::Open("", &kGl, CacheIn(dir));
  if (!device.ok()) GTEST_SKIP() << "no GL device: " << device.status().message();
  const View view(Small().mesh);
  for (int k : {1, 7, 64}) {
    for (const std::string& key : {std::string(), std::string("glsl-vertex.b3.soa.mat3x4.global")}) {
      SCOPED_TRACE(std::to_string(k) + " instances of " + key);
      SkinnerOptions options;
      options.instances = k;
      options.variant = key;
      Skinner skinner = MustCreate(*device, view.mesh, options);
      ExpectInstancesLikeTheGold(skinner, Small().mesh, Poses(Small(), k));
    }
  }
}

// A read-back of many host grains (runtime/skinner.cpp: GL copies it back in
// chunks, each with a fence the reading thread waits for, and the host pool
// scans and copies each chunk in 16k-vertex grains): float3 and
// float4 outputs match the gold across the grains, read in one pass; a
// palette that overflows only in the last vertices is an error that leaves
// the caller's array as it was (the scan first, then the copy).
TEST(GlSkinner, ALargeReadBackIsTheGoldAndAnOverflowInTheLastVerticesWritesNothing) {
  TempDir dir;
  Result<Device> device = Device::Open("", &kGl, CacheIn(dir));
  if (!device.ok()) GTEST_SKIP() << "no GL device: " << device.status().message();
  static const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("150001-b2-seed7"));
  const View view(asset.mesh);
  for (const char* key : {"glsl-compute.b2.padded.soa.float3.u16.f32.mat3x4.global.matrix.v1c.wg128",
                          "glsl-compute.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128"}) {
    SCOPED_TRACE(key);
    SkinnerOptions options;
    options.variant = key;
    Skinner skinner = MustCreate(*device, view.mesh, options);
    ExpectSkinsLikeTheGold(skinner, asset.mesh, Pose(asset, 0.3));
    ExpectSkinsLikeTheGold(skinner, asset.mesh, Pose(asset, 0.7));
    testing::ExpectOverflowWritesNothing(skinner, testing::OverflowingLastVertex(asset.mesh, Pose(asset, 0.3)));
  }
}

TEST(GlSkinner, FromCurrentGlSkinsIntoABufferOfTheCallersContextAndKeepsItsState) {
  CONTEXT_OR_SKIP(context);
  TempDir dir;
  Result<Device> device = Device::FromCurrentGl(CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  EXPECT_EQ(device->info().platform, "current");
  EXPECT_EQ(device->info().name, context.info().renderer);
  const View view(Small().mesh);
  SkinnerOptions options;
  options.normals = true;
  Skinner skinner = MustCreate(*device, view.mesh, options);

  // The caller's bindings survive a Skin(): a dispatch puts back the program
  // and texture unit it changes, a vertex draw also the vertex array and
  // rasteriser discard (the state each path touches).
  GLuint vertex_array = 0;
  glGenVertexArrays(1, &vertex_array);
  for (const std::string& key : {std::string(), std::string("glsl-compute.b4.soa.image.mat4"),
                                 std::string("glsl-vertex.b4.soa.image.mat4")}) {
    SCOPED_TRACE(key.empty() ? "built-in default" : key);
    SkinnerOptions keyed = options;
    keyed.variant = key;
    Skinner other = MustCreate(*device, view.mesh, keyed);
    glBindVertexArray(vertex_array);
    glActiveTexture(GL_TEXTURE3);
    glEnable(GL_RASTERIZER_DISCARD);
    ExpectSkinsLikeTheGold(other, Small().mesh, Pose(Small(), 0.6));
    GLint bound = 0, unit = 0;
    glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &bound);
    EXPECT_EQ(static_cast<GLuint>(bound), vertex_array);
    glGetIntegerv(GL_ACTIVE_TEXTURE, &unit);
    EXPECT_EQ(unit, GL_TEXTURE3);
    EXPECT_TRUE(glIsEnabled(GL_RASTERIZER_DISCARD));
    glDisable(GL_RASTERIZER_DISCARD);
    glActiveTexture(GL_TEXTURE0);
    glBindVertexArray(0);
  }
  glDeleteVertexArrays(1, &vertex_array);
  ExpectSkinsLikeTheGold(skinner, Small().mesh, Pose(Small(), 0.6));

  // The output is a buffer object of this context, in the mesh's order.
  const auto buffer = static_cast<GLuint>(reinterpret_cast<std::uintptr_t>(skinner.device_positions()));
  ASSERT_TRUE(glIsBuffer(buffer));
  const std::size_t n = skinner.vertex_count();
  std::vector<float> on_device(n * skinner.output_stride_bytes() / 4);
  glBindBuffer(GL_COPY_READ_BUFFER, buffer);
  glGetBufferSubData(GL_COPY_READ_BUFFER, 0, static_cast<GLsizeiptr>(on_device.size() * 4), on_device.data());
  glBindBuffer(GL_COPY_READ_BUFFER, 0);
  std::vector<float> read(n * 3);
  ASSERT_TRUE(skinner.ReadPositions(read.data(), read.size()).ok());
  const std::size_t stride = skinner.output_stride_bytes() / 4;
  for (std::size_t v = 0; v < n; v += 37)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(on_device[v * stride + c], read[v * 3 + c]) << "vertex " << v;
}

TEST(GlProgramCache, SecondDeviceOnTheSameContextCompilesNothing) {
  CONTEXT_OR_SKIP(context);
  GLint formats = 0;
  glGetIntegerv(GL_NUM_PROGRAM_BINARY_FORMATS, &formats);
  if (formats <= 0) GTEST_SKIP() << context.info().renderer << " offers no program binary format";
  TempDir dir;
  const View view(Small().mesh);
  for (const std::string& key : {std::string(), std::string("glsl-vertex.b3")}) {
    SCOPED_TRACE(key.empty() ? "built-in default" : key);
    SkinnerOptions options;
    options.variant = key;
    {
      Result<Device> first = Device::FromCurrentGl(CacheIn(dir));
      ASSERT_TRUE(first.ok()) << first.status().message();
      MustCreate(*first, view.mesh, options);
      EXPECT_EQ(first->cache_stats().builds, 1);
    }
    Result<Device> second = Device::FromCurrentGl(CacheIn(dir));
    ASSERT_TRUE(second.ok()) << second.status().message();
    Skinner skinner = MustCreate(*second, view.mesh, options);
    EXPECT_EQ(second->cache_stats().builds, 0);
    EXPECT_EQ(second->cache_stats().disk_hits, 1);
    ExpectSkinsLikeTheGold(skinner, Small().mesh, Pose(Small(), 0.2));
  }
}

// ---------------------------------------------------------------- OpenCL-GL interop

// Skins 3 instances straight into a GL buffer of the current context with
// `device` (OpenCL-GL sharing or CUDA-GL interop), reads the buffer back
// through GL and checks every instance against its gold; a buffer too small
// for the positions is kInvalidArgument.
void ExpectSkinsIntoGlBuffers(Device& device) {
  const View view(Small().mesh);
  SkinnerOptions options;
  options.instances = 3;
  Skinner skinner = MustCreate(device, view.mesh, options);
  const std::vector<std::vector<glm::mat4>> poses = Poses(Small(), 3);
  std::vector<float> palettes;
  for (const auto& pose : poses) {
    const std::vector<float> f = Floats(pose);
    palettes.insert(palettes.end(), f.begin(), f.end());
  }
  ASSERT_TRUE(skinner.SetPalette(palettes.data(), palettes.size()).ok());
  const std::size_t n = skinner.vertex_count();
  const std::size_t bytes = 3 * n * skinner.output_stride_bytes();
  GLuint buffers[2] = {0, 0};
  glGenBuffers(2, buffers);
  const std::vector<float> poison(bytes / 4, -12345.0f);  // what the skinning must overwrite
  glBindBuffer(GL_ARRAY_BUFFER, buffers[0]);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(bytes), poison.data(), GL_DYNAMIC_DRAW);
  glBindBuffer(GL_ARRAY_BUFFER, buffers[1]);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(bytes / 2), nullptr, GL_DYNAMIC_DRAW);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  const Status written = skinner.SkinIntoGlBuffer(buffers[0]);
  ASSERT_TRUE(written.ok()) << written.message();
  std::vector<float> on_gl(bytes / 4);
  glBindBuffer(GL_COPY_READ_BUFFER, buffers[0]);
  glGetBufferSubData(GL_COPY_READ_BUFFER, 0, static_cast<GLsizeiptr>(bytes), on_gl.data());
  glBindBuffer(GL_COPY_READ_BUFFER, 0);
  const std::size_t stride = skinner.output_stride_bytes() / 4;
  const Variant variant = ParseVariantKey(skinner.selection().variant);
  for (std::size_t k = 0; k < 3; ++k) {
    const GoldResult gold = SkinGold(QuantisedMesh(Small().mesh, variant), poses[k]);
    std::vector<glm::vec3> part(n);
    for (std::size_t v = 0; v < n; ++v) {
      const float* at = &on_gl[(k * n + v) * stride];
      part[v] = {at[0], at[1], at[2]};
    }
    const GoldComparison c = CompareToGold(gold.positions, part);
    EXPECT_EQ(c.non_finite, 0u) << "instance " << k;
    EXPECT_LT(c.max_relative, 1e-5) << "instance " << k << ", worst vertex " << c.worst_vertex;
  }
  const Status small = skinner.SkinIntoGlBuffer(buffers[1]);
  EXPECT_EQ(small.code(), ErrorCode::kInvalidArgument) << small.message();
  glDeleteBuffers(2, buffers);
}

TEST(OpenClGlInterop, SkinsStraightIntoAGlBufferWhereAPlatformSharesOne) {
  CONTEXT_OR_SKIP(context);
  TempDir dir;
  Result<Device> device = Device::OpenClForCurrentGl(CacheIn(dir));
  if (!device.ok()) {
    EXPECT_EQ(device.status().code(), ErrorCode::kUnavailable) << device.status().message();
    GTEST_SKIP() << "no OpenCL-GL sharing here: " << device.status().message();
  }
  EXPECT_TRUE(device->has_gl_sharing());
  ExpectSkinsIntoGlBuffers(*device);
}

// The paper's section 4.1 path: CUDA skins into a GL buffer it registered
// (cuGraphicsGLRegisterBuffer), on the GPU's own EGL context; read back
// through GL. Without a current GL context it is kInvalidState.
TEST(CudaGlInterop, SkinsIntoAGlBufferOfTheCurrentContext) {
  CONTEXT_OR_SKIP(context);
  TempDir dir;
  const Backend cuda = Backend::kCuda;
  Result<Device> device = Device::Open("", &cuda, CacheIn(dir));
  if (!device.ok()) GTEST_SKIP() << "no CUDA device here: " << device.status().message();
  if (GlDeviceType(context.info().renderer) != "gpu")
    GTEST_SKIP() << "the GL context is on " << context.info().renderer << ", not a GPU CUDA can share with";
  ExpectSkinsIntoGlBuffers(*device);
  Skinner skinner = MustCreate(*device, View(Small().mesh).mesh);
  const std::vector<float> palette = Floats(Pose(Small(), 0.3));
  ASSERT_TRUE(skinner.SetPalette(palette.data(), palette.size()).ok());
  GLuint buffer = 0;
  glGenBuffers(1, &buffer);
  glBindBuffer(GL_ARRAY_BUFFER, buffer);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(skinner.vertex_count() * skinner.output_stride_bytes()),
               nullptr, GL_DYNAMIC_DRAW);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  Status elsewhere;
  std::thread([&] { elsewhere = skinner.SkinIntoGlBuffer(buffer); }).join();  // no GL context there
  EXPECT_EQ(elsewhere.code(), ErrorCode::kInvalidState) << elsewhere.message();
  EXPECT_TRUE(skinner.SkinIntoGlBuffer(buffer).ok());
  const Status not_a_buffer = skinner.SkinIntoGlBuffer(buffer + 1000);
  EXPECT_EQ(not_a_buffer.code(), ErrorCode::kInvalidArgument) << not_a_buffer.message();
  glDeleteBuffers(1, &buffer);
}

TEST(OpenClGlInterop, WithoutACurrentContextThereIsNothingToShare) {
  Status status;
  std::thread([&] { status = Device::OpenClForCurrentGl().status(); }).join();
  EXPECT_EQ(status.code(), ErrorCode::kUnavailable) << status.message();
}

TEST(GlMisuse, NoCurrentContextIsUnavailable) {
  Status status;
  std::thread([&] { status = Device::FromCurrentGl().status(); }).join();  // a new thread has none
  EXPECT_EQ(status.code(), ErrorCode::kUnavailable) << status.message();
  EXPECT_FALSE(status.message().empty());
}

TEST(GlMisuse, SkinningWithAnotherContextCurrentOrTheContextGone) {
  auto context = std::make_unique<GlContext>();
  if (!context->ok()) GTEST_SKIP() << context->reason();
  TempDir dir;
  Result<Device> device = Device::FromCurrentGl(CacheIn(dir));
  ASSERT_TRUE(device.ok()) << device.status().message();
  const View view(Small().mesh);
  Skinner skinner = MustCreate(*device, view.mesh);
  const std::vector<float> palette = Floats(Pose(Small(), 0.5));
  ASSERT_TRUE(skinner.SetPalette(palette.data(), palette.size()).ok());
  {
    GlContext other;  // now current instead
    ASSERT_TRUE(other.ok());
    const Status status = skinner.Skin();
    EXPECT_EQ(status.code(), ErrorCode::kInvalidState) << status.message();
    EXPECT_NE(status.message().find("not current"), std::string::npos) << status.message();
    const Result<Skinner> created = Skinner::Create(*device, WinnersDb::Empty(), view.mesh);
    EXPECT_EQ(created.status().code(), ErrorCode::kInvalidState) << created.status().message();
  }
  context->MakeCurrent();
  EXPECT_TRUE(skinner.Skin().ok());
  context.reset();  // the caller destroys its context
  const Status gone = skinner.Skin();
  EXPECT_EQ(gone.code(), ErrorCode::kInvalidState) << gone.message();
}

}  // namespace
}  // namespace skintune::internal
