// Every OpenCL variant axis value, run on a real OpenCL device (PoCL in CI)
// against the float64 gold, on a fresh random synthetic mesh each run (the
// seed is printed; SKINTUNE_TEST_SEED=<n> reproduces a run) and on CesiumMan
// for the bucketed launches. Plus: the poisoned output catches a kernel that
// skips vertices, the guard one that writes past the end, and a build error
// carries its log.
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <thread>
#include <type_traits>
#include <vector>

#include "runner_test_support.h"
#include "runtime/backends/opencl/opencl_devices.h"
#include "runtime/backends/opencl/opencl_runner.h"
#include "runtime/program_cache.h"
#include "runtime/run_shape.h"

namespace skintune::internal {
namespace {

using testing::Asset;
using testing::Case;
using testing::CaseName;
using testing::ExpectCaseMatchesGold;
using testing::ExpectCoveringSetMatchesGold;
using testing::ExpectHalfPoisoned;
using testing::ExpectRunMatchesGold;
using testing::ExpectRunFails;
using testing::ErrorOf;
using testing::Faulty;
using testing::LaunchTimes;
using testing::Seed;
using testing::WithFault;
using testing::InstanceCase;
using testing::InstanceCaseName;
using testing::InstancedRun;
using testing::WithInstanceCounts;
using testing::WithInstancedFault;

// The device these tests run on: the first OpenCL device, or the first whose
// "platform-vendor platform / name" contains $SKINTUNE_TEST_OPENCL_DEVICE.
// Null (with the reason) when the machine has none.
const OpenClDeviceInfo* TestDevice(std::string& why) {
  static std::string reason;
  static const std::vector<OpenClDeviceInfo> devices = [] {
    const char* pattern = std::getenv("SKINTUNE_TEST_OPENCL_DEVICE");
    const OpenClInventory inventory = EnumerateOpenCl();
    std::vector<OpenClDeviceInfo> found = MatchDevices(inventory, pattern ? pattern : "");
    if (found.empty()) {
      reason = pattern ? "no OpenCL device matches SKINTUNE_TEST_OPENCL_DEVICE='" + std::string(pattern) + "'"
                       : "no OpenCL device on this machine: " + inventory.status;
    }
    return found;
  }();
  why = reason;
  return devices.empty() ? nullptr : &devices.front();
}

OpenClRunner* Runner(std::string& why) {
  static std::unique_ptr<OpenClRunner> runner = [&why]() -> std::unique_ptr<OpenClRunner> {
    const OpenClDeviceInfo* d = TestDevice(why);
    return d ? std::make_unique<OpenClRunner>(d->platform_index, d->device_index) : nullptr;
  }();
  if (!runner) {
    TestDevice(why);
    // An explicitly requested device that is missing is a failure, not a skip.
    if (std::getenv("SKINTUNE_TEST_OPENCL_DEVICE")) ADD_FAILURE() << why;
  }
  return runner.get();
}

class OpenClVariant : public ::testing::TestWithParam<Case> {};

TEST_P(OpenClVariant, MatchesTheGold) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const Case& c = GetParam();
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + ", seed " + std::to_string(Seed()) +
               " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name());
  ExpectCaseMatchesGold(*runner, c, ParseVariantKey(c.key), LaunchTimes::kAny);
}

// Every value of every axis at least once; every layout with every index
// format, every weight format and every storage.
const Case kCases[] = {
    // layout x index x weight
    {"opencl.b4.padded.aos.float4.i32.f32.mat4.constant.matrix.v1c.wg64.nonormals", "b4"},
    {"opencl.b3.padded.aos.float3.u16.unorm16.mat3x4.local.point.v2c.wg32.normals", "b3"},
    {"opencl.b1.padded.aos.float4.u8.unorm8.mat3x4.image.matrix.v4s.wg256.normals", "b1"},
    {"opencl.b2.padded.soa.float3.i32.unorm16.mat3x4.global.point.v8c.wg128.nonormals", "b2"},
    {"opencl.b5.padded.soa.float4.u16.unorm8.mat4.image.matrix.v2s.wg64.normals", "b5-random"},
    {"opencl.b8.padded.soa.float3.u8.f32.mat4.local.matrix.v1c.wg1024.nonormals", "b8"},
    {"opencl.b6.padded.soa-split.float4.i32.unorm8.mat3x4.constant.point.v4c.wg32.normals", "b6-random"},
    {"opencl.b7.padded.soa-split.float3.u16.f32.mat4.global.matrix.v8s.wg512.nonormals", "b7"},
    {"opencl.b4.padded.soa-split.float4.u8.unorm16.mat3x4.local.matrix.v2c.wg256.normals", "b4"},
    // the storage each layout has not seen yet
    {"opencl.b4.padded.aos.float3.u16.unorm8.mat4.global.point.v1c.wg128.normals", "b4"},
    {"opencl.b4.padded.soa.float4.u16.f32.mat3x4.constant.matrix.v1c.wg128.normals", "b4-random"},
    {"opencl.b3.padded.soa-split.float3.u8.unorm8.mat4.image.point.v4s.wg64.normals", "b3"},
    // padding: more slots than the mesh uses
    {"opencl.b8.padded.aos.float4.i32.f32.mat3x4.global.matrix.v1c.wg128.nonormals", "b3"},
    {"opencl.b4.padded.soa-split.float3.u8.f32.mat3x4.constant.matrix.v2c.wg64.normals", "cesium"},
    // bucketed: one launch per influence count, each with its own kernel
    {"opencl.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.normals", "cesium"},
    {"opencl.b4.bucketed.aos.float3.u8.unorm8.mat4.local.point.v2s.wg64.normals", "cesium"},
    {"opencl.b4.bucketed.soa-split.float4.u16.unorm16.mat3x4.image.matrix.v4c.wg32.nonormals", "cesium"},
    {"opencl.b2.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v8s.wg256.nonormals", "b2"},
    {"opencl.b4.bucketed.soa.float3.i32.unorm16.mat4.constant.point.v8s.wg512.normals", "cesium"},
    {"opencl.b6.bucketed.soa-split.float3.u8.unorm8.mat4.local.point.v2c.wg64.normals", "cesium"},
    {"opencl.b8.padded.soa.float4.u16.unorm16.mat4.global.matrix.v1c.wg128.normals", "cesium"},
    // more crossings: point blend with every storage and layout, local copies with large groups
    {"opencl.b4.padded.aos.float4.u8.f32.mat3x4.constant.point.v8s.wg256.normals", "b4"},
    {"opencl.b2.padded.aos.float3.i32.unorm16.mat4.image.point.v2c.wg512.nonormals", "b2"},
    {"opencl.b6.padded.aos.float4.u16.unorm8.mat4.local.matrix.v4c.wg1024.normals", "b6"},
    {"opencl.b1.padded.soa.float4.u8.unorm16.mat4.constant.point.v4s.wg32.normals", "b1"},
    {"opencl.b3.padded.soa.float3.u16.f32.mat3x4.local.point.v8s.wg256.normals", "b3-random"},
    {"opencl.b7.padded.soa.float4.i32.unorm8.mat3x4.image.point.v1c.wg64.normals", "b7"},
    {"opencl.b8.padded.soa-split.float4.u16.f32.mat4.local.point.v8c.wg128.normals", "b8-random"},
    {"opencl.b5.padded.soa-split.float3.i32.unorm16.mat3x4.constant.matrix.v2s.wg1024.normals", "b5"},
    {"opencl.b1.padded.soa-split.float4.u8.unorm8.mat3x4.global.point.v1c.wg32.normals", "b1"},
};

INSTANTIATE_TEST_SUITE_P(EveryAxis, OpenClVariant, ::testing::ValuesIn(kCases), CaseName);

// The generated covering set for this device (generator/covering.h): every
// value of every axis and every pair of layout x index x weight x palette x
// storage x blend, each variant on a fresh mesh with its own influence count.
TEST(OpenClCoveringSet, EveryVariantMatchesTheGold) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const DeviceLimits limits = LimitsOf(*TestDevice(why));
  const CoveringSet set = BuildCoveringSet(Lang::kOpenCl, limits, testing::CoveringShape());
  ASSERT_TRUE(set.uncoverable.empty());
  ExpectCoveringSetMatchesGold(*runner, set, LaunchTimes::kAny);
  std::cout << "[ covering ] " << set.variants.size() << " OpenCL variants verified on " << runner->device_name()
            << "\n";
}

// The faulty kernels: one padded soa launch (WithFault).
constexpr const char* kFaultKey = "opencl.b2.soa.float4.u16.f32.wg64";

TEST(OpenClRunner, PoisonedOutputCatchesAKernelThatSkipsVertices) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault(kFaultKey, "if (v >= n) break;", "if (v >= n / 2) break;");
  ExpectHalfPoisoned(f, runner->Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant)));
}

TEST(OpenClRunner, GuardCatchesAKernelThatWritesPastTheEnd) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault(kFaultKey, "STORE_XYZ(out_positions, out_first + v,", "STORE_XYZ(out_positions, out_first + v + 64,");
  ExpectRunFails(*runner, f, "a kernel writing 64 vertices past its output was not caught",
                 {"OpenCL guard", "out_positions", "wrote past the end"});
}

TEST(OpenClRunner, BuildFailureCarriesTheBuildLog) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  Faulty f = WithFault(kFaultKey, "if (v >= n) break;", "if (v >= n) break; undeclared_name_xyz = 1;");
  ExpectRunFails(*runner, f, "a kernel with an undeclared name built", {"OpenCL build", "undeclared_name_xyz"});
}

// Runner::ConcurrentBuilds (the tuner compiles ahead into the measuring
// runner): four threads share eight kernels and build each once in the
// runner's one context, and the runs that follow find every one built and
// match the gold.
TEST(OpenClRunner, ConcurrentBuildsBuildEachKernelOnceThenRunsFindThem) {
  std::string why;
  const OpenClDeviceInfo* d = TestDevice(why);
  if (!d) GTEST_SKIP() << why;
  OpenClRunner runner(d->platform_index, d->device_index);
  ASSERT_TRUE(runner.ConcurrentBuilds());
  ProgramCache cache("-");  // no disk: every kernel is built from source, and counted
  runner.UseProgramCache(&cache, "test");
  std::vector<Variant> variants;
  for (const char* storage : {"global", "constant"})
    for (const char* wg : {"wg32", "wg64", "wg128", "wg256"})
      variants.push_back(ParseVariantKey(std::string("opencl.b2.padded.soa.float4.u16.f32.mat3x4.") + storage +
                                         ".matrix.v1c." + wg + ".nonormals"));
  std::vector<KernelSource> kernels;
  for (const Variant& v : variants) {
    const std::vector<KernelSource> emitted = EmitLaunchKernels(Pack(Asset("b2").mesh, v));
    ASSERT_EQ(emitted.size(), 1u);
    kernels.push_back(emitted.front());
  }
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (std::size_t i = next++; i < kernels.size(); i = next++) runner.Build(kernels[i]);
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(cache.counters().builds, 8);
  EXPECT_EQ(cache.counters().memory_hits, 0);
  for (const Variant& v : variants) ExpectRunMatchesGold(runner, v, "b2", LaunchTimes::kAny);
  EXPECT_EQ(cache.counters().builds, 8) << "a run built its kernel again";
  EXPECT_EQ(cache.counters().memory_hits, 8);
}

TEST(OpenClRunner, RejectsAPaletteOfTheWrongSizeAndAMissingDevice) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const PackedMesh packed = Pack(Asset("b2").mesh, ParseVariantKey("opencl.b2.soa"));
  const std::vector<std::uint8_t> short_palette(16);
  try {
    runner->Run(packed, short_palette);
    ADD_FAILURE() << "a 16-byte palette was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("palette has 16 bytes"), std::string::npos) << e.what();
  }
  try {
    OpenClRunner missing(0, 1000);
    ADD_FAILURE() << "device 1000 exists";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("OpenCL setup"), std::string::npos) << e.what();
  }
}

// The runner's own queue, which the Skinner's frames use, has no profiling
// (on NVIDIA a launch returning an event costs ~10.5 us of host time on a
// profiling queue, ~4.9 on one without: the H100 machine, 2026-11-27),
// and a verification run still has each launch timed by the device, on a
// profiling queue of its own: a run on the frames' queue would read 0 ms.
TEST(OpenClRunner, TheFramesQueueHasNoProfilingAndARunStillTimesEachLaunch) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  cl_command_queue_properties properties = 0;
  ASSERT_EQ(clGetCommandQueueInfo(static_cast<cl_command_queue>(runner->queue()), CL_QUEUE_PROPERTIES,
                                  sizeof properties, &properties, nullptr),
            CL_SUCCESS);
  EXPECT_EQ(properties & CL_QUEUE_PROFILING_ENABLE, 0u);
  ExpectRunMatchesGold(*runner, ParseVariantKey("opencl.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64"),
                       "cesium", LaunchTimes::kPositive);
}

// A cold frame's launch is timed from the END of the marker queued before it
// to the START of the marker queued after it, the launch itself without an
// event (runtime/backends/opencl/opencl_runner.cpp TimeCold says why), and
// each measurement's timing.clock says so.
TEST(OpenClRunner, TheKernelClockNamesTheMarkersThatBoundALaunchsTime) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  EXPECT_EQ(runner->api().kernel_clock(), "OpenCL profiling stamps: a marker's END to the next marker's START");
}

// An OpenCL object released with its clRelease* function.
template <class T>
using Owned = std::unique_ptr<std::remove_pointer_t<T>, cl_int (*)(T)>;

// What that clock rests on, on the device the tests run on: in one in-order
// profiling queue a kernel starts after the END of the marker before it and
// ends by the START of the marker after it, so the span between the two
// markers holds the kernel and neither marker's own work.
TEST(OpenClRunner, AKernelRunsBetweenTheMarkersQueuedAroundIt) {
  std::string why;
  const OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const cl_device_id id = static_cast<cl_device_id>(runner->device());
  const cl_context context = static_cast<cl_context>(runner->context());
  cl_int err = CL_SUCCESS;
  const Owned<cl_command_queue> queue(clCreateCommandQueue(context, id, CL_QUEUE_PROFILING_ENABLE, &err),
                                      clReleaseCommandQueue);
  ASSERT_EQ(err, CL_SUCCESS);
  const char* source = "kernel void add(global uint* x) { x[get_global_id(0)] += 1u; }";
  const Owned<cl_program> program(clCreateProgramWithSource(context, 1, &source, nullptr, &err), clReleaseProgram);
  ASSERT_EQ(err, CL_SUCCESS);
  ASSERT_EQ(clBuildProgram(program.get(), 1, &id, "", nullptr, nullptr), CL_SUCCESS);
  const Owned<cl_kernel> kernel(clCreateKernel(program.get(), "add", &err), clReleaseKernel);
  ASSERT_EQ(err, CL_SUCCESS);
  constexpr std::size_t kItems = 1u << 16;
  const Owned<cl_mem> buffer(clCreateBuffer(context, CL_MEM_READ_WRITE, kItems * sizeof(cl_uint), nullptr, &err),
                            clReleaseMemObject);
  ASSERT_EQ(err, CL_SUCCESS);
  const cl_mem argument = buffer.get();
  ASSERT_EQ(clSetKernelArg(kernel.get(), 0, sizeof argument, &argument), CL_SUCCESS);
  const auto stamp = [](cl_event e, cl_profiling_info which) {
    cl_ulong at = 0;
    EXPECT_EQ(clGetEventProfilingInfo(e, which, sizeof at, &at, nullptr), CL_SUCCESS);
    return at;
  };
  for (int frame = 0; frame < 20; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame) + " on " + runner->device_name());
    cl_event before = nullptr, launch = nullptr, after = nullptr;
    ASSERT_EQ(clEnqueueNDRangeKernel(queue.get(), kernel.get(), 1, nullptr, &kItems, nullptr, 0, nullptr, nullptr),
              CL_SUCCESS);
    ASSERT_EQ(clEnqueueMarkerWithWaitList(queue.get(), 0, nullptr, &before), CL_SUCCESS);
    ASSERT_EQ(clEnqueueNDRangeKernel(queue.get(), kernel.get(), 1, nullptr, &kItems, nullptr, 0, nullptr, &launch),
              CL_SUCCESS);
    ASSERT_EQ(clEnqueueMarkerWithWaitList(queue.get(), 0, nullptr, &after), CL_SUCCESS);
    ASSERT_EQ(clFinish(queue.get()), CL_SUCCESS);
    EXPECT_LE(stamp(before, CL_PROFILING_COMMAND_END), stamp(launch, CL_PROFILING_COMMAND_START));
    EXPECT_LE(stamp(launch, CL_PROFILING_COMMAND_START), stamp(launch, CL_PROFILING_COMMAND_END));
    EXPECT_LE(stamp(launch, CL_PROFILING_COMMAND_END), stamp(after, CL_PROFILING_COMMAND_START));
    for (cl_event e : {before, launch, after}) clReleaseEvent(e);
  }
}

// ---------------------------------------------------------------- instances

// K instances per launch (docs/VARIANTS.md "Instancing"), each with its own
// random palette, each instance against the gold of that palette: every
// layout and storage, padded and bucketed (CesiumMan: 4 launches), several
// vertices per item contiguous and strided, float3 and float4, normals.
class OpenClInstanced : public ::testing::TestWithParam<InstanceCase> {};

TEST_P(OpenClInstanced, EveryInstanceMatchesTheGoldOfItsPalette) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const InstanceCase& c = GetParam();
  SCOPED_TRACE(std::string(c.key) + " on " + c.mesh + " x" + std::to_string(c.instances) + ", seed " +
               std::to_string(Seed()) + " (SKINTUNE_TEST_SEED reproduces), device " + runner->device_name());
  testing::ExpectInstanceCaseMatchesGold(*runner, c, LimitsOf(*TestDevice(why)));
}

const Case kInstancedCases[] = {
    {"opencl.b4.padded.aos.float4.u16.f32.mat4.constant.matrix.v1c.wg64.normals", "b4"},
    {"opencl.b3.padded.soa.float3.u8.unorm8.mat3x4.local.point.v2s.wg128.nonormals", "b3-random"},
    {"opencl.b2.padded.soa-split.float4.i32.unorm16.mat3x4.image.matrix.v4c.wg32.normals", "b2"},
    {"opencl.b5.padded.aos.float4.i32.unorm16.mat3x4.image.point.v1c.wg32.nonormals", "b5"},
    {"opencl.b4.bucketed.soa.float4.u16.f32.mat3x4.global.matrix.v8s.wg256.normals", "cesium"},
    {"opencl.b4.bucketed.aos.float3.u8.unorm8.mat4.local.matrix.v2c.wg64.nonormals", "cesium"},
    {"opencl.b4.bucketed.soa-split.float3.u16.f32.mat3x4.constant.point.v4s.wg128.normals", "cesium"},
};

INSTANTIATE_TEST_SUITE_P(Spread, OpenClInstanced, ::testing::ValuesIn(WithInstanceCounts(kInstancedCases)),
                         InstanceCaseName);

constexpr const char* kInstancedFaultKey = "opencl.b2.soa.float4.u16.f32.wg64";

TEST(OpenClInstancedRunner, GoldCatchesAKernelThatReadsOnePaletteForEveryInstance) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  std::vector<KernelSource> kernels;
  const InstancedRun run = WithInstancedFault(kInstancedFaultKey, 3, "const uint joint_base = instance * JOINTS;",
                                              "const uint joint_base = 0u;", kernels);
  testing::ExpectOnlyInstanceZeroMatches(run, runner->Run(run.packed, kernels, run.palette_bytes, 3));
}

TEST(OpenClInstancedRunner, PoisonCatchesAKernelThatWritesEveryInstanceOverTheFirst) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  std::vector<KernelSource> kernels;
  const InstancedRun run = WithInstancedFault(kInstancedFaultKey, 7, "const uint out_first = instance * vertex_count + first;",
                                              "const uint out_first = first + 0u * vertex_count;", kernels);
  EXPECT_EQ(runner->Run(run.packed, kernels, run.palette_bytes, 7).poisoned_vertices, 6 * run.packed.vertex_count);
}

TEST(OpenClInstancedRunner, GuardCatchesTheLastInstanceWritingPastTheEnd) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  std::vector<KernelSource> kernels;
  const InstancedRun run = WithInstancedFault(kInstancedFaultKey, 7, "const uint out_first = instance * vertex_count + first;",
                                              "const uint out_first = instance * vertex_count + first + instance * 8u;", kernels);
  try {
    runner->Run(run.packed, kernels, run.palette_bytes, 7);
    ADD_FAILURE() << "the last instance writing 48 vertices past the end was not caught";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("OpenCL guard"), std::string::npos) << e.what();
  }
}

TEST(OpenClInstancedRunner, RejectsPalettesOfTheWrongCountAndPlainKernelsWithInstances) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const PackedMesh packed = Pack(testing::SmallAsset("b2").mesh, ParseVariantKey("opencl.b2.soa"));
  const std::vector<std::uint8_t> six(6 * packed.palette.size());
  EXPECT_NE(ErrorOf([&] { runner->RunInstanced(packed, 7, six); }).find("expected 7 instances x 12 joints"),
            std::string::npos);
  const std::vector<KernelSource> plain = {Emit(packed.variant, 0, 12)};
  EXPECT_NE(ErrorOf([&] { runner->Run(packed, plain, six, 6); }).find("6 instances with plain kernels"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { runner->RunInstanced(packed, 0); }).find("0 instances"), std::string::npos);
}

TEST(OpenClInstancedRunner, RejectsPalettesLargerThanTheConstantBufferNamingTheLimit) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const PackedMesh packed = Pack(testing::SmallAsset("b2").mesh, ParseVariantKey("opencl.b2.soa.constant"));
  const std::uint64_t limit = LimitsOf(*TestDevice(why)).constant_memory_bytes;
  const std::size_t k = static_cast<std::size_t>(limit / packed.palette.size() + 1);
  if (k > 100000) GTEST_SKIP() << "constant buffer of " << limit << " bytes: too many instances to exceed it";
  const std::vector<std::uint8_t> palettes(k * packed.palette.size());
  const std::string message = ErrorOf([&] { runner->RunInstanced(packed, static_cast<int>(k), palettes); });
  EXPECT_NE(message.find("exceed CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE " + std::to_string(limit)), std::string::npos)
      << message;
}

TEST(OpenClInstancedRunner, TimesKInstancesPerFrame) {
  std::string why;
  OpenClRunner* runner = Runner(why);
  if (!runner) GTEST_SKIP() << why;
  const InstancedRun run = testing::InstancedInputs(ParseVariantKey("opencl.b2.soa.local"), "b2", 7);
  const std::vector<KernelSource> kernels = EmitLaunchKernels(run.packed, 7);
  const std::vector<std::vector<std::uint8_t>> sets = {run.palette_bytes, run.palette_bytes};
  const OpenClPrepared prepared = runner->Prepare(run.packed, kernels, sets, 7);
  EXPECT_EQ(prepared.input_sets(), 2);
  EXPECT_GE(prepared.bytes_per_set(), 7 * run.packed.vertex_count * run.packed.output_stride_bytes);
  EXPECT_EQ(runner->Time(prepared, 1, 3).size(), 3u);
  const std::vector<std::vector<std::uint8_t>> one = {std::vector<std::uint8_t>(run.packed.palette)};
  EXPECT_NE(ErrorOf([&] { runner->Prepare(run.packed, kernels, one, 7); }).find("palette has"), std::string::npos);
}

}  // namespace
}  // namespace skintune::internal
