// Host <-> device copies on a CUDA device, the raw costs under the frame loop
// (issue 15): what one palette upload (64 x 77 mat3x4, 236 KB; or mat4,
// 315 KB) and one read-back (1.6M float4, 25.6 MB) cost on this machine,
// from each kind of host memory, each copy waited for (the frame loop's
// fence wait is the same wait).
//
//   htod/<bytes>/pageable    cuMemcpyHtoD from malloc'd memory (synchronous)
//   htod/<bytes>/pinned      cuMemcpyHtoDAsync from cuMemHostAlloc(0) + cuStreamSynchronize
//   htod/<bytes>/pinned-wc   the same from write-combined page-locked memory (the palette staging)
//   dtoh/<bytes>/pageable    cuMemcpyDtoH into malloc'd memory
//   dtoh/<bytes>/pinned      cuMemcpyDtoHAsync into cuMemHostAlloc(0) + cuStreamSynchronize
//   sync/empty               cuEventRecord + cuEventSynchronize on an idle stream
//   call/<bytes>/<memory>    the host's time in the calls of one SetPalette upload alone:
//                            cuMemcpyHtoDAsync + cuEventRecord, the copy not waited for
//                            (the stream is drained every 32 copies, outside the time)
//   call/frame/<op>          each other driver call of a pipelined frame alone, the host's time:
//                              launch        cuLaunchKernel of an empty kernel (the stream drained every 32)
//                              record        cuEventRecord
//                              wait-event    cuStreamWaitEvent on an event already recorded
//                              sync-done     cuEventSynchronize on an event already complete
//                              query-done    cuEventQuery on an event already complete
//                              set-current   cuCtxSetCurrent (the runtime's MakeCurrent)
//                              all           the frame's five queueing calls in order: upload
//                                            (cuMemcpyHtoDAsync 236 KB + cuEventRecord on the
//                                            upload stream), cuStreamWaitEvent, cuLaunchKernel,
//                                            cuEventRecord on the kernel's stream
//   call/frame/<op>/thread:<beside>/cpu:<where>
//                            the same call made by a second thread, one call per frame, while
//                            the calling thread does <beside> (idle: spins on an atomic; pack-wc /
//                            pack: memcpy of a 236 KB palette into write-combined / ordinary
//                            page-locked memory, then spins) and <where> places the two threads
//                            (any: the scheduler's; sibling: the two hardware threads of one core;
//                            apart: two cores): the submit thread's launch, taken apart
//   call/frame/graph/<shape> cuGraphLaunch of a graph holding the frame's work (one-stream: the
//                            236 KB upload, then the kernel; two-streams: the upload on its own
//                            stream, joined to the kernel's by an event), instantiated once
//   host/<bytes>/pack-wc     memcpy of the bytes into write-combined memory (the packing's stores)
//   host/<bytes>/pack        the same into ordinary memory
//   palette/<memory>         PackPaletteInto of 64 x 77 mat3x4 (SetPalette's packing) into
//                            each kind of host memory, from 8 poses in turn as the frame
//                            benchmark's (2.5 MB of input: not all in a core's cache)
//   palette/<memory>/poses:2 the same from 2 poses (0.6 MB: in L2, as the frame benchmark's default)
//   palette/<memory>/chunks:<n>  the same in n chunks on the runtime's host pool
//                            (runtime/host_work.h ForChunks: the read-back's spinning threads)
//
// Each reports bytes/s; the time is the host's wall time per copy.
//
//   skintune_bench_upload [google benchmark flags]
#include <benchmark/benchmark.h>

#include <dlfcn.h>
#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <thread>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "generator/packer.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/host_work.h"

namespace {

using namespace skintune::internal;

const cuda::DriverApi* api = nullptr;
cuda::Stream stream = nullptr;
cuda::Context context = nullptr;  // the device's primary context

void Ok(cuda::Result r, const char* what) {
  if (r != cuda::kSuccess) {
    std::fprintf(stderr, "skintune_bench_upload: %s failed: %s\n", what, cuda::ErrorText(r).c_str());
    std::exit(1);
  }
}

enum class Memory { kPageable, kPinned, kPinnedWc };

struct Host {
  void* p = nullptr;
  Memory kind;
  Host(std::size_t bytes, Memory k) : kind(k) {
    if (kind == Memory::kPageable) {
      p = std::malloc(bytes);
      std::memset(p, 1, bytes);
    } else {
      Ok(api->cuMemHostAlloc(&p, bytes, kind == Memory::kPinnedWc ? cuda::kMemHostAllocWriteCombined : 0u),
         "cuMemHostAlloc");
      std::memset(p, 1, bytes);
    }
  }
  ~Host() {
    if (kind == Memory::kPageable) std::free(p);
    else api->cuMemFreeHost(p);
  }
};

struct DeviceMemory {
  cuda::DevicePtr p = 0;
  explicit DeviceMemory(std::size_t bytes) { Ok(api->cuMemAlloc(&p, bytes), "cuMemAlloc"); }
  ~DeviceMemory() { api->cuMemFree(p); }
};

void HtoD(benchmark::State& state, std::size_t bytes, Memory kind) {
  Host host(bytes, kind);
  DeviceMemory device(bytes);
  for (auto _ : state) {
    if (kind == Memory::kPageable) {
      Ok(api->cuMemcpyHtoD(device.p, host.p, bytes), "cuMemcpyHtoD");
    } else {
      Ok(api->cuMemcpyHtoDAsync(device.p, host.p, bytes, stream), "cuMemcpyHtoDAsync");
      Ok(api->cuStreamSynchronize(stream), "cuStreamSynchronize");
    }
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
}

void DtoH(benchmark::State& state, std::size_t bytes, Memory kind) {
  Host host(bytes, kind);
  DeviceMemory device(bytes);
  for (auto _ : state) {
    if (kind == Memory::kPageable) {
      Ok(api->cuMemcpyDtoH(host.p, device.p, bytes), "cuMemcpyDtoH");
    } else {
      Ok(api->cuMemcpyDtoHAsync(host.p, device.p, bytes, stream), "cuMemcpyDtoHAsync");
      Ok(api->cuStreamSynchronize(stream), "cuStreamSynchronize");
    }
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
}

void UploadCalls(benchmark::State& state, std::size_t bytes, Memory kind) {
  Host host(bytes, kind);
  DeviceMemory device(bytes);
  cuda::Event event = nullptr;
  Ok(api->cuEventCreate(&event, cuda::kEventDisableTiming), "cuEventCreate");
  std::size_t n = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    Ok(api->cuMemcpyHtoDAsync(device.p, host.p, bytes, stream), "cuMemcpyHtoDAsync");
    Ok(api->cuEventRecord(event, stream), "cuEventRecord");
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    if (++n % 32 == 0) Ok(api->cuStreamSynchronize(stream), "cuStreamSynchronize");
  }
  Ok(api->cuStreamSynchronize(stream), "cuStreamSynchronize");
  api->cuEventDestroy(event);
}

// An empty kernel, as PTX the driver compiles for any device.
constexpr char kEmptyPtx[] =
    ".version 7.0\n.target sm_50\n.address_size 64\n.visible .entry skintune_empty()\n{\n  ret;\n}\n";

enum class Call { kLaunch, kRecord, kWaitEvent, kSyncDone, kQueryDone, kSetCurrent, kAll };

// What the frame's call rows share: the empty kernel, an upload stream, three
// events (`done` recorded and complete), and a 236 KB palette in write-combined
// page-locked memory and on the device. Drains the device before it goes.
struct FrameSetup {
  static constexpr std::size_t kPalettes = 64 * 77 * 48;
  cuda::Module module = nullptr;
  cuda::Function function = nullptr;
  cuda::Stream uploads = nullptr;
  cuda::Event done = nullptr, uploaded = nullptr, marker = nullptr;
  Host staging{kPalettes, Memory::kPinnedWc};
  DeviceMemory device{kPalettes};

  FrameSetup() {
    Ok(api->cuModuleLoadDataEx(&module, kEmptyPtx, 0, nullptr, nullptr), "cuModuleLoadDataEx");
    Ok(api->cuModuleGetFunction(&function, module, "skintune_empty"), "cuModuleGetFunction");
    Ok(api->cuStreamCreate(&uploads, 1 /* CU_STREAM_NON_BLOCKING */), "cuStreamCreate");
    for (cuda::Event* e : {&done, &uploaded, &marker}) Ok(api->cuEventCreate(e, cuda::kEventDisableTiming), "cuEventCreate");
    Ok(api->cuEventRecord(done, stream), "cuEventRecord");
    Ok(api->cuStreamSynchronize(stream), "cuStreamSynchronize");
  }
  ~FrameSetup() {
    api->cuCtxSynchronize();
    for (cuda::Event e : {done, uploaded, marker}) api->cuEventDestroy(e);
    api->cuStreamDestroy(uploads);
    api->cuModuleUnload(module);
  }
  void Launch() const {
    Ok(api->cuLaunchKernel(function, 1, 1, 1, 32, 1, 1, 0, stream, nullptr, nullptr), "cuLaunchKernel");
  }
  // The frame's five queueing calls: upload, record, wait, launch, record.
  void All() const {
    Ok(api->cuMemcpyHtoDAsync(device.p, staging.p, kPalettes, uploads), "cuMemcpyHtoDAsync");
    Ok(api->cuEventRecord(uploaded, uploads), "cuEventRecord");
    Ok(api->cuStreamWaitEvent(stream, uploaded, 0), "cuStreamWaitEvent");
    Launch();
    Ok(api->cuEventRecord(marker, stream), "cuEventRecord");
  }
};

void FrameCall(benchmark::State& state, Call call) {
  const FrameSetup f;
  std::size_t n = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    switch (call) {
      case Call::kLaunch: f.Launch(); break;
      case Call::kRecord: Ok(api->cuEventRecord(f.marker, stream), "cuEventRecord"); break;
      case Call::kWaitEvent: Ok(api->cuStreamWaitEvent(stream, f.done, 0), "cuStreamWaitEvent"); break;
      case Call::kSyncDone: Ok(api->cuEventSynchronize(f.done), "cuEventSynchronize"); break;
      case Call::kQueryDone: Ok(api->cuEventQuery(f.done), "cuEventQuery"); break;
      case Call::kSetCurrent: Ok(api->cuCtxSetCurrent(context), "cuCtxSetCurrent"); break;
      case Call::kAll: f.All(); break;
    }
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    if (++n % 32 == 0) Ok(api->cuCtxSynchronize(), "cuCtxSynchronize");
  }
}

// The second thread's frame calls (call/frame/<op>/thread:...): `caller` and
// `submitter` are CPU numbers, or -1 for the scheduler's choice.
enum class Beside { kIdle, kPackWc, kPack };

// The CPUs the process started on: PinTo(-1) gives them back (a thread made
// by a pinned one inherits its one CPU).
cpu_set_t original_cpus;

void PinTo(int cpu) {
  cpu_set_t set = original_cpus;
  if (cpu >= 0) {
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
  }
  pthread_setaffinity_np(pthread_self(), sizeof set, &set);
}

void FrameCallOnThread(benchmark::State& state, Call call, Beside beside, int caller, int submitter) {
  const FrameSetup f;
  Host packed(FrameSetup::kPalettes, beside == Beside::kPack ? Memory::kPinned : Memory::kPinnedWc);
  std::vector<unsigned char> pose(FrameSetup::kPalettes, 3);
  std::atomic<int> go{0}, done{0};
  std::atomic<bool> stop{false};
  double call_seconds = 0.0;
  std::thread thread([&] {
    PinTo(submitter);
    Ok(api->cuCtxSetCurrent(context), "cuCtxSetCurrent");
    int seen = 0;
    while (true) {
      while (go.load(std::memory_order_acquire) == seen && !stop.load(std::memory_order_relaxed)) __builtin_ia32_pause();
      if (stop.load()) break;
      ++seen;
      const auto start = std::chrono::steady_clock::now();
      if (call == Call::kAll) f.All();
      else f.Launch();
      call_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (seen % 32 == 0) Ok(api->cuStreamSynchronize(stream), "cuStreamSynchronize");
      done.store(seen, std::memory_order_release);
    }
  });
  PinTo(caller);
  int n = 0;
  for (auto _ : state) {
    go.store(++n, std::memory_order_release);  // the thread calls while this one packs the next frame
    if (beside != Beside::kIdle) std::memcpy(packed.p, pose.data(), FrameSetup::kPalettes);
    while (done.load(std::memory_order_acquire) != n) __builtin_ia32_pause();
    state.SetIterationTime(call_seconds);
  }
  stop.store(true);
  thread.join();
  PinTo(-1);
}

// Stream capture and graphs, looked up here (the runtime does not use them).
struct GraphApi {
  cuda::Result (*cuStreamBeginCapture)(cuda::Stream, int mode) = nullptr;  // _v2
  cuda::Result (*cuStreamEndCapture)(cuda::Stream, void** graph) = nullptr;
  cuda::Result (*cuGraphInstantiateWithFlags)(void** exec, void* graph, unsigned long long flags) = nullptr;
  cuda::Result (*cuGraphLaunch)(void* exec, cuda::Stream) = nullptr;
  cuda::Result (*cuGraphExecDestroy)(void* exec) = nullptr;
  cuda::Result (*cuGraphDestroy)(void* graph) = nullptr;
};

const GraphApi* Graphs() {
  static const GraphApi graphs = [] {
    GraphApi g;
    void* handle = dlopen("libcuda.so.1", RTLD_NOW | RTLD_NOLOAD);
    if (!handle) return g;
    g.cuStreamBeginCapture = reinterpret_cast<decltype(g.cuStreamBeginCapture)>(dlsym(handle, "cuStreamBeginCapture_v2"));
    g.cuStreamEndCapture = reinterpret_cast<decltype(g.cuStreamEndCapture)>(dlsym(handle, "cuStreamEndCapture"));
    g.cuGraphInstantiateWithFlags =
        reinterpret_cast<decltype(g.cuGraphInstantiateWithFlags)>(dlsym(handle, "cuGraphInstantiateWithFlags"));
    g.cuGraphLaunch = reinterpret_cast<decltype(g.cuGraphLaunch)>(dlsym(handle, "cuGraphLaunch"));
    g.cuGraphExecDestroy = reinterpret_cast<decltype(g.cuGraphExecDestroy)>(dlsym(handle, "cuGraphExecDestroy"));
    g.cuGraphDestroy = reinterpret_cast<decltype(g.cuGraphDestroy)>(dlsym(handle, "cuGraphDestroy"));
    return g;
  }();
  return &graphs;
}

void GraphLaunch(benchmark::State& state, bool two_streams) {
  const GraphApi* g = Graphs();
  if (!g->cuStreamBeginCapture || !g->cuGraphLaunch || !g->cuGraphInstantiateWithFlags) {
    state.SkipWithError("the driver has no stream capture or graphs");
    return;
  }
  const FrameSetup f;
  void* graph = nullptr;
  void* exec = nullptr;
  Ok(g->cuStreamBeginCapture(stream, 2 /* CU_STREAM_CAPTURE_MODE_RELAXED */), "cuStreamBeginCapture");
  if (two_streams) {
    Ok(api->cuEventRecord(f.marker, stream), "cuEventRecord");  // the fork
    Ok(api->cuStreamWaitEvent(f.uploads, f.marker, 0), "cuStreamWaitEvent");
    Ok(api->cuMemcpyHtoDAsync(f.device.p, f.staging.p, FrameSetup::kPalettes, f.uploads), "cuMemcpyHtoDAsync");
    Ok(api->cuEventRecord(f.uploaded, f.uploads), "cuEventRecord");
    Ok(api->cuStreamWaitEvent(stream, f.uploaded, 0), "cuStreamWaitEvent");
  } else {
    Ok(api->cuMemcpyHtoDAsync(f.device.p, f.staging.p, FrameSetup::kPalettes, stream), "cuMemcpyHtoDAsync");
  }
  f.Launch();
  Ok(g->cuStreamEndCapture(stream, &graph), "cuStreamEndCapture");
  Ok(g->cuGraphInstantiateWithFlags(&exec, graph, 0), "cuGraphInstantiateWithFlags");
  std::size_t n = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    Ok(g->cuGraphLaunch(exec, stream), "cuGraphLaunch");
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    if (++n % 32 == 0) Ok(api->cuStreamSynchronize(stream), "cuStreamSynchronize");
  }
  Ok(api->cuCtxSynchronize(), "cuCtxSynchronize");
  g->cuGraphExecDestroy(exec);
  g->cuGraphDestroy(graph);
}

// CPU 0's partner hardware thread, or -1 (none, or unknown).
int SiblingOfCpu0() {
  std::ifstream in("/sys/devices/system/cpu/cpu0/topology/thread_siblings_list");
  std::string list;
  if (!(in >> list)) return -1;
  for (std::size_t at = 0; at < list.size();) {
    const std::size_t end = list.find_first_of(",-", at);
    const int cpu = std::atoi(list.substr(at, end - at).c_str());
    if (cpu != 0) return cpu;
    if (end == std::string::npos) break;
    at = end + 1;
  }
  return -1;
}

// A CPU on another core than CPU 0, or -1.
int ApartFromCpu0() {
  const int sibling = SiblingOfCpu0();
  const unsigned n = std::thread::hardware_concurrency();
  for (unsigned cpu = 1; cpu < n; ++cpu)
    if (static_cast<int>(cpu) != sibling) return static_cast<int>(cpu);
  return -1;
}

void EmptySync(benchmark::State& state) {
  cuda::Event event = nullptr;
  Ok(api->cuEventCreate(&event, cuda::kEventDisableTiming), "cuEventCreate");
  for (auto _ : state) {
    Ok(api->cuEventRecord(event, stream), "cuEventRecord");
    Ok(api->cuEventSynchronize(event), "cuEventSynchronize");
  }
  api->cuEventDestroy(event);
}

void CopyIn(benchmark::State& state, std::size_t bytes, Memory kind) {
  Host to(bytes, kind);
  std::vector<unsigned char> from(bytes, 2);
  for (auto _ : state) {
    std::memcpy(to.p, from.data(), bytes);
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
}

void PackPalettes(benchmark::State& state, Memory kind, std::size_t chunks, std::size_t kPoses) {
  constexpr std::size_t kMatrices = 64 * 77;
  Variant variant;
  variant.palette = PaletteFormat::kMat3x4;
  Host to(kMatrices * 48, kind);
  std::vector<std::vector<float>> poses(kPoses, std::vector<float>(kMatrices * 16));
  for (std::size_t p = 0; p < kPoses; ++p)
    for (std::size_t i = 0; i < poses[p].size(); ++i) poses[p][i] = static_cast<float>((i + p) % 97) * 0.01f;
  std::size_t pose = 0;
  auto* out = static_cast<std::uint8_t*>(to.p);
  for (auto _ : state) {
    const float* in = poses[pose++ % kPoses].data();
    if (chunks <= 1) {
      benchmark::DoNotOptimize(PackPaletteInto(in, kMatrices, variant, out));
    } else {
      ForChunks(kMatrices, (kMatrices + chunks - 1) / chunks, [&](std::size_t begin, std::size_t end) {
        benchmark::DoNotOptimize(PackPaletteInto(in + 16 * begin, end - begin, variant, out + 48 * begin));
      });
    }
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * kMatrices * 48));
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  pthread_getaffinity_np(pthread_self(), sizeof original_cpus, &original_cpus);
  std::string why;
  api = cuda::Driver(&why);
  if (!api) {
    std::fprintf(stderr, "skintune_bench_upload: no CUDA driver: %s\n", why.c_str());
    return 1;
  }
  cuda::Device device = 0;
  Ok(api->cuDeviceGet(&device, 0), "cuDeviceGet");
  Ok(api->cuDevicePrimaryCtxRetain(&context, device), "cuDevicePrimaryCtxRetain");
  Ok(api->cuCtxSetCurrent(context), "cuCtxSetCurrent");
  Ok(api->cuStreamCreate(&stream, 1 /* CU_STREAM_NON_BLOCKING */), "cuStreamCreate");
  const struct {
    const char* name;
    Memory kind;
  } memories[] = {{"pageable", Memory::kPageable}, {"pinned", Memory::kPinned}, {"pinned-wc", Memory::kPinnedWc}};
  for (std::size_t bytes : {std::size_t{64 * 77 * 48}, std::size_t{64 * 77 * 64}, std::size_t{1600000 * 16}}) {
    for (const auto& m : memories) {
      const std::string size = std::to_string(bytes);
      benchmark::RegisterBenchmark(("htod/" + size + "/" + m.name).c_str(), HtoD, bytes, m.kind)->UseRealTime();
      if (m.kind != Memory::kPinnedWc)
        benchmark::RegisterBenchmark(("dtoh/" + size + "/" + m.name).c_str(), DtoH, bytes, m.kind)->UseRealTime();
      if (m.kind != Memory::kPageable)
        benchmark::RegisterBenchmark(("call/" + size + "/" + m.name).c_str(), UploadCalls, bytes, m.kind)->UseManualTime();
      if (m.kind != Memory::kPinned)
        benchmark::RegisterBenchmark(("host/" + size + "/" + std::string(m.kind == Memory::kPinnedWc ? "pack-wc" : "pack")).c_str(),
                                     CopyIn, bytes, m.kind)
            ->UseRealTime();
    }
  }
  for (const auto& m : memories)
    for (std::size_t chunks : {1, 4, 8, 16}) {
      const std::string name = std::string("palette/") + m.name + (chunks > 1 ? "/chunks:" + std::to_string(chunks) : "");
      benchmark::RegisterBenchmark(name.c_str(), PackPalettes, m.kind, chunks, std::size_t{8})->UseRealTime();
      if (chunks == 1)
        benchmark::RegisterBenchmark((name + "/poses:2").c_str(), PackPalettes, m.kind, chunks, std::size_t{2})->UseRealTime();
    }
  const struct {
    const char* name;
    Call call;
  } calls[] = {{"launch", Call::kLaunch},         {"record", Call::kRecord},         {"wait-event", Call::kWaitEvent},
               {"sync-done", Call::kSyncDone},    {"query-done", Call::kQueryDone}, {"set-current", Call::kSetCurrent},
               {"all", Call::kAll}};
  for (const auto& c : calls)
    benchmark::RegisterBenchmark((std::string("call/frame/") + c.name).c_str(), FrameCall, c.call)->UseManualTime();
  const struct {
    const char* name;
    Beside beside;
  } besides[] = {{"idle", Beside::kIdle}, {"pack-wc", Beside::kPackWc}, {"pack", Beside::kPack}};
  const struct {
    const char* name;
    int caller, submitter;
  } places[] = {{"any", -1, -1}, {"sibling", 0, SiblingOfCpu0()}, {"apart", 0, ApartFromCpu0()}};
  for (Call call : {Call::kLaunch, Call::kAll})
    for (const auto& b : besides)
      for (const auto& p : places) {
        if (p.caller >= 0 && p.submitter < 0) continue;  // no such pair of CPUs here
        const std::string name = std::string("call/frame/") + (call == Call::kLaunch ? "launch" : "all") +
                                 "/thread:" + b.name + "/cpu:" + p.name;
        benchmark::RegisterBenchmark(name.c_str(), FrameCallOnThread, call, b.beside, p.caller, p.submitter)
            ->UseManualTime();
      }
  benchmark::RegisterBenchmark("call/frame/graph/one-stream", GraphLaunch, false)->UseManualTime();
  benchmark::RegisterBenchmark("call/frame/graph/two-streams", GraphLaunch, true)->UseManualTime();
  benchmark::RegisterBenchmark("sync/empty", EmptySync)->UseRealTime();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  api->cuStreamDestroy(stream);
  api->cuDevicePrimaryCtxRelease(device);
  return 0;
}
