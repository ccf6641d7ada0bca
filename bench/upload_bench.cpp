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
//   host/<bytes>/pack-wc     memcpy of the bytes into write-combined memory (the packing's stores)
//   host/<bytes>/pack        the same into ordinary memory
//
// Each reports bytes/s; the time is the host's wall time per copy.
//
//   skintune_bench_upload [google benchmark flags]
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "runtime/backends/cuda/cuda_api.h"

namespace {

using namespace skintune::internal;

const cuda::DriverApi* api = nullptr;
cuda::Stream stream = nullptr;

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

void EmptySync(benchmark::State& state) {
  cuda::Event event = nullptr;
  Ok(api->cuEventCreate(&event, cuda::kEventDisableTiming), "cuEventCreate");
  for (auto _ : state) {
    Ok(api->cuEventRecord(event, stream), "cuEventRecord");
    Ok(api->cuEventSynchronize(event), "cuEventSynchronize");
  }
  api->cuEventDestroy(event);
}

void Pack(benchmark::State& state, std::size_t bytes, Memory kind) {
  Host to(bytes, kind);
  std::vector<unsigned char> from(bytes, 2);
  for (auto _ : state) {
    std::memcpy(to.p, from.data(), bytes);
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  std::string why;
  api = cuda::Driver(&why);
  if (!api) {
    std::fprintf(stderr, "skintune_bench_upload: no CUDA driver: %s\n", why.c_str());
    return 1;
  }
  cuda::Device device = 0;
  cuda::Context context = nullptr;
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
      if (m.kind != Memory::kPinned)
        benchmark::RegisterBenchmark(("host/" + size + "/" + std::string(m.kind == Memory::kPinnedWc ? "pack-wc" : "pack")).c_str(),
                                     Pack, bytes, m.kind)
            ->UseRealTime();
    }
  }
  benchmark::RegisterBenchmark("sync/empty", EmptySync)->UseRealTime();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  api->cuStreamDestroy(stream);
  api->cuDevicePrimaryCtxRelease(device);
  return 0;
}
