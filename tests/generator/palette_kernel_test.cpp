// The palette kernel (cpu_kernels/palette_kernel.h on the CPU, templates/palette.cl
// on the first OpenCL device) against the float64 gold: the model's own sampling
// (SkinnedAsset::PoseAt) and composition (Skeleton::PaletteD).
//
// The bound: for joint j with gold palette entry P_j = G_j * IB_j (G_j the
// joint's global transform, IB_j its inverse bind matrix), the largest
// |kernel - gold| over P_j's 12 entries must be at most 1e-5 * s_j with
//   s_j = max(1, the Euclidean norms of P_j's four columns (three 3x3 columns
//             and the translation), of G_j's translation, of IB_j's translation).
// The translations of G_j and IB_j are in s_j because float32 cannot do better:
// at a bind pose P_j's translation is G_j's plus G_j's 3x3 times IB_j's, two
// vectors of the model's size that cancel to ~0, so its rounding error is
// float32's epsilon times the model's size (Fox, ~100 units: 1.4e-5 at rest,
// against a P_j of unit scale). Each test prints its worst error over this
// bound and over the bound without those two terms (1e-5 * max(1, P_j's
// column norms)), so both are on record.
#include <gtest/gtest.h>
#define CL_TARGET_OPENCL_VERSION 120  // clCreateCommandQueue, as runtime/backends/opencl does
#include <CL/cl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "base/error.h"
#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "generator/emit.h"
#include "tests/common/test_asset.h"
#include "tests/generator/deep_rig.h"

namespace skintune::internal {
namespace {

using testing::DeepRig;
using testing::TestAsset;

// ------------------------------------------------------------- the gold

// One instance's float64 pose: each clip's pose (the rest pose for
// kAnimRestPose) blended in local space (T, S lerped; R nlerped along the
// shortest path).
Pose GoldPose(const SkinnedAsset& asset, const PackedAnimation& packed, const AnimInstance& in) {
  auto pose_of = [&](std::uint16_t clip, float t) {
    return asset.PoseAt(clip == kAnimRestPose ? -1 : packed.clips[clip], static_cast<double>(t));
  };
  Pose pose = pose_of(in.clip, in.time);
  if (in.weight == 0.0f) return pose;
  const Pose other = pose_of(in.clip2, in.time2);
  const double w = in.weight;
  for (std::size_t n = 0; n < pose.size(); ++n) {
    Transform& a = pose[n];
    const glm::dquat ra = glm::normalize(a.rotation);
    glm::dquat rb = glm::normalize(other[n].rotation);
    if (glm::dot(ra, rb) < 0.0) rb = -rb;
    a.translation = glm::mix(a.translation, other[n].translation, w);
    a.scale = glm::mix(a.scale, other[n].scale, w);
    a.rotation = glm::normalize(glm::lerp(ra, rb, w));
  }
  return pose;
}

struct Worst {
  double ratio = 0.0;  // largest error / bound seen
  double error = 0.0, bound = 0.0;
  std::string where;
  double ratio_palette_only = 0.0;  // largest error / (1e-5 * max(1, P_j's column norms))
};

double ColumnNorm(const glm::dmat4& m, int c) { return glm::length(glm::dvec3(m[c])); }

// Compares K palettes (kernel rows) with their golds; returns the worst
// error relative to its bound, with where it is.
Worst Compare(const SkinnedAsset& asset, const PackedAnimation& packed, const std::vector<AnimInstance>& instances,
              const std::vector<float>& rows) {
  const std::size_t joints = packed.joints.size();
  EXPECT_EQ(rows.size(), instances.size() * joints * 12);
  Worst worst;
  const Skeleton& skeleton = asset.skeleton;
  for (std::size_t i = 0; i < instances.size() && rows.size() == instances.size() * joints * 12; ++i) {
    const Pose pose = GoldPose(asset, packed, instances[i]);
    const std::vector<glm::dmat4> gold = skeleton.PaletteD(pose), global = skeleton.GlobalTransforms(pose);
    for (std::size_t j = 0; j < joints; ++j) {
      double palette_scale = 1.0, error = 0.0;
      for (int c = 0; c < 4; ++c) palette_scale = std::max(palette_scale, ColumnNorm(gold[j], c));
      const double scale = std::max({palette_scale, ColumnNorm(global[static_cast<std::size_t>(skeleton.joints[j])], 3),
                                     ColumnNorm(skeleton.inverse_bind[j], 3)});
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
          const double v = rows[(i * joints + j) * 12 + 4 * r + c];
          error = std::isfinite(v) ? std::max(error, std::fabs(v - gold[j][c][r])) : INFINITY;
        }
      const double bound = 1e-5 * scale;
      worst.ratio_palette_only = std::max(worst.ratio_palette_only, error / (1e-5 * palette_scale));
      if (error / bound > worst.ratio || !std::isfinite(error)) {
        char where[200];
        std::snprintf(where, sizeof where, "instance %zu (clip %d, t=%.9g; clip2 %d, t2=%.9g, w=%g), joint %zu", i,
                      instances[i].clip, instances[i].time, instances[i].clip2, instances[i].time2, instances[i].weight, j);
        worst = Worst{error / bound, error, bound, where, worst.ratio_palette_only};
      }
    }
  }
  return worst;
}

void ExpectWithinBound(const std::string& what, const Worst& worst) {
  std::printf("[ palette  ] %s: max error / bound %.3g (error %.3g, bound %.3g at %s); without the translations "
              "of G and IB in the bound: %.3g\n",
              what.c_str(), worst.ratio, worst.error, worst.bound, worst.where.c_str(), worst.ratio_palette_only);
  EXPECT_LE(worst.ratio, 1.0) << what << ": error " << worst.error << " > bound " << worst.bound << " at " << worst.where;
}

// ------------------------------------------------------------- the instances

// Times of `clip` that cover every case of sampling: before its first key,
// on its first and last keys, on an inner key of a channel, between two keys
// (a midpoint and a quarter point) and after its last key.
std::vector<float> TimesOf(const AnimationClip& clip) {
  std::vector<float> times = {static_cast<float>(clip.start - 0.5), static_cast<float>(clip.start),
                              static_cast<float>(clip.end), static_cast<float>(clip.end + 1.0)};
  for (const Channel* c : {&clip.channels.front(), &clip.channels[clip.channels.size() / 2], &clip.channels.back()}) {
    const std::size_t n = c->times.size();
    if (n < 2) continue;
    const std::size_t k = n >= 3 ? n / 2 : 0;  // an inner key where there is one; k + 1 < n
    times.push_back(c->times[k]);
    times.push_back(c->times[k] + 0.5f * (c->times[k + 1] - c->times[k]));
    times.push_back(c->times[0] + 0.25f * (c->times[1] - c->times[0]));
  }
  return times;
}

// One instance per (clip, time) of TimesOf: every clip alone.
std::vector<AnimInstance> EveryClipAlone(const SkinnedAsset& asset, const PackedAnimation& packed) {
  std::vector<AnimInstance> instances;
  for (std::size_t c = 0; c < packed.clips.size(); ++c)
    for (const float t : TimesOf(asset.animations[static_cast<std::size_t>(packed.clips[c])]))
      instances.push_back(AnimInstance{static_cast<std::uint16_t>(c), kAnimRestPose, t, 0.0f, 0.0f});
  instances.push_back(AnimInstance{kAnimRestPose, kAnimRestPose, 0.0f, 0.0f, 0.0f});
  return instances;
}

// Two-clip blends: clip c with clip (c + 1) % clips (the rest pose when there
// is one clip) at weights from 0.1 to 1, each clip at its own time.
std::vector<AnimInstance> Blends(const SkinnedAsset& asset, const PackedAnimation& packed) {
  std::vector<AnimInstance> instances;
  const std::size_t clips = packed.clips.size();
  for (std::size_t c = 0; c < clips; ++c) {
    const std::uint16_t other = clips > 1 ? static_cast<std::uint16_t>((c + 1) % clips) : kAnimRestPose;
    const std::vector<float> times = TimesOf(asset.animations[static_cast<std::size_t>(packed.clips[c])]);
    const std::vector<float> times2 =
        other == kAnimRestPose ? times : TimesOf(asset.animations[static_cast<std::size_t>(packed.clips[other])]);
    for (std::size_t k = 0; k < times.size(); ++k) {
      const float w = 0.1f + 0.9f * static_cast<float>(k) / static_cast<float>(times.size() - 1);
      instances.push_back(AnimInstance{static_cast<std::uint16_t>(c), other, times[k], times2[(k * 3 + 1) % times2.size()], w});
    }
  }
  return instances;
}

std::vector<float> OnCpu(const PackedAnimation& packed, const std::vector<AnimInstance>& instances) {
  std::vector<float> rows(instances.size() * packed.joints.size() * 12);
  RunPaletteKernel(packed.View(), instances, rows.data());
  return rows;
}

// ------------------------------------------------------------- OpenCL

void Check(cl_int err, const char* what) {
  if (err != CL_SUCCESS) throw std::runtime_error(std::string(what) + " failed: " + std::to_string(err));
}

// templates/palette.cl built once on the first OpenCL device (PoCL here).
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
    clReleaseKernel(kernel_);
    clReleaseProgram(program_);
    clReleaseCommandQueue(queue_);
    clReleaseContext(context_);
  }

  // Instance i's palette rows, as RunPaletteKernel writes them; launched with
  // work-groups of `wg` joints (the global size rounded up to it).
  std::vector<float> Run(const PackedAnimation& packed, const std::vector<AnimInstance>& instances, std::size_t wg = 64) {
    const AnimationView view = packed.View();
    std::vector<cl_mem> buffers = {Upload(BufferBytes(packed.nodes)), Upload(BufferBytes(packed.channels)),
                                   Upload(BufferBytes(packed.times)), Upload(BufferBytes(packed.values)),
                                   Upload(BufferBytes(packed.joints)), Upload(BufferBytes(instances))};
    const std::size_t joints = packed.joints.size();
    std::vector<float> rows(instances.size() * joints * 12);
    cl_int err = CL_SUCCESS;
    cl_mem out = clCreateBuffer(context_, CL_MEM_WRITE_ONLY, rows.size() * sizeof(float), nullptr, &err);
    Check(err, "clCreateBuffer");
    const cl_uint scalars[] = {static_cast<cl_uint>(view.nodes.size()), static_cast<cl_uint>(joints), view.clip_count,
                               static_cast<cl_uint>(instances.size())};
    cl_uint arg = 0;
    for (const cl_uint& s : scalars) Check(clSetKernelArg(kernel_, arg++, sizeof s, &s), "clSetKernelArg");
    for (const cl_mem& b : buffers) Check(clSetKernelArg(kernel_, arg++, sizeof b, &b), "clSetKernelArg");
    Check(clSetKernelArg(kernel_, arg++, sizeof out, &out), "clSetKernelArg");
    const std::size_t global[2] = {(joints + wg - 1) / wg * wg, instances.size()}, local[2] = {wg, 1};
    Check(clEnqueueNDRangeKernel(queue_, kernel_, 2, nullptr, global, local, 0, nullptr, nullptr), "clEnqueueNDRangeKernel");
    Check(clEnqueueReadBuffer(queue_, out, CL_TRUE, 0, rows.size() * sizeof(float), rows.data(), 0, nullptr, nullptr),
          "clEnqueueReadBuffer");
    clReleaseMemObject(out);
    for (cl_mem b : buffers) clReleaseMemObject(b);
    return rows;
  }

 private:
  explicit OpenClPaletteKernel(cl_device_id device) : device_(device) {
    cl_int err = CL_SUCCESS;
    context_ = clCreateContext(nullptr, 1, &device_, nullptr, nullptr, &err);
    Check(err, "clCreateContext");
    queue_ = clCreateCommandQueue(context_, device_, 0, &err);
    Check(err, "clCreateCommandQueue");
    const std::string text = ExpandedTemplate("palette.cl");
    const char* source = text.c_str();
    const std::size_t length = text.size();
    program_ = clCreateProgramWithSource(context_, 1, &source, &length, &err);
    Check(err, "clCreateProgramWithSource");
    if (clBuildProgram(program_, 1, &device_, "-cl-std=CL1.2", nullptr, nullptr) != CL_SUCCESS) {
      std::size_t size = 0;
      clGetProgramBuildInfo(program_, device_, CL_PROGRAM_BUILD_LOG, 0, nullptr, &size);
      std::string log(size, '\0');
      clGetProgramBuildInfo(program_, device_, CL_PROGRAM_BUILD_LOG, size, log.data(), nullptr);
      throw std::runtime_error("palette.cl does not build: " + log);
    }
    kernel_ = clCreateKernel(program_, "skintune_palette", &err);
    Check(err, "clCreateKernel");
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
  cl_program program_ = nullptr;
  cl_kernel kernel_ = nullptr;
};

#define SKIP_WITHOUT_OPENCL(kernel)            \
  std::string why;                             \
  OpenClPaletteKernel* kernel = OpenClPaletteKernel::Get(why); \
  if (kernel == nullptr) GTEST_SKIP() << why

std::string Name(const SkinnedAsset& asset) { return asset.source.substr(asset.source.find_last_of('/') + 1); }

const char* const kModels[] = {"CesiumMan.gltf", "Fox.gltf", "RiggedSimple.gltf"};

// ------------------------------------------------------------- the tests

TEST(PaletteKernel, CpuMatchesTheGoldForEveryClipOfTheGltfModels) {
  for (const char* model : kModels) {
    const SkinnedAsset& asset = TestAsset(model);
    const PackedAnimation packed = PackAnimation(asset);
    const std::vector<AnimInstance> instances = EveryClipAlone(asset, packed);
    ExpectWithinBound(std::string(model) + " cpu", Compare(asset, packed, instances, OnCpu(packed, instances)));
  }
}

TEST(PaletteKernel, CpuMatchesTheGoldOnADeepRigWithEveryInterpolation) {
  const PackedAnimation packed = PackAnimation(DeepRig());
  const std::vector<AnimInstance> instances = EveryClipAlone(DeepRig(), packed);
  ExpectWithinBound("deep rig cpu", Compare(DeepRig(), packed, instances, OnCpu(packed, instances)));
}

TEST(PaletteKernel, CpuBlendsTwoClipsInLocalSpaceLikeTheGold) {
  for (const SkinnedAsset* asset : {&TestAsset("Fox.gltf"), &TestAsset("CesiumMan.gltf"), &DeepRig()}) {
    const PackedAnimation packed = PackAnimation(*asset);
    const std::vector<AnimInstance> instances = Blends(*asset, packed);
    ExpectWithinBound(Name(*asset) + " cpu blends", Compare(*asset, packed, instances, OnCpu(packed, instances)));
  }
}

TEST(PaletteKernel, OpenClMatchesTheGoldForEveryClipOfTheGltfModels) {
  SKIP_WITHOUT_OPENCL(kernel);
  for (const char* model : kModels) {
    const SkinnedAsset& asset = TestAsset(model);
    const PackedAnimation packed = PackAnimation(asset);
    const std::vector<AnimInstance> instances = EveryClipAlone(asset, packed);
    ExpectWithinBound(std::string(model) + " opencl", Compare(asset, packed, instances, kernel->Run(packed, instances)));
  }
}

TEST(PaletteKernel, OpenClMatchesTheGoldOnADeepRigWithEveryInterpolation) {
  SKIP_WITHOUT_OPENCL(kernel);
  const PackedAnimation packed = PackAnimation(DeepRig());
  const std::vector<AnimInstance> instances = EveryClipAlone(DeepRig(), packed);
  ExpectWithinBound("deep rig opencl", Compare(DeepRig(), packed, instances, kernel->Run(packed, instances)));
  // Work-groups of 32 over 321 joints: the last group's items beyond the joints write nothing.
  ExpectWithinBound("deep rig opencl wg32", Compare(DeepRig(), packed, instances, kernel->Run(packed, instances, 32)));
}

TEST(PaletteKernel, OpenClBlendsTwoClipsInLocalSpaceLikeTheGold) {
  SKIP_WITHOUT_OPENCL(kernel);
  for (const SkinnedAsset* asset : {&TestAsset("Fox.gltf"), &TestAsset("CesiumMan.gltf"), &DeepRig()}) {
    const PackedAnimation packed = PackAnimation(*asset);
    const std::vector<AnimInstance> instances = Blends(*asset, packed);
    ExpectWithinBound(Name(*asset) + " opencl blends", Compare(*asset, packed, instances, kernel->Run(packed, instances)));
  }
}

TEST(PaletteKernel, OpenClWritesNanRowsForAClipOutOfRangeInsteadOfReadingBeyond) {
  SKIP_WITHOUT_OPENCL(kernel);
  const SkinnedAsset& asset = TestAsset("Fox.gltf");
  const PackedAnimation packed = PackAnimation(asset);
  const std::vector<AnimInstance> instances = {AnimInstance{1, kAnimRestPose, 0.5f, 0.0f, 0.0f},
                                               AnimInstance{3, kAnimRestPose, 0.5f, 0.0f, 0.0f},
                                               AnimInstance{0, 7, 0.5f, 0.5f, 0.5f}};
  const std::vector<float> rows = kernel->Run(packed, instances);
  const std::size_t per_instance = packed.joints.size() * 12;
  for (std::size_t i = 0; i < instances.size(); ++i) {
    const auto first = rows.begin() + static_cast<std::ptrdiff_t>(i * per_instance);
    const std::size_t nans = static_cast<std::size_t>(std::count_if(first, first + static_cast<std::ptrdiff_t>(per_instance),
                                                                     [](float v) { return std::isnan(v); }));
    EXPECT_EQ(nans, i == 0 ? 0 : per_instance) << "instance " << i;
  }
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
