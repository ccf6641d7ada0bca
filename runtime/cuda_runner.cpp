#include "runtime/cuda_runner.h"

#include <algorithm>
#include <cstring>
#include <map>
#include <utility>

#include "reference/error.h"
#include "runtime/cuda_api.h"
#include "runtime/output_check.h"

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

}  // namespace

struct CudaRunner::Impl {
  const cuda::DriverApi* api = nullptr;
  cuda::Device device = 0;
  cuda::Context context = nullptr;  // the device's primary context, retained
  std::string name, arch;
  DeviceLimits limits;
  std::map<std::string, BuiltKernel> built;  // by source hash

  ~Impl() {
    if (!context) return;
    api->cuCtxSetCurrent(context);
    built.clear();  // unloads the modules while their context is current
    api->cuDevicePrimaryCtxRelease(device);
  }
  void MakeCurrent() const { Check(api->cuCtxSetCurrent(context), "launch", "cuCtxSetCurrent"); }
  const BuiltKernel& KernelFor(const KernelSource& source);
  Memory Buffer(std::size_t bytes, const void* data, const std::string& what) const;
};

CudaRunner::CudaRunner(int device_index) : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  const CudaAvailability available = Probe();
  if (!available.nvrtc) Fail("setup", available.nvrtc_missing);
  if (!available.driver) Fail("setup", available.driver_missing);
  im.api = cuda::Driver();
  if (device_index < 0 || device_index >= available.device_count)
    Fail("setup", "no device " + std::to_string(device_index) + " (" + std::to_string(available.device_count) +
                      " devices" + (available.device_count == 0 ? ": " + available.driver_missing : "") + ")");
  Check(im.api->cuDeviceGet(&im.device, device_index), "setup", "cuDeviceGet " + std::to_string(device_index));
  char text[256] = {};
  Check(im.api->cuDeviceGetName(text, sizeof text - 1, im.device), "setup", "cuDeviceGetName");
  im.name = text;
  auto attribute = [&](int which, const char* what) {
    int value = 0;
    Check(im.api->cuDeviceGetAttribute(&value, which, im.device), "setup", std::string("cuDeviceGetAttribute ") + what);
    return value;
  };
  const int major = attribute(cuda::kAttributeComputeCapabilityMajor, "(compute capability)");
  const int minor = attribute(cuda::kAttributeComputeCapabilityMinor, "(compute capability)");
  im.limits.max_wg_size = static_cast<std::size_t>(attribute(cuda::kAttributeMaxThreadsPerBlock, "(threads per block)"));
  im.limits.local_memory_bytes =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeMaxSharedMemoryPerBlock, "(shared memory per block)"));
  im.limits.constant_memory_bytes =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeTotalConstantMemory, "(constant memory)"));
  im.limits.image_support = true;  // texture objects: every device CUDA 11+ runs on
  im.limits.image_buffer_max_texels =
      static_cast<std::uint64_t>(attribute(cuda::kAttributeMaxTexture1dLinearWidth, "(1D linear texture width)"));
  im.arch = NvrtcArchFor(major, minor);
  if (im.arch.empty())
    Fail("setup", im.name + " (compute capability " + std::to_string(major) + "." + std::to_string(minor) +
                      ") is older than every architecture " + available.nvrtc_library + " supports");
  cuda::Context context = nullptr;
  Check(im.api->cuDevicePrimaryCtxRetain(&context, im.device), "setup", "cuDevicePrimaryCtxRetain on " + im.name);
  im.context = context;
  Check(im.api->cuCtxSetCurrent(im.context), "setup", "cuCtxSetCurrent on " + im.name);
}

CudaRunner::~CudaRunner() = default;

const std::string& CudaRunner::device_name() const { return impl_->name; }
const std::string& CudaRunner::arch() const { return impl_->arch; }
const DeviceLimits& CudaRunner::limits() const { return impl_->limits; }

const BuiltKernel& CudaRunner::Impl::KernelFor(const KernelSource& source) {
  if (source.lang != Lang::kCuda) Fail("build", std::string("kernel language is ") + Name(source.lang));
  const std::string key = source.source_hash.empty() ? SourceHash(source.text) : source.source_hash;
  if (auto found = built.find(key); found != built.end()) return found->second;

  const std::string what = "kernel " + key + " (" + source.text.substr(0, source.text.find('\n')) + ")";
  const CompileResult compiled = CompileWithNvrtc(source.text, arch);
  if (!compiled.ok) Fail("build", what + ": " + compiled.error);

  // The driver JIT-compiles the PTX for the device; its error log says why it cannot.
  std::string log(8192, '\0');
  int options[] = {cuda::kJitErrorLogBuffer, cuda::kJitErrorLogBufferSizeBytes};
  void* values[] = {log.data(), reinterpret_cast<void*>(static_cast<std::uintptr_t>(log.size()))};
  cuda::Module module = nullptr;
  const cuda::Result r = api->cuModuleLoadDataEx(&module, compiled.ptx.c_str(), 2, options, values);
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
  std::vector<KernelSource> kernels;
  for (const Launch& launch : mesh.launches)
    kernels.push_back(Emit(mesh.variant, launch.influences, static_cast<int>(mesh.palette_joints)));
  return Run(mesh, kernels, palette);
}

CudaRunResult CudaRunner::Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                              std::span<const std::uint8_t> palette) {
  Impl& im = *impl_;
  const cuda::DriverApi& api = *im.api;
  im.MakeCurrent();
  const Variant& variant = mesh.variant;
  if (kernels.size() != mesh.launches.size())
    Fail("launch", std::to_string(kernels.size()) + " kernels for " + std::to_string(mesh.launches.size()) +
                       " launches of " + variant.Key());
  if (palette.empty()) palette = mesh.palette;
  const std::size_t rows = variant.palette == PaletteFormat::kMat4 ? 4 : 3;
  if (palette.size() != mesh.palette_joints * rows * 16)
    Fail("launch", "palette has " + std::to_string(palette.size()) + " bytes, expected " +
                       std::to_string(mesh.palette_joints) + " joints x " + std::to_string(rows) + " rows x 16");

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

  // Outputs: poisoned, each followed by its guard.
  const std::size_t out_bytes = mesh.vertex_count * mesh.output_stride_bytes;
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
                           " (the kernel was emitted for fewer joints)");
      Check(api.cuMemcpyHtoD(symbol, palette.data(), palette.size()), "launch",
            where + ": cuMemcpyHtoD to '" + kConstantPaletteSymbol + "'");
    }

    // Argument values live in these arrays (reserved: no reallocation) while cuLaunchKernel reads them.
    std::uint32_t n = launch.count, first = launch.first;
    std::vector<cuda::DevicePtr> pointers;
    pointers.reserve(source.arguments.size());
    cuda::TexObject texture = palette_texture.get();
    std::vector<void*> parameters;
    for (const KernelArgument& arg : source.arguments) {
      if (arg.name == "n") {
        parameters.push_back(&n);
      } else if (arg.name == "first") {
        parameters.push_back(&first);
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
    Check(api.cuLaunchKernel(kernel.function, static_cast<unsigned>(blocks), 1, 1, static_cast<unsigned>(wg), 1, 1, 0,
                             nullptr, parameters.data(), nullptr),
          "launch", where + ": cuLaunchKernel (" + std::to_string(blocks) + " blocks of " + std::to_string(wg) + ")");
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
    const OutputCheck check = CheckGuardAndCountPoisoned(bytes, out_bytes, mesh.output_stride_bytes, mesh.vertex_count);
    if (!check.guard_ok)
      Fail("guard", variant.Key() + ": " + what + ": the kernel " + GuardFailure(check, out_bytes));
    result.poisoned_vertices += check.poisoned_vertices;
    out = std::move(bytes);
  };
  read_back(out_positions, "out_positions", result.positions);
  if (variant.normals) read_back(out_normals, "out_normals", result.normals);
  return result;
}

}  // namespace skintune
