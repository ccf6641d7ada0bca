#include "runtime/backends/cuda/cupti.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>

#include "base/error.h"

namespace skintune::internal::cupti {

namespace {

using Result = int;  // CUptiResult; 0 = CUPTI_SUCCESS
constexpr Result kMaxLimitReached = 12;  // CUPTI_ERROR_MAX_LIMIT_REACHED: the buffer's end
constexpr std::uint32_t kFlushForced = 1;  // CUPTI_ACTIVITY_FLAG_FLUSH_FORCED
constexpr std::size_t kBufferBytes = 4u << 20;
constexpr std::size_t kRecordAlignment = 8;  // ACTIVITY_RECORD_ALIGNMENT

using RequestFn = void (*)(std::uint8_t** buffer, std::size_t* size, std::size_t* max_records);
using CompleteFn = void (*)(void* context, std::uint32_t stream, std::uint8_t* buffer, std::size_t size,
                            std::size_t valid);
struct Api {
  Result (*cuptiActivityEnable)(std::uint32_t kind);
  Result (*cuptiActivityDisable)(std::uint32_t kind);
  Result (*cuptiActivityRegisterCallbacks)(RequestFn, CompleteFn);
  Result (*cuptiActivityFlushAll)(std::uint32_t flag);
  Result (*cuptiActivityGetNextRecord)(std::uint8_t* buffer, std::size_t valid, void** record);
  Result (*cuptiGetResultString)(Result result, const char** text);
};

struct Loaded {
  Api api{};
  bool ok = false;
  std::string why;  // why not
};

std::vector<std::string> Candidates() {
  if (const char* forced = std::getenv("SKINTUNE_CUPTI_LIBRARY"); forced && *forced) return {forced};
  std::vector<std::string> c = {"libcupti.so.13", "libcupti.so.12", "libcupti.so"};
  std::vector<std::string> roots;
  if (const char* home = std::getenv("CUDA_HOME"); home && *home) roots.push_back(home);
  roots.push_back("/usr/local/cuda");
  for (const std::string& root : roots) {
    c.push_back(root + "/lib64/libcupti.so");
    c.push_back(root + "/extras/CUPTI/lib64/libcupti.so");
  }
  return c;
}

// What every record buffer holds until its callback: the spans of the
// kernels it recorded (KernelActivity's collection).
struct Collected {
  std::mutex mutex;
  std::vector<KernelSpan> spans;
  std::size_t dropped_buffers = 0;
};
Collected& Collection() {
  static Collected c;
  return c;
}

const Loaded& Library();

void Request(std::uint8_t** buffer, std::size_t* size, std::size_t* max_records) {
  *buffer = static_cast<std::uint8_t*>(std::aligned_alloc(kRecordAlignment, kBufferBytes));
  *size = *buffer ? kBufferBytes : 0;
  *max_records = 0;  // as many as fit
}

void Complete(void*, std::uint32_t, std::uint8_t* buffer, std::size_t, std::size_t valid) {
  const Api& api = Library().api;
  std::vector<KernelSpan> spans;
  void* record = nullptr;
  while (api.cuptiActivityGetNextRecord(buffer, valid, &record) == 0) {
    const auto* kernel = static_cast<const KernelRecordPrefix*>(record);
    if (kernel->kind != kConcurrentKernel) continue;
    spans.push_back({kernel->start, kernel->end, kernel->stream_id, kernel->correlation_id});
  }
  std::free(buffer);
  Collected& c = Collection();
  const std::lock_guard<std::mutex> lock(c.mutex);
  c.spans.insert(c.spans.end(), spans.begin(), spans.end());
}

template <typename F>
void Resolve(void* handle, const char* name, F& pointer, std::string& missing) {
  pointer = reinterpret_cast<F>(dlsym(handle, name));
  if (!pointer) missing += std::string(missing.empty() ? "" : ", ") + name;
}

const Loaded& Library() {
  static const Loaded loaded = [] {
    Loaded l;
    void* handle = nullptr;
    std::string tried;
    for (const std::string& c : Candidates()) {
      if ((handle = dlopen(c.c_str(), RTLD_NOW | RTLD_LOCAL))) break;
      const char* e = dlerror();
      tried += (tried.empty() ? "" : "; ") + std::string(e ? e : c + ": unknown dlopen error");
    }
    if (!handle) {
      l.why = "libcupti not found (" + tried + ")";
      return l;
    }
    std::string missing;
    Resolve(handle, "cuptiActivityEnable", l.api.cuptiActivityEnable, missing);
    Resolve(handle, "cuptiActivityDisable", l.api.cuptiActivityDisable, missing);
    Resolve(handle, "cuptiActivityRegisterCallbacks", l.api.cuptiActivityRegisterCallbacks, missing);
    Resolve(handle, "cuptiActivityFlushAll", l.api.cuptiActivityFlushAll, missing);
    Resolve(handle, "cuptiActivityGetNextRecord", l.api.cuptiActivityGetNextRecord, missing);
    Resolve(handle, "cuptiGetResultString", l.api.cuptiGetResultString, missing);
    if (!missing.empty()) {
      l.why = "libcupti lacks " + missing;
      return l;
    }
    const Result registered = l.api.cuptiActivityRegisterCallbacks(Request, Complete);
    if (registered != 0) {
      const char* text = nullptr;
      l.api.cuptiGetResultString(registered, &text);
      l.why = std::string("cuptiActivityRegisterCallbacks failed: ") + (text ? text : "?");
      return l;
    }
    l.ok = true;
    return l;
  }();
  return loaded;
}

[[noreturn]] void Fail(const std::string& what, Result result) {
  const char* text = nullptr;
  if (Library().api.cuptiGetResultString) Library().api.cuptiGetResultString(result, &text);
  throw Error("CUDA launch: CUPTI " + what + " failed (" + std::to_string(result) + ": " + (text ? text : "?") + ")");
}

std::mutex& OneAtATime() {
  static std::mutex m;
  return m;
}

}  // namespace

std::string Unavailable() { return Library().ok ? "" : Library().why; }

KernelActivity::KernelActivity() = default;

KernelActivity::~KernelActivity() {
  if (on_) {
    Library().api.cuptiActivityDisable(kConcurrentKernel);
    Library().api.cuptiActivityFlushAll(kFlushForced);
    OneAtATime().unlock();
  }
}

void KernelActivity::Start() {
  const Loaded& l = Library();
  if (!l.ok) throw Error("CUDA launch: CUPTI: " + l.why);
  OneAtATime().lock();
  {
    Collected& c = Collection();
    const std::lock_guard<std::mutex> lock(c.mutex);
    c.spans.clear();
  }
  if (const Result r = l.api.cuptiActivityEnable(kConcurrentKernel); r != 0) {
    OneAtATime().unlock();
    Fail("cuptiActivityEnable(CONCURRENT_KERNEL)", r);
  }
  on_ = true;
}

std::vector<KernelSpan> KernelActivity::Stop() {
  if (!on_) return {};
  const Api& api = Library().api;
  on_ = false;
  const Result disabled = api.cuptiActivityDisable(kConcurrentKernel);
  const Result flushed = api.cuptiActivityFlushAll(kFlushForced);
  std::vector<KernelSpan> spans;
  {
    Collected& c = Collection();
    const std::lock_guard<std::mutex> lock(c.mutex);
    spans.swap(c.spans);
  }
  OneAtATime().unlock();
  if (disabled != 0) Fail("cuptiActivityDisable", disabled);
  if (flushed != 0) Fail("cuptiActivityFlushAll", flushed);
  std::sort(spans.begin(), spans.end(), [](const KernelSpan& a, const KernelSpan& b) { return a.start_ns < b.start_ns; });
  return spans;
}

std::vector<std::vector<double>> ColdFrameTimes(const std::vector<KernelSpan>& spans, std::size_t frames,
                                                std::size_t flush, std::size_t launches) {
  const std::size_t per_frame = flush + launches;
  if (spans.size() != frames * per_frame)
    throw Error("CUDA launch: CUPTI recorded " + std::to_string(spans.size()) + " kernels for " + std::to_string(frames) +
                " frames of " + std::to_string(flush) + " flush and " + std::to_string(launches) + " timed launches");
  // Each launch from the end of the command before it (the flush's last
  // launch, or the frame's previous launch) to its own end (device_api.h).
  std::vector<std::vector<double>> ms(frames);
  for (std::size_t f = 0; f < frames; ++f) {
    if (flush == 0) throw Error("CUDA launch: a cold frame without a flush before it");
    std::uint64_t previous_end = spans[f * per_frame + flush - 1].end_ns;
    for (std::size_t l = 0; l < launches; ++l) {
      const KernelSpan& s = spans[f * per_frame + flush + l];
      if (s.end_ns < s.start_ns || s.end_ns < previous_end)
        throw Error("CUDA launch: CUPTI recorded a kernel ending before it started or before the command before it (frame " +
                    std::to_string(f) + ")");
      ms[f].push_back(static_cast<double>(s.end_ns - previous_end) * 1e-6);
      previous_end = s.end_ns;
    }
  }
  return ms;
}

}  // namespace skintune::internal::cupti
