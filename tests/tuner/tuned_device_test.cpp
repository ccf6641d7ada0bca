// The tuner's TunedDevice (tuner/tuned_device.h) on this machine's devices: discovery
// (PoCL and Mesa's llvmpipe in CI, CUDA skipped with its reason where there is
// no driver), identities and their JSON, Measure of a few variants per API
// (verified, then timed over rotating input sets), the injected faults that
// must fail verification or the build, through a device whose executor is
// decorated with them (tuner/fault_injection.h; "hang" and "crash" are
// exercised by the orchestrator's tests, which run Measure in a child
// process; here the hang kernels are only built), the copy bandwidth, and
// the rotation rule.
// A test that needs an API the machine lacks skips with the discovery's reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <string>

#include <nlohmann/json.hpp>

#include "generator/axes.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "base/error.h"
#include "model/synthetic.h"
#include "runtime/device_clock.h"
#include "runtime/backends/cpu/cpu_runner.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/opencl/opencl_devices.h"
#include "runtime/backends/gl/gl_runner.h"
#include "runtime/backends/opencl/opencl_runner.h"
#include "runtime/backend_table.h"
#include "tuner/datasets.h"
#include "tuner/executor.h"
#include "tuner/fault_injection.h"
#include "tuner/measure_job.h"
#include "tuner/runner_device.h"
#include "tuner/tuned_device.h"
#include "tuner/report.h"
#include "model/scene.h"
#include "tests/tuner/scene_selection.h"

namespace skintune::internal {
namespace {

using tuner_internal::InputSetsFor;

constexpr const char* kDataset = "20k-b2";

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Discovery, once per test program.
const Discovery& Found() {
  static const Discovery discovery = [] {
    Discovery d = DiscoverTunedDevices();
    for (const auto& b : d.devices) std::cout << "[ device   ] " << b->identity().index << ": " << b->identity().Id() << "\n";
    for (const std::string& s : d.skipped) std::cout << "[ skipped  ] " << s << "\n";
    return d;
  }();
  return discovery;
}

std::string SkippedLines(const std::string& prefix) {
  std::string lines;
  for (const std::string& s : Found().skipped)
    if (s.rfind(prefix, 0) == 0) lines += (lines.empty() ? "" : "; ") + s;
  return lines.empty() ? "no " + prefix + " device and no skipped line" : lines;
}

// The first device of `api`; for OpenCL the first whose "platform / name"
// contains $SKINTUNE_TEST_OPENCL_DEVICE when set (as the runner tests do).
TunedDevice* Find(const std::string& api) {
  const char* pattern = api == "opencl" ? std::getenv("SKINTUNE_TEST_OPENCL_DEVICE") : nullptr;
  for (const auto& b : Found().devices) {
    const DeviceIdentity& d = b->identity();
    if (d.backend != api) continue;
    if (pattern && Lower(d.platform + " / " + d.name).find(Lower(pattern)) == std::string::npos) continue;
    return b.get();
  }
  return nullptr;
}

#define DEVICE_OR_SKIP(var, api)                                   \
  TunedDevice* var = Find(api);                                    \
  if (!var) {                                                      \
    if (std::string(api) == "opencl" && std::getenv("SKINTUNE_TEST_OPENCL_DEVICE")) \
      FAIL() << "the requested OpenCL device is missing";          \
    GTEST_SKIP() << SkippedLines(std::string(api) + ":");          \
  }

TimingOptions SmallTiming() {
  TimingOptions o;
  o.warmup = 1;
  o.repetitions = 5;
  o.max_input_sets = 3;
  o.stop.min_samples = 4;
  o.stop.batch = 4;
  o.stop.max_samples = 8;
  o.stop.max_ms = 30.0;
  return o;
}

// A variant that passed: verified, timed, everything filled in.
void ExpectOk(const Measurement& m, const TunedDevice& tuned, const std::string& dataset) {
  ASSERT_EQ(m.status, MeasureStatus::kOk) << Name(m.status) << ": " << m.detail;
  EXPECT_EQ(m.detail, "");
  EXPECT_EQ(m.device_id, tuned.identity().Id());
  EXPECT_EQ(m.dataset, dataset);
  EXPECT_EQ(m.generator_version, kGeneratorVersion);
  EXPECT_TRUE(std::regex_match(m.timestamp, std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)"))) << m.timestamp;
  EXPECT_GT(m.timing.min_ms, 0.0);
  EXPECT_LE(m.timing.min_ms, m.timing.median_ms);
  EXPECT_LE(m.timing.median_ms, m.timing.max_ms);
  EXPECT_EQ(m.timing.warmup, 1);
  EXPECT_GE(m.timing.repetitions, 4);  // the samples: at least min_samples, at most max_samples
  EXPECT_LE(m.timing.repetitions, 8);
  EXPECT_LE(m.timing.low_ms, m.timing.median_ms);
  EXPECT_GE(m.timing.high_ms, m.timing.median_ms);
  EXPECT_GT(m.timing.frame_ms, 0.0) << "the frame time, recorded for every ok measurement";
  EXPECT_GT(m.timing.flush_bytes, 0.0);
  EXPECT_FALSE(m.timing.clock.empty());
  // The schedule where the device chooses it: the cpu device's threads and chunk.
  if (tuned.identity().backend == "cpu")
    EXPECT_TRUE(std::regex_match(m.timing.schedule, std::regex(R"(\d+ threads? x \d+-vertex chunks, (streaming|plain) stores)")))
        << m.timing.schedule;
  else
    EXPECT_EQ(m.timing.schedule, "");
  // The GPU's clock around the samples, where its driver tells it (NVML on NVIDIA's GPUs).
  std::string unread;
  if (tuned.identity().type != "cpu" && DeviceClock::Open(tuned.identity(), &unread))
    EXPECT_GT(m.timing.sm_clock_mhz, 0.0) << "the clock is read on this GPU";
  else
    EXPECT_EQ(m.timing.sm_clock_mhz, 0.0) << "no clock is read here: " << unread;
  EXPECT_GE(m.timing.input_sets, 1);
  EXPECT_LE(m.timing.input_sets, 3);
  EXPECT_GT(m.bytes_per_frame, 0.0);
  EXPECT_GT(m.gbps, 0.0);
  EXPECT_NEAR(m.gbps, m.bytes_per_frame / m.timing.median_ms / 1e6, 1e-9 * m.gbps);
  EXPECT_LT(m.max_relative_error, 1e-5);
  std::cout << "[ measured ] " << m.variant.Key() << " on " << m.dataset << ": median " << m.timing.median_ms
            << " ms (min " << m.timing.min_ms << ", max " << m.timing.max_ms << "), " << m.timing.input_sets
            << " input sets, " << m.bytes_per_frame << " bytes/frame, " << m.gbps << " GB/s, max rel. error "
            << m.max_relative_error << "\n";
}

// Sets an environment variable for the scope (unset after).
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) { setenv(name, value.c_str(), 1); }
  ~ScopedEnv() { unsetenv(name_); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
};

// A fresh device like `device` that measures through the fault-injecting
// executor (tuner/fault_injection.h): `v`'s kernels fail as `kind` says.
std::unique_ptr<TunedDevice> Faulty(const TunedDevice& device, const Variant& v, const std::string& kind) {
  static const Discovered found = DiscoverDevices();
  for (const FoundDevice& f : found.devices)
    if (f.identity.Id() == device.identity().Id())
      return tuner_internal::MakeRunnerDevice(f, device.languages(), device.identity().index,
                                              tuner_internal::InjectingFault({v.Key(), kind}));
  throw Error("no device " + device.identity().Id() + " in a second discovery");
}

// The two injected faults on `v`: "compile" is compile_failed naming the
// API's build stage (`build`, e.g. "Vulkan build"), "wrong" is verify_failed
// with the error measured.
void ExpectInjectedCompileAndWrongFaults(const TunedDevice& device, const Variant& v, const std::string& build) {
  {
    const Measurement m = Faulty(device, v, "compile")->Measure(v, {kDataset}, SmallTiming());
    EXPECT_EQ(m.status, MeasureStatus::kCompileFailed) << Name(m.status) << ": " << m.detail;
    EXPECT_NE(m.detail.find(build), std::string::npos) << m.detail;
  }
  {
    const Measurement m = Faulty(device, v, "wrong")->Measure(v, {kDataset}, SmallTiming());
    EXPECT_EQ(m.status, MeasureStatus::kVerifyFailed) << Name(m.status) << ": " << m.detail;
    EXPECT_GT(m.max_relative_error, 1e-5);
  }
}

// The OpenCL runner of a tuned OpenCL device (found in the inventory by
// platform and name, as discovery names it), or null.
std::unique_ptr<OpenClRunner> RunnerOf(const TunedDevice& tuned) {
  const OpenClInventory inventory = EnumerateOpenCl();
  for (const OpenClDeviceInfo& d : inventory.devices)
    if (d.platform_name == tuned.identity().platform && d.name == tuned.identity().name)
      return std::make_unique<OpenClRunner>(d.platform_index, d.device_index);
  return nullptr;
}

// The device's copy bandwidth over 16 MiB: positive, and printed.
void ExpectCopyBandwidth(TunedDevice& tuned) {
  const double gbps = tuned.CopyBandwidthGBps(16u << 20);
  std::cout << "[ copy     ] " << tuned.identity().name << ": " << gbps << " GB/s\n";
  EXPECT_GT(gbps, 0.0);
}

// ---------------------------------------------------------------- discovery and identity

TEST(Discovery, FindsEveryOpenClDeviceWithItsIdentity) {
  const OpenClInventory inventory = EnumerateOpenCl();
  std::size_t opencl = 0;
  for (const auto& b : Found().devices) {
    const DeviceIdentity& d = b->identity();
    if (d.backend != "opencl") continue;
    ++opencl;
    EXPECT_FALSE(d.platform.empty());
    EXPECT_FALSE(d.vendor.empty());
    EXPECT_FALSE(d.name.empty());
    EXPECT_FALSE(d.driver_version.empty());
    EXPECT_FALSE(d.api_version.empty());
    EXPECT_FALSE(d.type.empty());
    EXPECT_GT(d.compute_units, 0u);
    EXPECT_GT(d.global_memory_bytes, 0u);
    EXPECT_GT(d.local_memory_bytes, 0u);
    EXPECT_GT(d.constant_memory_bytes, 0u);
    EXPECT_EQ(d.Id(), "opencl:" + d.platform + "/" + d.name + "/" + d.driver_version);
    EXPECT_EQ(b->languages(), std::vector<Lang>{Lang::kOpenCl});
    EXPECT_GT(b->limits().max_wg_size, 0u);
  }
  EXPECT_EQ(opencl, inventory.devices.size());
  if (inventory.devices.empty()) {
    EXPECT_NE(SkippedLines("opencl:").find("opencl: skipped: "), std::string::npos);
  }
  // PoCL, where CI has it: a CPU device with its cache size.
  for (const auto& b : Found().devices) {
    const DeviceIdentity& d = b->identity();
    if (d.backend == "opencl" && d.platform.find("Portable Computing Language") != std::string::npos) {
      EXPECT_EQ(d.type, "cpu");
      EXPECT_GT(d.last_level_cache_bytes, 0u);
    }
  }
}

TEST(Discovery, CudaBackendsOrTheReasonThereAreNone) {
  const CudaAvailability cuda = Probe();
  std::size_t found = 0;
  for (const auto& b : Found().devices) {
    const DeviceIdentity& d = b->identity();
    if (d.backend != "cuda") continue;
    ++found;
    EXPECT_EQ(d.platform, "CUDA");
    EXPECT_FALSE(d.name.empty());
    EXPECT_FALSE(d.driver_version.empty());
    EXPECT_GT(d.compute_units, 0u);
    EXPECT_GT(d.last_level_cache_bytes, 0u);  // the L2
    EXPECT_EQ(b->languages(), std::vector<Lang>{Lang::kCuda});
  }
  if (cuda.CanRun()) {
    EXPECT_EQ(found, static_cast<std::size_t>(cuda.device_count));
  } else {
    EXPECT_EQ(found, 0u);
    const std::string skipped = SkippedLines("cuda:");
    EXPECT_EQ(skipped.rfind("cuda: skipped: ", 0), 0u) << skipped;
    EXPECT_GT(skipped.size(), std::string("cuda: skipped: ").size() + 10) << "a reason: " << skipped;
  }
}

TEST(Discovery, OneGlBackendOrTheReasonThereIsNone) {
  std::size_t found = 0;
  for (const auto& b : Found().devices) {
    const DeviceIdentity& d = b->identity();
    if (d.backend != "gl") continue;
    ++found;
    EXPECT_FALSE(d.platform.empty());  // the EGL platform
    EXPECT_FALSE(d.vendor.empty());
    EXPECT_FALSE(d.name.empty());      // GL_RENDERER
    EXPECT_FALSE(d.driver_version.empty());
    EXPECT_FALSE(d.api_version.empty());
    EXPECT_GT(d.local_memory_bytes, 0u);
    EXPECT_GT(d.constant_memory_bytes, 0u);
    EXPECT_EQ(d.reported_cache_bytes, 0u);  // GL does not say
    // The rotation's cache is still known: the host's for a CPU renderer, a
    // GPU's from another API or its datasheet (unknown only for a chip of its own).
    if (d.type == "cpu") {
      EXPECT_GT(d.last_level_cache_bytes, 0u);
      EXPECT_NE(d.last_level_cache_source.find("host"), std::string::npos) << d.last_level_cache_source;
    }
    EXPECT_EQ(b->languages(), (std::vector<Lang>{Lang::kGlslCompute, Lang::kGlslVertex}));
    if (d.name.find("llvmpipe") != std::string::npos) {
      EXPECT_EQ(d.type, "cpu");
    }
  }
  EXPECT_LE(found, 1u);
  if (found == 0) {
    EXPECT_EQ(SkippedLines("gl:").rfind("gl: skipped: ", 0), 0u) << SkippedLines("gl:");
  }
}

TEST(Discovery, IndicesFollowTheDiscoveryOrder) {
  for (std::size_t i = 0; i < Found().devices.size(); ++i)
    EXPECT_EQ(Found().devices[i]->identity().index, static_cast<int>(i));
}

// A tune worker discovers its own API alone and takes the cache figure its
// parent resolved across every API (tuner/worker.h WorkerArguments): the
// named device takes it, no other does.
TEST(Discovery, OneApiAloneWithTheCacheFigureItsParentFound) {
  const Discovery own = DiscoverTunedDevices(tuner_internal::ExecutorDecorator{}, "cpu");
  ASSERT_EQ(own.devices.size(), 1u) << "skintune's cpu device is always found";
  const DeviceIdentity& found = own.devices[0]->identity();
  EXPECT_EQ(found.backend, "cpu");
  const tuner_internal::GivenCache given{found.Id(), 123456789, "the parent's view of the chip"};
  const Discovery told = DiscoverTunedDevices(tuner_internal::ExecutorDecorator{}, "cpu", &given);
  ASSERT_EQ(told.devices.size(), 1u);
  EXPECT_EQ(told.devices[0]->identity().last_level_cache_bytes, 123456789u);
  EXPECT_EQ(told.devices[0]->identity().last_level_cache_source, "the parent's view of the chip");
  EXPECT_EQ(told.devices[0]->identity().reported_cache_bytes, found.reported_cache_bytes);
  const tuner_internal::GivenCache elsewhere{"cpu:another/device/1", 123456789, "another device's"};
  const Discovery other = DiscoverTunedDevices(tuner_internal::ExecutorDecorator{}, "cpu", &elsewhere);
  ASSERT_EQ(other.devices.size(), 1u);
  EXPECT_EQ(other.devices[0]->identity().last_level_cache_bytes, found.last_level_cache_bytes);
  EXPECT_EQ(other.devices[0]->identity().last_level_cache_source, found.last_level_cache_source);
}

TEST(DeviceIdentity, JsonRoundTripsEveryField) {
  DeviceIdentity d;
  d.backend = "opencl";
  d.index = 3;
  d.platform = "Portable Computing Language";
  d.vendor = "AuthenticAMD";
  d.name = "pthread-skylake";
  d.driver_version = "3.1+debian";
  d.api_version = "OpenCL 3.0 PoCL";
  d.type = "cpu";
  d.compute_units = 2;
  d.global_memory_bytes = 1ull << 33;
  d.local_memory_bytes = 1 << 20;
  d.constant_memory_bytes = 1 << 16;
  d.last_level_cache_bytes = 32ull << 20;
  const nlohmann::json j = d;
  EXPECT_EQ(j.at("id"), "opencl:Portable Computing Language/pthread-skylake/3.1+debian");
  const DeviceIdentity back = j.get<DeviceIdentity>();
  EXPECT_EQ(nlohmann::json(back), j);
  EXPECT_EQ(back.last_level_cache_bytes, d.last_level_cache_bytes);
}

TEST(DeviceIdentity, JsonWithoutARequiredFieldThrowsNamingIt) {
  nlohmann::json j = DeviceIdentity{"gl", 0, "surfaceless", "Mesa", "llvmpipe", "4.5 Mesa 22"};
  j.erase("driver_version");
  try {
    (void)j.get<DeviceIdentity>();
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("driver_version"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------- rotation rule and helpers

TEST(RotationRule, EnoughSetsToExceedTwiceTheLastLevelCache) {
  // A tiny cache: 1 MiB, sets of 300 KiB -> ceil(2048 / 300) = 7, made even: 8.
  EXPECT_EQ(InputSetsFor(1u << 20, 300u << 10, 8), 8);
  // ... made even downwards where max_input_sets is odd and reached.
  EXPECT_EQ(InputSetsFor(1u << 20, 300u << 10, 7), 6);
  // A 1600k-b1 frame (43.2 MB) on an H100 (50 MiB): ceil(2.43) = 3 -> 4, so
  // the two lanes (even and odd frames) never read one set.
  EXPECT_EQ(InputSetsFor(50ull << 20, 43'204'928, 8), 4);
  // ... clamped to max_input_sets.
  EXPECT_EQ(InputSetsFor(1u << 20, 300u << 10, 4), 4);
  // Exactly 2 x LLC needs no rounding up.
  EXPECT_EQ(InputSetsFor(1u << 20, 1u << 20, 8), 2);
  // A large cache (50 MiB, an H100's L2) and a 1600k-b4 frame (~77 MB): 2 sets.
  EXPECT_EQ(InputSetsFor(50ull << 20, 76'800'000, 8), 2);
  // A large cache and a small frame: as many as allowed.
  EXPECT_EQ(InputSetsFor(256ull << 20, 1u << 20, 8), 8);
  // A set larger than twice the cache: one set.
  EXPECT_EQ(InputSetsFor(1u << 20, 3u << 20, 8), 1);
  // Unknown cache (0): 64 MiB assumed -> 128 MiB / 20 MiB = 6.4 -> 7 -> 8.
  EXPECT_EQ(InputSetsFor(0, 20u << 20, 8), 8);
  EXPECT_EQ(InputSetsFor(0, 20u << 20, 8), InputSetsFor(tuner_internal::kUnknownLastLevelCacheBytes, 20u << 20, 8));
  // Never fewer than one, whatever the options say.
  EXPECT_EQ(InputSetsFor(1u << 20, 1u << 10, 0), 1);
}

TEST(Helpers, RunnerErrorsMapToStatusByStage) {
  using tuner_internal::StatusOfRunnerError;
  EXPECT_EQ(StatusOfRunnerError("OpenCL build: kernel x failed"), MeasureStatus::kCompileFailed);
  EXPECT_EQ(StatusOfRunnerError("CUDA build: NVRTC ..."), MeasureStatus::kCompileFailed);
  EXPECT_EQ(StatusOfRunnerError("GL guard: wrote past the end"), MeasureStatus::kVerifyFailed);
  EXPECT_EQ(StatusOfRunnerError("GL launch: glDispatchCompute raised GL_INVALID_VALUE"), MeasureStatus::kLaunchFailed);
  EXPECT_EQ(StatusOfRunnerError("CUDA setup: cuCtxSetCurrent"), MeasureStatus::kLaunchFailed);
  EXPECT_EQ(StatusOfRunnerError("something else"), MeasureStatus::kLaunchFailed);
  EXPECT_EQ(StatusOfRunnerError("GL lost: finishing x: the GL context was lost (GL_CONTEXT_LOST)"),
            MeasureStatus::kLaunchFailed);
}

// Stage "lost", alone or after the timing's prefix, is a device lost for the worker.
TEST(Helpers, DeviceLostIsTheRunnerStageLost) {
  using tuner_internal::DeviceLostIn;
  EXPECT_TRUE(DeviceLostIn("GL lost: finishing x: the GL context was lost (GL_CONTEXT_LOST)"));
  EXPECT_TRUE(DeviceLostIn("timing: CUDA lost: cuStreamSynchronize failed: CUDA_ERROR_ILLEGAL_ADDRESS (700)"));
  EXPECT_TRUE(DeviceLostIn("Vulkan lost: vkQueueSubmit: VK_ERROR_DEVICE_LOST"));
  EXPECT_FALSE(DeviceLostIn("GL launch: glDispatchCompute raised GL_INVALID_VALUE"));
  EXPECT_FALSE(DeviceLostIn("wrong results against the float64 gold: the device was lost"));
  EXPECT_FALSE(DeviceLostIn("worker process died: signal 6 (Aborted)"));
  EXPECT_FALSE(DeviceLostIn(""));
}

TEST(Helpers, MedianCopyBytesAndTimestamp) {
  using namespace tuner_internal;
  EXPECT_EQ(Median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(Median({4.0, 1.0, 2.0, 3.0}), 2.5);
  EXPECT_EQ(CopyBytesCapped(256u << 20, 0), 256u << 20);
  EXPECT_EQ(CopyBytesCapped(256u << 20, 512u << 20), 128u << 20);  // a quarter of the largest allocation
  EXPECT_EQ(CopyBytesCapped(10000, 0), 8192u);
  EXPECT_EQ(CopyBytesCapped(1, 0), 4096u);
  EXPECT_NEAR(CopyGBps(1000000, {1.0, 2.0, 1.0}), 2.0, 1e-12);  // 2 MB moved in 1 ms
  EXPECT_TRUE(std::regex_match(skintune::internal::UtcTimestamp(), std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)")));
}

// DatasetCache::Packed: the variants of one packing (PackingKey) share its
// bytes, so each is packed once. Every axis PackingKey sets aside must leave
// the packer's bytes alone, and every other axis must change the key.
TEST(Packings, KernelOnlyAxesLeaveThePackedBytesAloneAndTheOthersChangeTheKey) {
  using tuner_internal::PackingKey;
  const SkinnedMesh mesh = GenerateDataset(ParseDatasetKey("3k-b4-seed5")).mesh;
  const Variant base = ParseVariantKey("opencl.b4.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals");
  const PackedMesh packed = Pack(mesh, base);
  const auto same_bytes = [&](const PackedMesh& other) {
    if (other.launches.size() != packed.launches.size() || other.palette != packed.palette) return false;
    for (std::size_t l = 0; l < packed.launches.size(); ++l) {
      if (other.launches[l].inputs.size() != packed.launches[l].inputs.size()) return false;
      for (std::size_t b = 0; b < packed.launches[l].inputs.size(); ++b)
        if (other.launches[l].inputs[b].bytes != packed.launches[l].inputs[b].bytes) return false;
    }
    return other.order == packed.order;
  };
  for (const char* kernel_only : {"cuda.b4.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals",
                                  "opencl.b4.padded.soa-split.float4.u8.unorm8.mat3x4.constant.matrix.v1c.wg64.nonormals",
                                  "opencl.b4.padded.soa-split.float4.u8.unorm8.mat3x4.local.point.v1c.wg64.nonormals",
                                  "opencl.b4.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v4s.wg256.nonormals"}) {
    SCOPED_TRACE(kernel_only);
    const Variant v = ParseVariantKey(kernel_only);
    EXPECT_EQ(PackingKey(v), PackingKey(base));
    EXPECT_TRUE(same_bytes(Pack(mesh, v)));
  }
  for (const char* packing : {"opencl.b4.padded.aos.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals",
                              "opencl.b4.padded.soa.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals",
                              "opencl.b4.padded.soa-split.float3.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals",
                              "opencl.b4.padded.soa-split.float4.u16.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals",
                              "opencl.b4.padded.soa-split.float4.u8.f32.mat3x4.global.matrix.v1c.wg64.nonormals",
                              "opencl.b4.padded.soa-split.float4.u8.unorm8.mat4.global.matrix.v1c.wg64.nonormals",
                              "opencl.b4.bucketed.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals",
                              "opencl.b5.padded.soa-split.float4.u8.unorm8.mat3x4.global.matrix.v1c.wg64.nonormals"}) {
    SCOPED_TRACE(packing);
    EXPECT_NE(PackingKey(ParseVariantKey(packing)), PackingKey(base));
  }
}

TEST(Packings, APackingIsReusedWithTheMeasuredVariantInIt) {
  tuner_internal::DatasetCache datasets;
  tuner_internal::DatasetCache::Entry& entry = datasets.Get("3k-b4-seed5");
  const Variant global = ParseVariantKey("opencl.b4.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.nonormals");
  const Variant local = ParseVariantKey("opencl.b4.padded.soa.float4.u16.f32.mat3x4.local.matrix.v1c.wg256.nonormals");
  const PackedMesh first = datasets.Packed(entry, global);
  const PackedMesh second = datasets.Packed(entry, local);
  EXPECT_EQ(first.variant, global);
  EXPECT_EQ(second.variant, local);
  // The cached packing itself, not a copy (a 6400k-vertex one is ~200 MB),
  // with the variant of the last call.
  const PackedMesh* at_global = &datasets.Packed(entry, global);
  const PackedMesh& again = datasets.Packed(entry, local);
  EXPECT_EQ(&again, at_global);
  EXPECT_EQ(again.variant, local);
  EXPECT_EQ(entry.packings.size(), 1u);
  EXPECT_EQ(second.launches.front().inputs.front().bytes, Pack(entry.mesh(), local).launches.front().inputs.front().bytes);
  // A variant that cannot be packed is named in the error, and nothing is kept for it.
  const Variant too_few = ParseVariantKey("opencl.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg64.nonormals");
  try {
    (void)datasets.Packed(entry, too_few);
    ADD_FAILURE() << "packed a b2 variant of a b4 mesh";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(too_few.Key()), std::string::npos) << e.what();
  }
  EXPECT_EQ(entry.packings.size(), 1u);
}

TEST(InjectedFault, ParsedFromTheEnvironmentWithTheCanonicalKey) {
  {
    ScopedEnv f("SKINTUNE_INJECT_FAULT", "wg64.b2.opencl=wrong");
    const InjectedFault fault = InjectedFaultFromEnvironment();
    EXPECT_EQ(fault.variant_key, ParseVariantKey("opencl.b2.wg64").Key());
    EXPECT_EQ(fault.kind, "wrong");
  }
  EXPECT_EQ(InjectedFaultFromEnvironment().kind, "");
  {
    ScopedEnv f("SKINTUNE_INJECT_FAULT", "opencl.b2=explode");
    EXPECT_THROW(InjectedFaultFromEnvironment(), Error);
  }
  {
    ScopedEnv f("SKINTUNE_INJECT_FAULT", "no-equals-sign");
    EXPECT_THROW(InjectedFaultFromEnvironment(), Error);
  }
}

TEST(InjectedFault, EveryTemplateTakesEveryEdit) {
  for (const char* key : {"opencl.b3.aos.float3.u8.unorm8.local.normals", "cuda.b2.soa-split.constant",
                          "glsl-compute.b4.soa.image.v2s", "glsl-vertex.b1.aos.v1c.wg0.normals"}) {
    const Variant v = ParseVariantKey(key);
    for (const char* kind : {"compile", "wrong", "hang"}) {
      SCOPED_TRACE(std::string(key) + " " + kind);
      KernelSource s = Emit(v, 0, 77);
      const std::string hash = s.source_hash;
      ASSERT_NO_THROW(tuner_internal::InjectFault(s, v, kind));
      EXPECT_NE(s.source_hash, hash);
      EXPECT_EQ(s.source_hash, SourceHash(s.text));
    }
  }
}

// ---------------------------------------------------------------- OpenCL

TEST(OpenClTunedDevice, MeasuresVariantsVerifiedThenTimed) {
  DEVICE_OR_SKIP(tuned, "opencl");
  for (const char* key : {"opencl.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.nonormals",
                          "opencl.b2.bucketed.soa-split.float3.u8.unorm8.mat4.local.point.v2s.wg64.nonormals",
                          "opencl.b2.padded.aos.float4.i32.unorm16.mat3x4.image.matrix.v4c.wg256.nonormals",
                          "opencl.b2.padded.soa.float4.u16.f32.mat3x4.constant.matrix.v8s.wg32.nonormals"}) {
    SCOPED_TRACE(key);
    ExpectOk(tuned->Measure(ParseVariantKey(key), {kDataset}, SmallTiming()), *tuned, kDataset);
  }
}

TEST(OpenClTunedDevice, MeasuresNormalsAndAGltfMesh) {
  DEVICE_OR_SKIP(tuned, "opencl");
  ExpectOk(tuned->Measure(ParseVariantKey("opencl.b2.soa.normals"), {"5000-b2-normals"}, SmallTiming()), *tuned,
           "5000-b2-normals");
  // CesiumMan: 1..4 bones per vertex, so bucketed makes four launches, timed together.
  const std::string cesium = std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf";
  ExpectOk(tuned->Measure(ParseVariantKey("opencl.b4.bucketed.soa.normals"), {cesium}, SmallTiming()), *tuned,
           "CesiumMan.gltf");
}

// Scenes (model/scene.h) on every device found: K instances through
// the instanced kernels and a batch of CesiumMan, Fox and a synthetic mix,
// verified per instance / mesh and timed against the copy of the whole
// scene's bytes; their winners go to the database keyed by shape, and the
// runtime's selection takes each shape's own.
TEST(Scenes, InstancesAndBatchesAreVerifiedTimedAndTheirWinnersSelectedByShape) {
  const std::string data = SKINTUNE_TEST_DATA_DIR;
  const std::string crowd = "2000-b4-x4";
  const std::string mix = data + "/CesiumMan.gltf+" + data + "/Fox.gltf+mix20k-b3";
  const std::string single = "8000-b4";
  int measured = 0;
  for (const auto& found : Found().devices) {
    TunedDevice& tuned = *found;
    TuningReport report;
    report.created = "2026-11-24T00:00:00Z";
    report.config = "test";
    report.strategy = "exhaustive";
    report.devices.push_back(tuned.identity());
    report.datasets.push_back({single, 8000, 4, 77, SceneKind::kSingle, 1, 1});
    report.datasets.push_back({crowd, 8000, 4, 77, SceneKind::kInstances, 4, 1});
    const SceneSpec mix_spec = ParseSceneKey(mix);
    report.datasets.push_back({mix, 3273 + 1728 + 20000, 4, 0, SceneKind::kBatch, 1,
                               static_cast<int>(mix_spec.meshes.size())});
    const Lang lang = tuned.languages().front();
    const std::string vertex = HasWorkGroups(lang) ? "v1c.wg64" : "v1c.wg0";  // glsl-vertex, cpu: none
    std::map<std::string, std::string> variant_of;  // dataset -> the variant measured on it
    variant_of[single] = std::string(Name(lang)) + ".b4.padded.soa.float4.u16.f32.mat3x4.global.matrix." + vertex;
    variant_of[crowd] = std::string(Name(lang)) + ".b4.padded.soa-split.float3.u16.unorm16.mat3x4.global.matrix." + vertex;
    variant_of[mix] = std::string(Name(lang)) + ".b4.padded.aos.float4.i32.f32.mat4.global.point." + vertex;
    for (const DatasetInfo& dataset : report.datasets) {
      SCOPED_TRACE(tuned.identity().Id() + " " + dataset.key);
      Measurement m = tuned.Measure(ParseVariantKey(variant_of[dataset.key]), {dataset.key}, SmallTiming());
      ExpectOk(m, tuned, IsGltfFile(dataset.key) ? std::filesystem::path(dataset.key).filename().string() : dataset.key);
      EXPECT_GT(m.x_copy, 0.0) << m.detail;
      m.dataset = dataset.key;  // as the worker records it (tuner/worker.cpp)
      report.measurements.push_back(m);
      ++measured;
    }
    // The runtime's selection (through the public API, tests/tuner/scene_selection.h).
    const std::string db = WinnersDatabase(report).dump();
    EXPECT_EQ(SelectedVariant(db, tuned.identity(), "single", 8000), ParseVariantKey(variant_of[single]).Key());
    EXPECT_EQ(SelectedVariant(db, tuned.identity(), "instances", 8000), ParseVariantKey(variant_of[crowd]).Key());
    EXPECT_EQ(SelectedVariant(db, tuned.identity(), "batch", 8000), ParseVariantKey(variant_of[mix]).Key());
  }
  if (measured == 0) GTEST_SKIP() << "no device here: " << SkippedLines("");
}

// Animated scenes ("-anim", docs/ANIMATION.md) on every device found: Fox's
// three clips played by a crowd, the palettes made on the device by the
// palette kernel as the frame's first launch. Sampled and baked forms are
// verified against the float64 gold of the palettes each makes, their error
// against the sampled float64 palettes recorded (baking's loss falls with the
// rate), the palette kernel's own time stated within the kernel time, and a
// baked variant's clips recorded with their frames, bytes and error. The host
// form is no variant of an animated scene, nor a device form of another.
TEST(Scenes, AnimatedCrowdsMakeTheirPalettesOnTheDeviceVerifiedTimedAndTheirBakingStated) {
  const std::string fox = std::string(SKINTUNE_TEST_DATA_DIR) + "/Fox.gltf";
  const std::string crowd = fox + "-x6-anim";
  int measured = 0;
  for (const auto& found : Found().devices) {
    TunedDevice& tuned = *found;
    const Lang lang = tuned.languages().front();
    const std::string base = std::string(Name(lang)) + ".b4.padded.soa.float4.u16.f32.mat3x4.global.matrix." +
                             (HasWorkGroups(lang) ? "v1c.wg64" : "v1c.wg0");
    SCOPED_TRACE(tuned.identity().Id());
    std::map<std::string, Measurement> by_form;
    for (const char* form : {"anim-sampled", "anim-baked30", "anim-baked240"}) {
      const Measurement m = tuned.Measure(ParseVariantKey(base + "." + form), {crowd}, SmallTiming());
      SCOPED_TRACE(form);
      ExpectOk(m, tuned, crowd);
      EXPECT_GT(m.timing.palette_kernel_ms, 0.0) << "the palette kernel's own time";
      EXPECT_LT(m.timing.palette_kernel_ms, m.timing.max_ms) << "part of each sample";
      ASSERT_TRUE(m.source_error.known);
      by_form[form] = m;
      ++measured;
    }
    EXPECT_TRUE(by_form["anim-sampled"].baked_clips.empty());
    EXPECT_LT(by_form["anim-sampled"].source_error.position_rel, 1e-5) << "float32 sampling of the float64 palettes";
    for (const char* form : {"anim-baked30", "anim-baked240"}) {
      const std::vector<BakedClipRecord>& clips = by_form[form].baked_clips;
      ASSERT_EQ(clips.size(), 3u) << form;
      for (const BakedClipRecord& c : clips) {
        EXPECT_GT(c.frames, 1.0) << c.name;
        EXPECT_GT(c.bytes, 0.0) << c.name;
        EXPECT_GT(c.max_error, 0.0) << c.name;
      }
    }
    EXPECT_GT(by_form["anim-baked240"].baked_clips.front().bytes, 4 * by_form["anim-baked30"].baked_clips.front().bytes);
    EXPECT_GT(by_form["anim-baked240"].baked_clips.front().frames, 7 * by_form["anim-baked30"].baked_clips.front().frames);
    EXPECT_GT(by_form["anim-baked30"].source_error.position_rel, by_form["anim-sampled"].source_error.position_rel);
    EXPECT_LT(by_form["anim-baked240"].source_error.position_rel, by_form["anim-baked30"].source_error.position_rel)
        << "baking's loss falls with the rate";
    // Cross-fades (-animblend): sampled clips blend each joint's local transform
    // as the float64 source does, and so do clips baked in local space, which
    // lose what baking each clip loses; palette records blend in the model's
    // space, which loses more than baking alone.
    const Measurement blended_sampled = tuned.Measure(ParseVariantKey(base + ".anim-sampled"), {fox + "-x6-animblend"}, SmallTiming());
    ExpectOk(blended_sampled, tuned, fox + "-x6-animblend");
    EXPECT_LT(blended_sampled.source_error.position_rel, 1e-5);
    const Measurement blended_baked = tuned.Measure(ParseVariantKey(base + ".anim-baked240"), {fox + "-x6-animblend"}, SmallTiming());
    ExpectOk(blended_baked, tuned, fox + "-x6-animblend");
    EXPECT_GT(blended_baked.source_error.position_rel, 10 * by_form["anim-baked240"].source_error.position_rel);
    const Measurement blended_local = tuned.Measure(ParseVariantKey(base + ".anim-local240"), {fox + "-x6-animblend"}, SmallTiming());
    ExpectOk(blended_local, tuned, fox + "-x6-animblend");
    EXPECT_GT(blended_local.timing.palette_kernel_ms, 0.0);
    double stated = 0.0;  // the largest a clip alone loses
    for (const BakedClipRecord& c : blended_local.baked_clips) stated = std::max(stated, c.max_error);
    EXPECT_EQ(blended_local.baked_clips.size(), 3u);
    EXPECT_LE(blended_local.source_error.position_rel, 2 * stated + 1e-6);
    EXPECT_LT(10 * blended_local.source_error.position_rel, blended_baked.source_error.position_rel);
    // Hybrid records: the instances of one clip read palette records, the
    // cross-fading third local ones; the crowd loses what the clips state
    // (the larger of both records'), far less than palette records alone,
    // for both records' bytes.
    const Measurement blended_hybrid =
        tuned.Measure(ParseVariantKey(base + ".anim-hybrid240"), {fox + "-x6-animblend"}, SmallTiming());
    ExpectOk(blended_hybrid, tuned, fox + "-x6-animblend");
    double hybrid_stated = 0.0;
    for (const BakedClipRecord& c : blended_hybrid.baked_clips) hybrid_stated = std::max(hybrid_stated, c.max_error);
    ASSERT_EQ(blended_hybrid.baked_clips.size(), 3u);
    EXPECT_LE(blended_hybrid.source_error.position_rel, 2 * hybrid_stated + 1e-6);
    EXPECT_LT(10 * blended_hybrid.source_error.position_rel, blended_baked.source_error.position_rel);
    EXPECT_GT(blended_hybrid.baked_clips.front().bytes, blended_local.baked_clips.front().bytes);
    // Palette records made in the skin launch (fused): the same records, so
    // the same error and clips as baked240's, and no palette kernel's time;
    // only a local copy can hold them.
    const Measurement fused_global = tuned.Measure(ParseVariantKey(base + ".anim-fused240"), {crowd}, SmallTiming());
    EXPECT_EQ(fused_global.status, MeasureStatus::kInvalid);
    EXPECT_NE(fused_global.detail.find("animation_fused"), std::string::npos) << fused_global.detail;
    if (HasWorkGroups(lang) && lang != Lang::kCpu) {
      std::string local = base;
      local.replace(local.find(".global."), 8, ".local.");
      const Measurement fused = tuned.Measure(ParseVariantKey(local + ".anim-fused240"), {crowd}, SmallTiming());
      ExpectOk(fused, tuned, crowd);
      EXPECT_EQ(fused.timing.palette_kernel_ms, 0.0) << "no palette kernel runs";
      ASSERT_TRUE(fused.source_error.known);
      EXPECT_NEAR(fused.source_error.position_rel, by_form["anim-baked240"].source_error.position_rel, 1e-6);
      ASSERT_EQ(fused.baked_clips.size(), 3u);
      EXPECT_EQ(fused.baked_clips.front().bytes, by_form["anim-baked240"].baked_clips.front().bytes);
      ++measured;
    }
    // The host's palettes on an animated scene, and a device form on a scene the host animates: not their variants.
    const Measurement host = tuned.Measure(ParseVariantKey(base), {crowd}, SmallTiming());
    EXPECT_EQ(host.status, MeasureStatus::kInvalid);
    EXPECT_NE(host.detail.find("animation_ignored"), std::string::npos) << host.detail;
    const Measurement missing = tuned.Measure(ParseVariantKey(base + ".anim-sampled"), {"2000-b4-x4"}, SmallTiming());
    EXPECT_EQ(missing.status, MeasureStatus::kInvalid);
    EXPECT_NE(missing.detail.find("animation_missing"), std::string::npos) << missing.detail;
  }
  if (measured == 0) GTEST_SKIP() << "no device here: " << SkippedLines("");
}

// Which devices compile ahead in helper processes (CompileAheadInProcesses),
// and how: PoCL by running each kernel once, NVIDIA's OpenCL by building into
// the program cache, so only where that cache has a directory. Other GPUs
// and APIs build on threads of the measuring worker.
TEST(CompileAhead, PoclAndNvidiasOpenClCompileInHelperProcesses) {
  const auto device = [](const char* backend, const char* platform, const char* type) {
    DeviceIdentity d;
    d.backend = backend;
    d.platform = platform;
    d.type = type;
    return d;
  };
  const DeviceIdentity nvidia = device("opencl", "NVIDIA CUDA", "gpu");
  const DeviceIdentity pocl = device("opencl", "Portable Computing Language", "cpu");
  ScopedEnv always("SKINTUNE_COMPILE_AHEAD", "always");  // a CPU device compiles ahead on any host
  ScopedEnv cache("SKINTUNE_CACHE_DIR", "/tmp/skintune-cache-test");
  EXPECT_TRUE(CompilesAheadInProcesses(nvidia));
  EXPECT_FALSE(CompilesAheadByRunning(nvidia));
  EXPECT_TRUE(CompilesAheadInProcesses(pocl));
  EXPECT_TRUE(CompilesAheadByRunning(pocl));
  for (const DeviceIdentity& other : {device("opencl", "AMD Accelerated Parallel Processing", "gpu"),
                                      device("cuda", "CUDA", "gpu"), device("vulkan", "Vulkan", "gpu")}) {
    EXPECT_FALSE(CompilesAheadInProcesses(other)) << other.backend << " " << other.platform;
    EXPECT_FALSE(CompilesAheadByRunning(other)) << other.backend << " " << other.platform;
  }
  // No program cache on disk: NVIDIA's helpers would build for nothing.
  ScopedEnv no_cache("SKINTUNE_CACHE_DIR", ""), no_xdg("XDG_CACHE_HOME", ""), no_home("HOME", "");
  EXPECT_FALSE(CompilesAheadInProcesses(nvidia));
  EXPECT_TRUE(CompilesAheadInProcesses(pocl)) << "PoCL's kernel cache is its own";
}

// Compiling ahead (the tuner's pool of compile threads, each with a device
// context of its own): every distinct kernel is built once and counted, a
// second call finds them all built, and the measurements that follow load
// them and pass. GPU devices only here (CPU devices compile ahead only on
// hosts with at least 8 CPUs).
// Every device of an API that compiles ahead (SKINTUNE_COMPILE_AHEAD=always:
// here PoCL, llvmpipe and lavapipe too), twice: the second time into the
// same threads' runners (GL, Vulkan) or the measuring runner (OpenCL, CUDA).
TEST(CompileAhead, BuildsEveryKernelThenMeasureUsesThem) {
  ScopedEnv always("SKINTUNE_COMPILE_AHEAD", "always");
  int tried = 0;
  for (const auto& found : Found().devices) {
    TunedDevice& tuned = *found;
    if (!CompilesAhead(tuned.identity())) continue;
    SCOPED_TRACE(tuned.identity().Id());
    const Lang lang = tuned.languages().front();
    std::vector<Variant> variants;
    for (const char* storage : {"global", "constant"})
      for (const char* wg : {"wg64", "wg256"})
        variants.push_back(ParseVariantKey(std::string(Name(lang)) + ".b2.padded.soa.float4.u16.f32.mat3x4." + storage +
                                           ".matrix.v1c." + wg + ".nonormals"));
    EXPECT_EQ(tuned.CompileAhead(variants, {kDataset}, CompileFor::kThisProcess), variants.size());
    EXPECT_EQ(tuned.CompileAhead(variants, {kDataset}, CompileFor::kThisProcess), variants.size())
        << "the second time: found built";
    for (const Variant& v : variants) ExpectOk(tuned.Measure(v, {kDataset}, SmallTiming()), tuned, kDataset);
    ++tried;
  }
  if (tried == 0)
    GTEST_SKIP() << "no device here compiles ahead (GPUs do; CPU devices only on hosts with at least 8 CPUs): "
                 << SkippedLines("");
}

TEST(OpenClTunedDevice, InvalidVariantsSayWhy) {
  DEVICE_OR_SKIP(tuned, "opencl");
  // Normals on a mesh without them: a constraint.
  Measurement m = tuned->Measure(ParseVariantKey("opencl.b2.normals"), {kDataset}, SmallTiming());
  EXPECT_EQ(m.status, MeasureStatus::kInvalid) << m.detail;
  EXPECT_NE(m.detail.find("normals"), std::string::npos) << m.detail;
  // Another API's language.
  m = tuned->Measure(ParseVariantKey("cuda.b2"), {kDataset}, SmallTiming());
  EXPECT_EQ(m.status, MeasureStatus::kInvalid);
  EXPECT_NE(m.detail.find("cuda"), std::string::npos) << m.detail;
  // Fewer slots than the mesh needs.
  m = tuned->Measure(ParseVariantKey("opencl.b1"), {kDataset}, SmallTiming());
  EXPECT_EQ(m.status, MeasureStatus::kInvalid) << m.detail;
}

TEST(OpenClTunedDevice, ABadDatasetIsASetUpError) {
  DEVICE_OR_SKIP(tuned, "opencl");
  EXPECT_THROW(tuned->Measure(ParseVariantKey("opencl.b2"), {"not-a-dataset"}, SmallTiming()), Error);
}

TEST(OpenClTunedDevice, InjectedCompileFaultIsCompileFailed) {
  DEVICE_OR_SKIP(tuned, "opencl");
  const Variant v = ParseVariantKey("opencl.b2.soa.v2c.wg64");
  const std::unique_ptr<TunedDevice> faulty = Faulty(*tuned, v, "compile");
  const Measurement m = faulty->Measure(v, {kDataset}, SmallTiming());
  EXPECT_EQ(m.status, MeasureStatus::kCompileFailed) << Name(m.status) << ": " << m.detail;
  EXPECT_NE(m.detail.find("OpenCL build"), std::string::npos) << m.detail;
  EXPECT_NE(m.detail.find("build log"), std::string::npos) << m.detail;
  // Another variant is not affected.
  ExpectOk(faulty->Measure(ParseVariantKey("opencl.b2.soa.v2c.wg128"), {kDataset}, SmallTiming()), *faulty, kDataset);
}

TEST(OpenClTunedDevice, InjectedWrongResultIsVerifyFailed) {
  DEVICE_OR_SKIP(tuned, "opencl");
  const Variant v = ParseVariantKey("opencl.b2.aos.float3.u8.unorm8");
  const Measurement m = Faulty(*tuned, v, "wrong")->Measure(v, {kDataset}, SmallTiming());
  EXPECT_EQ(m.status, MeasureStatus::kVerifyFailed) << Name(m.status) << ": " << m.detail;
  EXPECT_NE(m.detail.find("max relative error"), std::string::npos) << m.detail;
  EXPECT_NE(m.detail.find("at vertex"), std::string::npos) << m.detail;
  EXPECT_GT(m.max_relative_error, 1e-5);
  EXPECT_EQ(m.timing.repetitions, 0);  // never timed
}

TEST(OpenClTunedDevice, InjectedHangKernelBuilds) {
  DEVICE_OR_SKIP(tuned, "opencl");
  const std::unique_ptr<OpenClRunner> opencl = RunnerOf(*tuned);
  ASSERT_TRUE(opencl) << "the tuned device is not in the OpenCL inventory";
  OpenClRunner& runner = *opencl;
  for (const char* key : {"opencl.b2.soa", "opencl.b2.aos.float3"}) {
    const Variant v = ParseVariantKey(key);
    KernelSource s = Emit(v, 0, 77);
    tuner_internal::InjectFault(s, v, "hang");
    EXPECT_NO_THROW(runner.Build(s)) << key;
  }
}

TEST(OpenClTunedDevice, CopyBandwidthIsPositive) {
  DEVICE_OR_SKIP(tuned, "opencl");
  ExpectCopyBandwidth(*tuned);
}

TEST(OpenClRunnerTiming, PreparesOneSetPerPaletteAndTimesEachRepetition) {
  DEVICE_OR_SKIP(tuned, "opencl");
  const std::unique_ptr<OpenClRunner> opencl = RunnerOf(*tuned);
  ASSERT_TRUE(opencl) << "the tuned device is not in the OpenCL inventory";
  OpenClRunner& runner = *opencl;
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("3000-b3"));
  const Variant v = ParseVariantKey("opencl.b3.bucketed.soa.image");
  const PackedMesh packed = Pack(asset.mesh, v);
  std::vector<KernelSource> kernels;
  for (const Launch& l : packed.launches) kernels.push_back(Emit(v, l.influences, asset.mesh.joint_count));
  std::vector<std::vector<std::uint8_t>> palettes;
  for (const auto& p : tuner_internal::FramePalettes(asset, 3)) palettes.push_back(PackPalette(p, v));
  EXPECT_NE(palettes[0], palettes[1]);  // different frames
  const OpenClPrepared prepared = runner.Prepare(packed, kernels, palettes);
  EXPECT_EQ(prepared.input_sets(), 3);
  std::size_t inputs = 0;
  for (const Launch& l : packed.launches)
    for (const PackedBuffer& b : l.inputs) inputs += b.bytes.size();
  EXPECT_EQ(prepared.bytes_per_set(), inputs + palettes[0].size() + packed.vertex_count * packed.output_stride_bytes);
  const std::vector<double> ms = runner.Time(prepared, 2, 7);
  ASSERT_EQ(ms.size(), 7u);
  for (const double t : ms) EXPECT_GT(t, 0.0);
}

// ---------------------------------------------------------------- GL

TEST(GlTunedDevice, MeasuresComputeAndVertexVariants) {
  DEVICE_OR_SKIP(tuned, "gl");
  for (const char* key : {"glsl-compute.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.nonormals",
                          "glsl-compute.b2.bucketed.soa-split.float3.u8.unorm8.mat4.local.point.v2s.wg64.nonormals",
                          "glsl-vertex.b2.padded.aos.float4.u16.unorm16.mat3x4.constant.matrix.v1c.wg0.nonormals",
                          "glsl-vertex.b2.bucketed.soa.float3.i32.f32.mat4.image.point.v1c.wg0.nonormals"}) {
    SCOPED_TRACE(key);
    ExpectOk(tuned->Measure(ParseVariantKey(key), {kDataset}, SmallTiming()), *tuned, kDataset);
  }
}

TEST(GlTunedDevice, InjectedCompileFaultIsCompileFailed) {
  DEVICE_OR_SKIP(tuned, "gl");
  for (const char* key : {"glsl-compute.b2.soa", "glsl-vertex.b2.soa.v1c.wg0"}) {
    const Variant v = ParseVariantKey(key);
    const Measurement m = Faulty(*tuned, v, "compile")->Measure(v, {kDataset}, SmallTiming());
    EXPECT_EQ(m.status, MeasureStatus::kCompileFailed) << key << ": " << Name(m.status) << ": " << m.detail;
    EXPECT_NE(m.detail.find("GL build"), std::string::npos) << m.detail;
  }
}

TEST(GlTunedDevice, InjectedWrongResultIsVerifyFailed) {
  DEVICE_OR_SKIP(tuned, "gl");
  for (const char* key : {"glsl-compute.b2.aos.float3", "glsl-vertex.b2.soa-split.v1c.wg0"}) {
    const Variant v = ParseVariantKey(key);
    const Measurement m = Faulty(*tuned, v, "wrong")->Measure(v, {kDataset}, SmallTiming());
    EXPECT_EQ(m.status, MeasureStatus::kVerifyFailed) << key << ": " << Name(m.status) << ": " << m.detail;
    EXPECT_NE(m.detail.find("max relative error"), std::string::npos) << m.detail;
    EXPECT_GT(m.max_relative_error, 1e-5);
  }
}

TEST(GlTunedDevice, InjectedHangKernelsBuild) {
  DEVICE_OR_SKIP(tuned, "gl");
  GlRunner runner;
  for (const char* key : {"glsl-compute.b2.soa", "glsl-compute.b2.aos", "glsl-vertex.b2.soa.v1c.wg0"}) {
    const Variant v = ParseVariantKey(key);
    KernelSource s = Emit(v, 0, 77);
    tuner_internal::InjectFault(s, v, "hang");
    EXPECT_NO_THROW(runner.Build(s)) << key;
  }
}

TEST(GlTunedDevice, CopyBandwidthIsPositive) {
  DEVICE_OR_SKIP(tuned, "gl");
  ExpectCopyBandwidth(*tuned);
}

// ---------------------------------------------------------------- Vulkan (lavapipe here)

TEST(VulkanTunedDevice, MeasuresVariantsWithTheChipsIdentity) {
  DEVICE_OR_SKIP(tuned, "vulkan");
  EXPECT_EQ(tuned->languages(), std::vector<Lang>{Lang::kVulkan});
  const DeviceIdentity& d = tuned->identity();
  EXPECT_EQ(d.Id().rfind("vulkan:Vulkan/", 0), 0u) << d.Id();
  if (d.type == "gpu") {
    EXPECT_EQ(d.uuid.size(), 32u) << "a GPU's Vulkan device names its chip";
  }
  for (const char* key : {"vulkan.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.nonormals",
                          "vulkan.b2.bucketed.aos.float3.u8.unorm8.mat4.image.point.v2s.wg64.nonormals"}) {
    SCOPED_TRACE(key);
    ExpectOk(tuned->Measure(ParseVariantKey(key), {kDataset}, SmallTiming()), *tuned, kDataset);
  }
}

TEST(VulkanTunedDevice, InjectedCompileAndWrongFaultsAreCompileAndVerifyFailed) {
  DEVICE_OR_SKIP(tuned, "vulkan");
  ExpectInjectedCompileAndWrongFaults(*tuned, ParseVariantKey("vulkan.b2.soa.wg64"), "Vulkan build");
}

// ---------------------------------------------------------------- cpu (the fast path's kernels, every machine)

TEST(CpuTunedDevice, MeasuresVariantsWithTheSameSizeCopyAndRecordsFaults) {
  DEVICE_OR_SKIP(tuned, "cpu");
  EXPECT_EQ(tuned->languages(), std::vector<Lang>{Lang::kCpu});
  EXPECT_EQ(tuned->identity().Id().rfind("cpu:skintune/", 0), 0u) << tuned->identity().Id();
  for (const char* key : {"cpu.b2.padded.soa-split.float3.u8.unorm16.mat4.global.matrix.v1c.wg0.nonormals",
                          "cpu.b2.bucketed.aos.float4.i32.f32.mat3x4.global.point.v1c.wg0.nonormals"}) {
    SCOPED_TRACE(key);
    const Measurement m = tuned->Measure(ParseVariantKey(key), {kDataset}, SmallTiming());
    ExpectOk(m, *tuned, kDataset);
    EXPECT_GT(m.timing.copy_ms, 0.0) << "the all-thread memcpy of the same bytes";
    EXPECT_NEAR(m.x_copy, m.timing.median_ms / m.timing.copy_ms, 1e-9 * m.x_copy);
  }
  EXPECT_GT(tuned->CopyBandwidthGBps(16u << 20), 0.0);
  ExpectInjectedCompileAndWrongFaults(*tuned, ParseVariantKey("cpu.b2.soa.v1c.wg0"), "CPU build");
  // Storages other than global are invalid on the device, recorded so.
  const Measurement local = tuned->Measure(ParseVariantKey("cpu.b2.soa.local.v1c.wg0"), {kDataset}, SmallTiming());
  EXPECT_EQ(local.status, MeasureStatus::kInvalid) << local.detail;
}

// ---------------------------------------------------------------- CUDA (where there is a GPU)

TEST(CudaTunedDevice, MeasuresVariantsAndInjectedFaults) {
  DEVICE_OR_SKIP(tuned, "cuda");
  for (const char* key : {"cuda.b2.padded.soa.float4.u16.f32.mat3x4.global.matrix.v1c.wg128.nonormals",
                          "cuda.b2.bucketed.soa-split.float3.u8.unorm8.mat4.constant.point.v2s.wg64.nonormals",
                          "cuda.b2.padded.aos.float4.i32.unorm16.mat3x4.image.matrix.v4c.wg256.nonormals",
                          "cuda.b2.padded.soa.float4.u16.f32.mat3x4.local.matrix.v8s.wg32.nonormals"}) {
    SCOPED_TRACE(key);
    ExpectOk(tuned->Measure(ParseVariantKey(key), {kDataset}, SmallTiming()), *tuned, kDataset);
  }
  const Variant v = ParseVariantKey("cuda.b2.soa");
  {
    const Measurement m = Faulty(*tuned, v, "compile")->Measure(v, {kDataset}, SmallTiming());
    EXPECT_EQ(m.status, MeasureStatus::kCompileFailed) << m.detail;
  }
  {
    const Measurement m = Faulty(*tuned, v, "wrong")->Measure(v, {kDataset}, SmallTiming());
    EXPECT_EQ(m.status, MeasureStatus::kVerifyFailed) << m.detail;
  }
  const double gbps = tuned->CopyBandwidthGBps(256u << 20);
  std::cout << "[ copy     ] " << tuned->identity().name << ": " << gbps << " GB/s\n";
  EXPECT_GT(gbps, 0.0);
}

// The measuring runner chosen among runners on contexts of their own
// (tuner/runner_device.h OpenQuickest), with runners that stand for contexts
// (the cpu device's: any Runner will do) and launch starts given per runner.
struct Contexts {
  std::vector<std::vector<double>> starts;  // the samples each probe of runner i returns
  std::vector<bool> fails_to_open, fails_probe;
  std::vector<const Runner*> opened;        // by opening order (null: failed)
  std::vector<std::size_t> probed;          // runner indices in probing order
  int probes_made = 0;                      // one per runner opened, for every round
  std::unique_ptr<Runner> Open() {
    const std::size_t i = opened.size();
    if (i < fails_to_open.size() && fails_to_open[i]) {
      opened.push_back(nullptr);
      throw Error("context " + std::to_string(i) + " did not open");
    }
    auto runner = std::make_unique<CpuRunner>(1);
    opened.push_back(runner.get());
    return runner;
  }
  std::vector<double> Probe(Runner& runner) {
    const auto i = static_cast<std::size_t>(std::find(opened.begin(), opened.end(), &runner) - opened.begin());
    probed.push_back(i);
    if (i < fails_probe.size() && fails_probe[i]) throw Error("context " + std::to_string(i) + " did not time");
    return starts.at(i);
  }
  tuner_internal::QuickestRunner Choose(int count, int rounds) {
    return tuner_internal::OpenQuickest(count, rounds, [this] { return Open(); }, [this](Runner& r) {
      ++probes_made;
      return [this, &r] { return Probe(r); };
    });
  }
};

TEST(QuickestContext, KeepsTheLowestLaunchStartTheFirstOnATieProbingInTurn) {
  Contexts c;
  c.starts = {{2.20, 2.21}, {2.05, 2.06}, {2.05, 2.06}, {2.30, 2.30}};
  const tuner_internal::QuickestRunner q = c.Choose(4, 2);
  EXPECT_EQ(q.chosen, 1u);
  EXPECT_EQ(q.runner.get(), c.opened[1]);
  ASSERT_EQ(q.starts_ms.size(), 4u);
  EXPECT_DOUBLE_EQ(q.starts_ms[0], 2.205);
  EXPECT_DOUBLE_EQ(q.starts_ms[3], 2.30);
  // Every runner open together and probed in turn, round by round.
  EXPECT_EQ(c.probed, (std::vector<std::size_t>{0, 1, 2, 3, 0, 1, 2, 3}));
  // Each runner's probe prepared once, sampled in every round.
  EXPECT_EQ(c.probes_made, 4);
}

TEST(QuickestContext, LeavesOutARunnerThatFailsToOpenOrToBeProbed) {
  Contexts c;
  c.starts = {{2.2}, {1.0}, {1.5}, {2.1}};
  c.fails_to_open = {false, true};
  c.fails_probe = {false, false, true};
  const tuner_internal::QuickestRunner q = c.Choose(4, 2);
  EXPECT_EQ(q.chosen, 3u);
  EXPECT_TRUE(std::isnan(q.starts_ms[1]));
  EXPECT_TRUE(std::isnan(q.starts_ms[2]));
  // The one that failed its probe is not probed again.
  EXPECT_EQ(c.probed, (std::vector<std::size_t>{0, 2, 3, 0, 3}));
  EXPECT_EQ(c.probes_made, 3);
}

TEST(QuickestContext, ThrowsTheLastErrorWhenNoneIsLeft) {
  Contexts c;
  c.fails_to_open = {true, false};
  c.fails_probe = {false, true};
  c.starts = {{1.0}, {1.0}};
  try {
    (void)c.Choose(2, 1);
    ADD_FAILURE() << "a runner was chosen with none left";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("context 1 did not time"), std::string::npos) << e.what();
  }
}

// This machine's first OpenCL device (PoCL in CI) seen as a GPU that offers
// contexts of its own, its runners counted as they open (`open` the shared
// context's, `open_own` one of its own); none where there is no OpenCL device.
std::optional<FoundDevice> OpenClSeenAsAGpu(int& opened, int& opened_own) {
  static const Discovered found = DiscoverDevices();
  for (const FoundDevice& f : found.devices) {
    if (f.identity.backend != "opencl") continue;
    FoundDevice device = f;
    device.open = [&opened, open = f.open] { ++opened; return open(); };
    device.open_own = [&opened_own, open = f.open] { ++opened_own; return open(); };
    device.identity.type = "gpu";
    return device;
  }
  return std::nullopt;
}

// OpenMeasuringRunner's wiring on this machine's first OpenCL device (PoCL
// in CI), seen as a GPU that offers contexts of their own: six opened and
// probed, one kept, its launch start recorded; as a GPU whose API offers
// none (GL, Vulkan) or where none opens: the one runner opened, its launch
// start probed; as the host's CPU: opened once, no choice and no probe.
TEST(QuickestContext, AGpuChoosesAmongSixContextsAndTheHostsCpuOpensOne) {
  int opened = 0, opened_own = 0;
  std::optional<FoundDevice> counted = OpenClSeenAsAGpu(opened, opened_own);
  if (!counted) GTEST_SKIP() << SkippedLines("opencl");
  FoundDevice& device = *counted;
  tuner_internal::MeasuringContext context;
  EXPECT_NE(tuner_internal::OpenMeasuringRunner(device, Lang::kOpenCl, nullptr, &context), nullptr);
  EXPECT_EQ(opened_own, 6);
  EXPECT_EQ(opened, 0);
  // What every measurement then records (timing.context, timing.launch_start_ms).
  const std::string& choice = context.choice;
  EXPECT_EQ(choice.rfind("the quickest of 6 contexts by launch start (a 4 KiB copy after the flush): ", 0), 0u)
      << choice;
  EXPECT_NE(choice.find("; the others "), std::string::npos) << choice;
  char chosen[32];
  std::snprintf(chosen, sizeof chosen, ": %.3f us", context.launch_start_ms * 1e3);
  EXPECT_NE(choice.find(chosen), std::string::npos) << choice << " does not name " << chosen;
  EXPECT_GT(context.launch_start_ms, 0.0);

  device.identity.type = "cpu";
  opened = opened_own = 0;
  EXPECT_NE(tuner_internal::OpenMeasuringRunner(device, Lang::kOpenCl, nullptr, &context), nullptr);
  EXPECT_EQ(opened_own, 0);
  EXPECT_EQ(opened, 1);
  EXPECT_EQ(context.choice, "");
  EXPECT_EQ(context.launch_start_ms, 0.0) << "the host's CPU has no launch to start";

  device.identity.type = "gpu";
  device.open_own = nullptr;
  opened = opened_own = 0;
  EXPECT_NE(tuner_internal::OpenMeasuringRunner(device, Lang::kOpenCl, nullptr, &context), nullptr);
  EXPECT_EQ(opened, 1);
  EXPECT_EQ(context.choice, "");
  EXPECT_GT(context.launch_start_ms, 0.0) << "a GPU whose API offers no contexts of its own is probed too";

  device.open_own = []() -> std::unique_ptr<Runner> { throw Error("no context of its own here"); };
  opened = 0;
  context = {};
  EXPECT_NE(tuner_internal::OpenMeasuringRunner(device, Lang::kOpenCl, nullptr, &context), nullptr);
  EXPECT_EQ(opened, 1);
  EXPECT_EQ(context.choice, "");
  EXPECT_GT(context.launch_start_ms, 0.0);
}

// A compile ahead for the program cache alone (a compile helper's, or a
// later device's head start: processes that time nothing) chooses no
// context: the choice's probes would run on the chip beside another API's
// timing. One for the measuring process builds into the chosen context.
// This machine's first OpenCL device, seen as a GPU that offers contexts of their own.
TEST(QuickestContext, ACompileForTheCacheChoosesNoContext) {
  ScopedEnv always("SKINTUNE_COMPILE_AHEAD", "always");
  int opened = 0, opened_own = 0;
  std::optional<FoundDevice> counted = OpenClSeenAsAGpu(opened, opened_own);
  if (!counted) GTEST_SKIP() << SkippedLines("opencl");
  FoundDevice& device = *counted;
  std::vector<Variant> variants;
  for (const char* storage : {"global", "constant"})
    variants.push_back(ParseVariantKey(std::string("opencl.b2.padded.soa.float4.u16.f32.mat3x4.") + storage +
                                       ".matrix.v1c.wg64.nonormals"));
  {
    const std::unique_ptr<TunedDevice> tuned = tuner_internal::MakeRunnerDevice(device, {Lang::kOpenCl}, 0, {});
    EXPECT_EQ(tuned->CompileAhead(variants, {kDataset}, CompileFor::kTheCache), variants.size());
    EXPECT_EQ(opened_own, 0) << "a context chosen by a process that times nothing";
    EXPECT_EQ(opened, 1);
  }
  opened = 0;
  const std::unique_ptr<TunedDevice> tuned = tuner_internal::MakeRunnerDevice(device, {Lang::kOpenCl}, 0, {});
  EXPECT_EQ(tuned->CompileAhead(variants, {kDataset}, CompileFor::kThisProcess), variants.size());
  EXPECT_EQ(opened_own, 6);
  EXPECT_EQ(opened, 0);
  // Its measurements then run in the chosen context, which the cache's compile did not open.
  ExpectOk(tuned->Measure(variants.front(), {kDataset}, SmallTiming()), *tuned, kDataset);
  EXPECT_EQ(opened_own, 6);
}

}  // namespace
}  // namespace skintune::internal
