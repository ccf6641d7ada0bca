// The CUDA DeviceApi (runtime/device_api.h) and CudaRunner: modules from
// NVRTC's PTX (with the program cache), device buffers, texture objects and
// the __constant__ palette symbol, parameter arrays, and CUDA events.
#include "runtime/backends/cuda/cuda_runner.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <utility>

#include "base/error.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/backends/cuda/cupti.h"
#include "runtime/output_check.h"

namespace skintune::internal {

namespace {

using cuda::Check;
using cuda::Fail;

// Owns one driver object; released with the driver function given.
template <typename T>
class Handle {
 public:
  using Release = cuda::Result (*)(T);
  Handle() = default;
  Handle(T value, Release release) : value_(value), release_(release) {}
  ~Handle() { reset(); }
  Handle(Handle&& other) noexcept : value_(other.value_), release_(other.release_) { other.value_ = T{}; }
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      value_ = other.value_;
      release_ = other.release_;
      other.value_ = T{};
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  T get() const { return value_; }
  void reset() {
    if (value_ && release_) release_(value_);
    value_ = T{};
  }

 private:
  T value_{};
  Release release_ = nullptr;
};

using Memory = Handle<cuda::DevicePtr>;
using Module = Handle<cuda::Module>;
using Event = Handle<cuda::Event>;
using Texture = Handle<cuda::TexObject>;

struct BuiltKernel {
  Module module;
  cuda::Function function = nullptr;
};

// The __constant__ palette symbol of templates/skin.cu (STORAGE constant).
constexpr const char* kConstantPaletteSymbol = "skintune_palette";

}  // namespace

std::string CompilePtxCached(const KernelSource& source, const std::string& arch, ProgramCache* cache,
                             const std::string& device_id) {
  const std::string key = source.source_hash.empty() ? SourceHash(source.text) : source.source_hash;
  const std::string cache_key = cache ? ProgramKey("cuda", device_id, key, "-arch=" + arch) : "";
  if (cache) {
    if (const auto ptx = cache->Load("cuda", cache_key)) {
      ++cache->counters().disk_hits;
      return std::string(ptx->begin(), ptx->end());
    }
  }
  const CompileResult compiled = CompileWithNvrtc(source.text, arch);
  if (!compiled.ok)
    Fail("build", "kernel " + key + " (" + source.text.substr(0, source.text.find('\n')) + "): " + compiled.error);
  if (cache) {
    ++cache->counters().builds;
    cache->Store("cuda", cache_key, std::vector<std::uint8_t>(compiled.ptx.begin(), compiled.ptx.end()));
  }
  return compiled.ptx;
}

namespace {

// Page-locked host memory (cuMemHostAlloc), freed with the buffer it stages
// (the driver makes the context current first: ReadyToRelease).
class CudaPinned {
 public:
  CudaPinned(const cuda::DriverApi* api, std::size_t bytes, unsigned flags, const std::string& what) : api_(api) {
    Check(api->cuMemHostAlloc(&host, bytes, flags), "launch",
          "cuMemHostAlloc for " + what + " (" + std::to_string(bytes) + " bytes)");
  }
  ~CudaPinned() {
    if (host) api_->cuMemFreeHost(host);
  }
  CudaPinned(const CudaPinned&) = delete;
  CudaPinned& operator=(const CudaPinned&) = delete;
  void* host = nullptr;

 private:
  const cuda::DriverApi* api_;
};

// A device buffer; a palette also keeps the page-locked staging of its
// uploads (Write), an output that of its read-backs (ReadPinned).
class CudaMemory final : public DeviceBuffer {
 public:
  CudaMemory(Memory m, std::size_t bytes) : DeviceBuffer(bytes), memory(std::move(m)) {}
  void* native() const override { return reinterpret_cast<void*>(static_cast<std::uintptr_t>(memory.get())); }
  cuda::DevicePtr pointer() const { return memory.get(); }
  Memory memory;
  std::unique_ptr<CudaPinned> upload;            // write-combined: the host only writes it
  Event uploaded;                                // recorded on the upload stream after each upload from `upload`
  mutable std::unique_ptr<CudaPinned> readback;
  mutable std::vector<Event> readback_chunks;     // ReadPinnedChunks: one event per chunk, reused
};

// The palette ring's fence: an event without timing on the Skinner's stream.
class CudaMarker final : public DeviceObject {
 public:
  explicit CudaMarker(Event e) : event(std::move(e)) {}
  Event event;
};

// A texture object over the palette (`image` storage).
class CudaTexture final : public DeviceObject {
 public:
  explicit CudaTexture(Texture t) : texture(std::move(t)) {}
  Texture texture;
};

class CudaPlanned final : public PlannedLaunch {
 public:
  using PlannedLaunch::PlannedLaunch;
  cuda::Function function = nullptr;
  cuda::DevicePtr constant_symbol = 0;              // STORAGE constant: the module's palette symbol
  unsigned blocks = 0, instances = 1, threads = 0;  // grid (blocks, instances)
};

// One launch of one set: its argument values and the parameter array pointing at them.
class CudaBound final : public DeviceObject {
 public:
  const CudaPlanned* plan = nullptr;
  const CudaMemory* palette = nullptr;
  std::uint32_t n = 0, first = 0, vertex_count = 0;
  std::vector<cuda::DevicePtr> pointers;  // reserved: never reallocated
  cuda::TexObject texture = 0;
  std::vector<void*> parameters;
  int output_parameter = -1;              // the index in `parameters` of "out_positions"
  // The launch's scalars (the palette kernel's delta and fresh), set from the
  // frame's run before each launch (FrameRun::scalars); cuLaunchKernel copies them.
  std::vector<std::string> scalar_names;
  mutable std::array<std::uint32_t, 4> scalars{};
};

}  // namespace

class CudaApi final : public DeviceApi {
 public:
  const cuda::DriverApi* api = nullptr;
  cuda::Device device = 0;
  cuda::Context context = nullptr;  // the device's primary context (retained), its own, or the caller's
  bool primary = true;              // the context is the retained primary context
  bool own = false;                 // the context was made for this runner (destroyed with it)
  cuda::Stream stream = nullptr;    // the caller's stream for skinning; null: the legacy default stream
  CudaDeviceInfo info;

  ~CudaApi() override {
    if (!context) return;
    api->cuCtxSetCurrent(context);
    for (cuda::Stream& lane : lanes_)
      if (lane) api->cuStreamDestroy(lane);
    if (prologue_done_) api->cuEventDestroy(prologue_done_);
    if (prologues_) {
      api->cuStreamSynchronize(prologues_);
      api->cuStreamDestroy(prologues_);
    }
    if (uploads_) {
      api->cuStreamSynchronize(uploads_);
      api->cuStreamDestroy(uploads_);
    }
    built_.clear();  // unloads the modules while their context is current
    if (primary) api->cuDevicePrimaryCtxRelease(device);
    if (own) api->cuCtxDestroy(context);
  }
  const char* name() const override { return "CUDA"; }
  const std::string& device_name() const override { return info.name; }
  void MakeCurrent() override { Check(api->cuCtxSetCurrent(context), "launch", [] { return std::string("cuCtxSetCurrent"); }); }
  bool ReadyToRelease() override {
    api->cuCtxSetCurrent(context);  // frees the buffers and textures while their context is current
    api->cuCtxSynchronize();        // no upload or launch still uses what is about to be freed
    last_upload_ = nullptr;         // done, and its event may go with its buffer
    return true;
  }
  void Build(const KernelSource& source) override { KernelFor(source); }
  // NVRTC and the driver API are thread-safe, and every thread makes the
  // primary context current (Runner::Build); built_ is guarded by built_mutex_.
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
    Check(api->cuCtxSynchronize(), "launch", "cuCtxSynchronize after uploading the input sets of " + key);
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
  bool Signalled(DeviceObject& marker, const std::string& what) override;
  void Wait(DeviceObject& marker, const std::string& what) override;
  void Finish() override {
    JoinUploads(stream);
    Check(api->cuStreamSynchronize(stream), "launch", "cuStreamSynchronize");
  }
  // The driver API is thread-safe; MakeCurrent puts the context on the calling thread.
  bool SubmitsFromAnyThread() const override { return true; }
  std::string kernel_clock() const override {
    return cupti::Unavailable().empty() ? "CUPTI kernel activity" : "CUDA events around each launch (" + cupti::Unavailable() + ")";
  }

 private:
  const BuiltKernel& KernelFor(const KernelSource& source);
  Memory NewMemory(std::size_t bytes, const void* data, const std::string& what) const;
  Event NewEvent(const std::string& what) const;
  // `parameters`: the launch's own (null) or a copy with one argument redirected (kLive).
  void Launch(const CudaBound& bound, cuda::Stream lane, void** parameters = nullptr);
  // While RunFrames runs: its run, whose scalars Launch passes.
  const FrameRun* frame_run_ = nullptr;
  double ElapsedMs(const Event& start, const Event& end) const;
  std::vector<std::vector<double>> RunTimed(const FrameRun& run);
  // Kernel time (FrameUse::kCold) on one stream: CUPTI's kernel records, or
  // events around each launch where CUPTI is unavailable (kernel_clock()).
  std::vector<std::vector<double>> TimeCold(const FrameRun& run);
  void QueueColdFrame(const FrameRun& run, std::size_t frame, cuda::Stream lane, std::vector<std::pair<Event, Event>>* events);

  cuda::Stream Lane(int i);
  // Palette uploads run on a stream of their own (non-blocking: it does not
  // wait for the legacy default stream's kernels, which the Skinner uses
  // unless given one), so frame n+1's upload overlaps frame n's kernel. The
  // next work queued on `lane` after an upload waits for it on the device.
  void JoinUploads(cuda::Stream lane);

  std::map<std::string, BuiltKernel> built_;  // by source hash
  std::mutex built_mutex_;                     // built_ (ConcurrentBuilds)
  cuda::Stream lanes_[2] = {nullptr, nullptr};  // Time's two streams (made on first use)
  cuda::Stream uploads_ = nullptr;              // the palette uploads' stream (made on first use)
  // The prologues' stream (a Skinner's palette kernel) and the event the
  // frame's stream waits for after them, made on first use: frame n + 1's
  // palette kernel runs beside frame n's skin kernel (another palette slot).
  cuda::Stream prologues_ = nullptr;
  cuda::Event prologue_done_ = nullptr;
  cuda::Event last_upload_ = nullptr;           // the latest upload's event, until a stream waits for it
};

// ---------------------------------------------------------------- kernels

const BuiltKernel& CudaApi::KernelFor(const KernelSource& source) {
  if (source.lang != Lang::kCuda) Fail("build", std::string("kernel language is ") + Name(source.lang));
  const std::string key = HashOf(source);
  {
    const std::lock_guard<std::mutex> lock(built_mutex_);
    if (auto found = built_.find(key); found != built_.end()) {
      if (cache_) ++cache_->counters().memory_hits;
      return found->second;
    }
  }
  // Compiled and loaded outside the lock: other threads build other kernels meanwhile.
  const std::string what = "kernel " + key + " (" + source.text.substr(0, source.text.find('\n')) + ")";
  const std::string ptx = CompilePtxCached(source, info.arch, cache_, cache_device_id_);
  // The driver JIT-compiles the PTX for the device; its error log says why it cannot.
  std::string log(8192, '\0');
  int options[] = {cuda::kJitErrorLogBuffer, cuda::kJitErrorLogBufferSizeBytes};
  void* values[] = {log.data(), reinterpret_cast<void*>(static_cast<std::uintptr_t>(log.size()))};
  cuda::Module module = nullptr;
  const cuda::Result r = api->cuModuleLoadDataEx(&module, ptx.c_str(), 2, options, values);
  if (r != cuda::kSuccess) {
    log.resize(std::strlen(log.c_str()));
    Fail("build", what + ": cuModuleLoadDataEx (" + info.arch + " PTX on " + info.name + ") failed: " +
                      cuda::ErrorText(r) + "; JIT log:" + FirstLines(log, 20));
  }
  BuiltKernel b;
  b.module = Module(module, api->cuModuleUnload);
  Check(api->cuModuleGetFunction(&b.function, module, source.entry_point.c_str()), "build",
        "cuModuleGetFunction '" + source.entry_point + "' of " + what);
  const std::lock_guard<std::mutex> lock(built_mutex_);
  return built_.emplace(key, std::move(b)).first->second;  // a twin built meanwhile wins
}

// K instances need K blocks in grid y and, for `image` storage, K palettes of
// texels; say which limit a run exceeds before launching. (`constant` storage:
// the kernel's symbol size, checked per launch.)
void CudaApi::CheckRun(const PackedMesh& mesh, std::span<const KernelSource>, const RunShape& shape) const {
  const Variant& variant = mesh.variant;
  const DeviceLimits& limits = info.limits;
  if (static_cast<std::uint64_t>(shape.instances) > limits.max_grid_y)
    Fail("launch", variant.Key() + ": " + std::to_string(shape.instances) +
                       " instances exceed the grid's y dimension (CU_DEVICE_ATTRIBUTE_MAX_GRID_DIM_Y " +
                       std::to_string(limits.max_grid_y) + ") of " + info.name);
  const std::uint64_t texels = static_cast<std::uint64_t>(shape.instances) * shape.palette_bytes / 16;
  if (variant.storage == PaletteStorage::kImage && texels > limits.image_buffer_max_texels)
    Fail("launch", variant.Key() + ": the palettes (" + std::to_string(texels) +
                       " texels) exceed CU_DEVICE_ATTRIBUTE_MAXIMUM_TEXTURE1D_LINEAR_WIDTH " +
                       std::to_string(limits.image_buffer_max_texels) + " of " + info.name);
}

std::unique_ptr<PlannedLaunch> CudaApi::Plan(const LaunchSpec& spec) {
  auto plan = std::make_unique<CudaPlanned>(spec);
  const BuiltKernel& kernel = KernelFor(spec.source);
  plan->function = kernel.function;
  const std::size_t wg = static_cast<std::size_t>(spec.source.launch.wg_size);
  plan->threads = static_cast<unsigned>(wg);
  plan->blocks = static_cast<unsigned>(spec.source.launch.GlobalItems(spec.count) / wg);
  plan->instances = static_cast<unsigned>(spec.instances);
  if (spec.variant.storage == PaletteStorage::kConstant) {
    std::size_t symbol_bytes = 0;
    Check(api->cuModuleGetGlobal(&plan->constant_symbol, &symbol_bytes, kernel.module.get(), kConstantPaletteSymbol),
          "launch", spec.where + ": cuModuleGetGlobal '" + kConstantPaletteSymbol + "'");
    if (symbol_bytes < spec.palettes_bytes)
      Fail("launch", spec.where + ": __constant__ " + kConstantPaletteSymbol + " holds " + std::to_string(symbol_bytes) +
                         " bytes, the palette " + std::to_string(spec.palettes_bytes) +
                         " (the kernel was emitted for fewer joints or instances)");
  }
  return plan;
}

// ---------------------------------------------------------------- memory

Memory CudaApi::NewMemory(std::size_t bytes, const void* data, const std::string& what) const {
  cuda::DevicePtr pointer = 0;
  Check(api->cuMemAlloc(&pointer, bytes), "launch", "cuMemAlloc '" + what + "' (" + std::to_string(bytes) + " bytes)");
  Memory m(pointer, api->cuMemFree);
  if (data) Check(api->cuMemcpyHtoD(pointer, data, bytes), "launch", "cuMemcpyHtoD '" + what + "'");
  return m;
}

std::unique_ptr<DeviceBuffer> CudaApi::Allocate(BufferUse, std::size_t bytes, const void* initial,
                                                const std::string& what) {
  return std::make_unique<CudaMemory>(NewMemory(bytes, initial, what), bytes);
}

// `image` storage: a texture object of float4 texels over the palette buffer.
std::unique_ptr<DeviceObject> CudaApi::PaletteView(const Variant& variant, DeviceBuffer& palette,
                                                   const std::string& suffix) {
  if (variant.storage != PaletteStorage::kImage) return nullptr;
  cuda::ResourceDesc resource;
  resource.resType = cuda::kResourceTypeLinear;
  resource.res.linear = {static_cast<CudaMemory&>(palette).pointer(), cuda::kArrayFormatFloat, 4, palette.bytes()};
  cuda::TextureDesc texture;
  texture.addressMode[0] = texture.addressMode[1] = texture.addressMode[2] = cuda::kAddressModeClamp;
  texture.filterMode = cuda::kFilterModePoint;
  cuda::TexObject object = 0;
  Check(api->cuTexObjectCreate(&object, &resource, &texture, nullptr), "launch",
        "cuTexObjectCreate (linear, " + std::to_string(palette.bytes() / 16) + " float4 texels)" + suffix);
  return std::make_unique<CudaTexture>(Texture(object, api->cuTexObjectDestroy));
}

// The palette's page-locked staging (write-combined: the host only writes
// it), and an asynchronous copy from it on the upload stream. The driver's
// ring fence says no launch still reads the buffer, and covers its last
// upload too where a launch waited for it; otherwise (a slot written again
// before any launch used it) Staging waits until that upload has read the
// staging.
std::span<std::uint8_t> CudaApi::Staging(DeviceBuffer& buffer, const std::string& key, bool upload_fenced) {
  auto& m = static_cast<CudaMemory&>(buffer);
  if (!m.upload)
    m.upload = std::make_unique<CudaPinned>(api, m.bytes(), cuda::kMemHostAllocWriteCombined, "the palette staging of " + key);
  if (!upload_fenced && m.uploaded.get())
    Check(api->cuEventSynchronize(m.uploaded.get()), "launch",
          [&] { return "cuEventSynchronize on the last upload of 'palette' of " + key; });
  return {static_cast<std::uint8_t*>(m.upload->host), m.bytes()};
}

void CudaApi::Upload(DeviceBuffer& buffer, std::size_t bytes, const std::string& key) {
  auto& m = static_cast<CudaMemory&>(buffer);
  if (!m.upload) Fail("launch", "Upload of 'palette' of " + key + " before its Staging");
  if (!uploads_) Check(api->cuStreamCreate(&uploads_, cuda::kStreamNonBlocking), "launch", "cuStreamCreate for uploads");
  if (!m.uploaded.get()) {
    cuda::Event e = nullptr;
    Check(api->cuEventCreate(&e, cuda::kEventDisableTiming), "launch", "cuEventCreate for the uploads of " + key);
    m.uploaded = Event(e, api->cuEventDestroy);
  }
  Check(api->cuMemcpyHtoDAsync(m.pointer(), m.upload->host, bytes, uploads_), "launch",
        [&] { return "cuMemcpyHtoDAsync 'palette' of " + key; });
  Check(api->cuEventRecord(m.uploaded.get(), uploads_), "launch",
        [&] { return "cuEventRecord after uploading 'palette' of " + key; });
  last_upload_ = m.uploaded.get();
}

// One stream's wait covers every upload before the last (one upload stream, in order).
void CudaApi::JoinUploads(cuda::Stream lane) {
  if (!last_upload_) return;
  Check(api->cuStreamWaitEvent(lane, last_upload_, 0), "launch", [] { return std::string("cuStreamWaitEvent for the palette uploads"); });
  if (lane == stream) last_upload_ = nullptr;
}

void CudaApi::Read(const DeviceBuffer& buffer, std::span<std::uint8_t> out, const std::string& what, bool wait) {
  JoinUploads(stream);
  if (wait) Check(api->cuStreamSynchronize(stream), "launch", "cuStreamSynchronize before reading back " + what);
  Check(api->cuMemcpyDtoH(out.data(), static_cast<const CudaMemory&>(buffer).pointer(), out.size()), "launch",
        "cuMemcpyDtoH " + what);
}

// After the work queued on the stream, into page-locked memory, then wait.
// One copy per chunk on the Skinner's stream, each followed by its event:
// the host scans a chunk while the next ones are still in flight.
DeviceApi::PinnedRead CudaApi::ReadPinnedChunks(const DeviceBuffer& buffer, std::size_t bytes, std::size_t chunk,
                                                const std::string& what) {
  const auto& m = static_cast<const CudaMemory&>(buffer);
  if (!m.readback) m.readback = std::make_unique<CudaPinned>(api, m.bytes(), 0, "the read-back of " + what);
  const std::size_t chunks = (bytes + chunk - 1) / chunk;
  while (m.readback_chunks.size() < chunks) {
    cuda::Event e = nullptr;
    Check(api->cuEventCreate(&e, cuda::kEventDisableTiming), "launch", "cuEventCreate for the read-back of " + what);
    m.readback_chunks.emplace_back(e, api->cuEventDestroy);
  }
  auto* host = static_cast<std::uint8_t*>(m.readback->host);
  JoinUploads(stream);
  for (std::size_t c = 0; c < chunks; ++c) {
    const std::size_t at = c * chunk, n = std::min(chunk, bytes - at);
    Check(api->cuMemcpyDtoHAsync(host + at, m.pointer() + at, n, stream), "launch", "cuMemcpyDtoHAsync " + what);
    Check(api->cuEventRecord(m.readback_chunks[c].get(), stream), "launch", "cuEventRecord after reading back " + what);
  }
  const cuda::DriverApi* driver = api;
  return {{host, bytes}, [&m, driver, chunk, what](std::size_t end) {
            if (end == 0) return;
            Check(driver->cuEventSynchronize(m.readback_chunks[(end - 1) / chunk].get()), "launch",
                  "cuEventSynchronize while reading back " + what);
          }};
}

std::span<const std::uint8_t> CudaApi::ReadPinned(const DeviceBuffer& buffer, std::size_t bytes,
                                                  const std::string& what) {
  const auto& m = static_cast<const CudaMemory&>(buffer);
  if (!m.readback) m.readback = std::make_unique<CudaPinned>(api, m.bytes(), 0, "the read-back of " + what);
  JoinUploads(stream);
  Check(api->cuMemcpyDtoHAsync(m.readback->host, m.pointer(), bytes, stream), "launch", "cuMemcpyDtoHAsync " + what);
  Check(api->cuStreamSynchronize(stream), "launch", "cuStreamSynchronize after reading back " + what);
  return {static_cast<const std::uint8_t*>(m.readback->host), bytes};
}

void CudaApi::Mark(std::unique_ptr<DeviceObject>& marker, const std::string& what) {
  if (!marker) {
    cuda::Event e = nullptr;
    Check(api->cuEventCreate(&e, cuda::kEventDisableTiming), "launch", "cuEventCreate for the palette ring of " + what);
    marker = std::make_unique<CudaMarker>(Event(e, api->cuEventDestroy));
  }
  JoinUploads(stream);
  Check(api->cuEventRecord(static_cast<CudaMarker&>(*marker).event.get(), stream), "launch",
        [&] { return "cuEventRecord after " + what; });
}

void CudaApi::Wait(DeviceObject& marker, const std::string& what) {
  Check(api->cuEventSynchronize(static_cast<CudaMarker&>(marker).event.get()), "launch", [&] { return "waiting for " + what; });
}

bool CudaApi::Signalled(DeviceObject& marker, const std::string& what) {
  const cuda::Result r = api->cuEventQuery(static_cast<CudaMarker&>(marker).event.get());
  if (r == cuda::kErrorNotReady) return false;
  Check(r, "launch", [&] { return "cuEventQuery on " + what; });
  return true;
}

// ---------------------------------------------------------------- launches

std::unique_ptr<DeviceObject> CudaApi::Bind(const PlannedLaunch& launch, std::span<const ArgumentBinding> arguments,
                                            const SetOptions&, std::size_t&) {
  auto bound = std::make_unique<CudaBound>();
  CudaBound& a = *bound;
  a.plan = static_cast<const CudaPlanned*>(&launch);
  const LaunchSpec& spec = launch.spec;
  a.n = spec.count;
  a.first = spec.first;
  a.vertex_count = spec.vertex_count;
  a.pointers.reserve(arguments.size());
  for (const ArgumentBinding& b : arguments) {
    const std::string& name = b.argument->name;
    if (b.role == ArgumentRole::kPalette) a.palette = static_cast<const CudaMemory*>(b.buffer);
    if (b.role == ArgumentRole::kPalette && b.view) a.texture = static_cast<const CudaTexture*>(b.view)->texture.get();
    if (name == "n") {
      a.parameters.push_back(&a.n);
    } else if (name == "first") {
      a.parameters.push_back(&a.first);
    } else if (name == "vertex_count") {
      a.parameters.push_back(&a.vertex_count);
    } else if (b.argument->kind == ArgumentKind::kScalar) {
      if (a.scalar_names.size() == a.scalars.size()) Fail("launch", spec.where + ": more scalars than a prologue takes");
      a.parameters.push_back(&a.scalars[a.scalar_names.size()]);
      a.scalar_names.push_back(name);
    } else if (name == "palette" && b.argument->kind == ArgumentKind::kImage) {
      if (!a.texture) Fail("launch", spec.where + ": an image palette argument but the variant's storage is not image");
      a.parameters.push_back(&a.texture);
    } else {
      if (name == "out_positions") a.output_parameter = static_cast<int>(a.parameters.size());
      a.pointers.push_back(static_cast<const CudaMemory*>(b.buffer)->pointer());
      a.parameters.push_back(&a.pointers.back());
    }
  }
  return bound;
}

Event CudaApi::NewEvent(const std::string& what) const {
  cuda::Event e = nullptr;
  Check(api->cuEventCreate(&e, 0), "launch", what);
  return Event(e, api->cuEventDestroy);
}

// Enqueues one launch on `lane` (Run: the legacy default stream; the
// Skinner: the caller's stream). The module's symbol is shared by every set
// and Skinner of the kernel: `constant` storage first copies the set's
// palette into it, on that stream (device to device: part of a frame's cost).
void CudaApi::Launch(const CudaBound& bound, cuda::Stream lane, void** parameters) {
  const CudaPlanned& plan = *bound.plan;
  const std::string& where = plan.spec.where;
  for (std::size_t k = 0; k < bound.scalar_names.size(); ++k) {
    if (!frame_run_) Fail("launch", where + ": no value for the scalar '" + bound.scalar_names[k] + "'");
    bound.scalars[k] = ScalarOf(*frame_run_, bound.scalar_names[k], "CUDA");
  }
  if (plan.constant_symbol)
    Check(api->cuMemcpyDtoDAsync(plan.constant_symbol, bound.palette->pointer(), bound.palette->bytes(), lane),
          "launch", [&] { return where + ": cuMemcpyDtoDAsync to '" + kConstantPaletteSymbol + "'"; });
  Check(api->cuLaunchKernel(plan.function, plan.blocks, plan.instances, 1, plan.threads, 1, 1, 0, lane,
                            parameters ? parameters : const_cast<void**>(bound.parameters.data()), nullptr),
        "launch", [&] {
          return where + ": cuLaunchKernel (" + std::to_string(plan.blocks) + " x " + std::to_string(plan.instances) +
                 " blocks of " + std::to_string(plan.threads) + ")";
        });
}

double CudaApi::ElapsedMs(const Event& start, const Event& end) const {
  float elapsed = 0.0f;
  Check(api->cuEventElapsedTime(&elapsed, start.get(), end.get()), "launch", "cuEventElapsedTime");
  return static_cast<double>(elapsed);
}

cuda::Stream CudaApi::Lane(int i) {
  if (!lanes_[i]) Check(api->cuStreamCreate(&lanes_[i], cuda::kStreamNonBlocking), "launch", "cuStreamCreate for timing");
  return lanes_[i];
}

namespace {

bool UsesConstantSymbol(const FrameRun& run) {
  for (const auto& frame : run.frames)
    for (const std::unique_ptr<DeviceObject>& launch : frame)
      if (static_cast<const CudaBound&>(*launch).plan->constant_symbol) return true;
  return false;
}

}  // namespace

// Run's frame: CUDA events around each launch, on the legacy default stream.
// Time's bursts (docs/TUNING.md "Timing"): frames alternate between two
// streams, so one frame starts while the last blocks of the one before drain,
// as consecutive dispatches do in GL and Vulkan; one stream alone would add
// the dependent-launch gap (~2 us per frame on an H100) to every frame.
// Events around the burst only: the start on lane 0, which lane 1 waits for;
// the end on lane 0 after it waited for lane 1. `constant` storage keeps one
// lane: its frames share the module's __constant__ symbol.
std::vector<std::vector<double>> CudaApi::RunTimed(const FrameRun& run) {
  const bool verify = run.use == FrameUse::kVerify;
  if (last_upload_) {  // not timed: wait for the uploads on the host
    Check(api->cuStreamSynchronize(uploads_), "launch", "cuStreamSynchronize on the palette uploads");
    last_upload_ = nullptr;
  }
  const std::string what = verify ? "cuEventCreate for " + run.key : "cuEventCreate for timing " + run.key;
  const auto record = [&](const Event& e, cuda::Stream lane) {
    Check(api->cuEventRecord(e.get(), lane), "launch", "cuEventRecord of " + run.key);
  };
  std::vector<std::pair<Event, Event>> events;
  if (verify) {
    for (const std::unique_ptr<DeviceObject>& launch : run.frames.front()) {
      events.emplace_back(NewEvent(what), NewEvent(what));
      record(events.back().first, nullptr);
      Launch(static_cast<const CudaBound&>(*launch), nullptr);
      record(events.back().second, nullptr);
    }
  } else {
    const auto untimed = static_cast<std::size_t>(std::max(run.untimed, 0));
    const auto burst = static_cast<std::size_t>(std::max(run.burst, 1));
    const int lanes = UsesConstantSymbol(run) ? 1 : 2;
    const cuda::Stream first = Lane(0), second = lanes == 2 ? Lane(1) : first;
    for (std::size_t f = 0; f < untimed; ++f)
      for (const std::unique_ptr<DeviceObject>& launch : run.frames[f]) Launch(static_cast<const CudaBound&>(*launch), first);
    for (std::size_t b = 0; b < run.TimedBursts(); ++b) {
      events.emplace_back(NewEvent(what), NewEvent(what));
      record(events.back().first, first);
      if (second != first) Check(api->cuStreamWaitEvent(second, events.back().first.get(), 0), "launch", "cuStreamWaitEvent");
      for (std::size_t i = 0; i < burst; ++i) {
        const cuda::Stream lane = i % 2 == 0 ? first : second;
        for (const std::unique_ptr<DeviceObject>& launch : run.frames[untimed + b * burst + i])
          Launch(static_cast<const CudaBound&>(*launch), lane);
      }
      if (second != first) {
        const Event joined = NewEvent(what);
        record(joined, second);
        Check(api->cuStreamWaitEvent(first, joined.get(), 0), "launch", "cuStreamWaitEvent");
      }
      record(events.back().second, first);
    }
  }
  Check(api->cuCtxSynchronize(), "launch", std::string("cuCtxSynchronize after ") + (verify ? "" : "timing ") + run.key);
  std::vector<std::vector<double>> ms;
  if (verify) ms.emplace_back();
  for (const auto& [start, end] : events) {
    if (verify) {
      ms.front().push_back(ElapsedMs(start, end));
    } else {
      ms.push_back({ElapsedMs(start, end)});
    }
  }
  return ms;
}

// The Skinner's frame on the caller's stream; positions into run.out_positions
// (a CUdeviceptr: a mapped GL buffer, SkinIntoGlBuffer) instead of the set's
// own output when given.
// Queues frame `frame` of a kCold run on `lane`: the flush, then the
// frame's launches; when `events` is given, an event after the flush and
// after each launch (each launch's time runs from the event before it).
void CudaApi::QueueColdFrame(const FrameRun& run, std::size_t frame, cuda::Stream lane,
                             std::vector<std::pair<Event, Event>>* events) {
  for (const std::unique_ptr<DeviceObject>& launch : run.flush) Launch(static_cast<const CudaBound&>(*launch), lane);
  Event before;
  if (events) {
    before = NewEvent("cuEventCreate for timing " + run.key);
    Check(api->cuEventRecord(before.get(), lane), "launch", "cuEventRecord of " + run.key);
  }
  for (const std::unique_ptr<DeviceObject>& launch : run.frames[frame]) {
    Launch(static_cast<const CudaBound&>(*launch), lane);
    if (!events) continue;
    Event after = NewEvent("cuEventCreate for timing " + run.key);
    Check(api->cuEventRecord(after.get(), lane), "launch", "cuEventRecord of " + run.key);
    Event next = NewEvent("cuEventCreate for timing " + run.key);  // the next launch's start: this one's end
    Check(api->cuEventRecord(next.get(), lane), "launch", "cuEventRecord of " + run.key);
    events->emplace_back(std::move(before), std::move(after));
    before = std::move(next);
  }
}

// kCold (device_api.h): every frame on the Skinner's stream after the
// flush, each waited for before the next is queued. Each launch's time runs
// from the end of the command before it to its own end, by CUPTI's records
// of the kernels (cupti.h says why); where CUPTI cannot be loaded, by events
// between them, which count the events' own processing too (kernel_clock()
// says which, and the report with it).
//
// Why the Skinner's stream: a kernel on another stream, once the Skinner's
// frames had run on this one, started 0.25-0.3 us later after the flush for
// the rest of the process (an H200, December 2026: 3.008 us from its CUPTI
// start to end in every process, 1.09-1.22 us from the flush's end to its
// start before the frames, 1.34-1.50 after); on this stream the frames move
// nothing. Why one frame at a time: queued back to back, the gap before
// every other frame's kernel was 1 us longer (1.1 and 2.1 us, alternating),
// so a median of a batch fell on either side as the share of long gaps
// passed a half (4.2-5.0 us for one 100k-vertex kernel). And CUPTI's first
// launches after its activity is enabled take the host 0.15-2.5 ms, so the
// first timed frame would count the host's time: the untimed frames (one at
// least) run inside the records and are dropped.
std::vector<std::vector<double>> CudaApi::TimeCold(const FrameRun& run) {
  if (last_upload_) {
    Check(api->cuStreamSynchronize(uploads_), "launch", "cuStreamSynchronize on the palette uploads");
    last_upload_ = nullptr;
  }
  const cuda::Stream lane = stream;
  const std::size_t frames = run.frames.size();
  const auto untimed = std::min(frames, static_cast<std::size_t>(std::max(run.untimed, 0)));
  const std::size_t timed = frames - untimed;
  const std::size_t launches = timed ? run.frames[untimed].size() : 0;
  const std::size_t lead = frames ? std::max<std::size_t>(untimed, 1) : 0;  // frame 0 again when none is untimed
  const auto queue = [&](std::size_t f, std::vector<std::pair<Event, Event>>* events) {
    QueueColdFrame(run, f, lane, events);
    Check(api->cuStreamSynchronize(lane), "launch", "cuStreamSynchronize while timing " + run.key);
  };
  if (cupti::Unavailable().empty()) {
    cupti::KernelActivity activity;
    activity.Start();
    std::size_t dropped = 0;
    for (std::size_t f = 0; f < lead; ++f) {
      queue(f, nullptr);
      dropped += run.flush.size() + run.frames[f].size();
    }
    for (std::size_t f = untimed; f < frames; ++f) queue(f, nullptr);
    std::vector<cupti::KernelSpan> spans = activity.Stop();
    if (spans.size() < dropped)
      Fail("launch", "timing " + run.key + ": CUPTI recorded " + std::to_string(spans.size()) + " kernels, fewer than the " +
                         std::to_string(dropped) + " untimed");
    spans.erase(spans.begin(), spans.begin() + static_cast<std::ptrdiff_t>(dropped));
    return cupti::ColdFrameTimes(spans, timed, run.flush.size(), launches);
  }
  for (std::size_t f = 0; f < untimed; ++f) queue(f, nullptr);
  std::vector<std::pair<Event, Event>> events;
  for (std::size_t f = untimed; f < frames; ++f) queue(f, &events);
  std::vector<std::vector<double>> ms(timed);
  for (std::size_t e = 0; e < events.size(); ++e) ms[e / std::max<std::size_t>(launches, 1)].push_back(ElapsedMs(events[e].first, events[e].second));
  return ms;
}

std::vector<std::vector<double>> CudaApi::RunFrames(const FrameRun& run) {
  const CurrentRun current(frame_run_, run);
  if (run.use == FrameUse::kCold) return TimeCold(run);
  if (run.use != FrameUse::kLive) return RunTimed(run);
  const auto out = static_cast<cuda::DevicePtr>(reinterpret_cast<std::uintptr_t>(run.out_positions));
  if (!run.prologue.empty()) {
    // On a stream of its own after the uploads (the instances), the frame's
    // stream waiting for it: the slot it writes is one no queued frame
    // reads (the palette ring's fence), so it may run beside the frame
    // before, whose skin kernel reads another slot.
    if (!prologues_) {
      Check(api->cuStreamCreate(&prologues_, cuda::kStreamNonBlocking), "launch", "cuStreamCreate for the palette kernels");
      Check(api->cuEventCreate(&prologue_done_, cuda::kEventDisableTiming), "launch", "cuEventCreate for the palette kernels");
    }
    JoinUploads(prologues_);
    for (const std::unique_ptr<DeviceObject>& launch : run.prologue) {
      Launch(static_cast<const CudaBound&>(*launch), prologues_);
    }
    Check(api->cuEventRecord(prologue_done_, prologues_), "launch", "cuEventRecord after the palette kernel");
    Check(api->cuStreamWaitEvent(stream, prologue_done_, 0), "launch", "cuStreamWaitEvent for the palette kernel");
    last_upload_ = nullptr;  // the frame's stream waited for it through the palette kernel
  }
  JoinUploads(stream);
  for (const auto& frame : run.frames)
    for (const std::unique_ptr<DeviceObject>& launch : frame) {
      const auto& bound = static_cast<const CudaBound&>(*launch);
      if (!out) {
        Launch(bound, stream);
        continue;
      }
      if (bound.output_parameter < 0) Fail("launch", bound.plan->spec.where + ": no 'out_positions' argument to redirect");
      std::vector<void*> parameters = bound.parameters;  // the same launch, the positions into `out`
      cuda::DevicePtr into = out;
      parameters[static_cast<std::size_t>(bound.output_parameter)] = &into;
      Launch(bound, stream, parameters.data());
    }
  return {};
}

// ---------------------------------------------------------------- CudaRunner

namespace {

[[noreturn]] void TooOld(const CudaDeviceInfo& info, const std::string& nvrtc_library) {
  Fail("setup", info.name + " (compute capability " + std::to_string(info.major) + "." + std::to_string(info.minor) +
                    ") is older than every architecture " + nvrtc_library + " supports");
}

std::unique_ptr<CudaApi> OpenDevice(int device_index, bool own_context) {
  auto c = std::make_unique<CudaApi>();
  c->info = QueryCudaDevice(device_index);
  c->api = cuda::Driver();
  if (c->info.arch.empty()) TooOld(c->info, Probe().nvrtc_library);
  Check(c->api->cuDeviceGet(&c->device, device_index), "setup", "cuDeviceGet " + std::to_string(device_index));
  cuda::Context context = nullptr;
  if (own_context) {
    if (!c->api->cuCtxCreate || !c->api->cuCtxDestroy) Fail("setup", "the driver lacks cuCtxCreate_v2 or cuCtxDestroy_v2");
    Check(c->api->cuCtxCreate(&context, 0, c->device), "setup", "cuCtxCreate on " + c->info.name);
    c->primary = false;
    c->own = true;
  } else {
    Check(c->api->cuDevicePrimaryCtxRetain(&context, c->device), "setup", "cuDevicePrimaryCtxRetain on " + c->info.name);
  }
  c->context = context;
  Check(c->api->cuCtxSetCurrent(c->context), "setup", "cuCtxSetCurrent on " + c->info.name);
  return c;
}

std::unique_ptr<CudaApi> AdoptContext(void* cu_context, void* cu_stream) {
  auto c = std::make_unique<CudaApi>();
  if (!cu_context) Fail("setup", "a null CUcontext");
  const CudaAvailability available = Probe();
  if (!available.nvrtc) Fail("setup", available.nvrtc_missing);
  c->api = cuda::Driver();
  if (!c->api) Fail("setup", available.driver_missing);
  Check(c->api->cuCtxSetCurrent(static_cast<cuda::Context>(cu_context)), "setup",
        "cuCtxSetCurrent of the given context");
  cuda::Device device = 0;
  Check(c->api->cuCtxGetDevice(&device), "setup", "cuCtxGetDevice of the given context");
  c->info = QueryCudaDevice(device);  // a CUdevice is its ordinal
  if (c->info.arch.empty()) TooOld(c->info, available.nvrtc_library);
  c->device = device;
  c->context = static_cast<cuda::Context>(cu_context);
  c->primary = false;
  c->stream = static_cast<cuda::Stream>(cu_stream);
  return c;
}

}  // namespace

CudaRunner::CudaRunner(int device_index) : Runner(OpenDevice(device_index, false)) {}
CudaRunner::CudaRunner(int device_index, OwnContext) : Runner(OpenDevice(device_index, true)) {}
CudaRunner::CudaRunner(void* cu_context, void* cu_stream) : Runner(AdoptContext(cu_context, cu_stream)) {}

const CudaDeviceInfo& CudaRunner::info() const { return static_cast<const CudaApi&>(api()).info; }
const std::string& CudaRunner::arch() const { return info().arch; }
void* CudaRunner::context() const { return static_cast<const CudaApi&>(api()).context; }
void* CudaRunner::stream() const { return static_cast<const CudaApi&>(api()).stream; }
const DeviceLimits& CudaRunner::limits() const { return info().limits; }

}  // namespace skintune::internal
