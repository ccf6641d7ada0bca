// The host time of the OpenCL calls a frame makes, one variation at a time
// (on the H100 machine, 2026-11, NVIDIA's clEnqueueNDRangeKernel took ~14 us of host time in the
// Skinner's frame against ~7 us a frame in the tuner's bursts). Each row times
// only the call named, on a device kept idle: the kernel is empty and one
// work-group, and the queue is drained every kDrain calls outside the timing.
//
//   skintune_bench_opencl_calls [--platform SUBSTRING] [--benchmark_* flags]
//
// Rows, each on the first device of the first platform whose name contains
// SUBSTRING (default: the first platform):
//   enqueue/queue:<profiling|plain>/event:<none|out>/wait:<none|same|other>/args:<2|12>[/set-arg]
//     clEnqueueNDRangeKernel with or without an event out and a wait list
//     holding an event of the same queue or of a write on a second queue, on a
//     kernel of 2 or 12 arguments, with one clSetKernelArg (a palette slot
//     changing) inside the timing when set-arg;
//   flush, marker: clFlush after one enqueue; clEnqueueMarkerWithWaitList with an event out;
//   write/236544: clEnqueueWriteBuffer of 236 544 bytes (64 palettes of 77 mat3x4) from
//     page-locked memory, non-blocking, with an event out.
// Device time (profiling events), not host time:
//   upload/<write-mapped|copy-buffer|write-pageable>/queues:<1|2|4>: 64 uploads of the
//     236 544-byte palette back to back, each split over 1, 2 or 4 in-order upload queues;
//     the time is the span from the first START to the last END over 64: what one upload
//     costs where uploads follow each other (write-mapped: from the mapped pointer of a
//     CL_MEM_ALLOC_HOST_PTR buffer, the runtime's way; copy-buffer: clEnqueueCopyBuffer
//     from that buffer, which stays mapped, so formally undefined (OpenCL 1.2 5.4.2.1):
//     for comparison only; write-pageable: from ordinary memory);
//   frame/<how>/queues:<n>: the crowd frame's shape, 64 frames: each a kernel streaming
//     48 MiB that reads the whole palette, on one queue, waiting for its frame's upload on
//     the upload queues; frame n + 1's upload may run beside kernel n. Span over 64 per
//     frame, against frame/kernel-only (the kernels alone).
//   after-kernel/<launch:event|launch:plain/marker:event|marker:event>: from the END of
//     the stream kernel to the END of what follows it: the empty kernel with an event out,
//     the empty kernel without one and then a marker with one, or the marker alone. What
//     a dependent launch costs the device with and without its profiling event (the
//     kernel time's launch start: docs/TUNING.md "Kernel time").
//   frame/write-mapped/queues:1/<no-wait|barrier|out-of-order>: the same frame with the
//     kernel not waiting for its upload at all (wrong, for timing only: do the two queues'
//     work overlap when nothing orders them?), waiting through a barrier before the
//     launch (the runtime's launch takes the upload's event as its wait list, like the
//     plain row; its reads and markers wait through a barrier, OpenClApi::JoinUploads),
//     or with the upload and the kernel on one out-of-order queue, the kernel waiting for
//     its upload's event (skipped where the device refuses such a queue).
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <benchmark/benchmark.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

constexpr int kDrain = 256;  // calls between two clFinish (outside the timing)

[[noreturn]] void Die(const std::string& what, cl_int err) {
  std::fprintf(stderr, "skintune_bench_opencl_calls: %s failed with OpenCL error %d\n", what.c_str(), err);
  std::exit(1);
}

void Check(cl_int err, const char* what) {
  if (err != CL_SUCCESS) Die(what, err);
}

struct Device {
  cl_platform_id platform = nullptr;
  cl_device_id device = nullptr;
  cl_context context = nullptr;
  cl_command_queue profiling = nullptr, plain = nullptr, uploads = nullptr;
  cl_kernel two = nullptr, twelve = nullptr;
  std::vector<cl_mem> buffers;  // 12, one float each
  cl_mem palette = nullptr, staging = nullptr;
  void* staging_host = nullptr;
  std::vector<unsigned char> pageable;
  cl_command_queue timed = nullptr;        // profiling: the frame kernels
  cl_command_queue timed_uploads[4] = {};  // profiling: the uploads
  cl_command_queue out_of_order = nullptr;  // profiling and out-of-order, or null where refused
  cl_kernel stream = nullptr;
  cl_mem in = nullptr, out = nullptr;
  std::size_t stream_items = 0;
  std::string name;
};

Device& TheDevice() {
  static Device d;
  return d;
}

constexpr const char* kSource = R"(
__kernel void two(__global float* a, uint n) { if (get_global_id(0) >= n) a[0] = 1.0f; }
__kernel void twelve(__global float* a0, __global float* a1, __global float* a2, __global float* a3,
                     __global float* a4, __global float* a5, __global float* a6, __global float* a7,
                     __global float* a8, __global float* a9, __global float* a10, __global float* a11) {
  if (get_global_id(0) > 100000) a0[0] = a1[0] + a2[0] + a3[0] + a4[0] + a5[0] + a6[0] + a7[0] + a8[0] + a9[0] + a10[0] + a11[0];
}
__kernel void stream(__global const float4* a, __global float4* b, __global const float4* p, uint n) {
  uint i = get_global_id(0);
  if (i < n) b[i] = a[i] + p[i % 14784u];
}
)";

bool Open(const std::string& platform_substring) {
  Device& d = TheDevice();
  cl_uint count = 0;
  if (clGetPlatformIDs(0, nullptr, &count) != CL_SUCCESS || count == 0) return false;
  std::vector<cl_platform_id> platforms(count);
  clGetPlatformIDs(count, platforms.data(), nullptr);
  for (cl_platform_id p : platforms) {
    char name[256] = {};
    clGetPlatformInfo(p, CL_PLATFORM_NAME, sizeof name, name, nullptr);
    if (std::string(name).find(platform_substring) == std::string::npos) continue;
    cl_uint devices = 0;
    if (clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, 1, &d.device, &devices) != CL_SUCCESS || devices == 0) continue;
    d.platform = p;
    char device_name[256] = {};
    clGetDeviceInfo(d.device, CL_DEVICE_NAME, sizeof device_name, device_name, nullptr);
    d.name = std::string(name) + " / " + device_name;
    break;
  }
  if (!d.device) return false;
  cl_int err = CL_SUCCESS;
  d.context = clCreateContext(nullptr, 1, &d.device, nullptr, nullptr, &err);
  Check(err, "clCreateContext");
  d.profiling = clCreateCommandQueue(d.context, d.device, CL_QUEUE_PROFILING_ENABLE, &err);
  Check(err, "clCreateCommandQueue (profiling)");
  d.plain = clCreateCommandQueue(d.context, d.device, 0, &err);
  Check(err, "clCreateCommandQueue");
  d.uploads = clCreateCommandQueue(d.context, d.device, 0, &err);
  Check(err, "clCreateCommandQueue (uploads)");
  const char* source = kSource;
  cl_program program = clCreateProgramWithSource(d.context, 1, &source, nullptr, &err);
  Check(err, "clCreateProgramWithSource");
  Check(clBuildProgram(program, 1, &d.device, "", nullptr, nullptr), "clBuildProgram");
  d.two = clCreateKernel(program, "two", &err);
  Check(err, "clCreateKernel two");
  d.twelve = clCreateKernel(program, "twelve", &err);
  Check(err, "clCreateKernel twelve");
  for (int i = 0; i < 12; ++i) {
    d.buffers.push_back(clCreateBuffer(d.context, CL_MEM_READ_WRITE, 64, nullptr, &err));
    Check(err, "clCreateBuffer");
    Check(clSetKernelArg(d.twelve, static_cast<cl_uint>(i), sizeof(cl_mem), &d.buffers.back()), "clSetKernelArg");
  }
  const cl_uint n = 1;
  Check(clSetKernelArg(d.two, 0, sizeof(cl_mem), &d.buffers[0]), "clSetKernelArg");
  Check(clSetKernelArg(d.two, 1, sizeof n, &n), "clSetKernelArg");
  constexpr std::size_t kPalette = 236544;
  d.palette = clCreateBuffer(d.context, CL_MEM_READ_ONLY, kPalette, nullptr, &err);
  Check(err, "clCreateBuffer palette");
  d.staging = clCreateBuffer(d.context, CL_MEM_ALLOC_HOST_PTR, kPalette, nullptr, &err);
  Check(err, "clCreateBuffer staging");
  d.staging_host = clEnqueueMapBuffer(d.plain, d.staging, CL_TRUE, CL_MAP_WRITE, 0, kPalette, 0, nullptr, nullptr, &err);
  Check(err, "clEnqueueMapBuffer staging");
  d.pageable.assign(kPalette, 0);
  d.timed = clCreateCommandQueue(d.context, d.device, CL_QUEUE_PROFILING_ENABLE, &err);
  Check(err, "clCreateCommandQueue (timed)");
  for (cl_command_queue& q : d.timed_uploads) {
    q = clCreateCommandQueue(d.context, d.device, CL_QUEUE_PROFILING_ENABLE, &err);
    Check(err, "clCreateCommandQueue (timed uploads)");
  }
  d.out_of_order = clCreateCommandQueue(d.context, d.device,
                                        CL_QUEUE_PROFILING_ENABLE | CL_QUEUE_OUT_OF_ORDER_EXEC_MODE_ENABLE, &err);
  if (err != CL_SUCCESS) d.out_of_order = nullptr;
  d.stream = clCreateKernel(program, "stream", &err);
  Check(err, "clCreateKernel stream");
  d.stream_items = std::size_t{48} << 20 >> 5;  // 48 MiB read + written, 16 + 16 bytes an item
  d.in = clCreateBuffer(d.context, CL_MEM_READ_ONLY, d.stream_items * 16, nullptr, &err);
  Check(err, "clCreateBuffer in");
  d.out = clCreateBuffer(d.context, CL_MEM_WRITE_ONLY, d.stream_items * 16, nullptr, &err);
  Check(err, "clCreateBuffer out");
  const cl_uint items = static_cast<cl_uint>(d.stream_items);
  Check(clSetKernelArg(d.stream, 0, sizeof(cl_mem), &d.in), "clSetKernelArg");
  Check(clSetKernelArg(d.stream, 1, sizeof(cl_mem), &d.out), "clSetKernelArg");
  Check(clSetKernelArg(d.stream, 2, sizeof(cl_mem), &d.palette), "clSetKernelArg");
  Check(clSetKernelArg(d.stream, 3, sizeof items, &items), "clSetKernelArg");
  return true;
}

using Clock = std::chrono::steady_clock;

enum class Wait { kNone, kSame, kOther };

void Enqueue(benchmark::State& state, bool profiling, bool event_out, Wait wait, bool twelve, bool set_arg) {
  Device& d = TheDevice();
  const cl_command_queue q = profiling ? d.profiling : d.plain;
  const cl_kernel k = twelve ? d.twelve : d.two;
  const std::size_t global = 64, local = 64;
  int calls = 0;
  cl_event previous = nullptr;
  for (auto _ : state) {
    cl_event wait_event = nullptr;
    if (wait == Wait::kOther) {
      Check(clEnqueueWriteBuffer(d.uploads, d.buffers[1], CL_FALSE, 0, 4, d.staging_host, 0, nullptr, &wait_event),
            "clEnqueueWriteBuffer");
      Check(clFlush(d.uploads), "clFlush");
    } else if (wait == Wait::kSame) {
      wait_event = previous;
      previous = nullptr;
    }
    cl_event event = nullptr;
    const cl_mem arg = d.buffers[static_cast<std::size_t>(calls % 2)];
    const auto start = Clock::now();
    if (set_arg) Check(clSetKernelArg(k, 0, sizeof arg, &arg), "clSetKernelArg");
    Check(clEnqueueNDRangeKernel(q, k, 1, nullptr, &global, &local, wait_event ? 1 : 0, wait_event ? &wait_event : nullptr,
                                 event_out || wait == Wait::kSame ? &event : nullptr),
          "clEnqueueNDRangeKernel");
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - start).count());
    if (wait_event) clReleaseEvent(wait_event);
    if (wait == Wait::kSame) previous = event;
    else if (event) clReleaseEvent(event);
    if (++calls % kDrain == 0) {
      Check(clFinish(q), "clFinish");
      Check(clFinish(d.uploads), "clFinish");
    } else {
      Check(clFlush(q), "clFlush");
    }
  }
  if (previous) clReleaseEvent(previous);
  Check(clFinish(q), "clFinish");
  Check(clFinish(d.uploads), "clFinish");
}

void Flush(benchmark::State& state) {
  Device& d = TheDevice();
  const std::size_t global = 64, local = 64;
  int calls = 0;
  for (auto _ : state) {
    Check(clEnqueueNDRangeKernel(d.plain, d.two, 1, nullptr, &global, &local, 0, nullptr, nullptr), "clEnqueueNDRangeKernel");
    const auto start = Clock::now();
    Check(clFlush(d.plain), "clFlush");
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - start).count());
    if (++calls % kDrain == 0) Check(clFinish(d.plain), "clFinish");
  }
  Check(clFinish(d.plain), "clFinish");
}

void Marker(benchmark::State& state) {
  Device& d = TheDevice();
  int calls = 0;
  for (auto _ : state) {
    cl_event event = nullptr;
    const auto start = Clock::now();
    Check(clEnqueueMarkerWithWaitList(d.plain, 0, nullptr, &event), "clEnqueueMarkerWithWaitList");
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - start).count());
    clReleaseEvent(event);
    Check(clFlush(d.plain), "clFlush");
    if (++calls % kDrain == 0) Check(clFinish(d.plain), "clFinish");
  }
  Check(clFinish(d.plain), "clFinish");
}

void Write(benchmark::State& state) {
  Device& d = TheDevice();
  int calls = 0;
  for (auto _ : state) {
    cl_event event = nullptr;
    const auto start = Clock::now();
    Check(clEnqueueWriteBuffer(d.uploads, d.palette, CL_FALSE, 0, 236544, d.staging_host, 0, nullptr, &event),
          "clEnqueueWriteBuffer");
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - start).count());
    Check(clFlush(d.uploads), "clFlush");
    clReleaseEvent(event);
    if (++calls % 16 == 0) Check(clFinish(d.uploads), "clFinish");
  }
  Check(clFinish(d.uploads), "clFinish");
}

enum class How { kWriteMapped, kCopyBuffer, kWritePageable };

// One upload of the palette split over `queues` upload queues (or on `only`,
// when given); its events into `events`.
void Upload(How how, int queues, std::vector<cl_event>& events, cl_command_queue only = nullptr) {
  Device& d = TheDevice();
  constexpr std::size_t kPalette = 236544;
  const std::size_t part = kPalette / static_cast<std::size_t>(queues);
  for (int q = 0; q < queues; ++q) {
    const std::size_t at = part * static_cast<std::size_t>(q);
    cl_event e = nullptr;
    const cl_command_queue queue = only ? only : d.timed_uploads[q];
    if (how == How::kCopyBuffer) {
      Check(clEnqueueCopyBuffer(queue, d.staging, d.palette, at, at, part, 0, nullptr, &e), "clEnqueueCopyBuffer");
    } else {
      const unsigned char* from = how == How::kWriteMapped ? static_cast<const unsigned char*>(d.staging_host)
                                                           : d.pageable.data();
      Check(clEnqueueWriteBuffer(queue, d.palette, CL_FALSE, at, part, from + at, 0, nullptr, &e), "clEnqueueWriteBuffer");
    }
    Check(clFlush(queue), "clFlush");
    events.push_back(e);
  }
}

cl_ulong Profile(cl_event e, cl_profiling_info what) {
  cl_ulong t = 0;
  Check(clGetEventProfilingInfo(e, what, sizeof t, &t, nullptr), "clGetEventProfilingInfo");
  return t;
}

// The span from the earliest START to the latest END of `events`, seconds; releases them.
double Span(std::vector<cl_event>& events) {
  cl_ulong start = ~cl_ulong{0}, end = 0;
  for (cl_event e : events) {
    start = std::min(start, Profile(e, CL_PROFILING_COMMAND_START));
    end = std::max(end, Profile(e, CL_PROFILING_COMMAND_END));
    clReleaseEvent(e);
  }
  events.clear();
  return end > start ? static_cast<double>(end - start) * 1e-9 : 0.0;
}

constexpr int kBurst = 64;

void Uploads(benchmark::State& state, How how, int queues) {
  Device& d = TheDevice();
  std::vector<cl_event> events;
  for (auto _ : state) {
    for (int i = 0; i < kBurst; ++i) Upload(how, queues, events);
    for (int q = 0; q < queues; ++q) Check(clFinish(d.timed_uploads[q]), "clFinish");
    state.SetIterationTime(Span(events) / kBurst);
  }
}

// How a frame's kernel is ordered after its upload.
enum class Order { kWaitList, kNoWait, kBarrier, kOutOfOrder };

// queues 0: the kernels alone.
void FrameModel(benchmark::State& state, How how, int queues, Order order) {
  Device& d = TheDevice();
  if (order == Order::kOutOfOrder && !d.out_of_order) {
    state.SkipWithError("the device refuses an out-of-order queue with profiling");
    return;
  }
  const cl_command_queue kernels = order == Order::kOutOfOrder ? d.out_of_order : d.timed;
  const std::size_t local = 256, global = (d.stream_items + local - 1) / local * local;
  std::vector<cl_event> events, uploads;
  for (auto _ : state) {
    for (int i = 0; i < kBurst; ++i) {
      if (queues > 0) Upload(how, queues, uploads, order == Order::kOutOfOrder ? d.out_of_order : nullptr);
      const bool wait_list = order == Order::kWaitList || order == Order::kOutOfOrder;
      if (order == Order::kBarrier && !uploads.empty())
        Check(clEnqueueBarrierWithWaitList(kernels, static_cast<cl_uint>(uploads.size()), uploads.data(), nullptr),
              "clEnqueueBarrierWithWaitList");
      cl_event e = nullptr;
      Check(clEnqueueNDRangeKernel(kernels, d.stream, 1, nullptr, &global, &local,
                                   wait_list ? static_cast<cl_uint>(uploads.size()) : 0,
                                   wait_list && !uploads.empty() ? uploads.data() : nullptr, &e),
            "clEnqueueNDRangeKernel");
      Check(clFlush(kernels), "clFlush");
      events.push_back(e);
      events.insert(events.end(), uploads.begin(), uploads.end());
      uploads.clear();
    }
    Check(clFinish(kernels), "clFinish");
    for (int q = 0; q < 4; ++q) Check(clFinish(d.timed_uploads[q]), "clFinish");
    state.SetIterationTime(Span(events) / kBurst);
  }
}

// What follows a command on the device: from the END of a stream kernel (48
// MiB read and written) to the END of what comes next, on a profiling queue.
enum class After { kLaunchWithEvent, kLaunchThenMarker, kMarker };

void AfterKernel(benchmark::State& state, After after) {
  Device& d = TheDevice();
  const std::size_t local = 256, global = (d.stream_items + local - 1) / local * local, one = 1;
  for (auto _ : state) {
    cl_event before = nullptr, last = nullptr;
    Check(clEnqueueNDRangeKernel(d.timed, d.stream, 1, nullptr, &global, &local, 0, nullptr, &before),
          "clEnqueueNDRangeKernel");
    if (after != After::kMarker)
      Check(clEnqueueNDRangeKernel(d.timed, d.two, 1, nullptr, &one, &one, 0, nullptr,
                                   after == After::kLaunchWithEvent ? &last : nullptr),
            "clEnqueueNDRangeKernel");
    if (after != After::kLaunchWithEvent)
      Check(clEnqueueMarkerWithWaitList(d.timed, 0, nullptr, &last), "clEnqueueMarkerWithWaitList");
    Check(clFinish(d.timed), "clFinish");
    const cl_ulong from = Profile(before, CL_PROFILING_COMMAND_END), to = Profile(last, CL_PROFILING_COMMAND_END);
    state.SetIterationTime(to > from ? static_cast<double>(to - from) * 1e-9 : 0.0);
    clReleaseEvent(before);
    clReleaseEvent(last);
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  CLI::App app{"The host time of the OpenCL calls a frame makes, one variation at a time; "
               "Google Benchmark's --benchmark_* flags are taken too"};
  std::string platform;
  app.add_option("--platform", platform, "the first platform whose name contains this (default: the first)");
  CLI11_PARSE(app, argc, argv);
  if (!Open(platform)) {
    std::fprintf(stderr, "skintune_bench_opencl_calls: no OpenCL platform%s with a device\n",
                 platform.empty() ? "" : (" named like '" + platform + "'").c_str());
    return 1;
  }
  std::fprintf(stderr, "skintune_bench_opencl_calls: %s\n", TheDevice().name.c_str());
  for (const bool profiling : {true, false})
    for (const bool event_out : {false, true})
      for (const auto& [wait, wait_name] : {std::pair{Wait::kNone, "none"}, {Wait::kSame, "same"}, {Wait::kOther, "other"}})
        for (const bool twelve : {false, true})
          for (const bool set_arg : {false, true}) {
            if (wait == Wait::kSame && !event_out) continue;  // the same-queue wait needs the event
            const std::string name = std::string("enqueue/queue:") + (profiling ? "profiling" : "plain") +
                                     "/event:" + (event_out ? "out" : "none") + "/wait:" + wait_name +
                                     "/args:" + (twelve ? "12" : "2") + (set_arg ? "/set-arg" : "");
            benchmark::RegisterBenchmark(name.c_str(), Enqueue, profiling, event_out, wait, twelve, set_arg)->UseManualTime();
          }
  benchmark::RegisterBenchmark("flush", Flush)->UseManualTime();
  benchmark::RegisterBenchmark("marker", Marker)->UseManualTime();
  benchmark::RegisterBenchmark("write/236544", Write)->UseManualTime();
  benchmark::RegisterBenchmark("frame/kernel-only", FrameModel, How::kWriteMapped, 0, Order::kWaitList)->UseManualTime();
  for (const auto& [order, order_name] : {std::pair{Order::kNoWait, "no-wait"}, {Order::kBarrier, "barrier"},
                                          {Order::kOutOfOrder, "out-of-order"}})
    benchmark::RegisterBenchmark((std::string("frame/write-mapped/queues:1/") + order_name).c_str(), FrameModel,
                                 How::kWriteMapped, 1, order)
        ->UseManualTime();
  for (const auto& [how, how_name] : {std::pair{How::kWriteMapped, "write-mapped"}, {How::kCopyBuffer, "copy-buffer"},
                                      {How::kWritePageable, "write-pageable"}})
    for (const int queues : {1, 2, 4}) {
      const std::string tail = std::string(how_name) + "/queues:" + std::to_string(queues);
      benchmark::RegisterBenchmark(("upload/" + tail).c_str(), Uploads, how, queues)->UseManualTime();
      benchmark::RegisterBenchmark(("frame/" + tail).c_str(), FrameModel, how, queues, Order::kWaitList)->UseManualTime();
    }
  for (const auto& [after, after_name] : {std::pair{After::kLaunchWithEvent, "launch:event"},
                                          {After::kLaunchThenMarker, "launch:plain/marker:event"},
                                          {After::kMarker, "marker:event"}})
    benchmark::RegisterBenchmark((std::string("after-kernel/") + after_name).c_str(), AfterKernel, after)
        ->UseManualTime();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
