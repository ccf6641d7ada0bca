// skintune (internal): CUDA kernels' own device times from CUPTI's activity
// records, loaded at run time like the driver (cuda_api.h).
//
// The kernel time (docs/TUNING.md "Kernel time") is a kernel's execution on
// the device, start to end, without the host's launch processing. CUDA
// events around one launch count ~1.2 us more than that on an H100 (a B=4
// kernel of 25k vertices: 4.96 us against Nsight Compute's 3.78, measured in
// November 2026), and a graph of (flush, kernel) minus a graph of flushes
// counted less (2.51). CUPTI's kernel activity records carry the start and
// end timestamps the GPU stamps for the kernel itself, the clock Nsight
// Compute's gpu__time_duration reads.
//
// libcupti: SKINTUNE_CUPTI_LIBRARY (a path or soname) when set, and then only
// it; otherwise libcupti.so.13, libcupti.so.12, libcupti.so, then
// $CUDA_HOME/lib64/ and /usr/local/cuda/lib64/ and their extras/CUPTI/lib64/.
// The few types used are declared here, checked against CUDA 13's
// cupti_activity.h (tests/runtime/cupti_layout_test.cpp, where the toolkit's
// header is found at build time).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace skintune::internal::cupti {

// The leading fields of CUPTI's CUpti_ActivityKernel records (versions 4 to
// 10 share them; packed, 8-byte aligned).
#pragma pack(push, 1)
struct KernelRecordPrefix {
  std::uint32_t kind;  // CUpti_ActivityKind: kConcurrentKernel
  std::uint8_t cache_config;
  std::uint8_t shared_memory_config;
  std::uint16_t registers_per_thread;
  std::uint32_t partitioned_global_cache_requested;
  std::uint32_t partitioned_global_cache_executed;
  std::uint64_t start;  // ns, the GPU's timestamp of the kernel's start
  std::uint64_t end;    // ns, of its end
  std::uint64_t completed;
  std::uint32_t device_id;
  std::uint32_t context_id;
  std::uint32_t stream_id;
  std::int32_t grid[3];
  std::int32_t block[3];
  std::int32_t static_shared_memory;
  std::int32_t dynamic_shared_memory;
  std::uint32_t local_memory_per_thread;
  std::uint32_t local_memory_total;
  std::uint32_t correlation_id;
};
#pragma pack(pop)
inline constexpr std::uint32_t kConcurrentKernel = 10;  // CUPTI_ACTIVITY_KIND_CONCURRENT_KERNEL

// One kernel's execution as CUPTI recorded it.
struct KernelSpan {
  std::uint64_t start_ns = 0, end_ns = 0;
  std::uint32_t stream_id = 0;
  std::uint32_t correlation_id = 0;
};

// The kernel times of kCold frames (runtime/device_api.h) from the spans of
// one stream, sorted by start: per frame `flush` (>= 1) flush launches,
// then `launches` launches; returns per frame each launch's time from the
// end of the command before it to its own end, ms.
// Throws Error("CUDA launch: ...") when the spans are not frames x (flush +
// launches) kernels (a kernel of another stream, or records CUPTI dropped).
std::vector<std::vector<double>> ColdFrameTimes(const std::vector<KernelSpan>& spans, std::size_t frames,
                                                std::size_t flush, std::size_t launches);

// Collects kernel activity between Start and Stop. One per process at a
// time (CUPTI's callbacks are global). Start throws Error("CUDA launch:
// CUPTI ...") when CUPTI cannot be loaded or enabled (why() says why, for
// the fallback's note); Stop flushes CUPTI's buffers and returns every
// kernel that ran meanwhile, sorted by start.
class KernelActivity {
 public:
  KernelActivity();
  ~KernelActivity();  // disables the activity if still on
  KernelActivity(const KernelActivity&) = delete;
  KernelActivity& operator=(const KernelActivity&) = delete;
  void Start();
  std::vector<KernelSpan> Stop();

 private:
  bool on_ = false;
};

// Whether libcupti loads and its activity API answers, or why not ("" when it does).
std::string Unavailable();

}  // namespace skintune::internal::cupti
