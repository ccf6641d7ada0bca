// The host time of the OpenCL calls a frame makes, one variation at a time
// (issue 15: NVIDIA's clEnqueueNDRangeKernel took ~14 us of host time in the
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
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <benchmark/benchmark.h>

#include <CLI/CLI.hpp>
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
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
