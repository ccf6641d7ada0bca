#include "runtime/backends/cuda/cuda_runner.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <utility>

#include "reference/error.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/output_check.h"
#include "runtime/run_shape.h"

namespace skintune {

namespace {

[[noreturn]] void Fail(const std::string& stage, const std::string& message) {
  throw Error("CUDA " + stage + ": " + message);
}

void Check(cuda::Result r, const std::string& stage, const std::string& what) {
  if (r != cuda::kSuccess) Fail(stage, what + " failed: " + cuda::ErrorText(r));
}

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

// Device attributes beyond cuda_api.h's.
constexpr int kAttributeClockRate = 13;          // CU_DEVICE_ATTRIBUTE_CLOCK_RATE (kHz)
constexpr int kAttributeMultiprocessorCount = 16;  // CU_DEVICE_ATTRIBUTE_MULTIPROCESSOR_COUNT
constexpr int kAttributeL2CacheSize = 38;        // CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE (bytes)
constexpr int kAttributeMaxGridDimY = 6;         // CU_DEVICE_ATTRIBUTE_MAX_GRID_DIM_Y (instances per launch)

// cuDeviceTotalMem_v2 from the driver library Probe() loaded (cuda_api.h
// does not declare it); 0 when it cannot be found.
std::uint64_t TotalMemory(const std::string& library, cuda::Device device) {
  void* handle = dlopen(library.c_str(), RTLD_LAZY | RTLD_NOLOAD);
  if (!handle) return 0;
  using TotalMem = cuda::Result (*)(std::size_t*, cuda::Device);
  const auto total_mem = reinterpret_cast<TotalMem>(dlsym(handle, "cuDeviceTotalMem_v2"));
  std::size_t bytes = 0;
  const bool ok = total_mem && total_mem(&bytes, device) == cuda::kSuccess;
  dlclose(handle);  // drops the reference RTLD_NOLOAD added; the driver stays loaded
  return ok ? bytes : 0;
}

}  // namespace

CudaDeviceInfo QueryCudaDevice(int device_index) {
  const CudaAvailability available = Probe();
  if (!available.nvrtc) Fail("setup", available.nvrtc_missing);
  if (!available.driver) Fail("setup", available.driver_missing);
  const cuda::DriverApi* api = cuda::Driver();
  if (!api) Fail("setup", available.driver_missing);
  if (device_index < 0 || device_index >= available.device_count)
    Fail("setup", "no device " + std::to_string(device_index) + " (" + std::to_string(available.device_count) +
                      " devices" + (available.device_count == 0 ? ": " + available.driver_missing : "") + ")");
  cuda::Device device = 0;
  Check(api->cuDeviceGet(&device, device_index), "setup", "cuDeviceGet " + std::to_string(device_index));
  CudaDeviceInfo info;
  info.index = device_index;
  char text[256] = {};
  Check(api->cuDeviceGetName(text, sizeof text - 1, device), "setup", "cuDeviceGetName");
  info.name = text;
  auto attribute = [&](int which, const char* what) {
    int value = 0;
    Check(api->cuDeviceGetAttribute(&value, which, device), "setup", std::string("cuDeviceGetAttribute ") + what);
    return value;
  };
  info.major = attribute(cuda::kAttributeComputeCapabilityMajor, "(compute capability)");
  info.minor = attribute(cuda::kAttributeComputeCapabilityMinor, "(compute capability)");
  info.multiprocessors = attribute(kAttributeMultiprocessorCount, "(multiprocessors)");
  info.clock_khz = attribute(kAttributeClockRate, "(clock rate)");
  info.l2_cache_bytes = static_cast<std::uint64_t>(attribute(kAttributeL2CacheSize, "(L2 cache size)"));
  info.total_memory_bytes = TotalMemory(available.driver_library, device);
  info.driver_version = available.driver_version;
  info.limits.max_wg_size = static_cast<std::size_t>(attribute(cuda::kAttributeMaxThreadsPerBlock, "(threads per block)"));
  info.limits.local_memory_bytes =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeMaxSharedMemoryPerBlock, "(shared memory per block)"));
  info.limits.constant_memory_bytes =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeTotalConstantMemory, "(constant memory)"));
  info.limits.image_support = true;  // texture objects: every device CUDA 11+ runs on
  info.limits.image_buffer_max_texels =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeMaxTexture1dLinearWidth, "(1D linear texture width)"));
  info.limits.max_grid_y = static_cast<std::uint64_t>(attribute(kAttributeMaxGridDimY, "(grid y)"));
  info.arch = NvrtcArchFor(info.major, info.minor);
  return info;
}

struct CudaRunner::Impl {
  const cuda::DriverApi* api = nullptr;
  cuda::Device device = 0;
  cuda::Context context = nullptr;  // the device's primary context (retained), or the caller's
  bool primary = true;              // the context is the retained primary context
  cuda::Stream stream = nullptr;    // the caller's stream for skinning; null: the legacy default stream
  std::string name, arch;
  DeviceLimits limits;
  CudaDeviceInfo info;
  std::map<std::string, BuiltKernel> built;  // by source hash
  ProgramCache* cache = nullptr;             // UseProgramCache
  std::string cache_device_id;

  ~Impl() {
    if (!context) return;
    api->cuCtxSetCurrent(context);
    built.clear();  // unloads the modules while their context is current
    if (primary) api->cuDevicePrimaryCtxRelease(device);
  }
  void MakeCurrent() const { Check(api->cuCtxSetCurrent(context), "launch", "cuCtxSetCurrent"); }
  const BuiltKernel& KernelFor(const KernelSource& source);
  Memory Buffer(std::size_t bytes, const void* data, const std::string& what) const;
  void CheckInstancesFit(const RunShape& shape, const Variant& variant) const;
};

// K instances need K blocks in grid y and, for `image` storage, K palettes of
// texels; say which limit a run exceeds before launching. (`constant` storage:
// the kernel's symbol size, checked per launch.)
void CudaRunner::Impl::CheckInstancesFit(const RunShape& shape, const Variant& variant) const {
  if (static_cast<std::uint64_t>(shape.instances) > limits.max_grid_y)
    Fail("launch", variant.Key() + ": " + std::to_string(shape.instances) +
                       " instances exceed the grid's y dimension (CU_DEVICE_ATTRIBUTE_MAX_GRID_DIM_Y " +
                       std::to_string(limits.max_grid_y) + ") of " + name);
  const std::uint64_t texels = static_cast<std::uint64_t>(shape.instances) * shape.palette_bytes / 16;
  if (variant.storage == PaletteStorage::kImage && texels > limits.image_buffer_max_texels)
    Fail("launch", variant.Key() + ": the palettes (" + std::to_string(texels) +
                       " texels) exceed CU_DEVICE_ATTRIBUTE_MAXIMUM_TEXTURE1D_LINEAR_WIDTH " +
                       std::to_string(limits.image_buffer_max_texels) + " of " + name);
}

CudaRunner::CudaRunner(int device_index) : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  im.info = QueryCudaDevice(device_index);
  im.api = cuda::Driver();
  im.name = im.info.name;
  im.limits = im.info.limits;
  im.arch = im.info.arch;
  if (im.arch.empty())
    Fail("setup", im.name + " (compute capability " + std::to_string(im.info.major) + "." +
                      std::to_string(im.info.minor) + ") is older than every architecture " + Probe().nvrtc_library +
                      " supports");
  Check(im.api->cuDeviceGet(&im.device, device_index), "setup", "cuDeviceGet " + std::to_string(device_index));
  cuda::Context context = nullptr;
  Check(im.api->cuDevicePrimaryCtxRetain(&context, im.device), "setup", "cuDevicePrimaryCtxRetain on " + im.name);
  im.context = context;
  Check(im.api->cuCtxSetCurrent(im.context), "setup", "cuCtxSetCurrent on " + im.name);
}

CudaRunner::CudaRunner(void* cu_context, void* cu_stream) : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  if (!cu_context) Fail("setup", "a null CUcontext");
  const CudaAvailability available = Probe();
  if (!available.nvrtc) Fail("setup", available.nvrtc_missing);
  im.api = cuda::Driver();
  if (!im.api) Fail("setup", available.driver_missing);
  Check(im.api->cuCtxSetCurrent(static_cast<cuda::Context>(cu_context)), "setup", "cuCtxSetCurrent of the given context");
  cuda::Device device = 0;
  Check(im.api->cuCtxGetDevice(&device), "setup", "cuCtxGetDevice of the given context");
  im.info = QueryCudaDevice(device);  // a CUdevice is its ordinal
  im.name = im.info.name;
  im.limits = im.info.limits;
  im.arch = im.info.arch;
  if (im.arch.empty())
    Fail("setup", im.name + " (compute capability " + std::to_string(im.info.major) + "." +
                      std::to_string(im.info.minor) + ") is older than every architecture " + available.nvrtc_library +
                      " supports");
  im.device = device;
  im.context = static_cast<cuda::Context>(cu_context);
  im.primary = false;
  im.stream = static_cast<cuda::Stream>(cu_stream);
}

CudaRunner::~CudaRunner() = default;

void CudaRunner::UseProgramCache(ProgramCache* cache, const std::string& device_id) {
  impl_->cache = cache;
  impl_->cache_device_id = device_id;
}

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

const std::string& CudaRunner::device_name() const { return impl_->name; }
const std::string& CudaRunner::arch() const { return impl_->arch; }
const DeviceLimits& CudaRunner::limits() const { return impl_->limits; }
const CudaDeviceInfo& CudaRunner::info() const { return impl_->info; }

const BuiltKernel& CudaRunner::Impl::KernelFor(const KernelSource& source) {
  if (source.lang != Lang::kCuda) Fail("build", std::string("kernel language is ") + Name(source.lang));
  const std::string key = source.source_hash.empty() ? SourceHash(source.text) : source.source_hash;
  if (auto found = built.find(key); found != built.end()) {
    if (cache) ++cache->counters().memory_hits;
    return found->second;
  }

  const std::string what = "kernel " + key + " (" + source.text.substr(0, source.text.find('\n')) + ")";
  const std::string ptx = CompilePtxCached(source, arch, cache, cache_device_id);

  // The driver JIT-compiles the PTX for the device; its error log says why it cannot.
  std::string log(8192, '\0');
  int options[] = {cuda::kJitErrorLogBuffer, cuda::kJitErrorLogBufferSizeBytes};
  void* values[] = {log.data(), reinterpret_cast<void*>(static_cast<std::uintptr_t>(log.size()))};
  cuda::Module module = nullptr;
  const cuda::Result r = api->cuModuleLoadDataEx(&module, ptx.c_str(), 2, options, values);
  if (r != cuda::kSuccess) {
    log.resize(std::strlen(log.c_str()));
    Fail("build", what + ": cuModuleLoadDataEx (" + arch + " PTX on " + name + ") failed: " + cuda::ErrorText(r) +
                      "; JIT log:" + FirstLines(log, 20));
  }
  BuiltKernel b;
  b.module = Module(module, api->cuModuleUnload);
  Check(api->cuModuleGetFunction(&b.function, module, source.entry_point.c_str()), "build",
        "cuModuleGetFunction '" + source.entry_point + "' of " + what);
  return built.emplace(key, std::move(b)).first->second;
}

Memory CudaRunner::Impl::Buffer(std::size_t bytes, const void* data, const std::string& what) const {
  if (bytes == 0) Fail("launch", "buffer '" + what + "' is empty");
  cuda::DevicePtr pointer = 0;
  Check(api->cuMemAlloc(&pointer, bytes), "launch", "cuMemAlloc '" + what + "' (" + std::to_string(bytes) + " bytes)");
  Memory m(pointer, api->cuMemFree);
  if (data) Check(api->cuMemcpyHtoD(pointer, data, bytes), "launch", "cuMemcpyHtoD '" + what + "'");
  return m;
}

void CudaRunner::Build(const KernelSource& source) {
  impl_->MakeCurrent();
  impl_->KernelFor(source);
}

CudaRunResult CudaRunner::Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette) {
  return Run(mesh, EmitLaunchKernels(mesh), palette);
}

CudaRunResult CudaRunner::RunInstanced(const PackedMesh& mesh, int instances, std::span<const std::uint8_t> palettes) {
  return Run(mesh, EmitLaunchKernels(mesh, instances), palettes, instances);
}

CudaRunResult CudaRunner::Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                              std::span<const std::uint8_t> palettes, int instances) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  const Variant& variant = mesh.variant;
  const std::vector<std::uint8_t> palette = PalettesOrMeshPalette(mesh, palettes, instances);
  const RunShape shape = CheckRunShape(mesh, kernels, palette.size(), instances, "CUDA");
  im.CheckInstancesFit(shape, variant);

  // Palette (and its texture object for `image` storage: float4 texels over the buffer).
  Memory palette_buffer = im.Buffer(palette.size(), palette.data(), "palette");
  Texture palette_texture;
  if (variant.storage == PaletteStorage::kImage) {
    cuda::ResourceDesc resource;
    resource.resType = cuda::kResourceTypeLinear;
    resource.res.linear = {palette_buffer.get(), cuda::kArrayFormatFloat, 4, palette.size()};
    cuda::TextureDesc texture;
    texture.addressMode[0] = texture.addressMode[1] = texture.addressMode[2] = cuda::kAddressModeClamp;
    texture.filterMode = cuda::kFilterModePoint;
    cuda::TexObject object = 0;
    Check(api.cuTexObjectCreate(&object, &resource, &texture, nullptr), "launch",
          "cuTexObjectCreate (linear, " + std::to_string(palette.size() / 16) + " float4 texels)");
    palette_texture = Texture(object, api.cuTexObjectDestroy);
  }

  // Outputs (K instances, one after another): poisoned, each followed by its guard.
  const std::size_t out_bytes = shape.out_bytes;
  const std::vector<std::uint8_t> fill = PoisonedOutput(out_bytes);
  Memory out_positions = im.Buffer(fill.size(), fill.data(), "out_positions");
  Memory out_normals;
  if (variant.normals) out_normals = im.Buffer(fill.size(), fill.data(), "out_normals");

  std::vector<Memory> inputs;  // kept alive until the context is synchronised
  std::vector<std::pair<Event, Event>> events;
  for (std::size_t l = 0; l < mesh.launches.size(); ++l) {
    const Launch& launch = mesh.launches[l];
    const KernelSource& source = kernels[l];
    if (launch.count == 0) continue;
    const BuiltKernel& kernel = im.KernelFor(source);
    const std::string where = "launch " + std::to_string(l) + " of " + variant.Key();

    if (variant.storage == PaletteStorage::kConstant) {
      cuda::DevicePtr symbol = 0;
      std::size_t symbol_bytes = 0;
      Check(api.cuModuleGetGlobal(&symbol, &symbol_bytes, kernel.module.get(), kConstantPaletteSymbol), "launch",
            where + ": cuModuleGetGlobal '" + kConstantPaletteSymbol + "'");
      if (symbol_bytes < palette.size())
        Fail("launch", where + ": __constant__ " + kConstantPaletteSymbol + " holds " + std::to_string(symbol_bytes) +
                           " bytes, the palette " + std::to_string(palette.size()) +
                           " (the kernel was emitted for fewer joints or instances)");
      Check(api.cuMemcpyHtoD(symbol, palette.data(), palette.size()), "launch",
            where + ": cuMemcpyHtoD to '" + kConstantPaletteSymbol + "'");
    }

    // Argument values live in these arrays (reserved: no reallocation) while cuLaunchKernel reads them.
    std::uint32_t n = launch.count, first = launch.first, vertex_count = static_cast<std::uint32_t>(mesh.vertex_count);
    std::vector<cuda::DevicePtr> pointers;
    pointers.reserve(source.arguments.size());
    cuda::TexObject texture = palette_texture.get();
    std::vector<void*> parameters;
    for (const KernelArgument& arg : source.arguments) {
      if (arg.name == "n") {
        parameters.push_back(&n);
      } else if (arg.name == "first") {
        parameters.push_back(&first);
      } else if (arg.name == "vertex_count") {
        parameters.push_back(&vertex_count);
      } else if (arg.name == "palette" && arg.kind == ArgumentKind::kImage) {
        if (!texture) Fail("launch", where + ": an image palette argument but the variant's storage is not image");
        parameters.push_back(&texture);
      } else {
        cuda::DevicePtr pointer = 0;
        if (arg.name == "palette") {
          pointer = palette_buffer.get();
        } else if (arg.name == "out_positions") {
          pointer = out_positions.get();
        } else if (arg.name == "out_normals") {
          pointer = out_normals.get();
        } else {
          auto input = std::find_if(launch.inputs.begin(), launch.inputs.end(),
                                    [&](const PackedBuffer& b) { return b.name == arg.name; });
          if (input == launch.inputs.end()) Fail("launch", where + ": no packed buffer for argument '" + arg.name + "'");
          inputs.push_back(im.Buffer(input->bytes.size(), input->bytes.data(), arg.name));
          pointer = inputs.back().get();
        }
        if (!pointer) Fail("launch", where + ": nothing to bind to argument '" + arg.name + "'");
        pointers.push_back(pointer);
        parameters.push_back(&pointers.back());
      }
    }

    const std::size_t wg = static_cast<std::size_t>(source.launch.wg_size);
    const std::size_t blocks = source.launch.GlobalItems(launch.count) / wg;
    cuda::Event start = nullptr, end = nullptr;
    Check(api.cuEventCreate(&start, 0), "launch", where + ": cuEventCreate");
    Event start_event(start, api.cuEventDestroy);
    Check(api.cuEventCreate(&end, 0), "launch", where + ": cuEventCreate");
    Event end_event(end, api.cuEventDestroy);
    Check(api.cuEventRecord(start, nullptr), "launch", where + ": cuEventRecord");
    // Instanced: grid y is the instance.
    const auto grid_y = static_cast<unsigned>(shape.instances);
    Check(api.cuLaunchKernel(kernel.function, static_cast<unsigned>(blocks), grid_y, 1, static_cast<unsigned>(wg), 1, 1,
                             0, nullptr, parameters.data(), nullptr),
          "launch", where + ": cuLaunchKernel (" + std::to_string(blocks) + " x " + std::to_string(grid_y) +
                        " blocks of " + std::to_string(wg) + ")");
    Check(api.cuEventRecord(end, nullptr), "launch", where + ": cuEventRecord");
    events.emplace_back(std::move(start_event), std::move(end_event));
  }
  Check(api.cuCtxSynchronize(), "launch", "cuCtxSynchronize after " + variant.Key());

  CudaRunResult result;
  for (const auto& [start, end] : events) {
    float ms = 0.0f;
    Check(api.cuEventElapsedTime(&ms, start.get(), end.get()), "launch", "cuEventElapsedTime");
    result.launch_ms.push_back(static_cast<double>(ms));
  }

  // Read back, check the guards, count vertices never written.
  auto read_back = [&](const Memory& buffer, const char* what, std::vector<std::uint8_t>& out) {
    std::vector<std::uint8_t> bytes(out_bytes + kGuardBytes);
    Check(api.cuMemcpyDtoH(bytes.data(), buffer.get(), bytes.size()), "launch",
          std::string("cuMemcpyDtoH '") + what + "'");
    const OutputCheck check = CheckGuardAndCountPoisoned(bytes, out_bytes, mesh.output_stride_bytes, shape.out_vertices);
    if (!check.guard_ok)
      Fail("guard", variant.Key() + ": " + what + ": the kernel " + GuardFailure(check, out_bytes));
    result.poisoned_vertices += check.poisoned_vertices;
    out = std::move(bytes);
  };
  read_back(out_positions, "out_positions", result.positions);
  if (variant.normals) read_back(out_normals, "out_normals", result.normals);
  return result;
}

// ---------------------------------------------------------------- timing

struct CudaPrepared::Impl {
  const cuda::DriverApi* api = nullptr;
  cuda::Context context = nullptr;
  struct LaunchPlan {
    cuda::Function function = nullptr;
    cuda::DevicePtr constant_symbol = 0;  // STORAGE constant: the module's palette symbol
    unsigned blocks = 0, instances = 1, threads = 0;  // grid (blocks, instances)
  };
  // One launch's argument values and the parameter array pointing at them.
  struct Arguments {
    std::uint32_t n = 0, first = 0, vertex_count = 0;
    std::vector<cuda::DevicePtr> pointers;  // reserved: never reallocated
    cuda::TexObject texture = 0;
    std::vector<void*> parameters;
  };
  struct Set {
    std::vector<Memory> buffers;
    Texture texture;
    std::vector<std::uint8_t> palette;  // host copy, for the constant symbol (Time)
    std::vector<std::unique_ptr<Arguments>> launches;
    cuda::DevicePtr palette_buffer = 0, out_positions = 0, out_normals = 0;
    std::vector<std::uint8_t> staging;  // the palettes being uploaded (WritePalette)
    Event upload;                       // recorded after that upload
  };
  std::string key;
  bool constant = false;
  std::vector<LaunchPlan> launches;
  std::vector<Set> sets;
  std::size_t bytes_per_set = 0;
  std::size_t out_bytes = 0;

  ~Impl() {
    if (!context) return;
    api->cuCtxSetCurrent(context);
    sets.clear();  // frees the buffers and textures while their context is current
  }
};

CudaPrepared::CudaPrepared() : impl_(std::make_unique<Impl>()) {}
CudaPrepared::~CudaPrepared() = default;
CudaPrepared::CudaPrepared(CudaPrepared&&) noexcept = default;
CudaPrepared& CudaPrepared::operator=(CudaPrepared&&) noexcept = default;
int CudaPrepared::input_sets() const { return impl_ ? static_cast<int>(impl_->sets.size()) : 0; }
std::size_t CudaPrepared::bytes_per_set() const { return impl_ ? impl_->bytes_per_set : 0; }

CudaPrepared CudaRunner::Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                 std::span<const std::vector<std::uint8_t>> palettes, int instances) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  const Variant& variant = mesh.variant;
  if (palettes.empty()) Fail("launch", "no palette (input set) to time " + variant.Key() + " with");
  RunShape shape;
  for (const std::vector<std::uint8_t>& palette : palettes)
    shape = CheckRunShape(mesh, kernels, palette.size(), instances, "CUDA");
  im.CheckInstancesFit(shape, variant);

  CudaPrepared prepared;
  CudaPrepared::Impl& p = *prepared.impl_;
  p.api = im.api;
  p.context = im.context;
  p.key = variant.Key();
  p.constant = variant.storage == PaletteStorage::kConstant;
  std::vector<std::size_t> launch_of_plan;
  for (std::size_t l = 0; l < mesh.launches.size(); ++l) {
    const Launch& launch = mesh.launches[l];
    if (launch.count == 0) continue;
    const KernelSource& source = kernels[l];
    const BuiltKernel& kernel = im.KernelFor(source);
    const std::string where = "launch " + std::to_string(l) + " of " + variant.Key();
    CudaPrepared::Impl::LaunchPlan plan;
    plan.function = kernel.function;
    const std::size_t wg = static_cast<std::size_t>(source.launch.wg_size);
    plan.threads = static_cast<unsigned>(wg);
    plan.blocks = static_cast<unsigned>(source.launch.GlobalItems(launch.count) / wg);
    plan.instances = static_cast<unsigned>(shape.instances);
    if (p.constant) {
      std::size_t symbol_bytes = 0;
      Check(api.cuModuleGetGlobal(&plan.constant_symbol, &symbol_bytes, kernel.module.get(), kConstantPaletteSymbol),
            "launch", where + ": cuModuleGetGlobal '" + kConstantPaletteSymbol + "'");
      if (symbol_bytes < palettes.front().size())
        Fail("launch", where + ": __constant__ " + kConstantPaletteSymbol + " holds " + std::to_string(symbol_bytes) +
                           " bytes, the palette " + std::to_string(palettes.front().size()) +
                           " (the kernel was emitted for fewer joints or instances)");
    }
    p.launches.push_back(plan);
    launch_of_plan.push_back(l);
  }

  const std::size_t out_bytes = shape.out_bytes;
  const std::vector<std::uint8_t> poison = PoisonedOutput(out_bytes);  // the first out_bytes are used
  p.out_bytes = out_bytes;
  for (std::size_t k = 0; k < palettes.size(); ++k) {
    p.sets.emplace_back();
    CudaPrepared::Impl::Set& set = p.sets.back();
    std::size_t bytes = 0;
    const std::string suffix = " (input set " + std::to_string(k) + ")";
    auto add = [&](std::size_t size, const void* data, const std::string& what) {
      set.buffers.push_back(im.Buffer(size, data, what + suffix));
      bytes += size;
      return set.buffers.back().get();
    };
    const std::vector<std::uint8_t>& palette = palettes[k];
    set.palette = palette;
    const cuda::DevicePtr palette_buffer = add(palette.size(), palette.data(), "palette");
    if (variant.storage == PaletteStorage::kImage) {
      cuda::ResourceDesc resource;
      resource.resType = cuda::kResourceTypeLinear;
      resource.res.linear = {palette_buffer, cuda::kArrayFormatFloat, 4, palette.size()};
      cuda::TextureDesc texture;
      texture.addressMode[0] = texture.addressMode[1] = texture.addressMode[2] = cuda::kAddressModeClamp;
      texture.filterMode = cuda::kFilterModePoint;
      cuda::TexObject object = 0;
      Check(api.cuTexObjectCreate(&object, &resource, &texture, nullptr), "launch",
            "cuTexObjectCreate (linear, " + std::to_string(palette.size() / 16) + " float4 texels)" + suffix);
      set.texture = Texture(object, api.cuTexObjectDestroy);
    }
    const cuda::DevicePtr out_positions = add(out_bytes, poison.data(), "out_positions");
    const cuda::DevicePtr out_normals = variant.normals ? add(out_bytes, poison.data(), "out_normals") : 0;
    set.palette_buffer = palette_buffer;
    set.out_positions = out_positions;
    set.out_normals = out_normals;

    for (std::size_t i = 0; i < p.launches.size(); ++i) {
      const std::size_t l = launch_of_plan[i];
      const Launch& launch = mesh.launches[l];
      const KernelSource& source = kernels[l];
      const std::string where = "launch " + std::to_string(l) + " of " + variant.Key();
      auto arguments = std::make_unique<CudaPrepared::Impl::Arguments>();
      CudaPrepared::Impl::Arguments& a = *arguments;
      a.n = launch.count;
      a.first = launch.first;
      a.vertex_count = static_cast<std::uint32_t>(mesh.vertex_count);
      a.texture = set.texture.get();
      a.pointers.reserve(source.arguments.size());
      for (const KernelArgument& arg : source.arguments) {
        if (arg.name == "n") {
          a.parameters.push_back(&a.n);
        } else if (arg.name == "first") {
          a.parameters.push_back(&a.first);
        } else if (arg.name == "vertex_count") {
          a.parameters.push_back(&a.vertex_count);
        } else if (arg.name == "palette" && arg.kind == ArgumentKind::kImage) {
          if (!a.texture) Fail("launch", where + ": an image palette argument but the variant's storage is not image");
          a.parameters.push_back(&a.texture);
        } else {
          cuda::DevicePtr pointer = 0;
          if (arg.name == "palette") {
            pointer = palette_buffer;
          } else if (arg.name == "out_positions") {
            pointer = out_positions;
          } else if (arg.name == "out_normals") {
            pointer = out_normals;
          } else {
            auto input = std::find_if(launch.inputs.begin(), launch.inputs.end(),
                                      [&](const PackedBuffer& b) { return b.name == arg.name; });
            if (input == launch.inputs.end())
              Fail("launch", where + ": no packed buffer for argument '" + arg.name + "'");
            pointer = add(input->bytes.size(), input->bytes.data(), arg.name);
          }
          if (!pointer) Fail("launch", where + ": nothing to bind to argument '" + arg.name + "'");
          a.pointers.push_back(pointer);
          a.parameters.push_back(&a.pointers.back());
        }
      }
      set.launches.push_back(std::move(arguments));
    }
    p.bytes_per_set = bytes;
  }
  Check(api.cuCtxSynchronize(), "launch", "cuCtxSynchronize after uploading the input sets of " + variant.Key());
  return prepared;
}

std::vector<double> CudaRunner::Time(const CudaPrepared& prepared, int warmup, int repetitions) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  CudaPrepared::Impl& p = *prepared.impl_;
  if (p.sets.empty()) Fail("launch", "Time: nothing prepared");
  warmup = std::max(warmup, 0);
  repetitions = std::max(repetitions, 0);
  std::vector<std::vector<std::pair<Event, Event>>> events(static_cast<std::size_t>(repetitions));
  auto new_event = [&]() {
    cuda::Event e = nullptr;
    Check(api.cuEventCreate(&e, 0), "launch", "cuEventCreate for timing " + p.key);
    return Event(e, api.cuEventDestroy);
  };
  for (int frame = 0; frame < warmup + repetitions; ++frame) {
    CudaPrepared::Impl::Set& set = p.sets[static_cast<std::size_t>(frame) % p.sets.size()];
    const bool timed = frame >= warmup;
    for (std::size_t l = 0; l < p.launches.size(); ++l) {
      const CudaPrepared::Impl::LaunchPlan& plan = p.launches[l];
      const std::string where = "launch " + std::to_string(l) + " of " + p.key;
      if (p.constant)
        Check(api.cuMemcpyHtoD(plan.constant_symbol, set.palette.data(), set.palette.size()), "launch",
              where + ": cuMemcpyHtoD to '" + kConstantPaletteSymbol + "'");
      Event start, end;
      if (timed) {
        start = new_event();
        end = new_event();
        Check(api.cuEventRecord(start.get(), nullptr), "launch", where + ": cuEventRecord");
      }
      Check(api.cuLaunchKernel(plan.function, plan.blocks, plan.instances, 1, plan.threads, 1, 1, 0, nullptr,
                               set.launches[l]->parameters.data(), nullptr),
            "launch", where + ": cuLaunchKernel (" + std::to_string(plan.blocks) + " x " +
                          std::to_string(plan.instances) + " blocks of " + std::to_string(plan.threads) + ")");
      if (timed) {
        Check(api.cuEventRecord(end.get(), nullptr), "launch", where + ": cuEventRecord");
        events[static_cast<std::size_t>(frame - warmup)].emplace_back(std::move(start), std::move(end));
      }
    }
  }
  Check(api.cuCtxSynchronize(), "launch", "cuCtxSynchronize after timing " + p.key);
  std::vector<double> ms;
  for (const auto& frame : events) {
    double total = 0.0;
    for (const auto& [start, end] : frame) {
      float elapsed = 0.0f;
      Check(api.cuEventElapsedTime(&elapsed, start.get(), end.get()), "launch", "cuEventElapsedTime");
      total += static_cast<double>(elapsed);
    }
    ms.push_back(total);
  }
  return ms;
}

namespace {

CudaPrepared::Impl::Set& SetOf(const CudaPrepared& prepared, CudaPrepared::Impl* impl, int set) {
  if (!impl || set < 0 || static_cast<std::size_t>(set) >= impl->sets.size())
    Fail("launch", "no input set " + std::to_string(set) + " (" + std::to_string(prepared.input_sets()) + " prepared)");
  return impl->sets[static_cast<std::size_t>(set)];
}

}  // namespace

void CudaRunner::WritePalette(CudaPrepared& prepared, int set, std::span<const std::uint8_t> palettes) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  CudaPrepared::Impl* p = prepared.impl_.get();
  CudaPrepared::Impl::Set& s = SetOf(prepared, p, set);
  if (palettes.size() != s.palette.size())
    Fail("launch", "palettes have " + std::to_string(palettes.size()) + " bytes, expected " +
                       std::to_string(s.palette.size()));
  if (s.upload.get())  // the staging copy may still be read by the previous upload
    Check(api.cuEventSynchronize(s.upload.get()), "launch", "waiting for the previous palette upload of " + p->key);
  s.staging.assign(palettes.begin(), palettes.end());
  s.palette = s.staging;
  Check(api.cuMemcpyHtoDAsync(s.palette_buffer, s.staging.data(), s.staging.size(), im.stream), "launch",
        "cuMemcpyHtoDAsync 'palette' of " + p->key);
  if (!s.upload.get()) {
    cuda::Event event = nullptr;
    Check(api.cuEventCreate(&event, 0), "launch", "cuEventCreate");
    s.upload = Event(event, api.cuEventDestroy);
  }
  Check(api.cuEventRecord(s.upload.get(), im.stream), "launch", "cuEventRecord after the palette upload of " + p->key);
}

void CudaRunner::LaunchSet(const CudaPrepared& prepared, int set) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  const CudaPrepared::Impl& p = *prepared.impl_;
  const CudaPrepared::Impl::Set& s = SetOf(prepared, prepared.impl_.get(), set);
  for (std::size_t l = 0; l < p.launches.size(); ++l) {
    const CudaPrepared::Impl::LaunchPlan& plan = p.launches[l];
    const std::string where = "launch " + std::to_string(l) + " of " + p.key;
    // The module's symbol is shared by every set and Skinner of this kernel: fill it for this launch.
    if (p.constant)
      Check(api.cuMemcpyDtoDAsync(plan.constant_symbol, s.palette_buffer, s.palette.size(), im.stream), "launch",
            where + ": cuMemcpyDtoDAsync to '" + kConstantPaletteSymbol + "'");
    Check(api.cuLaunchKernel(plan.function, plan.blocks, plan.instances, 1, plan.threads, 1, 1, 0, im.stream,
                             s.launches[l]->parameters.data(), nullptr),
          "launch", where + ": cuLaunchKernel (" + std::to_string(plan.blocks) + " x " +
                        std::to_string(plan.instances) + " blocks of " + std::to_string(plan.threads) + ")");
  }
}

void CudaRunner::ReadOutput(const CudaPrepared& prepared, int set, bool normals, std::span<std::uint8_t> out) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  const CudaPrepared::Impl& p = *prepared.impl_;
  const CudaPrepared::Impl::Set& s = SetOf(prepared, prepared.impl_.get(), set);
  const cuda::DevicePtr buffer = normals ? s.out_normals : s.out_positions;
  if (!buffer) Fail("launch", std::string("no ") + (normals ? "normals" : "positions") + " output in " + p.key);
  if (out.size() != p.out_bytes)
    Fail("launch", "read-back of " + std::to_string(out.size()) + " bytes, the output has " + std::to_string(p.out_bytes));
  Check(api.cuStreamSynchronize(im.stream), "launch", "cuStreamSynchronize before reading back " + p.key);
  Check(api.cuMemcpyDtoH(out.data(), buffer, out.size()), "launch",
        std::string("cuMemcpyDtoH '") + (normals ? "out_normals" : "out_positions") + "' of " + p.key);
}

void CudaRunner::Finish() {
  Impl& im = *impl_;
  im.MakeCurrent();
  Check(im.api->cuStreamSynchronize(im.stream), "launch", "cuStreamSynchronize");
}

unsigned long long CudaRunner::OutputBuffer(const CudaPrepared& prepared, int set, bool normals) const {
  const CudaPrepared::Impl::Set& s = SetOf(prepared, prepared.impl_.get(), set);
  return normals ? s.out_normals : s.out_positions;
}

namespace {

constexpr const char* kCopyKernel = R"(// skintune copy bandwidth kernel
extern "C" __global__ void skintune_copy(const uint4* __restrict__ in, uint4* __restrict__ out,
                                         unsigned long long n) {
  const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
  if (i < n) out[i] = in[i];
}
)";

// A non-zero pattern (an LCG), so nothing can be elided or compressed away.
std::vector<std::uint32_t> CopyPattern(std::size_t words) {
  std::vector<std::uint32_t> pattern(words);
  std::uint32_t x = 0x9e3779b9u;
  for (std::uint32_t& w : pattern) w = x = x * 1664525u + 1013904223u;
  return pattern;
}

}  // namespace

std::vector<double> CudaRunner::TimeCopy(std::size_t bytes, int warmup, int repetitions) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  bytes -= bytes % 16;
  if (bytes == 0) Fail("launch", "copy of less than 16 bytes");
  KernelSource source;
  source.lang = Lang::kCuda;
  source.entry_point = "skintune_copy";
  source.text = kCopyKernel;
  source.source_hash = SourceHash(source.text);
  const BuiltKernel& kernel = im.KernelFor(source);
  const std::vector<std::uint32_t> pattern = CopyPattern(bytes / 4);
  Memory in = im.Buffer(bytes, pattern.data(), "copy source");
  Memory out = im.Buffer(bytes, nullptr, "copy destination");
  cuda::DevicePtr in_pointer = in.get(), out_pointer = out.get();
  unsigned long long n = bytes / 16;
  void* parameters[] = {&in_pointer, &out_pointer, &n};
  const auto blocks = static_cast<unsigned>((n + 255) / 256);
  std::vector<std::pair<Event, Event>> events;
  for (int r = 0; r < std::max(warmup, 0) + std::max(repetitions, 0); ++r) {
    const bool timed = r >= warmup;
    cuda::Event start = nullptr, end = nullptr;
    if (timed) {
      Check(api.cuEventCreate(&start, 0), "launch", "cuEventCreate");
      events.emplace_back(Event(start, api.cuEventDestroy), Event());
      Check(api.cuEventCreate(&end, 0), "launch", "cuEventCreate");
      events.back().second = Event(end, api.cuEventDestroy);
      Check(api.cuEventRecord(start, nullptr), "launch", "cuEventRecord");
    }
    Check(api.cuLaunchKernel(kernel.function, blocks, 1, 1, 256, 1, 1, 0, nullptr, parameters, nullptr), "launch",
          "cuLaunchKernel of the copy kernel (" + std::to_string(blocks) + " blocks of 256)");
    if (timed) Check(api.cuEventRecord(end, nullptr), "launch", "cuEventRecord");
  }
  Check(api.cuCtxSynchronize(), "launch", "cuCtxSynchronize after the copy kernel");
  std::vector<double> ms;
  for (const auto& [start, end] : events) {
    float elapsed = 0.0f;
    Check(api.cuEventElapsedTime(&elapsed, start.get(), end.get()), "launch", "cuEventElapsedTime");
    ms.push_back(static_cast<double>(elapsed));
  }
  return ms;
}

}  // namespace skintune
