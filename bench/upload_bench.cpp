// Host <-> device copies on a CUDA device, the raw costs under the frame loop:
// what one palette upload (64 x 77 mat3x4, 236 KB; or mat4,
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
//   model/<frame>/<submit>   a frame loop in miniature, its wall time per frame: a kernel that
//                            holds every SM for 11 us (the 64 x 25k-b4 crowd kernel's time on
//                            the H100; it spins on %globaltimer), a ring of 6 palette slots whose
//                            marker is waited for before the slot is packed again, and
//                              <frame>  skin-only  the launch and its marker alone
//                                       pipelined  PackPaletteInto of 64 x 77 mat3x4 (2 poses)
//                                                  into the slot's write-combined staging, its
//                                                  236 KB upload, the launch, the marker
//                                       unpacked   pipelined without the packing (the staging
//                                                  uploaded as it is): the submission's bound
//                                       packed-only  pipelined without the upload (the packing
//                                                  beside the kernel but no copy engine reading)
//                                       pipelined-cached  pipelined from ordinary (not
//                                                  write-combined) page-locked staging
//                                       pipelined-pool  pipelined, the packing in 4 chunks on a
//                                                  ThreadPool of 4 threads (20 us spin; with
//                                                  /spin:<us>, that spin)
//                                       finish     pipelined, then the marker waited for
//                                       finish-unpacked  unpacked, the marker waited for
//                                       finish-pool  finish, packed as pipelined-pool (the
//                                                  pool's workers asleep after the wait)
//                              <submit> calls      the runtime's five calls (upload on a stream
//                                                  of its own, record, wait, launch, record)
//                                       calls:no-wait  the same without the launch's wait for
//                                                  the upload (wrong: what the wait costs)
//                                       calls:same-stream  the upload on the kernel's stream
//                                                  (no event: serialised with the kernels)
//                                       fetch      no copy engine: a kernel on the kernel's
//                                                  stream reads the staging over PCIe (16 bytes
//                                                  a thread) into the slot's palette
//                                       graph:one-stream    one cuGraphLaunch per frame of a graph
//                                                  per slot (upload -> kernel -> marker) on the
//                                                  kernel's stream: frames run one after another
//                                       graph:alternating   the same graphs on two streams by
//                                                  the slot's parity, each kernel after the last
//                                                  frame's marker (an event wait node), so frame
//                                                  n+1's upload can run beside kernel n
//                                       graph:rotating      the same on three streams
//                                       calls:thread / graph:thread  calls or graph:alternating made
//                                                  by a thread of their own, which also waits for
//                                                  the ring (the caller makes no driver call: it
//                                                  packs, hands the frame over by an atomic, and
//                                                  spins on one for a free slot)
//   model/<frame>/<submit>/parts:<k>  calls and calls:thread with the upload in k copies of
//                            whole matrices on k streams of their own (more copies in flight)
//                            Counters: the host's time per frame in the ring's wait, the packing
//                            and the submission (ring_us, pack_us, submit_us: the thread's when
//                            threaded).
//                            What a frame's submission costs beside a kernel really running.
//   host/<bytes>/pack-wc     memcpy of the bytes into write-combined memory (the packing's stores)
//   host/<bytes>/pack        the same into ordinary memory
//   palette/<memory>         PackPaletteInto of 64 x 77 mat3x4 (SetPalette's packing) into
//                            each kind of host memory, from 8 poses in turn as the frame
//                            benchmark's (2.5 MB of input: not all in a core's cache)
//   palette/<memory>/poses:2 the same from 2 poses (0.6 MB: in L2, as the frame benchmark's default)
//   palette/pinned-wc/poses:2/spinning:<n>  the same on n threads, n - 1 of them helpers that spin
//                            between frames (no wake-up), each packing its share of the matrices
//   palette/pinned-wc/poses:2/spinning:<n>/claims  the same, each share handed out by a counter
//                            (a thread packs a different share each frame, as pool claims fall)
//   palette/pinned-wc/poses:2/pool-fixed:<n>  on a ThreadPool of n threads (20 us spin), each
//                            thread packing the same share every frame
//   palette/pinned-wc/poses:2/runtime  SetPalette's packing: PackPaletteOnPool (runtime/host_work.h)
//   palette/<memory>/chunks:<n>  the same in n chunks on the runtime's host pool
//                            (runtime/host_work.h ForChunks: the read-back's spinning threads)
//   palette/pinned-wc/poses:2/chunks:<n>[/pool:<n>]  from 2 poses in n chunks on the host pool, or
//                            on a ThreadPool of n threads (the host pool's 20 us spin)
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
#include <memory>
#include <thread>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "generator/packer.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "base/thread_pool.h"
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

// `count` poses of `matrices` column-major 4x4 matrices each, for the packing
// rows (the values only need to be finite and differ between poses).
std::vector<std::vector<float>> Poses(std::size_t count, std::size_t matrices) {
  std::vector<std::vector<float>> poses(count, std::vector<float>(matrices * 16));
  for (std::size_t p = 0; p < count; ++p)
    for (std::size_t i = 0; i < poses[p].size(); ++i) poses[p][i] = static_cast<float>((i + p) % 97) * 0.01f;
  return poses;
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
  cuda::Result (*cuEventRecordWithFlags)(cuda::Event, cuda::Stream, unsigned flags) = nullptr;
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
    g.cuEventRecordWithFlags =
        reinterpret_cast<decltype(g.cuEventRecordWithFlags)>(dlsym(handle, "cuEventRecordWithFlags"));
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

// The model frame's kernel: every thread spins on %globaltimer for `ns`.
constexpr char kSpinPtx[] =
    ".version 7.0\n.target sm_50\n.address_size 64\n"
    ".visible .entry skintune_spin(.param .u64 ns, .param .u64 palette)\n{\n"
    "  .reg .pred %p;\n  .reg .b64 %r<5>;\n"
    "  ld.param.u64 %r1, [ns];\n  mov.u64 %r2, %globaltimer;\n"
    "LOOP:\n  mov.u64 %r3, %globaltimer;\n  sub.s64 %r4, %r3, %r2;\n"
    "  setp.lt.u64 %p, %r4, %r1;\n  @%p bra LOOP;\n  ret;\n}\n"
    // The palette fetched by the device itself: each thread copies 16 bytes
    // from page-locked host memory (read over PCIe) into device memory.
    ".visible .entry skintune_fetch(.param .u64 dst, .param .u64 src, .param .u64 n16)\n{\n"
    "  .reg .pred %p;\n  .reg .b32 %t<4>;\n  .reg .b32 %v<4>;\n  .reg .b64 %r<8>;\n"
    "  ld.param.u64 %r1, [dst];\n  ld.param.u64 %r2, [src];\n  ld.param.u64 %r3, [n16];\n"
    "  mov.u32 %t1, %ctaid.x;\n  mov.u32 %t2, %ntid.x;\n  mov.u32 %t3, %tid.x;\n"
    "  mul.wide.u32 %r4, %t1, %t2;\n  cvt.u64.u32 %r5, %t3;\n  add.u64 %r4, %r4, %r5;\n"
    "  setp.ge.u64 %p, %r4, %r3;\n  @%p bra DONE;\n  shl.b64 %r5, %r4, 4;\n"
    "  add.u64 %r6, %r2, %r5;\n  ld.global.nc.v4.u32 {%v0, %v1, %v2, %v3}, [%r6];\n"
    "  add.u64 %r7, %r1, %r5;\n  st.global.v4.u32 [%r7], {%v0, %v1, %v2, %v3};\n"
    "DONE:\n  ret;\n}\n";

enum class ModelFrame {
  kSkinOnly,
  kPipelined,
  kUnpacked,
  kPackedOnly,
  kPipelinedCached,
  kPipelinedPool,
  kFinish,
  kFinishUnpacked,
  kFinishPool
};
constexpr bool Packs(ModelFrame f) {
  return f != ModelFrame::kSkinOnly && f != ModelFrame::kUnpacked && f != ModelFrame::kFinishUnpacked;
}
constexpr bool Uploads(ModelFrame f) { return f != ModelFrame::kSkinOnly && f != ModelFrame::kPackedOnly; }
constexpr bool Waits(ModelFrame f) {
  return f == ModelFrame::kFinish || f == ModelFrame::kFinishUnpacked || f == ModelFrame::kFinishPool;
}
constexpr bool PoolPacks(ModelFrame f) { return f == ModelFrame::kPipelinedPool || f == ModelFrame::kFinishPool; }
enum class Submit {
  kCalls,
  kCallsNoWait,
  kCallsSameStream,
  kFetch,
  kGraphOneStream,
  kGraphAlternating,
  kGraphRotating,
  kCallsThread,
  kGraphThread
};
// cuMemHostGetDevicePointer_v2 (write-combined page-locked memory has a device
// address of its own even under unified addressing).
using HostDevicePointerFn = cuda::Result (*)(cuda::DevicePtr*, void*, unsigned);
HostDevicePointerFn HostDevicePointer() {
  static const HostDevicePointerFn f = [] {
    void* handle = dlopen("libcuda.so.1", RTLD_NOW | RTLD_NOLOAD);
    return handle ? reinterpret_cast<HostDevicePointerFn>(dlsym(handle, "cuMemHostGetDevicePointer_v2")) : nullptr;
  }();
  return f;
}

void FrameModel(benchmark::State& state, ModelFrame frame, Submit submit, std::size_t parts, unsigned spin_us) {
  constexpr std::size_t kSlots = 6, kMatrices = 64 * 77, kBytes = kMatrices * 48;
  constexpr unsigned long long kKernelNs = 11000;
  const GraphApi* g = Graphs();
  const bool calls = submit != Submit::kGraphOneStream && submit != Submit::kGraphAlternating &&
                     submit != Submit::kGraphRotating && submit != Submit::kGraphThread;
  const bool threaded = submit == Submit::kCallsThread || submit == Submit::kGraphThread;
  const std::size_t n_streams = submit == Submit::kGraphRotating                                       ? 3
                                : submit == Submit::kGraphAlternating || submit == Submit::kGraphThread ? 2
                                                                                                        : 1;
  if (!calls && (!g->cuStreamBeginCapture || !g->cuEventRecordWithFlags)) {
    state.SkipWithError("the driver has no stream capture or external event nodes");
    return;
  }
  cuda::Device device = 0;
  int sms = 0;
  Ok(api->cuCtxGetDevice(&device), "cuCtxGetDevice");
  Ok(api->cuDeviceGetAttribute(&sms, 16 /* CU_DEVICE_ATTRIBUTE_MULTIPROCESSOR_COUNT */, device), "cuDeviceGetAttribute");
  cuda::Module module = nullptr;
  cuda::Function spin = nullptr;
  Ok(api->cuModuleLoadDataEx(&module, kSpinPtx, 0, nullptr, nullptr), "cuModuleLoadDataEx");
  Ok(api->cuModuleGetFunction(&spin, module, "skintune_spin"), "cuModuleGetFunction");
  cuda::Function fetch = nullptr;
  Ok(api->cuModuleGetFunction(&fetch, module, "skintune_fetch"), "cuModuleGetFunction");
  if (submit == Submit::kFetch && !HostDevicePointer()) {
    state.SkipWithError("the driver has no cuMemHostGetDevicePointer_v2");
    api->cuModuleUnload(module);
    return;
  }
  constexpr std::size_t kMaxParts = 4;
  cuda::Stream streams[3] = {stream, nullptr, nullptr}, uploads[kMaxParts] = {};
  for (std::size_t i = 1; i < 3; ++i) Ok(api->cuStreamCreate(&streams[i], 1), "cuStreamCreate");
  for (cuda::Stream& u : uploads) Ok(api->cuStreamCreate(&u, 1), "cuStreamCreate");
  std::vector<std::unique_ptr<Host>> staging;
  std::vector<std::unique_ptr<DeviceMemory>> palettes;
  cuda::Event marker[kSlots], uploaded[kSlots][kMaxParts];
  for (std::size_t s = 0; s < kSlots; ++s) {
    staging.push_back(
        std::make_unique<Host>(kBytes, frame == ModelFrame::kPipelinedCached ? Memory::kPinned : Memory::kPinnedWc));
    palettes.push_back(std::make_unique<DeviceMemory>(kBytes));
    Ok(api->cuEventCreate(&marker[s], cuda::kEventDisableTiming), "cuEventCreate");
    for (cuda::Event& e : uploaded[s]) Ok(api->cuEventCreate(&e, cuda::kEventDisableTiming), "cuEventCreate");
    Ok(api->cuEventRecord(marker[s], stream), "cuEventRecord");
  }
  Variant variant;
  variant.palette = PaletteFormat::kMat3x4;
  const std::vector<std::vector<float>> poses = Poses(2, kMatrices);
  std::unique_ptr<ThreadPool> pack_pool;  // pipelined-pool: the packing in 4 chunks on 4 threads
  std::vector<cuda::DevicePtr> staging_on_device(kSlots, 0);  // fetch: the staging's device addresses
  if (submit == Submit::kFetch)
    for (std::size_t s = 0; s < kSlots; ++s)
      Ok(HostDevicePointer()(&staging_on_device[s], staging[s]->p, 0), "cuMemHostGetDevicePointer");
  if (PoolPacks(frame)) pack_pool = std::make_unique<ThreadPool>(4, std::chrono::microseconds(spin_us));
  unsigned long long ns = kKernelNs;
  const auto launch = [&](std::size_t s, cuda::Stream on) {
    void* params[] = {&ns, &palettes[s]->p};
    Ok(api->cuLaunchKernel(spin, 2 * sms, 1, 1, 256, 1, 1, 0, on, params, nullptr), "cuLaunchKernel");
  };
  // One graph per slot: its upload, its launch, its marker.
  void* graphs[kSlots] = {};
  void* execs[kSlots] = {};
  if (!calls) {
    for (std::size_t s = 0; s < kSlots; ++s) {
      const cuda::Stream on = streams[s % n_streams];
      Ok(g->cuStreamBeginCapture(on, 2 /* CU_STREAM_CAPTURE_MODE_RELAXED */), "cuStreamBeginCapture");
      if (Uploads(frame))
        Ok(api->cuMemcpyHtoDAsync(palettes[s]->p, staging[s]->p, kBytes, on), "cuMemcpyHtoDAsync");
      if (n_streams > 1)  // after the last frame's kernel
        Ok(api->cuStreamWaitEvent(on, marker[(s + kSlots - 1) % kSlots], 1 /* CU_EVENT_WAIT_EXTERNAL */),
           "cuStreamWaitEvent");
      launch(s, on);
      Ok(g->cuEventRecordWithFlags(marker[s], on, 1 /* CU_EVENT_RECORD_EXTERNAL */), "cuEventRecordWithFlags");
      Ok(g->cuStreamEndCapture(on, &graphs[s]), "cuStreamEndCapture");
      Ok(g->cuGraphInstantiateWithFlags(&execs[s], graphs[s], 0), "cuGraphInstantiateWithFlags");
    }
  }
  const auto submit_frame = [&](std::size_t s) {
    if (calls && Uploads(frame) && submit == Submit::kCallsSameStream) {
      Ok(api->cuMemcpyHtoDAsync(palettes[s]->p, staging[s]->p, kBytes, stream), "cuMemcpyHtoDAsync");
    } else if (calls && Uploads(frame) && submit == Submit::kFetch) {
      unsigned long long n16 = kBytes / 16;
      void* params[] = {&palettes[s]->p, &staging_on_device[s], &n16};
      Ok(api->cuLaunchKernel(fetch, static_cast<unsigned>((n16 + 255) / 256), 1, 1, 256, 1, 1, 0, stream, params, nullptr),
         "cuLaunchKernel (fetch)");
    } else if (calls && Uploads(frame)) {
      {  // in `parts` copies on as many streams, each of whole matrices
        const std::size_t part = (kMatrices + parts - 1) / parts * 48;
        for (std::size_t p = 0; p < parts; ++p) {
          const std::size_t at = p * part, bytes = std::min(part, kBytes - at);
          Ok(api->cuMemcpyHtoDAsync(palettes[s]->p + at, static_cast<std::uint8_t*>(staging[s]->p) + at, bytes,
                                    uploads[p]),
             "cuMemcpyHtoDAsync");
          Ok(api->cuEventRecord(uploaded[s][p], uploads[p]), "cuEventRecord");
        }
        if (submit != Submit::kCallsNoWait)
          for (std::size_t p = 0; p < parts; ++p)
            Ok(api->cuStreamWaitEvent(stream, uploaded[s][p], 0), "cuStreamWaitEvent");
      }
    }
    if (calls) {
      launch(s, stream);
      Ok(api->cuEventRecord(marker[s], stream), "cuEventRecord");
    } else {
      Ok(g->cuGraphLaunch(execs[s], streams[s % n_streams]), "cuGraphLaunch");
    }
  };
  Ok(api->cuCtxSynchronize(), "cuCtxSynchronize");
  using Clock = std::chrono::steady_clock;
  const auto seconds = [](Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); };
  // threaded: a thread of its own makes every driver call (the submission and
  // the ring's wait), the caller only packs: it waits for `freed` (frames whose
  // slot is free again) and hands each frame over by `requested`.
  std::atomic<std::size_t> requested{0}, freed{1};  // frames 0 and 1 may be packed at once
  std::atomic<bool> stop{false};
  double thread_submit_s = 0;
  std::thread thread;
  if (threaded)
    thread = std::thread([&] {
      Ok(api->cuCtxSetCurrent(context), "cuCtxSetCurrent");
      std::size_t done = 0;
      for (;;) {
        while (requested.load(std::memory_order_acquire) == done && !stop.load(std::memory_order_acquire))
          __builtin_ia32_pause();
        if (requested.load(std::memory_order_acquire) == done) break;
        const auto a = Clock::now();
        submit_frame(done % kSlots);
        thread_submit_s += seconds(a, Clock::now());
        ++done;
        // Frame done + 1 may be packed once its slot's last frame (done + 1 - kSlots) is complete:
        // the caller packs up to two frames ahead of the submission.
        Ok(api->cuEventSynchronize(marker[(done + 1) % kSlots]), "cuEventSynchronize");
        freed.store(done + 1, std::memory_order_release);
      }
    });
  std::size_t n = 0;
  double ring_s = 0, pack_s = 0, submit_s = 0;  // the host's time in each part
  for (auto _ : state) {
    const std::size_t s = n % kSlots;
    const auto t0 = Clock::now();
    if (threaded) {
      while (freed.load(std::memory_order_acquire) < n) __builtin_ia32_pause();
    } else {
      Ok(api->cuEventSynchronize(marker[s]), "cuEventSynchronize");  // the ring: slot s is free again
    }
    const auto t1 = Clock::now();
    if (pack_pool) {
      auto* out = static_cast<std::uint8_t*>(staging[s]->p);
      const float* in = poses[n % 2].data();
      pack_pool->ParallelFor(kMatrices, (kMatrices + 3) / 4, [&](std::size_t begin, std::size_t end) {
        PackPaletteInto(in + 16 * begin, end - begin, variant, out + 48 * begin);
      });
    } else if (Packs(frame)) {
      PackPaletteInto(poses[n % 2].data(), kMatrices, variant, static_cast<std::uint8_t*>(staging[s]->p));
    }
    const auto t2 = Clock::now();
    if (threaded) requested.store(n + 1, std::memory_order_release);
    else submit_frame(s);
    const auto t3 = Clock::now();
    if (Waits(frame)) Ok(api->cuEventSynchronize(marker[s]), "cuEventSynchronize");
    ring_s += seconds(t0, t1);
    pack_s += seconds(t1, t2);
    submit_s += seconds(t2, t3);
    ++n;
  }
  if (threaded) {
    stop.store(true, std::memory_order_release);
    thread.join();
    submit_s = thread_submit_s;
  }
  const double per_frame_us = 1e6 / static_cast<double>(std::max<std::size_t>(n, 1));
  state.counters["ring_us"] = ring_s * per_frame_us;
  state.counters["pack_us"] = pack_s * per_frame_us;
  state.counters["submit_us"] = submit_s * per_frame_us;
  Ok(api->cuCtxSynchronize(), "cuCtxSynchronize");
  for (std::size_t s = 0; s < kSlots; ++s) {
    if (execs[s]) g->cuGraphExecDestroy(execs[s]);
    if (graphs[s]) g->cuGraphDestroy(graphs[s]);
    api->cuEventDestroy(marker[s]);
    for (cuda::Event e : uploaded[s]) api->cuEventDestroy(e);
  }
  for (std::size_t i = 1; i < 3; ++i) api->cuStreamDestroy(streams[i]);
  for (cuda::Stream u : uploads) api->cuStreamDestroy(u);
  api->cuModuleUnload(module);
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

// The packing rows' work: 64 x 77 mat3x4 (SetPalette's crowd palette) from 2
// poses in turn into write-combined page-locked staging.
struct PackingSetup {
  static constexpr std::size_t kMatrices = 64 * 77;
  Variant variant = [] {
    Variant v;
    v.palette = PaletteFormat::kMat3x4;
    return v;
  }();
  Host to{kMatrices * 48, Memory::kPinnedWc};
  std::vector<std::vector<float>> poses = Poses(2, kMatrices);
  std::uint8_t* out = static_cast<std::uint8_t*>(to.p);
};

// The palette on a ThreadPool of `threads` threads (20 us spin), each thread
// packing the same share every frame whatever chunk it claimed (a thread's
// share fixed on its first chunk): the pool's machinery with the spinning
// helpers' placement of the work.
void PackPalettesPoolFixed(benchmark::State& state, std::size_t threads) {
  const PackingSetup setup;
  constexpr std::size_t kMatrices = PackingSetup::kMatrices;
  const Variant& variant = setup.variant;
  const std::vector<std::vector<float>>& poses = setup.poses;
  std::uint8_t* out = setup.out;
  const std::size_t share = (kMatrices + threads - 1) / threads;
  ThreadPool pool(static_cast<unsigned>(threads), std::chrono::microseconds(20));
  std::atomic<std::size_t> next_id{0};
  std::vector<std::atomic<bool>> taken(threads);
  std::size_t frame = 0;
  for (auto _ : state) {
    const float* in = poses[frame++ % 2].data();
    for (auto& t : taken) t.store(false, std::memory_order_relaxed);
    pool.ParallelFor(kMatrices, share, [&](std::size_t ticket, std::size_t) {
      thread_local std::pair<const void*, std::size_t> id{nullptr, 0};  // this pool's number for the thread
      if (id.first != &pool) id = {&pool, next_id.fetch_add(1)};
      std::size_t part = id.second % threads;
      bool free = false;
      if (!taken[part].compare_exchange_strong(free, true)) {
        for (part = ticket / share;; part = (part + 1) % threads) {
          free = false;
          if (taken[part].compare_exchange_strong(free, true)) break;
        }
      }
      const std::size_t begin = std::min(kMatrices, part * share), end = std::min(kMatrices, begin + share);
      PackPaletteInto(in + 16 * begin, end - begin, variant, out + 48 * begin);
    });
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * kMatrices * 48));
}

// SetPalette's packing itself: the runtime's PackPaletteOnPool (its palette
// pool, its poll), with the largest magnitude it also gives.
void PackPalettesRuntime(benchmark::State& state) {
  const PackingSetup setup;
  std::size_t frame = 0;
  float largest = 0.0f;
  for (auto _ : state) {
    benchmark::DoNotOptimize(PackPaletteOnPool(setup.poses[frame++ % 2].data(), PackingSetup::kMatrices, setup.variant,
                                               setup.out, &largest));
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * PackingSetup::kMatrices * 48));
}

void PackPalettes(benchmark::State& state, Memory kind, std::size_t chunks, std::size_t kPoses, unsigned pool_threads) {
  // pool_threads: a pool of that many threads of the bench's own (the host pool's spin), not the host pool
  std::unique_ptr<ThreadPool> pool;
  if (pool_threads > 0) pool = std::make_unique<ThreadPool>(pool_threads, std::chrono::microseconds(20));
  constexpr std::size_t kMatrices = 64 * 77;
  Variant variant;
  variant.palette = PaletteFormat::kMat3x4;
  Host to(kMatrices * 48, kind);
  const std::vector<std::vector<float>> poses = Poses(kPoses, kMatrices);
  std::size_t pose = 0;
  auto* out = static_cast<std::uint8_t*>(to.p);
  for (auto _ : state) {
    const float* in = poses[pose++ % kPoses].data();
    if (chunks <= 1) {
      benchmark::DoNotOptimize(PackPaletteInto(in, kMatrices, variant, out));
    } else {
      const auto body = [&](std::size_t begin, std::size_t end) {
        benchmark::DoNotOptimize(PackPaletteInto(in + 16 * begin, end - begin, variant, out + 48 * begin));
      };
      if (pool) pool->ParallelFor(kMatrices, (kMatrices + chunks - 1) / chunks, body);
      else ForChunks(kMatrices, (kMatrices + chunks - 1) / chunks, body);
    }
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * kMatrices * 48));
}

// PackPaletteInto on `threads` threads: the caller's share and threads - 1
// helpers that spin between frames (no sleep, no wake-up), each packing its
// share of whole matrices into the write-combined staging.
void PackPalettesSpinning(benchmark::State& state, std::size_t threads, bool claims) {
  const PackingSetup setup;
  constexpr std::size_t kMatrices = PackingSetup::kMatrices;
  const Variant& variant = setup.variant;
  const std::vector<std::vector<float>>& poses = setup.poses;
  std::uint8_t* out = setup.out;
  const std::size_t share = (kMatrices + threads - 1) / threads;
  std::atomic<std::size_t> generation{0}, finished{0}, claimed{0};
  std::atomic<bool> stop{false};
  const auto pack = [&](std::size_t t, std::size_t frame) {
    if (claims) t = claimed.fetch_add(1) % threads;  // the share a counter hands out, as the pool's claims do
    const std::size_t begin = std::min(kMatrices, t * share), end = std::min(kMatrices, begin + share);
    PackPaletteInto(poses[frame % 2].data() + 16 * begin, end - begin, variant, out + 48 * begin);
  };
  std::vector<std::thread> helpers;
  for (std::size_t t = 1; t < threads; ++t)
    helpers.emplace_back([&, t] {
      std::size_t seen = 0;
      for (;;) {
        std::size_t g;
        while ((g = generation.load(std::memory_order_acquire)) == seen && !stop.load(std::memory_order_relaxed))
          __builtin_ia32_pause();
        if (stop.load()) return;
        seen = g;
        pack(t, g);
        finished.fetch_add(1, std::memory_order_acq_rel);
      }
    });
  std::size_t frame = 0;
  for (auto _ : state) {
    ++frame;
    finished.store(0, std::memory_order_relaxed);
    generation.store(frame, std::memory_order_release);
    pack(0, frame);
    while (finished.load(std::memory_order_acquire) != threads - 1) __builtin_ia32_pause();
  }
  stop.store(true);
  for (std::thread& h : helpers) h.join();
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
      benchmark::RegisterBenchmark(name.c_str(), PackPalettes, m.kind, chunks, std::size_t{8}, 0u)->UseRealTime();
      if (chunks == 1)
        benchmark::RegisterBenchmark((name + "/poses:2").c_str(), PackPalettes, m.kind, chunks, std::size_t{2}, 0u)
            ->UseRealTime();
    }
  for (std::size_t chunks : {2, 4}) {
    const std::string name = "palette/pinned-wc/poses:2/chunks:" + std::to_string(chunks);
    benchmark::RegisterBenchmark(name.c_str(), PackPalettes, Memory::kPinnedWc, chunks, std::size_t{2}, 0u)->UseRealTime();
    benchmark::RegisterBenchmark((name + "/pool:" + std::to_string(chunks)).c_str(), PackPalettes, Memory::kPinnedWc,
                                 chunks, std::size_t{2}, static_cast<unsigned>(chunks))
        ->UseRealTime();
    }
  benchmark::RegisterBenchmark("palette/pinned-wc/poses:2/runtime", PackPalettesRuntime)->UseRealTime();
  for (std::size_t threads : {1, 2, 4}) {
    benchmark::RegisterBenchmark(("palette/pinned-wc/poses:2/spinning:" + std::to_string(threads)).c_str(),
                                 PackPalettesSpinning, threads, false)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("palette/pinned-wc/poses:2/spinning:" + std::to_string(threads) + "/claims").c_str(),
                                 PackPalettesSpinning, threads, true)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("palette/pinned-wc/poses:2/pool-fixed:" + std::to_string(threads)).c_str(),
                                 PackPalettesPoolFixed, threads)
        ->UseRealTime();
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
  const struct {
    const char* name;
    ModelFrame frame;
  } model_frames[] = {{"skin-only", ModelFrame::kSkinOnly}, {"pipelined", ModelFrame::kPipelined},
                      {"unpacked", ModelFrame::kUnpacked},   {"packed-only", ModelFrame::kPackedOnly},
                      {"pipelined-cached", ModelFrame::kPipelinedCached},
                      {"pipelined-pool", ModelFrame::kPipelinedPool}, {"finish", ModelFrame::kFinish},
                      {"finish-unpacked", ModelFrame::kFinishUnpacked}, {"finish-pool", ModelFrame::kFinishPool}};
  const struct {
    const char* name;
    Submit submit;
  } submits[] = {{"calls", Submit::kCalls},
                 {"calls:no-wait", Submit::kCallsNoWait},
                 {"calls:same-stream", Submit::kCallsSameStream},
                 {"fetch", Submit::kFetch},
                 {"graph:one-stream", Submit::kGraphOneStream},
                 {"graph:alternating", Submit::kGraphAlternating},
                 {"graph:rotating", Submit::kGraphRotating},
                 {"calls:thread", Submit::kCallsThread},
                 {"graph:thread", Submit::kGraphThread}};
  for (const auto& f : model_frames)
    for (const auto& m : submits) {
      if (Waits(f.frame) && (m.submit == Submit::kCallsThread || m.submit == Submit::kGraphThread))
        continue;  // a frame waited for has nothing to overlap
      const std::string name = std::string("model/") + f.name + "/" + m.name;
      benchmark::RegisterBenchmark(name.c_str(), FrameModel, f.frame, m.submit, std::size_t{1}, 20u)->UseRealTime();
      if (m.submit == Submit::kCalls || m.submit == Submit::kCallsThread)
        for (std::size_t parts : {2, 4})
          benchmark::RegisterBenchmark((name + "/parts:" + std::to_string(parts)).c_str(), FrameModel, f.frame, m.submit,
                                       parts, 20u)
              ->UseRealTime();
      if (PoolPacks(f.frame))
        for (unsigned spin : {100u, 500u, 2000u})
          benchmark::RegisterBenchmark((name + "/spin:" + std::to_string(spin)).c_str(), FrameModel, f.frame, m.submit,
                                       std::size_t{1}, spin)
              ->UseRealTime();
    }
  benchmark::RegisterBenchmark("sync/empty", EmptySync)->UseRealTime();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  api->cuStreamDestroy(stream);
  api->cuDevicePrimaryCtxRelease(device);
  return 0;
}
