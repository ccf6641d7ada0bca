// The OpenCL DeviceApi (runtime/device_api.h) and OpenClRunner: programs
// (with the program cache), buffers, image1d_buffer palettes, kernel
// arguments set per launch, and profiling events.
#include "runtime/backends/opencl/opencl_runner.h"

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <map>
#include <mutex>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "base/cache_eviction.h"
#include "base/error.h"
#include "base/thread_pool.h"
#include "runtime/backends/opencl/opencl_info.h"
#include "runtime/host_work.h"
#include "runtime/output_check.h"

namespace skintune::internal {

namespace {

// Owns one OpenCL object; released with its clRelease* function.
template <typename T, cl_int (*Release)(T)>
class Handle {
 public:
  Handle() = default;
  explicit Handle(T value) : value_(value) {}
  ~Handle() { reset(); }
  Handle(Handle&& other) noexcept : value_(other.value_) { other.value_ = nullptr; }
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      value_ = other.value_;
      other.value_ = nullptr;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  T get() const { return value_; }
  T release() {  // the handle's reference, now the caller's
    T value = value_;
    value_ = nullptr;
    return value;
  }
  void reset() {
    if (value_) Release(value_);
    value_ = nullptr;
  }

 private:
  T value_ = nullptr;
};

using Context = Handle<cl_context, clReleaseContext>;
using Queue = Handle<cl_command_queue, clReleaseCommandQueue>;
using Program = Handle<cl_program, clReleaseProgram>;
using Kernel = Handle<cl_kernel, clReleaseKernel>;
using Memory = Handle<cl_mem, clReleaseMemObject>;
using Event = Handle<cl_event, clReleaseEvent>;

[[noreturn]] void Fail(const std::string& stage, const std::string& message) {
  throw Error("OpenCL " + stage + ": " + message);
}

void Check(cl_int err, const std::string& stage, const std::string& what) {
  if (err != CL_SUCCESS) Fail(stage, what + " failed with error " + std::to_string(err));
}

// The same with the message built only on failure (the frame loop's calls).
template <typename Message>
  requires std::is_invocable_r_v<std::string, Message>
void Check(cl_int err, const char* stage, Message&& what) {
  if (err != CL_SUCCESS) Check(err, stage, what());
}

struct BuiltKernel {
  Program program;
  Kernel kernel;
};

// Page-locked host memory: a CL_MEM_ALLOC_HOST_PTR buffer mapped once and
// kept mapped (NVIDIA's OpenCL best-practice pinned path: copies between it
// and device buffers run at full bus speed and asynchronously).
struct ClPinned {
  ClPinned(cl_context context, cl_command_queue queue, std::size_t bytes, const std::string& what) : queue_(queue) {
    cl_int err = CL_SUCCESS;
    buffer = Memory(clCreateBuffer(context, CL_MEM_ALLOC_HOST_PTR | CL_MEM_READ_WRITE, bytes, nullptr, &err));
    Check(err, "launch", "clCreateBuffer(CL_MEM_ALLOC_HOST_PTR) for " + what + " (" + std::to_string(bytes) + " bytes)");
    host = clEnqueueMapBuffer(queue, buffer.get(), CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, bytes, 0, nullptr, nullptr,
                              &err);
    Check(err, "launch", "clEnqueueMapBuffer of " + what);
  }
  ~ClPinned() {
    if (host) clEnqueueUnmapMemObject(queue_, buffer.get(), host, 0, nullptr, nullptr);
  }
  ClPinned(const ClPinned&) = delete;
  ClPinned& operator=(const ClPinned&) = delete;
  Memory buffer;
  void* host = nullptr;

 private:
  cl_command_queue queue_;
};

// A buffer, or the image1d_buffer over the palette; the palette also keeps
// the page-locked staging of its uploads (Write), an output that of its
// read-backs (ReadPinned).
class ClMemory final : public DeviceBuffer {
 public:
  ClMemory(Memory m, std::size_t bytes) : DeviceBuffer(bytes), memory(std::move(m)) {}
  void* native() const override { return memory.get(); }
  Memory memory;
  std::unique_ptr<ClPinned> upload;            // made on the first Write
  Event uploaded;                              // the last upload from `upload`
  mutable std::unique_ptr<ClPinned> readback;  // made on the first ReadPinned
  mutable std::vector<Event> readback_chunks;  // ReadPinnedChunks' events, of the last read
};

// The palette ring's fence: a marker event.
class ClMarker final : public DeviceObject {
 public:
  explicit ClMarker(cl_event e) : event(e) {}
  Event event;
};

class ClPlanned final : public PlannedLaunch {
 public:
  using PlannedLaunch::PlannedLaunch;
  cl_kernel kernel = nullptr;  // owned by the API
  cl_uint dimensions = 1;      // 2: instanced, the second dimension is the instance
  std::size_t global[2] = {0, 1}, local[2] = {0, 1};
};

// A launch of one set: the memory object of each kernel argument (null for scalars).
class ClBound final : public DeviceObject {
 public:
  const ClPlanned* plan = nullptr;
  std::vector<cl_mem> arguments;
  // The buffer objects among them, each once, with its size (what an evicting kCold evicts).
  std::vector<std::pair<cl_mem, std::size_t>> buffers;
};

// The native kernel that evicts one buffer (OpenClApi::evicts_): its
// argument block is the api's count of bytes evicted, the buffer's bytes,
// then the slot where clEnqueueNativeKernel puts the buffer's host address
// in place of its cl_mem. One buffer per native kernel: PoCL 3.1 fills the
// slots of a mem_list of several buffers in an order of its own (writable
// buffers first, measured 2026-11-29: a read-write output's address went to
// the slot of a read-only input's), so a frame's buffers would be evicted
// with each other's sizes, past the end of the smaller ones.
struct EvictArgs {
  std::atomic<std::size_t>* evicted;
  std::size_t bytes;
  const std::uint8_t* address;
};
void CL_CALLBACK EvictNatively(void* args) {
  const auto* a = static_cast<const EvictArgs*>(args);
  if (!a->address) return;  // not allocated on the device yet (PoCL allocates at first use): in no cache
  const std::span<const std::uint8_t> span(a->address, a->bytes);
  // On every logical CPU (base/cache_eviction.h), one eviction at a time:
  // the queues of one process may run native kernels at once. The pool
  // sleeps between evictions and is left to the process's end.
  static std::mutex one_at_a_time;
  static ThreadPool& threads = *new ThreadPool();
  const std::lock_guard<std::mutex> lock(one_at_a_time);
  EvictFromCaches({&span, 1}, threads);
  a->evicted->fetch_add(a->bytes);
}

}  // namespace

class OpenClApi final : public DeviceApi {
 public:
  cl_platform_id platform = nullptr;
  cl_device_id device = nullptr;
  std::string name_;
  Context context;
  // The frames' queue, without profiling: on NVIDIA a launch that returns an
  // event costs ~10.5 us of host time on a profiling queue against ~4.9 on
  // one without (`skintune_bench_opencl_calls` on the H100
  // machine, 2026-11-27), and the Skinner's last launch of a frame returns its ring fence.
  Queue queue;
  Queue lanes[2];  // Time's two queues and Run's (made on first use, profiling)

  const char* name() const override { return "OpenCL"; }
  const std::string& device_name() const override { return name_; }
  void Build(const KernelSource& source) override { KernelFor(source); }
  // clBuildProgram of distinct programs in one context is thread-safe
  // (OpenCL 1.2, appendix A.2); built_ is guarded by built_mutex_.
  bool ConcurrentBuilds() const override { return true; }
  void CheckRun(const PackedMesh& mesh, std::span<const KernelSource> kernels, const RunShape& shape) const override;
  std::unique_ptr<PlannedLaunch> Plan(const LaunchSpec& spec) override;
  std::unique_ptr<DeviceBuffer> Allocate(BufferUse use, std::size_t bytes, const void* initial,
                                         const std::string& what) override;
  std::unique_ptr<DeviceObject> PaletteView(const Variant& variant, DeviceBuffer& palette,
                                            const std::string& suffix) override;
  std::unique_ptr<DeviceObject> Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                     const SetOptions& options, std::size_t& allocated) override;
  void FinishUploads(const std::string& key) override {
    Check(clFinish(queue.get()), "launch", "clFinish after uploading the input sets of " + key);
  }
  std::vector<std::vector<double>> RunFrames(const FrameRun& run) override;
  std::span<std::uint8_t> Staging(DeviceBuffer& buffer, const std::string& key, bool upload_fenced) override;
  void Upload(DeviceBuffer& buffer, std::size_t bytes, const std::string& key) override;
  void Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string& what, bool wait) override;
  std::span<const std::uint8_t> ReadPinned(const DeviceBuffer& buffer, std::size_t bytes,
                                           const std::string& what) override;
  PinnedRead ReadPinnedChunks(const DeviceBuffer& buffer, std::size_t bytes, std::size_t chunk,
                              const std::string& what) override;
  void Mark(std::unique_ptr<DeviceObject>& marker, const std::string& what) override;
  void Wait(DeviceObject& marker, const std::string& what) override;
  bool Signalled(DeviceObject& marker, const std::string& what) override;
  void Finish() override {
    JoinUploads(queue.get());
    Check(clFinish(queue.get()), "launch", "clFinish");
  }
  // Every OpenCL call but clSetKernelArg is thread-safe (OpenCL 1.2, appendix
  // A.2); the live frame's arguments are set only by the thread making it.
  bool SubmitsFromAnyThread() const override { return true; }
  std::string kernel_clock() const override { return "OpenCL profiling stamps: a marker's END to the next marker's START"; }
  // A CPU device that runs native kernels (PoCL) evicts each cold frame's
  // buffers with one, queued where the flush kernel was: the flush read
  // twice a last-level cache the host shares with other cores (capped at
  // 32 MiB, so not cold in the whole L3), at the host's speed, before each sample.
  bool evicts_own_buffers() const override { return evicts_; }
  std::size_t evicted_bytes() const override { return evicted_bytes_.load(); }
  bool evicts_ = false;
  std::atomic<std::size_t> evicted_bytes_{0};  // by the eviction's native kernels, in all
  bool ReadyToRelease() override {  // no upload or launch still uses what is about to be released
    for (const Queue* q : {&uploads_, &queue, &lanes[0], &lanes[1]})
      if (q->get()) clFinish(q->get());
    last_upload_.reset();
    return true;
  }

 private:
  cl_kernel KernelFor(const KernelSource& source);
  Program ProgramFromSource(const KernelSource& source, const std::string& key, const char* options);
  Program ProgramFromBinary(const std::vector<std::uint8_t>& binary, const char* options);
  std::vector<std::uint8_t> BinaryOf(cl_program program);
  Memory NewMemory(cl_mem_flags flags, std::size_t bytes, const void* data, const std::string& what);
  void Enqueue(const ClBound& bound, cl_mem out_positions, cl_event* event, cl_command_queue on = nullptr,
               cl_uint wait_count = 0, const cl_event* wait_list = nullptr);
  const FrameRun* frame_run_ = nullptr;  // while RunFrames runs: its run, whose scalars Enqueue passes
  cl_command_queue Lane(int i);
  // Palette uploads run on an in-order queue of their own, so frame n+1's
  // upload overlaps frame n's kernel; the next command queued on `on` after
  // an upload waits for it (a barrier on its event).
  void JoinUploads(cl_command_queue on);
  // Time's bursts (FrameUse::kTime) on the two lanes.
  struct LaneEdges {
    Event first[2], last[2];  // per lane: its first launch of the burst, its last
  };
  std::vector<std::vector<double>> TimeOnLanes(const FrameRun& run);
  // Kernel time (FrameUse::kCold) on one profiling lane.
  std::vector<std::vector<double>> TimeCold(const FrameRun& run);
  // Queues on `on` the native kernels that evict `frame`'s buffers (evicts_), one per
  // buffer; the last one's event into `event`.
  void EnqueueEviction(std::span<const std::unique_ptr<DeviceObject>> frame, cl_event* event, cl_command_queue on);
  static double SpanMs(const LaneEdges& e, const std::string& key);

  std::map<std::string, BuiltKernel> built_;  // by source hash
  std::mutex built_mutex_;                     // built_ (ConcurrentBuilds)
  Queue uploads_;                              // the palette uploads' queue (made on first use)
  // The palette kernels' own in-order queue (made on first use): frame n + 1's
  // palette kernel writes a slot no queued frame reads (the palette ring's
  // fence), so it may run beside frame n's skin kernel instead of after it
  // on the one in-order queue.
  Queue prologues_;
  Event last_live_;  // the last live frame's last launch (whether the device is still busy with it)
  Event last_prologue_;  // the last palette kernel's launch, on either queue (the next one waits for it)
  Event last_upload_;                          // the latest upload's event, until `queue` waits for it
  // The Skinner's last launch (RunFrames, kLive), until Mark takes its event
  // as the palette ring's fence: on the in-order queue it completes after
  // everything queued before it, so no marker need be queued. Anything else
  // queued on `queue` in between drops it (Mark then queues a marker).
  Event last_launch_;
  // What each kernel's arguments were last set to (clSetKernelArg is called
  // only for those that changed: a Skinner's frame changes only the palette).
  struct ArgValue {
    std::size_t size = 0;
    std::uint64_t value = 0;
  };
  std::map<cl_kernel, std::vector<ArgValue>> kernel_args_;
};

// ---------------------------------------------------------------- programs

Program OpenClApi::ProgramFromBinary(const std::vector<std::uint8_t>& binary, const char* options) {
  cl_int err = CL_SUCCESS, binary_status = CL_SUCCESS;
  const std::size_t size = binary.size();
  const unsigned char* bytes = binary.data();
  Program program(clCreateProgramWithBinary(context.get(), 1, &device, &size, &bytes, &binary_status, &err));
  if (err != CL_SUCCESS || binary_status != CL_SUCCESS) return Program();
  if (clBuildProgram(program.get(), 1, &device, options, nullptr, nullptr) != CL_SUCCESS) return Program();
  return program;
}

std::vector<std::uint8_t> OpenClApi::BinaryOf(cl_program program) {
  std::size_t size = 0;
  if (clGetProgramInfo(program, CL_PROGRAM_BINARY_SIZES, sizeof size, &size, nullptr) != CL_SUCCESS || size == 0)
    return {};
  std::vector<std::uint8_t> binary(size);
  unsigned char* at = binary.data();
  if (clGetProgramInfo(program, CL_PROGRAM_BINARIES, sizeof at, &at, nullptr) != CL_SUCCESS) return {};
  return binary;
}

Program OpenClApi::ProgramFromSource(const KernelSource& source, const std::string& key, const char* options) {
  cl_int err = CL_SUCCESS;
  const char* text = source.text.c_str();
  const std::size_t length = source.text.size();
  Program program(clCreateProgramWithSource(context.get(), 1, &text, &length, &err));
  Check(err, "build", "clCreateProgramWithSource");
  err = clBuildProgram(program.get(), 1, &device, options, nullptr, nullptr);
  if (err != CL_SUCCESS) {
    std::size_t log_size = 0;
    clGetProgramBuildInfo(program.get(), device, CL_PROGRAM_BUILD_LOG, 0, nullptr, &log_size);
    std::string log(log_size, '\0');
    clGetProgramBuildInfo(program.get(), device, CL_PROGRAM_BUILD_LOG, log_size, log.data(), nullptr);
    log.resize(std::strlen(log.c_str()));
    Fail("build", "kernel " + key + " (" + source.text.substr(0, source.text.find('\n')) + ") failed with error " +
                      std::to_string(err) + " on " + name_ + "; build log:" + FirstLines(log, 20));
  }
  return program;
}

cl_kernel OpenClApi::KernelFor(const KernelSource& source) {
  if (source.lang != Lang::kOpenCl) Fail("build", std::string("kernel language is ") + Name(source.lang));
  const std::string key = HashOf(source);
  {
    const std::lock_guard<std::mutex> lock(built_mutex_);
    if (auto found = built_.find(key); found != built_.end()) {
      if (cache_) ++cache_->counters().memory_hits;
      return found->second.kernel.get();
    }
  }
  // Built outside the lock: other threads build other kernels meanwhile.
  constexpr const char* kOptions = "-cl-std=CL1.2";
  BuiltKernel b;
  const std::string cache_key = cache_ ? ProgramKey("opencl", cache_device_id_, key, kOptions) : "";
  if (cache_) {
    // A binary the driver refuses (another driver wrote it, it is corrupt) is built from source below.
    if (const auto binary = cache_->Load("opencl", cache_key)) b.program = ProgramFromBinary(*binary, kOptions);
    if (b.program.get()) ++cache_->counters().disk_hits;
  }
  if (!b.program.get()) {
    b.program = ProgramFromSource(source, key, kOptions);
    if (cache_) {
      ++cache_->counters().builds;
      cache_->Store("opencl", cache_key, BinaryOf(b.program.get()));
    }
  }
  cl_int err = CL_SUCCESS;
  b.kernel = Kernel(clCreateKernel(b.program.get(), source.entry_point.c_str(), &err));
  Check(err, "build", "clCreateKernel '" + source.entry_point + "' of kernel " + key);
  const std::lock_guard<std::mutex> lock(built_mutex_);
  return built_.emplace(key, std::move(b)).first->second.kernel.get();  // a twin built meanwhile wins
}

// ---------------------------------------------------------------- memory

Memory OpenClApi::NewMemory(cl_mem_flags flags, std::size_t bytes, const void* data, const std::string& what) {
  cl_int err = CL_SUCCESS;
  Memory m(clCreateBuffer(context.get(), flags | (data ? CL_MEM_COPY_HOST_PTR : 0), bytes, const_cast<void*>(data),
                          &err));
  Check(err, "launch", "clCreateBuffer '" + what + "' (" + std::to_string(bytes) + " bytes)");
  return m;
}

std::unique_ptr<DeviceBuffer> OpenClApi::Allocate(BufferUse use, std::size_t bytes, const void* initial,
                                                  const std::string& what) {
  const cl_mem_flags flags = use == BufferUse::kOutput ? CL_MEM_READ_WRITE : CL_MEM_READ_ONLY;
  return std::make_unique<ClMemory>(NewMemory(flags, bytes, initial, what), bytes);
}

std::unique_ptr<DeviceObject> OpenClApi::PaletteView(const Variant& variant, DeviceBuffer& palette,
                                                     const std::string& suffix) {
  if (variant.storage != PaletteStorage::kImage) return nullptr;
  cl_image_format format{CL_RGBA, CL_FLOAT};
  cl_image_desc desc{};
  desc.image_type = CL_MEM_OBJECT_IMAGE1D_BUFFER;
  desc.image_width = palette.bytes() / 16;
  desc.buffer = static_cast<cl_mem>(palette.native());
  cl_int err = CL_SUCCESS;
  Memory image(clCreateImage(context.get(), CL_MEM_READ_ONLY, &format, &desc, nullptr, &err));
  Check(err, "launch", "clCreateImage (image1d_buffer of " + std::to_string(desc.image_width) + " texels)" + suffix);
  return std::make_unique<ClMemory>(std::move(image), 0);
}

// The palette's page-locked staging, and a non-blocking write from it on the
// upload queue. The driver's ring fence says no launch still reads the
// buffer, and covers its last upload too where a launch waited for it;
// otherwise (a slot written again before any launch used it) Staging waits
// until that upload has read the staging.
std::span<std::uint8_t> OpenClApi::Staging(DeviceBuffer& buffer, const std::string& key, bool upload_fenced) {
  auto& memory = static_cast<ClMemory&>(buffer);
  if (!memory.upload)
    memory.upload = std::make_unique<ClPinned>(context.get(), queue.get(), memory.bytes(), "the palette staging of " + key);
  if (const cl_event last = memory.uploaded.get(); last && !upload_fenced)
    Check(clWaitForEvents(1, &last), "launch", [&] { return "clWaitForEvents on the last upload of 'palette' of " + key; });
  return {static_cast<std::uint8_t*>(memory.upload->host), memory.bytes()};
}

void OpenClApi::Upload(DeviceBuffer& buffer, std::size_t bytes, const std::string& key) {
  auto& memory = static_cast<ClMemory&>(buffer);
  if (!memory.upload) Fail("launch", "Upload of 'palette' of " + key + " before its Staging");
  if (!uploads_.get()) {
    cl_int err = CL_SUCCESS;
    uploads_ = Queue(clCreateCommandQueue(context.get(), device, 0, &err));
    Check(err, "launch", "clCreateCommandQueue for uploads on " + name_);
  }
  cl_event event = nullptr;
  Check(clEnqueueWriteBuffer(uploads_.get(), memory.memory.get(), CL_FALSE, 0, bytes, memory.upload->host, 0, nullptr,
                             &event),
        "launch", [&] { return "clEnqueueWriteBuffer 'palette' of " + key; });
  memory.uploaded = Event(event);
  Check(clRetainEvent(event), "launch", [&] { return "clRetainEvent of the upload of " + key; });
  last_upload_ = Event(event);
  Check(clFlush(uploads_.get()), "launch", [&] { return "clFlush after uploading 'palette' of " + key; });
}

// One barrier covers every upload before the last (one in-order upload queue).
void OpenClApi::JoinUploads(cl_command_queue on) {
  if (on == queue.get()) last_launch_.reset();  // a command after the launch: Mark queues a marker
  const cl_event last = last_upload_.get();
  if (!last) return;
  Check(clEnqueueBarrierWithWaitList(on, 1, &last, nullptr), "launch", "clEnqueueBarrierWithWaitList for the palette uploads");
  if (on == queue.get()) last_upload_.reset();
}

void OpenClApi::Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string& what, bool) {
  JoinUploads(queue.get());
  Check(clEnqueueReadBuffer(queue.get(), static_cast<cl_mem>(buffer.native()), CL_TRUE, 0, out.size(), out.data(), 0,
                            nullptr, nullptr),
        "launch", "clEnqueueReadBuffer " + what);
}

// One non-blocking read per chunk, each with its event: the host scans a
// chunk while the next ones are still in flight. At most kReadChunks chunks
// (each a multiple of `chunk`): a read costs NVIDIA's OpenCL ~20 us of host
// time to queue (the H100 machine, 2026-11-26), so 25 of 64k vertices took
// ~500 us; and the first is flushed at once, so the copies start while the
// rest are queued.
DeviceApi::PinnedRead OpenClApi::ReadPinnedChunks(const DeviceBuffer& buffer, std::size_t bytes, std::size_t chunk_bytes,
                                                  const std::string& what) {
  constexpr std::size_t kReadChunks = 8;
  const std::size_t chunk = ChunkCovering(bytes, chunk_bytes, kReadChunks);
  const auto& memory = static_cast<const ClMemory&>(buffer);
  if (!memory.readback)
    memory.readback = std::make_unique<ClPinned>(context.get(), queue.get(), memory.bytes(), "the read-back of " + what);
  auto* host = static_cast<std::uint8_t*>(memory.readback->host);
  memory.readback_chunks.clear();
  JoinUploads(queue.get());
  for (std::size_t at = 0; at < bytes; at += chunk) {
    cl_event event = nullptr;
    Check(clEnqueueReadBuffer(queue.get(), memory.memory.get(), CL_FALSE, at, std::min(chunk, bytes - at), host + at,
                              0, nullptr, &event),
          "launch", "clEnqueueReadBuffer " + what);
    memory.readback_chunks.emplace_back(event);
    if (at == 0) Check(clFlush(queue.get()), "launch", "clFlush after queueing the read-back of " + what);
  }
  Check(clFlush(queue.get()), "launch", "clFlush after queueing the read-back of " + what);
  return {{host, bytes}, [&memory, chunk, what](std::size_t end) {
            if (end == 0) return;
            const cl_event event = memory.readback_chunks[(end - 1) / chunk].get();
            Check(clWaitForEvents(1, &event), "launch", "clWaitForEvents while reading back " + what);
          }};
}

std::span<const std::uint8_t> OpenClApi::ReadPinned(const DeviceBuffer& buffer, std::size_t bytes,
                                                    const std::string& what) {
  const auto& memory = static_cast<const ClMemory&>(buffer);
  if (!memory.readback)
    memory.readback = std::make_unique<ClPinned>(context.get(), queue.get(), memory.bytes(), "the read-back of " + what);
  JoinUploads(queue.get());
  Check(clEnqueueReadBuffer(queue.get(), memory.memory.get(), CL_TRUE, 0, bytes, memory.readback->host, 0, nullptr,
                            nullptr),
        "launch", "clEnqueueReadBuffer " + what);
  return {static_cast<const std::uint8_t*>(memory.readback->host), bytes};
}

// A marker after everything queued, and the queue flushed: the device starts
// on the frame while the host prepares the next one.
void OpenClApi::Mark(std::unique_ptr<DeviceObject>& marker, const std::string& what) {
  if (last_launch_.get() && !last_upload_.get()) {
    marker = std::make_unique<ClMarker>(last_launch_.release());
  } else {
    JoinUploads(queue.get());
    cl_event event = nullptr;
    Check(clEnqueueMarkerWithWaitList(queue.get(), 0, nullptr, &event), "launch", "clEnqueueMarkerWithWaitList after " + what);
    marker = std::make_unique<ClMarker>(event);
  }
  Check(clFlush(queue.get()), "launch", [&] { return "clFlush after " + what; });
}

void OpenClApi::Wait(DeviceObject& marker, const std::string& what) {
  const cl_event event = static_cast<ClMarker&>(marker).event.get();
  Check(clWaitForEvents(1, &event), "launch", [&] { return "waiting for " + what; });
}

// A negative status is the command's error (clWaitForEvents reports it as
// CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST): Wait then says so.
bool OpenClApi::Signalled(DeviceObject& marker, const std::string& what) {
  const cl_event event = static_cast<ClMarker&>(marker).event.get();
  cl_int status = CL_QUEUED;
  Check(clGetEventInfo(event, CL_EVENT_COMMAND_EXECUTION_STATUS, sizeof status, &status, nullptr), "launch",
        [&] { return "clGetEventInfo on " + what; });
  if (status < 0) Wait(marker, what);
  return status <= CL_COMPLETE;
}

// ---------------------------------------------------------------- launches

// The K palettes of an instanced run may exceed what the device allows a
// __constant buffer or an image1d_buffer; say which limit, before launching.
void OpenClApi::CheckRun(const PackedMesh& mesh, std::span<const KernelSource>, const RunShape& shape) const {
  const Variant& variant = mesh.variant;
  const std::size_t palette_bytes = static_cast<std::size_t>(shape.instances) * shape.palette_bytes;
  if (variant.storage == PaletteStorage::kConstant) {
    cl_ulong limit = 0;
    clGetDeviceInfo(device, CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE, sizeof limit, &limit, nullptr);
    if (limit != 0 && palette_bytes > limit)
      Fail("launch", variant.Key() + ": the palettes (" + std::to_string(palette_bytes) +
                         " bytes) exceed CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE " + std::to_string(limit) + " of " + name_);
  } else if (variant.storage == PaletteStorage::kImage) {
    std::size_t limit = 0;
    clGetDeviceInfo(device, CL_DEVICE_IMAGE_MAX_BUFFER_SIZE, sizeof limit, &limit, nullptr);
    if (limit != 0 && palette_bytes / 16 > limit)
      Fail("launch", variant.Key() + ": the palettes (" + std::to_string(palette_bytes / 16) +
                         " texels) exceed CL_DEVICE_IMAGE_MAX_BUFFER_SIZE " + std::to_string(limit) + " of " + name_);
  }
}

std::unique_ptr<PlannedLaunch> OpenClApi::Plan(const LaunchSpec& spec) {
  auto plan = std::make_unique<ClPlanned>(spec);
  plan->kernel = KernelFor(spec.source);
  plan->dimensions = spec.instanced ? 2 : 1;
  plan->global[0] = spec.source.launch.GlobalItems(spec.count);
  plan->global[1] = static_cast<std::size_t>(spec.instances);
  plan->local[0] = static_cast<std::size_t>(spec.source.launch.wg_size);
  return plan;
}

std::unique_ptr<DeviceObject> OpenClApi::Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                              const SetOptions&, std::size_t&) {
  auto bound = std::make_unique<ClBound>();
  bound->plan = static_cast<const ClPlanned*>(&launch);
  for (const ArgumentBinding& a : arguments) {
    const DeviceObject* object = a.view ? a.view : a.buffer;
    bound->arguments.push_back(object ? static_cast<cl_mem>(static_cast<const ClMemory*>(object)->native()) : nullptr);
    // The buffers under views too (an image view of a palette evicts its buffer).
    const cl_mem buffer = a.buffer ? static_cast<cl_mem>(static_cast<const ClMemory*>(a.buffer)->native()) : nullptr;
    cl_mem_object_type type = 0;
    std::size_t bytes = 0;
    const bool listed = std::any_of(bound->buffers.begin(), bound->buffers.end(), [&](const auto& b) { return b.first == buffer; });
    if (buffer && !listed && clGetMemObjectInfo(buffer, CL_MEM_TYPE, sizeof type, &type, nullptr) == CL_SUCCESS &&
        type == CL_MEM_OBJECT_BUFFER && clGetMemObjectInfo(buffer, CL_MEM_SIZE, sizeof bytes, &bytes, nullptr) == CL_SUCCESS)
      bound->buffers.emplace_back(buffer, bytes);
  }
  return bound;
}

// Sets the arguments of one launch (positions into `out_positions` when not
// null) and enqueues it, its event into `event` when given.
void OpenClApi::Enqueue(const ClBound& bound, cl_mem out_positions, cl_event* event, cl_command_queue on,
                        cl_uint wait_count, const cl_event* wait_list) {
  const ClPlanned& plan = *bound.plan;
  const LaunchSpec& spec = plan.spec;
  const cl_uint vertex_count = spec.vertex_count;
  std::vector<ArgValue>& set = kernel_args_[plan.kernel];
  set.resize(spec.source.arguments.size());
  for (std::size_t a = 0; a < spec.source.arguments.size(); ++a) {
    const KernelArgument& arg = spec.source.arguments[a];
    ArgValue value;
    if (arg.name == "n") {
      value = {sizeof(cl_uint), spec.count};
    } else if (arg.name == "first") {
      value = {sizeof(cl_uint), spec.first};
    } else if (arg.name == "vertex_count") {
      value = {sizeof(cl_uint), vertex_count};
    } else if (arg.kind == ArgumentKind::kScalar) {  // the palette kernel's (its bits: a float's too)
      if (!frame_run_) Fail("launch", spec.where + ": no value for the scalar '" + arg.name + "'");
      value = {sizeof(cl_uint), ScalarOf(*frame_run_, arg.name, "OpenCL")};
    } else {
      const cl_mem memory = arg.name == "out_positions" && out_positions ? out_positions : bound.arguments[a];
      value = {sizeof(cl_mem), reinterpret_cast<std::uintptr_t>(memory)};
    }
    if (set[a].size == value.size && set[a].value == value.value) continue;
    cl_int err = CL_SUCCESS;
    if (value.size == sizeof(cl_uint)) {
      const auto scalar = static_cast<cl_uint>(value.value);
      err = clSetKernelArg(plan.kernel, static_cast<cl_uint>(a), sizeof scalar, &scalar);
    } else {
      const auto memory = reinterpret_cast<cl_mem>(static_cast<std::uintptr_t>(value.value));
      err = clSetKernelArg(plan.kernel, static_cast<cl_uint>(a), sizeof memory, &memory);
    }
    if (err != CL_SUCCESS) {
      set[a] = {};
      Check(err, "launch", spec.where + ": clSetKernelArg " + std::to_string(a) + " '" + arg.name + "'");
    }
    set[a] = value;
  }
  Check(clEnqueueNDRangeKernel(on ? on : queue.get(), plan.kernel, plan.dimensions, nullptr, plan.global, plan.local,
                               wait_count, wait_list, event),
        "launch", [&] {
          return spec.where + ": clEnqueueNDRangeKernel (" + std::to_string(plan.global[0]) + " items x " +
                 std::to_string(plan.global[1]) + " instances, groups of " + std::to_string(plan.local[0]) + ")";
        });
}

namespace {

// Profiling END - START of `event` in ms; a query that fails reads as 0 (a
// verification run's launch times are only shown).
double EventMs(cl_event event) {
  cl_ulong start = 0, end = 0;
  clGetEventProfilingInfo(event, CL_PROFILING_COMMAND_START, sizeof start, &start, nullptr);
  clGetEventProfilingInfo(event, CL_PROFILING_COMMAND_END, sizeof end, &end, nullptr);
  return end > start ? static_cast<double>(end - start) * 1e-6 : 0.0;
}

}  // namespace

std::vector<std::vector<double>> OpenClApi::RunFrames(const FrameRun& run) {
  const CurrentRun current(frame_run_, run);
  last_launch_.reset();
  if (run.use == FrameUse::kLive) {
    // The prologue (the palette kernel), while the device still runs an
    // earlier frame, on its own queue after the palette uploads and the last
    // prologue (its wait list: one that went on the frame's queue writes the
    // states this one reads), flushed so that the frame's queue may wait for
    // its event: it runs beside that frame's skin kernel. When everything
    // queued has completed (a frame waited for) it goes first on the frame's
    // in-order queue instead, where it costs no wait between two queues
    // (NVIDIA's OpenCL on an H200: 64 x 25k-b4 pipelined at 0.93 of
    // Skin-only against 0.74-0.89 on one queue, the waited-for frame 4 us
    // slower with two). The frame's first launch waits for the prologue's
    // event or the uploads (its wait list, not a barrier). The last launch's
    // event is kept for Mark.
    Event ready = std::move(last_upload_);
    cl_int status = CL_COMPLETE;
    if (last_live_.get())
      Check(clGetEventInfo(last_live_.get(), CL_EVENT_COMMAND_EXECUTION_STATUS, sizeof status, &status, nullptr),
            "launch", "clGetEventInfo of the last frame");
    const bool beside = !run.prologue.empty() && status != CL_COMPLETE;
    if (beside) {
      if (!prologues_.get()) {
        cl_int err = CL_SUCCESS;
        prologues_ = Queue(clCreateCommandQueue(context.get(), device, 0, &err));
        Check(err, "launch", "clCreateCommandQueue for the palette kernels on " + name_);
      }
      for (std::size_t l = 0; l < run.prologue.size(); ++l) {
        std::vector<cl_event> wait;
        for (const cl_event e : {ready.get(), last_prologue_.get()})
          if (e) wait.push_back(e);
        cl_event event = nullptr;
        Enqueue(static_cast<const ClBound&>(*run.prologue[l]), nullptr, &event, prologues_.get(),
                static_cast<cl_uint>(wait.size()), wait.empty() ? nullptr : wait.data());
        clRetainEvent(event);
        last_prologue_ = Event(event);
        ready = Event(event);
      }
      Check(clFlush(prologues_.get()), "launch", "clFlush of the palette kernels' queue");
    }
    std::vector<const ClBound*> launches;
    if (!beside)
      for (const std::unique_ptr<DeviceObject>& launch : run.prologue) launches.push_back(static_cast<const ClBound*>(launch.get()));
    for (const auto& frame : run.frames)
      for (const std::unique_ptr<DeviceObject>& launch : frame) launches.push_back(static_cast<const ClBound*>(launch.get()));
    const std::size_t in_line = beside ? 0 : run.prologue.size();  // the prologue's launches first in `launches`
    for (std::size_t l = 0; l < launches.size(); ++l) {
      const cl_event wait = ready.get();
      const bool last = l + 1 == launches.size();
      cl_event event = nullptr;
      Enqueue(*launches[l], static_cast<cl_mem>(run.out_positions), last || l < in_line ? &event : nullptr, nullptr,
              wait ? 1 : 0, wait ? &wait : nullptr);
      ready.reset();
      if (l < in_line && !last) {
        last_prologue_ = Event(event);
        continue;
      }
      if (event) {
        clRetainEvent(event);
        last_live_ = Event(event);
        last_launch_ = Event(event);
      }
    }
    return {};
  }
  if (last_upload_.get()) {  // not timed: wait for the uploads on the host
    Check(clFinish(uploads_.get()), "launch", "clFinish on the palette uploads");
    last_upload_.reset();
  }
  if (run.use == FrameUse::kVerify) {
    // On a profiling lane, after everything queued before (`queue` has no
    // profiling, and a caller's adopted queue may have none either).
    Check(clFinish(queue.get()), "launch", "clFinish before " + run.key);
    const cl_command_queue lane = Lane(0);
    std::vector<Event> events;
    for (const std::unique_ptr<DeviceObject>& launch : run.frames.front()) {
      cl_event event = nullptr;
      Enqueue(static_cast<const ClBound&>(*launch), nullptr, &event, lane);
      events.emplace_back(event);
    }
    Check(clFinish(lane), "launch", "clFinish after " + run.key);
    std::vector<double> ms;
    for (const Event& e : events) ms.push_back(EventMs(e.get()));
    return {ms};
  }
  if (run.use == FrameUse::kCold) return TimeCold(run);
  return TimeOnLanes(run);
}

// kCold (device_api.h): one in-order profiling queue, each frame after the
// flush's launches and, on a GPU, waited for before the next is queued. In a
// timed frame a marker with an event follows the flush and every launch, the
// launches themselves without events: a launch's time runs from the END of
// the marker before it to the START of the marker after it, so no marker's
// own work is in any launch's (on a CPU device the eviction's END starts the
// first). (Queued back to back, NVIDIA's frames alternated between two gaps
// after the flush, as CUDA's did: runtime/backends/cuda/cuda_runner.cpp
// TimeCold.)
//
// Why markers and not the launch's own event: on NVIDIA's driver an event on
// a kernel costs the device its stamps' work beside the kernel. One
// 100k-vertex B=4 kernel read 6.59 us to its own END, 5.25 to the START of a
// marker after it queued without an event, and 5.92 to that marker's END;
// CUDA's twin 4.10-4.13 (an H200, driver 580.159.04, 2026-12-03; 10.50,
// 9.12-9.15 and 8.96-9.02 at 400k, 26.53, 25.06-25.15 and 24.54 at 1600k).
// A marker's own START to END is 0.6-0.96 us there, and the kernel after it
// started (its event's START) 1.25-1.28 us after that END in all 30 frames
// of a dump (GPU-bf7355ef, 2026-12-03): starting the next launch's time at
// the marker's END counts none of it, where its START counted it in every
// launch after a frame's first.
std::vector<std::vector<double>> OpenClApi::TimeCold(const FrameRun& run) {
  const cl_command_queue lane = Lane(0);
  const auto untimed = std::min(run.frames.size(), static_cast<std::size_t>(std::max(run.untimed, 0)));
  std::vector<std::vector<Event>> events(run.frames.size() - untimed);  // the flush's marker, then each launch's
  const auto mark = [&](std::vector<Event>& into, const char* after) {
    cl_event event = nullptr;
    Check(clEnqueueMarkerWithWaitList(lane, 0, nullptr, &event), "launch",
          std::string("clEnqueueMarkerWithWaitList after ") + after + " of " + run.key);
    into.emplace_back(event);
  };
  for (std::size_t f = 0; f < run.frames.size(); ++f) {
    const bool timed = f >= untimed;
    if (evicts_) {  // the frame's own buffers, evicted by a native kernel in the flush's place
      cl_event event = nullptr;
      EnqueueEviction(run.frames[f], timed ? &event : nullptr, lane);
      if (event) events[f - untimed].emplace_back(event);
    }
    // The flush once per launch of the frame (it leaves the same clean cache
    // each time), so the device is still flushing while the host queues the
    // frame: each launch here costs NVIDIA's host 6-8 us to queue, and one
    // flush of twice the L2 (about 30 us on an H200) covered one launch and
    // its markers, not four (runtime/device_api.h, docs/PERFORMANCE.md "NVIDIA's
    // OpenCL frames of several launches"). A bucketed frame of four launches
    // read 24.0-41.5 us with one flush, 17.7-17.9 with four, Vulkan's twin
    // 17.1 (H200s, 2026-12-03).
    const std::size_t flushes = evicts_ ? 0 : std::max<std::size_t>(run.frames[f].size(), 1);
    for (std::size_t again = 0; again < flushes; ++again)
      for (const std::unique_ptr<DeviceObject>& flush : run.flush)
        Enqueue(static_cast<const ClBound&>(*flush), nullptr, nullptr, lane);
    if (timed && !evicts_) mark(events[f - untimed], "the flush");
    for (const std::unique_ptr<DeviceObject>& launch : run.frames[f]) {
      Enqueue(static_cast<const ClBound&>(*launch), nullptr, nullptr, lane);
      if (timed) mark(events[f - untimed], "a launch");
    }
    // A GPU's frame waits (the launch gaps above are a GPU's); a CPU
    // device's (evicts_) follows the one before, its worker threads kept
    // awake: with every frame waited for, PoCL's winners moved 1.3-1.8x
    // between three tuning runs on the H200 machine's host (December 2026),
    // where they had moved up to 1.17x.
    Check(evicts_ ? clFlush(lane) : clFinish(lane), "launch", "waiting for a frame while timing " + run.key);
  }
  Check(clFinish(lane), "launch", "clFinish after timing " + run.key);
  const auto stamp = [&](const Event& e, cl_profiling_info which) {
    cl_ulong at = 0;
    Check(clGetEventProfilingInfo(e.get(), which, sizeof at, &at, nullptr), "launch",
          "clGetEventProfilingInfo of " + run.key);
    return at;
  };
  std::vector<std::vector<double>> ms;
  for (const std::vector<Event>& frame : events) {
    std::vector<double>& launches = ms.emplace_back();
    for (std::size_t k = 1; k < frame.size(); ++k) {
      const cl_ulong from = stamp(frame[k - 1], CL_PROFILING_COMMAND_END), to = stamp(frame[k], CL_PROFILING_COMMAND_START);
      launches.push_back(to > from ? static_cast<double>(to - from) * 1e-6 : 0.0);
    }
  }
  return ms;
}

void OpenClApi::EnqueueEviction(std::span<const std::unique_ptr<DeviceObject>> frame, cl_event* event,
                                cl_command_queue on) {
  std::vector<std::pair<cl_mem, std::size_t>> buffers;
  for (const std::unique_ptr<DeviceObject>& launch : frame)
    for (const auto& buffer : static_cast<const ClBound&>(*launch).buffers)
      if (std::find(buffers.begin(), buffers.end(), buffer) == buffers.end()) buffers.push_back(buffer);
  for (std::size_t b = 0; b < buffers.size(); ++b) {
    EvictArgs args{&evicted_bytes_, buffers[b].second, nullptr};
    const void* slot = &args.address;
    static_assert(sizeof(cl_mem) == sizeof(args.address));
    std::memcpy(&args.address, &buffers[b].first, sizeof(cl_mem));
    Check(clEnqueueNativeKernel(on, EvictNatively, &args, sizeof args, 1, &buffers[b].first, &slot, 0, nullptr,
                                b + 1 == buffers.size() ? event : nullptr),
          "launch", "clEnqueueNativeKernel (the cache eviction before a cold frame)");
  }
}

// kTime (docs/TUNING.md "Timing"): frames alternate between two in-order
// queues, so one frame starts while the last work-groups of the one before
// drain, as consecutive dispatches do in GL and Vulkan; one queue alone
// would add the dependent-launch gap to every frame. Each burst starts
// with both queues fenced on each other; its time runs from the earliest
// START of its first launches to the latest END of its last ones.
std::vector<std::vector<double>> OpenClApi::TimeOnLanes(const FrameRun& run) {
  const auto untimed = static_cast<std::size_t>(std::max(run.untimed, 0));
  const auto burst = static_cast<std::size_t>(std::max(run.burst, 1));
  const cl_command_queue lane[2] = {Lane(0), Lane(1)};
  for (std::size_t f = 0; f < untimed; ++f)
    for (const std::unique_ptr<DeviceObject>& launch : run.frames[f])
      Enqueue(static_cast<const ClBound&>(*launch), nullptr, nullptr, lane[0]);
  std::vector<LaneEdges> bursts(run.TimedBursts());
  for (std::size_t b = 0; b < bursts.size(); ++b) {
    for (int l = 0; l < 2; ++l) {  // each lane waits for the other's earlier work
      cl_event marker = nullptr;
      Check(clEnqueueMarkerWithWaitList(lane[l], 0, nullptr, &marker), "launch", "clEnqueueMarkerWithWaitList");
      const Event fence(marker);
      Check(clEnqueueBarrierWithWaitList(lane[1 - l], 1, &marker, nullptr), "launch", "clEnqueueBarrierWithWaitList");
    }
    for (std::size_t i = 0; i < burst; ++i) {
      const int l = static_cast<int>(i % 2);
      const auto& frame = run.frames[untimed + b * burst + i];
      // Events only on each lane's first and last launch of the burst: an
      // event per launch is host work (and a driver object) per frame that
      // CUDA's two events per burst do not pay.
      const bool lane_first = i < 2, lane_last = i + 2 >= burst;
      for (std::size_t k = 0; k < frame.size(); ++k) {
        const bool first = lane_first && k == 0, last = lane_last && k + 1 == frame.size();
        if (!first && !last) {
          Enqueue(static_cast<const ClBound&>(*frame[k]), nullptr, nullptr, lane[l]);
          continue;
        }
        cl_event event = nullptr;
        Enqueue(static_cast<const ClBound&>(*frame[k]), nullptr, &event, lane[l]);
        Event e(event);
        if (first) {
          bursts[b].first[l] = std::move(e);
        } else {
          bursts[b].last[l] = std::move(e);
        }
      }
      // Submitted now, so neither queue waits for the host to flush it. (On
      // the H100 this did not remove NVIDIA's OpenCL's ~7 us per frame with
      // two queues at 400k-b4, 2026-11-24; it was the event on every launch,
      // docs/PERFORMANCE.md "Lessons that still hold".)
      Check(clFlush(lane[l]), "launch", "clFlush while timing " + run.key);
    }
  }
  for (int l = 0; l < 2; ++l) Check(clFinish(lane[l]), "launch", "clFinish after timing " + run.key);
  std::vector<std::vector<double>> ms;
  for (const LaneEdges& e : bursts) ms.push_back({SpanMs(e, run.key)});
  return ms;
}

// A burst's time: from the earliest START of its lanes' first launches to the
// latest END of their last ones, ms (0 when none ran).
double OpenClApi::SpanMs(const LaneEdges& e, const std::string& key) {
  cl_ulong start = ~cl_ulong{0}, end = 0;
  for (int l = 0; l < 2; ++l) {
    if (!e.first[l].get()) continue;
    cl_ulong s = 0, t = 0;
    Check(clGetEventProfilingInfo(e.first[l].get(), CL_PROFILING_COMMAND_START, sizeof s, &s, nullptr), "launch",
          "clGetEventProfilingInfo (start) of " + key);
    const cl_event last = e.last[l].get() ? e.last[l].get() : e.first[l].get();
    Check(clGetEventProfilingInfo(last, CL_PROFILING_COMMAND_END, sizeof t, &t, nullptr), "launch",
          "clGetEventProfilingInfo (end) of " + key);
    start = std::min(start, s);
    end = std::max(end, t);
  }
  return end > start ? static_cast<double>(end - start) * 1e-6 : 0.0;
}

cl_command_queue OpenClApi::Lane(int i) {
  if (!lanes[i].get()) {
    cl_int err = CL_SUCCESS;
    lanes[i] = Queue(clCreateCommandQueue(context.get(), device, CL_QUEUE_PROFILING_ENABLE, &err));
    Check(err, "launch", "clCreateCommandQueue for timing on " + name_);
  }
  return lanes[i].get();
}

// ---------------------------------------------------------------- OpenClRunner

namespace {

std::unique_ptr<OpenClApi> OpenDevice(int platform_index, int device_index) {
  auto api = std::make_unique<OpenClApi>();
  cl_uint platform_count = 0;
  if (clGetPlatformIDs(0, nullptr, &platform_count) != CL_SUCCESS || platform_index < 0 ||
      static_cast<cl_uint>(platform_index) >= platform_count) {
    Fail("setup", "no platform " + std::to_string(platform_index) + " (" + std::to_string(platform_count) +
                      " platforms)");
  }
  std::vector<cl_platform_id> platforms(platform_count);
  clGetPlatformIDs(platform_count, platforms.data(), nullptr);
  api->platform = platforms[static_cast<std::size_t>(platform_index)];
  cl_uint device_count = 0;
  if (clGetDeviceIDs(api->platform, CL_DEVICE_TYPE_ALL, 0, nullptr, &device_count) != CL_SUCCESS || device_index < 0 ||
      static_cast<cl_uint>(device_index) >= device_count) {
    Fail("setup", "platform " + std::to_string(platform_index) + " has no device " + std::to_string(device_index) +
                      " (" + std::to_string(device_count) + " devices)");
  }
  std::vector<cl_device_id> devices(device_count);
  clGetDeviceIDs(api->platform, CL_DEVICE_TYPE_ALL, device_count, devices.data(), nullptr);
  api->device = devices[static_cast<std::size_t>(device_index)];
  api->name_ = DeviceString(api->device, CL_DEVICE_NAME);
  cl_int err = CL_SUCCESS;
  const cl_context_properties properties[] = {CL_CONTEXT_PLATFORM,
                                              reinterpret_cast<cl_context_properties>(api->platform), 0};
  api->context = Context(clCreateContext(properties, 1, &api->device, nullptr, nullptr, &err));
  Check(err, "setup", "clCreateContext on " + api->name_);
  api->queue = Queue(clCreateCommandQueue(api->context.get(), api->device, 0, &err));
  Check(err, "setup", "clCreateCommandQueue on " + api->name_);
  cl_device_type type = 0;
  cl_device_exec_capabilities exec = 0;
  api->evicts_ = clGetDeviceInfo(api->device, CL_DEVICE_TYPE, sizeof type, &type, nullptr) == CL_SUCCESS &&
                 (type & CL_DEVICE_TYPE_CPU) &&
                 clGetDeviceInfo(api->device, CL_DEVICE_EXECUTION_CAPABILITIES, sizeof exec, &exec, nullptr) == CL_SUCCESS &&
                 (exec & CL_EXEC_NATIVE_KERNEL);
  return api;
}

// The caller's handles, checked to belong together; retained.
std::unique_ptr<OpenClApi> AdoptHandles(void* device_handle, void* context_handle, void* queue_handle) {
  if (!device_handle || !context_handle || !queue_handle)
    Fail("setup", "a null cl_device_id, cl_context or cl_command_queue");
  const auto device = static_cast<cl_device_id>(device_handle);
  const auto context = static_cast<cl_context>(context_handle);
  const auto queue = static_cast<cl_command_queue>(queue_handle);
  cl_uint count = 0;
  Check(clGetContextInfo(context, CL_CONTEXT_NUM_DEVICES, sizeof count, &count, nullptr), "setup",
        "clGetContextInfo(CL_CONTEXT_NUM_DEVICES) of the given context");
  std::vector<cl_device_id> devices(count);
  Check(clGetContextInfo(context, CL_CONTEXT_DEVICES, count * sizeof(cl_device_id), devices.data(), nullptr), "setup",
        "clGetContextInfo(CL_CONTEXT_DEVICES) of the given context");
  if (std::find(devices.begin(), devices.end(), device) == devices.end())
    Fail("setup", "the given device is not one of the given context's " + std::to_string(count) + " devices");
  cl_context queue_context = nullptr;
  cl_device_id queue_device = nullptr;
  cl_command_queue_properties properties = 0;
  Check(clGetCommandQueueInfo(queue, CL_QUEUE_CONTEXT, sizeof queue_context, &queue_context, nullptr), "setup",
        "clGetCommandQueueInfo(CL_QUEUE_CONTEXT) of the given queue");
  Check(clGetCommandQueueInfo(queue, CL_QUEUE_DEVICE, sizeof queue_device, &queue_device, nullptr), "setup",
        "clGetCommandQueueInfo(CL_QUEUE_DEVICE) of the given queue");
  Check(clGetCommandQueueInfo(queue, CL_QUEUE_PROPERTIES, sizeof properties, &properties, nullptr), "setup",
        "clGetCommandQueueInfo(CL_QUEUE_PROPERTIES) of the given queue");
  if (queue_context != context || queue_device != device)
    Fail("setup", "the given queue belongs to another context or device");
  if (properties & CL_QUEUE_OUT_OF_ORDER_EXEC_MODE_ENABLE)
    Fail("setup", "the given queue is out-of-order; an in-order queue is needed");
  auto api = std::make_unique<OpenClApi>();
  Check(clGetDeviceInfo(device, CL_DEVICE_PLATFORM, sizeof api->platform, &api->platform, nullptr), "setup",
        "clGetDeviceInfo(CL_DEVICE_PLATFORM) of the given device");
  Check(clRetainContext(context), "setup", "clRetainContext");
  api->context = Context(context);
  Check(clRetainCommandQueue(queue), "setup", "clRetainCommandQueue");
  api->queue = Queue(queue);
  api->device = device;
  api->name_ = DeviceString(device, CL_DEVICE_NAME);
  return api;
}

}  // namespace

OpenClRunner::OpenClRunner(int platform_index, int device_index) : Runner(OpenDevice(platform_index, device_index)) {}

OpenClRunner::OpenClRunner(void* device_handle, void* context_handle, void* queue_handle)
    : Runner(AdoptHandles(device_handle, context_handle, queue_handle)) {}

const OpenClApi& OpenClRunner::cl() const { return static_cast<const OpenClApi&>(api()); }
void* OpenClRunner::device() const { return cl().device; }
void* OpenClRunner::context() const { return cl().context.get(); }
void* OpenClRunner::queue() const { return cl().queue.get(); }

}  // namespace skintune::internal
