// The palette kernel (cpu_kernels/palette_kernel.h on the CPU, templates/palette.cl
// on the first OpenCL device) against the float64 gold: the model's own sampling
// (SkinnedAsset::PoseAt) and composition (Skeleton::PaletteD).
//
// The bound and the instances (times before, on, between and after keys;
// blends): tests/generator/palette_gold.h.
#include <gtest/gtest.h>
#define CL_TARGET_OPENCL_VERSION 120  // clCreateCommandQueue, as runtime/backends/opencl does
#include <CL/cl.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "base/error.h"
#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "generator/emit.h"
#include "generator/languages.h"
#include "generator/packer.h"
#include "generator/palette_kernel.h"
#include "model/synthetic.h"
#include "reference/skinning.h"
#include "tests/common/test_asset.h"
#include "tests/generator/deep_rig.h"
#include "tests/generator/palette_checks.h"
#include "tests/generator/palette_gold.h"

namespace skintune::internal {
namespace {

using testing::BakedGoldPalette;
using testing::BakedGoldPaletteOf;
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

std::vector<float> OnCpu(const PackedAnimation& packed, const std::vector<AnimInstance>& instances) {
  std::vector<float> rows(instances.size() * packed.joints.size() * 12);
  RunPaletteKernel(packed.View(), instances, rows.data());
  return rows;
}

// ------------------------------------------------------------- OpenCL

void Check(cl_int err, const char* what) {
  if (err != CL_SUCCESS) throw std::runtime_error(std::string(what) + " failed: " + std::to_string(err));
}

// templates/palette.cl on the first OpenCL device (PoCL here): the template
// built alone once, then each packed animation's kernel (EmitPalette).
class OpenClPaletteKernel {
 public:
  // Null, with the reason in `why`, without an OpenCL device.
  static OpenClPaletteKernel* Get(std::string& why) {
    static std::string reason;
    static const std::unique_ptr<OpenClPaletteKernel> kernel = [] {
      cl_uint count = 0;
      if (clGetPlatformIDs(0, nullptr, &count) != CL_SUCCESS || count == 0) {
        reason = "no OpenCL platform on this machine";
        return std::unique_ptr<OpenClPaletteKernel>();
      }
      std::vector<cl_platform_id> platforms(count);
      clGetPlatformIDs(count, platforms.data(), nullptr);
      for (cl_platform_id platform : platforms) {
        cl_device_id device = nullptr;
        if (clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, 1, &device, nullptr) == CL_SUCCESS)
          return std::unique_ptr<OpenClPaletteKernel>(new OpenClPaletteKernel(device));
      }
      reason = "no OpenCL device on this machine";
      return std::unique_ptr<OpenClPaletteKernel>();
    }();
    why = reason;
    return kernel.get();
  }

  ~OpenClPaletteKernel() {
    for (auto& [hash, built] : built_) {
      clReleaseKernel(built.second);
      clReleaseProgram(built.first);
    }
    clReleaseCommandQueue(queue_);
    clReleaseContext(context_);
  }

  // Instance i's palette rows, as RunPaletteKernel writes them; launched with
  // one work-group of 64 per instance and `groups_x` groups along the first
  // dimension (the kernel's launch is 1; the others must change nothing).
  std::vector<float> Run(const PackedAnimation& packed, const std::vector<AnimInstance>& instances,
                         std::size_t groups_x = 1) {
    std::vector<float> rows(instances.size() * packed.joints.size() * 12);
    const cl_mem out = LaunchPalettes(packed, instances, groups_x);
    Check(clEnqueueReadBuffer(queue_, out, CL_TRUE, 0, rows.size() * sizeof(float), rows.data(), 0, nullptr, nullptr),
          "clEnqueueReadBuffer");
    clReleaseMemObject(out);
    return rows;
  }

  // The instances' palettes made on the device and read there, as they are,
  // by `skin` (an instanced kernel of `mesh`'s padded variant: one launch):
  // the skinned positions of every instance, instance after instance.
  std::vector<std::uint8_t> Skin(const PackedAnimation& packed, const std::vector<AnimInstance>& instances,
                                 const PackedMesh& mesh, const KernelSource& skin) {
    const cl_mem palettes = LaunchPalettes(packed, instances);
    const Launch& launch = mesh.launches.at(0);
    std::vector<cl_mem> buffers = {palettes};
    std::vector<std::uint8_t> positions(instances.size() * mesh.vertex_count * mesh.output_stride_bytes);
    cl_int err = CL_SUCCESS;
    const cl_mem out = clCreateBuffer(context_, CL_MEM_WRITE_ONLY, positions.size(), nullptr, &err);
    Check(err, "clCreateBuffer");
    buffers.push_back(out);
    const cl_kernel kernel = SkinKernel(skin.text);
    const cl_uint scalars[] = {launch.count, launch.first, static_cast<cl_uint>(mesh.vertex_count)};
    cl_uint arg = 0;
    for (const KernelArgument& a : skin.arguments) {
      const cl_uint* scalar = a.name == "n"              ? &scalars[0]
                              : a.name == "first"        ? &scalars[1]
                              : a.name == "vertex_count" ? &scalars[2]
                                                         : nullptr;
      cl_mem buffer = a.name == "palette" ? palettes : a.name == "out_positions" ? out : nullptr;
      for (const PackedBuffer& input : launch.inputs)
        if (input.name == a.name) buffers.push_back(buffer = Upload(input.bytes));
      if (scalar)
        Check(clSetKernelArg(kernel, arg++, sizeof *scalar, scalar), "clSetKernelArg");
      else if (buffer)
        Check(clSetKernelArg(kernel, arg++, sizeof buffer, &buffer), "clSetKernelArg");
      else
        throw std::runtime_error("no value for the skin kernel's argument " + a.name);
    }
    const std::size_t wg = static_cast<std::size_t>(skin.launch.wg_size);
    const std::size_t global[2] = {skin.launch.GlobalItems(launch.count), instances.size()}, local[2] = {wg, 1};
    Check(clEnqueueNDRangeKernel(queue_, kernel, 2, nullptr, global, local, 0, nullptr, nullptr), "skin launch");
    Check(clEnqueueReadBuffer(queue_, out, CL_TRUE, 0, positions.size(), positions.data(), 0, nullptr, nullptr),
          "clEnqueueReadBuffer");
    clReleaseKernel(kernel);
    for (cl_mem b : buffers) clReleaseMemObject(b);
    return positions;
  }

 private:
  explicit OpenClPaletteKernel(cl_device_id device) : device_(device) {
    cl_int err = CL_SUCCESS;
    context_ = clCreateContext(nullptr, 1, &device_, nullptr, nullptr, &err);
    Check(err, "clCreateContext");
    queue_ = clCreateCommandQueue(context_, device_, 0, &err);
    Check(err, "clCreateCommandQueue");
    Build(ExpandedTemplate("palette.cl"));  // the template alone, at its defaults
  }

  // The kernel "skintune_palette" of `text`, built once.
  cl_kernel Build(const std::string& text) {
    const std::string hash = SourceHash(text);
    if (const auto found = built_.find(hash); found != built_.end()) return found->second.second;
    const char* source = text.c_str();
    const std::size_t length = text.size();
    cl_int err = CL_SUCCESS;
    const cl_program program = clCreateProgramWithSource(context_, 1, &source, &length, &err);
    Check(err, "clCreateProgramWithSource");
    if (clBuildProgram(program, 1, &device_, "-cl-std=CL1.2", nullptr, nullptr) != CL_SUCCESS) {
      std::size_t size = 0;
      clGetProgramBuildInfo(program, device_, CL_PROGRAM_BUILD_LOG, 0, nullptr, &size);
      std::string log(size, '\0');
      clGetProgramBuildInfo(program, device_, CL_PROGRAM_BUILD_LOG, size, log.data(), nullptr);
      throw std::runtime_error("palette.cl does not build: " + log);
    }
    const cl_kernel kernel = clCreateKernel(program, "skintune_palette", &err);
    Check(err, "clCreateKernel");
    built_[hash] = {program, kernel};
    return kernel;
  }

  // Enqueues the palette kernel over `instances`; returns its output buffer
  // (the caller releases it).
  cl_mem LaunchPalettes(const PackedAnimation& packed, const std::vector<AnimInstance>& instances,
                        std::size_t groups_x = 1) {
    const std::size_t joints = packed.joints.size();
    cl_int err = CL_SUCCESS;
    cl_mem out = clCreateBuffer(context_, CL_MEM_READ_WRITE, instances.size() * joints * 48, nullptr, &err);
    Check(err, "clCreateBuffer");
    const PaletteKernel emitted = EmitPalette(Lang::kOpenCl, packed.View(), 3);
    const cl_kernel kernel = Build(emitted.kernel.text);
    // Every buffer by its name (the states written back), then the frame's
    // scalars: fresh, so the states are the instances as given.
    std::vector<cl_mem> buffers;
    cl_uint arg = 0;
    for (const KernelArgument& a : emitted.kernel.arguments) {
      if (a.kind != ArgumentKind::kBuffer) continue;
      cl_mem buffer = out;
      if (a.name != kAnimOutput) buffers.push_back(buffer = Upload(PaletteInputBytes(packed, instances, a.name)));
      Check(clSetKernelArg(kernel, arg++, sizeof buffer, &buffer), "clSetKernelArg");
    }
    const float delta = 0.0f;
    const cl_uint fresh = 1;
    Check(clSetKernelArg(kernel, arg++, sizeof delta, &delta), "clSetKernelArg");
    Check(clSetKernelArg(kernel, arg++, sizeof fresh, &fresh), "clSetKernelArg");
    const auto group = static_cast<std::size_t>(emitted.kernel.launch.wg_size);  // palette.cl's ANIM_GROUP
    const std::size_t global[2] = {groups_x * group, instances.size()}, local[2] = {group, 1};
    Check(clEnqueueNDRangeKernel(queue_, kernel, 2, nullptr, global, local, 0, nullptr, nullptr),
          "clEnqueueNDRangeKernel");
    Check(clFinish(queue_), "clFinish");
    for (cl_mem b : buffers) clReleaseMemObject(b);
    return out;
  }

  // The kernel "skin" of an emitted skin kernel's text.
  cl_kernel SkinKernel(const std::string& text) {
    const char* source = text.c_str();
    const std::size_t length = text.size();
    cl_int err = CL_SUCCESS;
    const cl_program program = clCreateProgramWithSource(context_, 1, &source, &length, &err);
    Check(err, "clCreateProgramWithSource");
    Check(clBuildProgram(program, 1, &device_, "-cl-std=CL1.2", nullptr, nullptr), "building the skin kernel");
    const cl_kernel kernel = clCreateKernel(program, "skin", &err);
    Check(err, "clCreateKernel skin");
    clReleaseProgram(program);  // the kernel keeps it
    return kernel;
  }

  // A read-only buffer of `bytes` (at least 16: OpenCL has no empty buffers).
  cl_mem Upload(std::span<const std::uint8_t> bytes) {
    std::vector<std::uint8_t> padded(bytes.begin(), bytes.end());
    padded.resize(std::max<std::size_t>(padded.size(), 16), 0);
    cl_int err = CL_SUCCESS;
    cl_mem b = clCreateBuffer(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, padded.size(), padded.data(), &err);
    Check(err, "clCreateBuffer");
    return b;
  }

  cl_device_id device_ = nullptr;
  cl_context context_ = nullptr;
  cl_command_queue queue_ = nullptr;
  std::map<std::string, std::pair<cl_program, cl_kernel>> built_;  // by source hash
};

#define SKIP_WITHOUT_OPENCL(kernel)                            \
  std::string why;                                             \
  OpenClPaletteKernel* kernel = OpenClPaletteKernel::Get(why); \
  if (kernel == nullptr) GTEST_SKIP() << why

const char* const kModels[] = {"CesiumMan.gltf", "Fox.gltf", "RiggedSimple.gltf"};

// ------------------------------------------------------------- the tests

TEST(PaletteKernel, CpuMatchesTheGoldForEveryClipOfTheGltfModels) {
  ExpectEveryClipOfTheGltfModelsMatchesTheGold(OnCpu, "cpu");
}

TEST(PaletteKernel, CpuMatchesTheGoldOnADeepRigWithEveryInterpolation) {
  ExpectTheDeepRigMatchesTheGold(OnCpu, "cpu");
}

TEST(PaletteKernel, CpuBlendsTwoClipsInLocalSpaceLikeTheGold) {
  ExpectBlendsMatchTheGold(OnCpu, "cpu");
}

TEST(PaletteKernel, OpenClMatchesTheGoldForEveryClipOfTheGltfModels) {
  SKIP_WITHOUT_OPENCL(kernel);
  ExpectEveryClipOfTheGltfModelsMatchesTheGold(On(kernel), "opencl");
}

TEST(PaletteKernel, OpenClMatchesTheGoldOnADeepRigWithEveryInterpolation) {
  SKIP_WITHOUT_OPENCL(kernel);
  ExpectTheDeepRigMatchesTheGold(On(kernel), "opencl");
  // Groups beyond the first along dimension 0 (the launch has one) do nothing.
  ExpectTheDeepRigMatchesTheGold(
      [&](const PackedAnimation& p, const std::vector<AnimInstance>& in) { return kernel->Run(p, in, 3); },
      "opencl, 3 groups along x");
}

TEST(PaletteKernel, OpenClBlendsTwoClipsInLocalSpaceLikeTheGold) {
  SKIP_WITHOUT_OPENCL(kernel);
  ExpectBlendsMatchTheGold(On(kernel), "opencl");
}

TEST(PaletteKernel, OpenClWritesNanRowsForAClipOutOfRangeInsteadOfReadingBeyond) {
  SKIP_WITHOUT_OPENCL(kernel);
  ExpectNanRowsForAClipOutOfRange(On(kernel));
  ExpectNanRowsForAClipOutOfRange(On(kernel), Animation::kBaked30);
  ExpectNanRowsForAClipOutOfRange(On(kernel), Animation::kLocal30);
}

// ------------------------------------------------------------- baked clips

TEST(PaletteKernelBaked, CpuMatchesItsFramesAloneAndBlended) { ExpectBakedClipsMatchTheirFrames(OnCpu, "cpu"); }

TEST(PaletteKernelBaked, OpenClMatchesItsFramesAloneAndBlended) {
  SKIP_WITHOUT_OPENCL(kernel);
  ExpectBakedClipsMatchTheirFrames(On(kernel), "opencl");
}

// The largest distance between a vertex of `mesh` skinned by `baked` and by
// `exact`, over the mesh's bounding-box diagonal.
double SkinDistance(const SkinnedMesh& mesh, const std::vector<glm::dmat4>& baked, const std::vector<glm::dmat4>& exact) {
  const double diagonal = BoundingBoxDiagonal(mesh.positions);
  const auto b = static_cast<std::size_t>(mesh.influences);
  double worst = 0.0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    glm::dvec4 moved(0.0);
    for (std::size_t i = 0; i < b; ++i) {
      const auto j = static_cast<std::size_t>(mesh.joints[v * b + i]);
      moved += double{mesh.weights[v * b + i]} * ((baked[j] - exact[j]) * glm::dvec4(glm::dvec3(mesh.positions[v]), 1.0));
    }
    worst = std::max(worst, glm::length(glm::dvec3(moved)) / diagonal);
  }
  return worst;
}

// The stated error (BakedClipInfo::max_error, measured at the frames and 1/4,
// 1/2, 3/4 between them) holds at other times too, within 25%, and falls with
// the rate (4x the rate, at least 2x less: linearly where a LINEAR clip's
// keys make kinks between two frames, quadratically elsewhere), in both
// spaces. Memory: the frames x joints (local: nodes) x 32 bytes stated.
TEST(PaletteKernelBaked, StatesEachClipsMemoryAndErrorWhichHoldsBetweenItsChecksAndFallsWithTheRate) {
  for (const auto& [space, asset] : {std::pair{BakeSpace::kPalette, &TestAsset("CesiumMan.gltf")},
                                     std::pair{BakeSpace::kPalette, &TestAsset("Fox.gltf")},
                                     std::pair{BakeSpace::kLocal, &TestAsset("CesiumMan.gltf")},
                                     std::pair{BakeSpace::kLocal, &TestAsset("Fox.gltf")}}) {
    const PackedAnimation coarse = BakeAnimation(*asset, 30.0, space), fine = BakeAnimation(*asset, 120.0, space);
    const bool local = space == BakeSpace::kLocal;
    const std::size_t items = local ? coarse.nodes.size() : coarse.joints.size();
    ASSERT_EQ(coarse.baked.size(), asset->animations.size());
    const SkinnedMesh& mesh = asset->mesh;
    std::mt19937 random(7);
    for (std::size_t c = 0; c < coarse.baked.size(); ++c) {
      const AnimationClip& clip = asset->animations[c];
      const BakedClipInfo& info = coarse.baked[c];
      EXPECT_EQ(info.frames, static_cast<std::uint32_t>(std::ceil(clip.duration() * 30.0 - 1e-9) + 1)) << info.name;
      EXPECT_EQ(coarse.baked_rows, kBakedRowsSimilar) << info.name;  // no joint of these scales unevenly
      EXPECT_EQ(info.bytes, std::size_t{info.frames} * items * 32) << info.name;
      double worst = 0.0;  // at random times: the vertices skinned by both palettes
      for (int k = 0; k < 100; ++k) {
        const double t = clip.start + std::uniform_real_distribution<double>(0.0, 1.0)(random) * clip.duration();
        const AnimInstance in{static_cast<std::uint16_t>(c), kAnimRestPose, static_cast<float>(t), 0.0f, 0.0f};
        const std::vector<glm::dmat4> exact = asset->skeleton.PaletteD(asset->PoseAt(static_cast<int>(c), in.time));
        worst = std::max(worst, SkinDistance(mesh, BakedGoldPaletteOf(*asset, coarse, in), exact));
      }
      std::printf("[ baked    ] %s %s%s: %u frames, %zu bytes at 30/s; stated error %.3g (120/s: %.3g), at random "
                  "times %.3g\n",
                  Name(*asset).c_str(), info.name.c_str(), local ? " (local)" : "", info.frames, info.bytes,
                  info.max_error, fine.baked[c].max_error, worst);
      EXPECT_LE(worst, 1.25 * info.max_error + 1e-7) << info.name;
      if (info.max_error > 1e-5) {
        EXPECT_LT(fine.baked[c].max_error, info.max_error / 2) << info.name;
      }
    }
  }
}

// A rig whose joints scale unevenly (the synthetic data sets': each axis by
// up to 20%, sheared through the hierarchy) is baked as 4-row records with
// the polar decomposition's stretch, not as a similarity that would lose it:
// its error falls with the rate like the real models'.
TEST(PaletteKernelBaked, JointsThatScaleUnevenlyKeepTheirStretch) {
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("2000-b4"));
  const PackedAnimation coarse = BakeAnimation(asset, 30.0), fine = BakeAnimation(asset, 120.0);
  EXPECT_EQ(coarse.baked_rows, kBakedRowsAffine);
  ASSERT_EQ(coarse.baked.size(), 1u);
  std::printf("[ baked    ] 2000-b4: %u frames at 30/s, stated error %.3g (120/s: %.3g)\n", coarse.baked[0].frames,
              coarse.baked[0].max_error, fine.baked[0].max_error);
  EXPECT_LT(coarse.baked[0].max_error, 2e-2);
  EXPECT_LT(fine.baked[0].max_error, coarse.baked[0].max_error / 4);
  EXPECT_EQ(coarse.baked[0].bytes, std::size_t{coarse.baked[0].frames} * coarse.joints.size() * 64);
  // At a frame the stored stretch reproduces the palette to float32 precision.
  const AnimInstance at_frame{0, kAnimRestPose, coarse.clip_ranges[0], 0.0f, 0.0f};
  const std::vector<glm::dmat4> baked = BakedGoldPalette(coarse, at_frame);
  const std::vector<glm::dmat4> exact = asset.skeleton.PaletteD(asset.PoseAt(0, at_frame.time));
  for (std::size_t j = 0; j < baked.size(); ++j)
    for (int c = 0; c < 4; ++c)
      EXPECT_LT(glm::length(baked[j][c] - exact[j][c]), 1e-5 * std::max(1.0, glm::length(exact[j][c]))) << j;
  // Every API's kernel check (ExpectBakedClipsMatchTheirFrames) runs both
  // forms: the glTF models' 2-row records and the deep rig's 4-row ones.
  EXPECT_EQ(BakeAnimation(DeepRig(), 30.0).baked_rows, kBakedRowsAffine);
  EXPECT_EQ(BakeAnimation(TestAsset("Fox.gltf"), 30.0).baked_rows, kBakedRowsSimilar);
}

// What local records are for: a blend of two clips. Each node's local
// transform is mixed, as sampled clips are mixed, so a crowd in transition
// loses what baking each clip loses, where palette records, mixed in the
// model's space, bend a blended limb off its chain. Every blend of the Fox's
// and CesiumMan's clips and the synthetic rig's (Blends), against the
// float64 sampled blend (BlendedPoseAt).
TEST(PaletteKernelBaked, LocalRecordsBlendTwoClipsAsSampledClipsDo) {
  for (const SkinnedAsset* asset :
       {&TestAsset("Fox.gltf"), &TestAsset("CesiumMan.gltf"), &TestAsset("2000-b4")}) {
    const PackedAnimation sampled = PackAnimation(*asset);
    const PackedAnimation palette = BakeAnimation(*asset, 120.0), local = BakeAnimation(*asset, 120.0, BakeSpace::kLocal);
    double baking = 0.0;  // the largest a clip alone loses, stated
    for (const BakedClipInfo& clip : local.baked) baking = std::max(baking, clip.max_error);
    double palette_blend = 0.0, local_blend = 0.0;
    for (const AnimInstance& in : testing::Blends(*asset, sampled)) {
      if (in.weight == 0.0f) continue;
      const std::vector<glm::dmat4> exact = asset->skeleton.PaletteD(testing::GoldPose(*asset, sampled, in));
      palette_blend = std::max(palette_blend, SkinDistance(asset->mesh, BakedGoldPaletteOf(*asset, palette, in), exact));
      local_blend = std::max(local_blend, SkinDistance(asset->mesh, BakedGoldPaletteOf(*asset, local, in), exact));
    }
    std::printf("[ baked    ] %s blends at 120/s: palette records %.3g, local records %.3g (a clip alone: %.3g)\n",
                Name(*asset).c_str(), palette_blend, local_blend, baking);
    EXPECT_LE(local_blend, 2.0 * baking + 1e-6) << Name(*asset);
    EXPECT_GT(palette_blend, 10.0 * local_blend) << Name(*asset);
  }
}

// Local records of nodes that scale unevenly keep each axis's scale (3 rows:
// 48 bytes a node and frame), and reproduce the pose at a frame to float32
// precision; the kernel's buffers are nodes, frames, joints, then the
// baked kernel's (ANIM_BAKED 3 and 4), its group one item per node.
TEST(PaletteKernelBaked, LocalRecordsKeepEachAxissScaleAndEmitTheirOwnKernel) {
  const SkinnedAsset& asset = TestAsset("2000-b4");
  const PackedAnimation local = BakeAnimation(asset, 30.0, BakeSpace::kLocal);
  EXPECT_TRUE(local.baked_local);
  EXPECT_EQ(local.baked_rows, kBakedRowsLocalScaled);
  ASSERT_EQ(local.baked.size(), 1u);
  EXPECT_EQ(local.baked[0].bytes, std::size_t{local.baked[0].frames} * local.nodes.size() * 48);
  EXPECT_EQ(local.Bytes(), local.frames.size() * 4 + local.clip_ranges.size() * 4 +
                               local.nodes.size() * sizeof(AnimNodeRecord) + local.joints.size() * sizeof(AnimJointRecord));
  const AnimInstance at_frame{0, kAnimRestPose, local.clip_ranges[0], 0.0f, 0.0f};
  const std::vector<glm::dmat4> baked = BakedGoldPaletteOf(asset, local, at_frame);
  const std::vector<glm::dmat4> exact = asset.skeleton.PaletteD(asset.PoseAt(0, at_frame.time));
  for (std::size_t j = 0; j < baked.size(); ++j)
    for (int c = 0; c < 4; ++c)
      EXPECT_LT(glm::length(baked[j][c] - exact[j][c]), 1e-5 * std::max(1.0, glm::length(exact[j][c]))) << j;
  EXPECT_EQ(BakeAnimation(TestAsset("Fox.gltf"), 30.0, BakeSpace::kLocal).baked_rows, kBakedRowsSimilar);
  EXPECT_EQ(BakeAnimation(DeepRig(), 30.0, BakeSpace::kLocal).baked_rows, kBakedRowsLocalScaled);

  const PackedAnimation fox = BakeAnimation(TestAsset("Fox.gltf"), 30.0, BakeSpace::kLocal);
  const PackedAnimation coarse_palette_of_fox = BakeAnimation(TestAsset("Fox.gltf"), 30.0);
  for (Lang lang : {Lang::kOpenCl, Lang::kCuda, Lang::kGlslCompute, Lang::kVulkan, Lang::kCpu}) {
    for (const PackedAnimation* packed : {&fox, &local}) {
      const PaletteKernel kernel = EmitPalette(lang, packed->View(), 3);
      EXPECT_EQ(kernel.kernel.launch.wg_size, AnimBakedGroupFor(packed->nodes.size())) << Name(lang);
      const std::string define = packed == &fox ? "#define ANIM_BAKED 3\n" : "#define ANIM_BAKED 4\n";
      EXPECT_NE(kernel.kernel.text.find(define), std::string::npos) << Name(lang);
      std::vector<std::string> buffers;
      for (const KernelArgument& a : kernel.kernel.arguments)
        if (a.kind == ArgumentKind::kBuffer) buffers.push_back(a.name);
      EXPECT_EQ(buffers, (std::vector<std::string>{kAnimInputs[0], kAnimFrames, kAnimInputs[4], kAnimInputs[5],
                                                   kAnimOutput, kAnimClips, kAnimStates}))
          << Name(lang);
    }
  }
  for (const PackedAnimation* packed : {&fox, &local, &coarse_palette_of_fox}) {  // the define read back
    const BakedForm form = BakedFormOf(BakedDefine(packed->View()));
    EXPECT_TRUE(form.baked);
    EXPECT_EQ(form.local, packed->baked_local);
    EXPECT_EQ(form.rows, packed->baked_rows);
  }
  EXPECT_FALSE(BakedFormOf(0).baked);
  EXPECT_THROW(BakedFormOf(5), Error);
  EXPECT_EQ(PackForm(TestAsset("Fox.gltf"), Animation::kLocal60).bake_rate, 60.0);
  EXPECT_TRUE(PackForm(TestAsset("Fox.gltf"), Animation::kLocal60).baked_local);
  EXPECT_FALSE(PackForm(TestAsset("Fox.gltf"), Animation::kBaked60).baked_local);
  EXPECT_TRUE(PackForm(TestAsset("Fox.gltf"), Animation::kSampled).frames.empty());
  EXPECT_THROW(PackForm(TestAsset("Fox.gltf"), Animation::kHost), Error);
}

// What ValidateBakedAnimation says of `from` spoiled by spoil(packing).
template <typename Spoil>
std::string ValidationErrorAfter(const PackedAnimation& from, Spoil&& spoil) {
  PackedAnimation bad = from;
  spoil(bad);
  try {
    ValidateBakedAnimation(bad.View());
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

// Hybrid records (docs/ANIMATION.md "Hybrid records"): the local records
// and the palette records of the same frames, each clip's bytes both's and
// its stated error the larger; the kernel takes `steady` after frames and
// says its records' rows (ANIM_STEADY); ValidateBakedAnimation checks the
// steady records as it checks frames, naming them.
TEST(PaletteKernelBaked, HybridRecordsHoldBothRecordsOfTheSameFramesAndStateBoth) {
  for (const SkinnedAsset* asset : {&TestAsset("Fox.gltf"), &TestAsset("2000-b4")}) {
    const PackedAnimation palette = BakeAnimation(*asset, 30.0), local = BakeAnimation(*asset, 30.0, BakeSpace::kLocal);
    const PackedAnimation hybrid = BakeAnimation(*asset, 30.0, BakeSpace::kHybrid);
    EXPECT_TRUE(hybrid.baked_local);
    EXPECT_EQ(hybrid.frames, local.frames);
    EXPECT_EQ(hybrid.baked_rows, local.baked_rows);
    EXPECT_EQ(hybrid.steady, palette.frames);
    EXPECT_EQ(hybrid.steady_rows, palette.baked_rows);
    EXPECT_EQ(hybrid.clip_ranges, local.clip_ranges);
    EXPECT_EQ(hybrid.Bytes(), local.Bytes() + palette.frames.size() * 4);
    ASSERT_EQ(hybrid.baked.size(), local.baked.size());
    for (std::size_t c = 0; c < hybrid.baked.size(); ++c) {
      EXPECT_EQ(hybrid.baked[c].frames, local.baked[c].frames);
      EXPECT_EQ(hybrid.baked[c].bytes, local.baked[c].bytes + palette.baked[c].bytes);
      EXPECT_EQ(hybrid.baked[c].max_error, std::max(local.baked[c].max_error, palette.baked[c].max_error));
    }
    // The gold: an instance of one clip is its palette records', one that cross-fades its local records'.
    const AnimInstance one{0, kAnimRestPose, 0.37f, 0.0f, 0.0f}, fading{0, 0, 0.37f, 0.11f, 0.4f};
    EXPECT_EQ(BakedGoldPaletteOf(*asset, hybrid, one), BakedGoldPaletteOf(*asset, palette, one));
    EXPECT_EQ(BakedGoldPaletteOf(*asset, hybrid, fading), BakedGoldPaletteOf(*asset, local, fading));
    for (Lang lang : {Lang::kOpenCl, Lang::kCuda, Lang::kGlslCompute, Lang::kVulkan, Lang::kCpu}) {
      const PaletteKernel kernel = EmitPalette(lang, hybrid.View(), 3);
      EXPECT_EQ(kernel.kernel.launch.wg_size, AnimBakedGroupFor(hybrid.nodes.size())) << Name(lang);
      EXPECT_NE(kernel.kernel.text.find("#define ANIM_STEADY " + std::to_string(palette.baked_rows) + "\n"),
                std::string::npos)
          << Name(lang);
      std::vector<std::string> buffers;
      for (const KernelArgument& a : kernel.kernel.arguments)
        if (a.kind == ArgumentKind::kBuffer) buffers.push_back(a.name);
      EXPECT_EQ(buffers, (std::vector<std::string>{kAnimInputs[0], kAnimFrames, kAnimSteady, kAnimInputs[4],
                                                   kAnimInputs[5], kAnimOutput, kAnimClips, kAnimStates}))
          << Name(lang);
      EXPECT_NE(EmitPalette(lang, local.View(), 3).kernel.text.find("#define ANIM_STEADY 0\n"), std::string::npos);
    }
  }
  EXPECT_TRUE(BakesHybrid(Animation::kHybrid120));
  EXPECT_TRUE(BakesLocally(Animation::kHybrid120));  // its cross-fades mix local records
  EXPECT_FALSE(BakesHybrid(Animation::kLocal120));
  EXPECT_EQ(BakeRateOf(Animation::kHybrid30), 30.0);
  const PackedAnimation formed = PackForm(TestAsset("Fox.gltf"), Animation::kHybrid60);
  EXPECT_EQ(formed.bake_rate, 60.0);
  EXPECT_FALSE(formed.steady.empty());

  const PackedAnimation hybrid = BakeAnimation(TestAsset("Fox.gltf"), 30.0, BakeSpace::kHybrid);
  EXPECT_NO_THROW(ValidateBakedAnimation(hybrid.View()));
  const auto error_of = [&](auto&& spoil) { return ValidationErrorAfter(hybrid, spoil); };
  const std::size_t frame1 = 8 * hybrid.joints.size();
  EXPECT_EQ(error_of([&](PackedAnimation& p) { p.steady[frame1 + 8 * 4 + 5] = NAN; }),
            "baked animation: steady[1] joint 4: nan is not finite");
  EXPECT_EQ(error_of([](PackedAnimation& p) { p.steady_rows = kBakedRowsLocalScaled; }),
            "baked animation: steady records of 3 float4s (2 or 4)");
  EXPECT_NE(error_of([](PackedAnimation& p) { p.steady.resize(p.steady.size() - 8 * p.joints.size()); })
                .find("steady floats, not the"),
            std::string::npos);
  EXPECT_NE(error_of([](PackedAnimation& p) { p.baked_local = false; }).find("steady records beside records not in local"),
            std::string::npos);
}

TEST(PaletteKernelBaked, RefusesBadRatesAndBadFramesNamingTheElement) {
  const SkinnedAsset& fox = TestAsset("Fox.gltf");
  for (const double rate : {0.0, -30.0, double{NAN}, double{INFINITY}, 1001.0})
    EXPECT_THROW(BakeAnimation(fox, rate), Error) << rate;
  try {
    BakeAnimation(fox, 0.0);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("Fox.gltf: bake rate 0 frames a second, outside (0, 1000]"), std::string::npos)
        << e.what();
  }
  const PackedAnimation good = BakeAnimation(fox, 30.0);
  EXPECT_NO_THROW(ValidateBakedAnimation(good.View()));
  const auto error_of = [&](auto&& spoil) { return ValidationErrorAfter(good, spoil); };
  EXPECT_NE(error_of([](PackedAnimation& p) { p.frames[8 * 30 + 3] = 2.0f; })
                .find("baked animation: frames[1] joint 6: rotation of length 2.0"),
            std::string::npos);
  EXPECT_EQ(error_of([](PackedAnimation& p) { p.frames[8 * 30 + 5] = NAN; }),
            "baked animation: frames[1] joint 6: nan is not finite");
  EXPECT_NE(error_of([](PackedAnimation& p) { p.frames.resize(p.frames.size() - 8); })
                .find("baked animation: " + std::to_string(good.frames.size() - 8) + " frame floats, not whole frames"),
            std::string::npos);
  EXPECT_NE(error_of([](PackedAnimation& p) { p.clip_ranges[4 * 2 + 2] = std::bit_cast<float>(1000000u); })
                .find("baked animation: clips[2]: frames "),
            std::string::npos);
  // Local records: named by node, of 2 or 3 rows, over a hierarchy without cycles.
  const PackedAnimation local = BakeAnimation(fox, 30.0, BakeSpace::kLocal);
  EXPECT_NO_THROW(ValidateBakedAnimation(local.View()));
  const auto local_error_of = [&](auto&& spoil) { return ValidationErrorAfter(local, spoil); };
  const std::size_t frame1 = 8 * local.nodes.size();
  EXPECT_EQ(local_error_of([&](PackedAnimation& p) { p.frames[frame1 + 8 * 5 + 6] = INFINITY; }),
            "baked animation: frames[1] node 5: inf is not finite");
  EXPECT_EQ(local_error_of([](PackedAnimation& p) { p.baked_rows = kBakedRowsAffine; }),
            "baked animation: 4 float4s a record (2 or 3 in local space)");
  EXPECT_EQ(local_error_of([](PackedAnimation& p) { p.nodes[2].parent = 2; }),
            "packed animation: nodes[2]: the node hierarchy has a cycle");
}

// A clip of one key (no duration) bakes as one frame, its pose at every time;
// a clip so long that its frames would pass kMaxBakedFloats is refused before
// anything is baked, naming the file.
TEST(PaletteKernelBaked, AClipWithoutDurationIsOneFrameAndAnAbsurdOneIsRefused) {
  SkinnedAsset still = TestAsset("RiggedSimple.gltf");
  for (Channel& channel : still.animations[0].channels) {
    channel.times.resize(1);
    channel.values.resize(channel.interpolation == Interpolation::kCubicSpline ? 3 : 1);
  }
  still.animations[0].UpdateRange();
  const PackedAnimation baked = BakeAnimation(still, 60.0);
  ASSERT_EQ(baked.baked.size(), 1u);
  EXPECT_EQ(baked.baked[0].frames, 1u);
  EXPECT_LT(baked.baked[0].max_error, 1e-6);
  for (const float t : {-1.0f, 0.0f, 5.0f}) {
    const std::vector<glm::dmat4> at = BakedGoldPalette(baked, AnimInstance{0, kAnimRestPose, t, 0.0f, 0.0f});
    const std::vector<glm::dmat4> exact = still.skeleton.PaletteD(still.PoseAt(0, t));
    for (std::size_t j = 0; j < at.size(); ++j)
      for (int c = 0; c < 4; ++c) EXPECT_LT(glm::length(at[j][c] - exact[j][c]), 1e-5) << "t " << t << " joint " << j;
  }
  const std::vector<AnimInstance> instances = {{0, kAnimRestPose, -1.0f, 0.0f, 0.0f}, {0, kAnimRestPose, 5.0f, 0.0f, 0.0f}};
  ExpectWithinBound("a clip without duration, cpu baked", testing::CompareBaked(baked, instances, OnCpu(baked, instances)));

  SkinnedAsset endless = TestAsset("RiggedSimple.gltf");
  Channel& channel = endless.animations[0].channels[0];
  channel.times.push_back(1e6f);
  channel.values.push_back(channel.values.back());
  if (channel.interpolation == Interpolation::kCubicSpline)
    channel.values.insert(channel.values.end(), {channel.values.back(), channel.values.back()});
  endless.animations[0].UpdateRange();
  try {
    BakeAnimation(endless, 1000.0);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("RiggedSimple.gltf: baked at 1000 frames a second, more than 268435456 "
                                         "floats of frames"),
              std::string::npos)
        << e.what();
  }
}

// A baked animation's kernel: ANIM_BAKED 1, an item per joint, and its
// buffers frames, instances, out_palette, clips, states in that order.
TEST(PaletteKernelBaked, EmitsTheBakedKernelWithItsOwnArgumentsAndGroup) {
  EXPECT_EQ(AnimBakedGroupFor(1), 32);
  EXPECT_EQ(AnimBakedGroupFor(24), 32);
  EXPECT_EQ(AnimBakedGroupFor(77), 96);
  EXPECT_EQ(AnimBakedGroupFor(1000), 256);
  const PackedAnimation baked = BakeAnimation(TestAsset("Fox.gltf"), 30.0);
  for (Lang lang : {Lang::kOpenCl, Lang::kCuda, Lang::kGlslCompute, Lang::kVulkan, Lang::kCpu}) {
    const PaletteKernel kernel = EmitPalette(lang, baked.View(), 3);
    EXPECT_EQ(kernel.kernel.launch.wg_size, AnimBakedGroupFor(baked.joints.size())) << Name(lang);
    EXPECT_NE(kernel.kernel.text.find("#define ANIM_BAKED 1\n"), std::string::npos) << Name(lang);
    std::vector<std::string> buffers;
    for (const KernelArgument& a : kernel.kernel.arguments)
      if (a.kind == ArgumentKind::kBuffer) buffers.push_back(a.name);
    EXPECT_EQ(buffers, (std::vector<std::string>{kAnimFrames, kAnimInputs[5], kAnimOutput, kAnimClips, kAnimStates}))
        << Name(lang);
  }
  const PaletteKernel sampled = EmitPalette(Lang::kOpenCl, PackAnimation(TestAsset("Fox.gltf")).View(), 3);
  EXPECT_NE(sampled.kernel.text.find("#define ANIM_BAKED 0\n"), std::string::npos);
}

// A fused kernel (docs/ANIMATION.md "The palette in the skin launch") is the
// skin kernel specialised again: its palette argument becomes the palette
// records, the instances and the clips, the scalar elapsed comes last, the
// animation's defines are added and GLSL's bindings follow the new arguments.
// Anything but baked records into a local copy of matching joints is
// refused, naming why.
TEST(PaletteKernelBaked, AFusedSkinKernelTakesTheRecordsWhereThePaletteWas) {
  const SkinnedAsset& fox = TestAsset("Fox.gltf");
  const PackedAnimation records = BakeAnimation(fox, 30.0);
  const int joints = static_cast<int>(records.joints.size());
  EmitOptions instanced;
  instanced.instanced = true;
  instanced.max_instances = 4;
  for (const char* key : {"opencl.b4.soa.local", "cuda.b4.aos.mat4.local", "glsl-compute.b4.soa-split.local",
                          "vulkan.b4.soa.local.normals"}) {
    const KernelSource skin = Emit(ParseVariantKey(key), 0, joints, instanced);
    const KernelSource fused = EmitFused(skin, records.View());
    std::vector<std::string> names, expected;
    for (const KernelArgument& a : fused.arguments) names.push_back(a.name);
    for (const KernelArgument& a : skin.arguments) {
      if (a.name != "palette") {
        expected.push_back(a.name);
        continue;
      }
      expected.insert(expected.end(), {kAnimFrames, kAnimInputs[5], kAnimClips});
    }
    expected.push_back(kAnimElapsed);
    EXPECT_EQ(names, expected) << key;
    EXPECT_EQ(fused.arguments.back().kind, ArgumentKind::kScalar) << key;
    for (const char* define : {"#define ANIM_FUSED 1\n", "#define ANIM_BAKED 1\n"})
      EXPECT_NE(fused.text.find(define), std::string::npos) << key << ": " << define;
    EXPECT_NE(fused.text.find("#define ANIM_CLIP_COUNT " + std::to_string(records.View().clip_count) + "\n"), std::string::npos);
    EXPECT_NE(fused.source_hash, skin.source_hash) << key;
    if (IsGlslText(fused.lang)) {
      std::map<std::string, long long> defines(fused.defines.begin(), fused.defines.end());
      EXPECT_FALSE(defines.contains("BINDING_PALETTE")) << key;
      EXPECT_EQ(defines["BINDING_CLIPS"], defines["BINDING_FRAMES"] + 2) << key;
    }
    EXPECT_EQ(PushConstantOffset(kAnimElapsed), kPushConstantBytes - 4);
  }
  const KernelSource local = Emit(ParseVariantKey("opencl.b4.soa.local"), 0, joints, instanced);
  const auto refused = [&](const KernelSource& skin, const PackedAnimation& animation, const std::string& expected) {
    try {
      (void)EmitFused(skin, animation.View());
      ADD_FAILURE() << "accepted: " << expected;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  refused(local, PackAnimation(fox), "the animation is sampled clips");
  refused(Emit(ParseVariantKey("opencl.b4.soa.global"), 0, joints, instanced), records, "storage is not local");
  refused(Emit(ParseVariantKey("opencl.b4.soa.local"), 0, joints + 1, instanced), records,
          "has " + std::to_string(joints + 1) + " joints, the animation " + std::to_string(joints));
  refused(EmitFused(local, records.View()), records, "fused already");
}

// Local and hybrid records fused: the work-group walks the hierarchy, so the
// kernel takes the nodes and the joints around the records (hybrid: the
// palette records after the local ones, as the palette kernel does), and the
// hierarchy's defines: its nodes, its rounds of pointer jumping, and the
// skin kernel's group as the walk's.
TEST(PaletteKernelBaked, AFusedSkinKernelOfLocalRecordsTakesTheHierarchyItWalks) {
  const SkinnedAsset& fox = TestAsset("Fox.gltf");
  EmitOptions instanced;
  instanced.instanced = true;
  instanced.max_instances = 4;
  for (const BakeSpace space : {BakeSpace::kLocal, BakeSpace::kHybrid}) {
    const PackedAnimation records = BakeAnimation(fox, 30.0, space);
    const int joints = static_cast<int>(records.joints.size());
    for (const char* key : {"opencl.b4.soa.local.wg64", "cuda.b4.aos.mat4.local.wg32", "glsl-compute.b4.soa-split.local.wg256",
                            "vulkan.b4.soa.local.normals.wg128"}) {
      const Variant variant = ParseVariantKey(key);
      const KernelSource fused = EmitFused(Emit(variant, 0, joints, instanced), records.View());
      std::vector<std::string> names;
      for (const KernelArgument& a : fused.arguments) names.push_back(a.name);
      std::vector<std::string> expected = {kAnimInputs[0], kAnimFrames, kAnimInputs[4], kAnimInputs[5], kAnimClips};
      if (space == BakeSpace::kHybrid) expected.insert(expected.begin() + 2, kAnimSteady);
      const auto first = std::find(names.begin(), names.end(), kAnimInputs[0]);
      ASSERT_NE(first, names.end()) << key;
      EXPECT_EQ(std::vector<std::string>(first, first + static_cast<std::ptrdiff_t>(expected.size())), expected) << key;
      EXPECT_EQ(names.back(), kAnimElapsed) << key;
      const std::map<std::string, long long> defines(fused.defines.begin(), fused.defines.end());
      EXPECT_EQ(defines.at("ANIM_BAKED"), BakedDefine(records.View())) << key;
      EXPECT_EQ(defines.at("ANIM_NODE_COUNT"), static_cast<long long>(records.nodes.size())) << key;
      EXPECT_EQ(defines.at("ANIM_JUMPS"), AnimJumpRounds(records.nodes)) << key;
      EXPECT_EQ(defines.at("ANIM_GROUP"), variant.wg_size) << key;
      EXPECT_EQ(defines.at("ANIM_STEADY"), space == BakeSpace::kHybrid ? records.steady_rows : 0u) << key;
      for (const std::string& name : expected)  // what the runner uploads by name; instances are the frame's
        if (name != kAnimInputs[5]) {
          EXPECT_FALSE(AnimationBufferBytes(records.View(), name).empty()) << key << ": " << name;
        }
    }
  }
}

// The hierarchy kernels compose each node's global transform by pointer
// jumping: ceil(log2(depth + 1)) rounds for the deepest node's ancestors
// (after round r a node has joined its 2^r-th ancestor), a define of the
// emitted kernel.
TEST(PaletteKernel, PointerJumpingTakesTheRoundsTheDeepestChainNeeds) {
  const auto chain = [](int depth) {  // depth + 1 nodes, each the child of the one before
    std::vector<AnimNodeRecord> nodes(static_cast<std::size_t>(depth) + 1);
    for (std::size_t n = 1; n < nodes.size(); ++n) nodes[n].parent = static_cast<std::int32_t>(n) - 1;
    return nodes;
  };
  for (const auto& [depth, rounds] : {std::pair{0, 0}, {1, 1}, {2, 2}, {3, 2}, {4, 3}, {7, 3}, {8, 4}, {64, 7}, {511, 9}})
    EXPECT_EQ(AnimJumpRounds(chain(depth)), rounds) << depth;
  std::vector<AnimNodeRecord> cycle = chain(3);
  cycle[0].parent = 3;  // refused by the validation; the count still ends
  EXPECT_LE(AnimJumpRounds(cycle), 3);
  for (const char* model : {"CesiumMan.gltf", "Fox.gltf", "RiggedSimple.gltf", "2000-b4"})
    std::printf("[ palette  ] %s: %d rounds of pointer jumping\n", model,
                AnimJumpRounds(PackAnimation(TestAsset(model)).nodes));
  const PackedAnimation deep = PackAnimation(DeepRig());
  const int rounds = AnimJumpRounds(deep.nodes);
  // The order of the nodes is not the hierarchy's: every child of the reversed rig comes before its parent.
  const PackedAnimation reversed = PackAnimation(testing::ReversedDeepRig());
  for (std::size_t n = 0; n + 1 < reversed.nodes.size(); ++n) EXPECT_GT(reversed.nodes[n].parent, static_cast<int>(n)) << n;
  EXPECT_EQ(AnimJumpRounds(reversed.nodes), rounds);
  EXPECT_GE(rounds, 6);  // chains 64 deep
  EXPECT_NE(EmitPalette(Lang::kOpenCl, deep.View(), 3).kernel.text.find("#define ANIM_JUMPS " + std::to_string(rounds) + "\n"),
            std::string::npos);
}

// What a skin kernel reads: the packer's mat3x4 palette rows (PackPalette of
// the host's float32 palette, SkinnedAsset::PaletteAt), K instances one after
// another, element for element, from the palette kernel as it is.
TEST(PaletteKernel, OutputIsThePackersMat3x4PaletteOfEachInstanceInTurn) {
  const SkinnedAsset& asset = TestAsset("CesiumMan.gltf");
  const PackedAnimation packed = PackAnimation(asset);
  const std::vector<AnimInstance> instances = {AnimInstance{0, kAnimRestPose, 0.25f, 0.0f, 0.0f},
                                               AnimInstance{kAnimRestPose, kAnimRestPose, 0.0f, 0.0f, 0.0f},
                                               AnimInstance{0, kAnimRestPose, 1.5f, 0.0f, 0.0f}};
  std::vector<std::uint8_t> expected;
  for (const AnimInstance& in : instances) {
    const std::vector<std::uint8_t> rows =
        PackPalette(asset.PaletteAt(in.clip == kAnimRestPose ? -1 : 0, in.time), ParseVariantKey("opencl.mat3x4"));
    expected.insert(expected.end(), rows.begin(), rows.end());
  }
  const std::vector<float> rows = OnCpu(packed, instances);
  ASSERT_EQ(rows.size() * sizeof(float), expected.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    float want = 0.0f;
    std::memcpy(&want, expected.data() + 4 * k, 4);
    EXPECT_NEAR(rows[k], want, 1e-5) << "float " << k << ": instance " << k / (packed.joints.size() * 12) << ", joint "
                                     << k / 12 % packed.joints.size() << ", row " << k / 4 % 3 << ", column " << k % 4;
  }
}

// The point of the layout: an instanced skin kernel reads the palette
// kernel's output buffer on the device as it is, and skins every instance
// like the float64 gold skins the mesh with that instance's host palette.
TEST(PaletteKernel, OpenClSkinKernelReadsThePalettesOnTheDeviceAsTheyAre) {
  SKIP_WITHOUT_OPENCL(kernel);
  const SkinnedAsset& asset = TestAsset("CesiumMan.gltf");
  const PackedAnimation packed = PackAnimation(asset);
  const Variant variant = ParseVariantKey("opencl.aos.mat3x4.global");
  const PackedMesh mesh = Pack(asset.mesh, variant);
  const KernelSource skin = Emit(variant, 0, static_cast<int>(packed.joints.size()), EmitOptions{.instanced = true});
  const std::vector<AnimInstance> instances = {AnimInstance{0, kAnimRestPose, 0.3f, 0.0f, 0.0f},
                                               AnimInstance{kAnimRestPose, kAnimRestPose, 0.0f, 0.0f, 0.0f},
                                               AnimInstance{0, kAnimRestPose, 1.7f, 0.0f, 0.0f}};
  const std::vector<std::uint8_t> positions = kernel->Skin(packed, instances, mesh, skin);
  const std::size_t bytes = mesh.vertex_count * mesh.output_stride_bytes;
  for (std::size_t i = 0; i < instances.size(); ++i) {
    const std::vector<glm::vec3> out = Unpack(mesh, std::span<const std::uint8_t>(positions).subspan(i * bytes, bytes));
    const int clip = instances[i].clip == kAnimRestPose ? -1 : 0;
    const GoldComparison c =
        CompareToGold(SkinGold(asset.mesh, asset.PaletteAt(clip, instances[i].time)).positions, out);
    std::printf("[ palette  ] CesiumMan.gltf instance %zu skinned from device palettes: max relative error %.3g\n", i,
                c.max_relative);
    EXPECT_EQ(c.non_finite, 0u) << "instance " << i;
    EXPECT_LT(c.max_relative, 1e-5) << "instance " << i << " vertex " << c.worst_vertex;
  }
}

// The work-group every template is written for is the one the runtime
// launches: ANIM_GROUP, 3 x the nodes rounded up to 32 within 64..256.
TEST(PaletteKernel, EveryTemplatesWorkGroupIsTheLaunchedOne) {
  EXPECT_EQ(AnimGroupFor(1), 64);
  EXPECT_EQ(AnimGroupFor(22), 96);
  EXPECT_EQ(AnimGroupFor(78), 256);
  EXPECT_EQ(AnimGroupFor(512), 256);
  const PackedAnimation packed = PackAnimation(TestAsset("Fox.gltf"));
  const int expected = AnimGroupFor(packed.nodes.size());
  for (Lang lang : {Lang::kOpenCl, Lang::kCuda, Lang::kGlslCompute, Lang::kVulkan}) {
    const PaletteKernel kernel = EmitPalette(lang, packed.View(), 3);
    EXPECT_EQ(kernel.kernel.launch.wg_size, expected);
    EXPECT_EQ(kernel.variant.wg_size, expected);
    const std::string declared = "#define ANIM_GROUP " + std::to_string(expected) + "\n";
    EXPECT_NE(kernel.kernel.text.find(declared), std::string::npos) << Name(lang) << ": no '" << declared << "'";
    const std::string used = IsGlslText(kernel.kernel.lang) ? "layout(local_size_x = ANIM_GROUP) in;"
                             : lang == Lang::kCuda          ? "__launch_bounds__(ANIM_GROUP)"
                                                            : "reqd_work_group_size(ANIM_GROUP, 1, 1)";
    EXPECT_NE(kernel.kernel.text.find(used), std::string::npos) << Name(lang) << ": no '" << used << "'";
  }
  EXPECT_THROW(EmitPalette(Lang::kOpenCl, packed.View(), 5), Error);
}

TEST(PaletteKernel, CpuRefusesBadInstancesNamingTheInstanceAndField) {
  const PackedAnimation packed = PackAnimation(TestAsset("Fox.gltf"));  // 3 clips
  auto error_of = [&](const AnimInstance& bad) {
    const std::vector<AnimInstance> instances = {AnimInstance{}, bad};
    std::vector<float> rows(instances.size() * packed.joints.size() * 12);
    try {
      RunPaletteKernel(packed.View(), instances, rows.data());
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error_of(AnimInstance{3, kAnimRestPose, 0.0f, 0.0f, 0.0f}),
            "instances[1]: clip 3 out of range (3 clips packed; 65535 is the rest pose)");
  EXPECT_EQ(error_of(AnimInstance{0, 9, 0.0f, 0.0f, 0.5f}),
            "instances[1]: clip2 9 out of range (3 clips packed; 65535 is the rest pose)");
  EXPECT_EQ(error_of(AnimInstance{0, kAnimRestPose, NAN, 0.0f, 0.0f}), "instances[1]: time nan is not finite");
  EXPECT_EQ(error_of(AnimInstance{0, 1, 0.0f, INFINITY, 0.5f}), "instances[1]: time2 inf is not finite");
  EXPECT_EQ(error_of(AnimInstance{0, 1, 0.0f, 0.0f, 1.5f}), "instances[1]: weight 1.5 outside [0, 1]");
  EXPECT_EQ(error_of(AnimInstance{0, 1, 0.0f, 0.0f, NAN}), "instances[1]: weight nan is not finite");
  // clip2 and time2 are not read at weight 0: whatever they hold is no error.
  EXPECT_EQ(error_of(AnimInstance{0, 9, 0.0f, NAN, 0.0f}), "no error");
}

}  // namespace
}  // namespace skintune::internal
