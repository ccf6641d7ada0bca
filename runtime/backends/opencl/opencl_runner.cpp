#include "runtime/backends/opencl/opencl_runner.h"

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <utility>

#include "reference/error.h"
#include "runtime/output_check.h"
#include "runtime/run_shape.h"

namespace skintune {

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

struct BuiltKernel {
  Program program;
  Kernel kernel;
};

}  // namespace

struct OpenClRunner::Impl {
  cl_platform_id platform = nullptr;
  cl_device_id device = nullptr;
  std::string name;
  Context context;
  Queue queue;
  std::map<std::string, BuiltKernel> built;  // by source hash
  ProgramCache* cache = nullptr;             // UseProgramCache
  std::string cache_device_id;

  cl_kernel KernelFor(const KernelSource& source);
  void CheckPaletteFits(const Variant& variant, std::size_t palette_bytes) const;
  Program ProgramFromSource(const KernelSource& source, const std::string& key, const char* options);
  Program ProgramFromBinary(const std::vector<std::uint8_t>& binary, const char* options);
  std::vector<std::uint8_t> BinaryOf(cl_program program);
  Memory Buffer(cl_mem_flags flags, std::size_t bytes, const void* data, const std::string& what);
};

OpenClRunner::OpenClRunner(int platform_index, int device_index) : impl_(std::make_unique<Impl>()) {
  cl_uint platform_count = 0;
  if (clGetPlatformIDs(0, nullptr, &platform_count) != CL_SUCCESS || platform_index < 0 ||
      static_cast<cl_uint>(platform_index) >= platform_count) {
    Fail("setup", "no platform " + std::to_string(platform_index) + " (" + std::to_string(platform_count) +
                      " platforms)");
  }
  std::vector<cl_platform_id> platforms(platform_count);
  clGetPlatformIDs(platform_count, platforms.data(), nullptr);
  impl_->platform = platforms[static_cast<std::size_t>(platform_index)];
  cl_uint device_count = 0;
  if (clGetDeviceIDs(impl_->platform, CL_DEVICE_TYPE_ALL, 0, nullptr, &device_count) != CL_SUCCESS ||
      device_index < 0 || static_cast<cl_uint>(device_index) >= device_count) {
    Fail("setup", "platform " + std::to_string(platform_index) + " has no device " + std::to_string(device_index) +
                      " (" + std::to_string(device_count) + " devices)");
  }
  std::vector<cl_device_id> devices(device_count);
  clGetDeviceIDs(impl_->platform, CL_DEVICE_TYPE_ALL, device_count, devices.data(), nullptr);
  impl_->device = devices[static_cast<std::size_t>(device_index)];

  std::size_t size = 0;
  clGetDeviceInfo(impl_->device, CL_DEVICE_NAME, 0, nullptr, &size);
  impl_->name.assign(size, '\0');
  clGetDeviceInfo(impl_->device, CL_DEVICE_NAME, size, impl_->name.data(), nullptr);
  impl_->name.resize(std::strlen(impl_->name.c_str()));

  cl_int err = CL_SUCCESS;
  const cl_context_properties properties[] = {CL_CONTEXT_PLATFORM,
                                              reinterpret_cast<cl_context_properties>(impl_->platform), 0};
  impl_->context = Context(clCreateContext(properties, 1, &impl_->device, nullptr, nullptr, &err));
  Check(err, "setup", "clCreateContext on " + impl_->name);
  impl_->queue = Queue(clCreateCommandQueue(impl_->context.get(), impl_->device, CL_QUEUE_PROFILING_ENABLE, &err));
  Check(err, "setup", "clCreateCommandQueue on " + impl_->name);
}

OpenClRunner::OpenClRunner(void* device_handle, void* context_handle, void* queue_handle) : impl_(std::make_unique<Impl>()) {
  if (!device_handle || !context_handle || !queue_handle) Fail("setup", "a null cl_device_id, cl_context or cl_command_queue");
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
  if (properties & CL_QUEUE_OUT_OF_ORDER_EXEC_MODE_ENABLE) Fail("setup", "the given queue is out-of-order; an in-order queue is needed");
  Check(clGetDeviceInfo(device, CL_DEVICE_PLATFORM, sizeof impl_->platform, &impl_->platform, nullptr), "setup",
        "clGetDeviceInfo(CL_DEVICE_PLATFORM) of the given device");
  Check(clRetainContext(context), "setup", "clRetainContext");
  impl_->context = Context(context);
  Check(clRetainCommandQueue(queue), "setup", "clRetainCommandQueue");
  impl_->queue = Queue(queue);
  impl_->device = device;
  std::size_t size = 0;
  clGetDeviceInfo(device, CL_DEVICE_NAME, 0, nullptr, &size);
  impl_->name.assign(size, '\0');
  clGetDeviceInfo(device, CL_DEVICE_NAME, size, impl_->name.data(), nullptr);
  impl_->name.resize(std::strlen(impl_->name.c_str()));
}

OpenClRunner::~OpenClRunner() = default;

const std::string& OpenClRunner::device_name() const { return impl_->name; }
void* OpenClRunner::device() const { return impl_->device; }
void* OpenClRunner::context() const { return impl_->context.get(); }
void* OpenClRunner::queue() const { return impl_->queue.get(); }

void OpenClRunner::UseProgramCache(ProgramCache* cache, const std::string& device_id) {
  impl_->cache = cache;
  impl_->cache_device_id = device_id;
}

Program OpenClRunner::Impl::ProgramFromBinary(const std::vector<std::uint8_t>& binary, const char* options) {
  cl_int err = CL_SUCCESS, binary_status = CL_SUCCESS;
  const std::size_t size = binary.size();
  const unsigned char* bytes = binary.data();
  Program program(clCreateProgramWithBinary(context.get(), 1, &device, &size, &bytes, &binary_status, &err));
  if (err != CL_SUCCESS || binary_status != CL_SUCCESS) return Program();
  if (clBuildProgram(program.get(), 1, &device, options, nullptr, nullptr) != CL_SUCCESS) return Program();
  return program;
}

std::vector<std::uint8_t> OpenClRunner::Impl::BinaryOf(cl_program program) {
  std::size_t size = 0;
  if (clGetProgramInfo(program, CL_PROGRAM_BINARY_SIZES, sizeof size, &size, nullptr) != CL_SUCCESS || size == 0)
    return {};
  std::vector<std::uint8_t> binary(size);
  unsigned char* at = binary.data();
  if (clGetProgramInfo(program, CL_PROGRAM_BINARIES, sizeof at, &at, nullptr) != CL_SUCCESS) return {};
  return binary;
}

Program OpenClRunner::Impl::ProgramFromSource(const KernelSource& source, const std::string& key,
                                              const char* options) {
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
    Fail("build", "kernel " + key + " (" + source.text.substr(0, source.text.find('\n')) +
                      ") failed with error " + std::to_string(err) + " on " + name + "; build log:" +
                      FirstLines(log, 20));
  }
  return program;
}

cl_kernel OpenClRunner::Impl::KernelFor(const KernelSource& source) {
  if (source.lang != Lang::kOpenCl) Fail("build", std::string("kernel language is ") + Name(source.lang));
  const std::string key = source.source_hash.empty() ? SourceHash(source.text) : source.source_hash;
  if (auto found = built.find(key); found != built.end()) {
    if (cache) ++cache->counters().memory_hits;
    return found->second.kernel.get();
  }

  constexpr const char* kOptions = "-cl-std=CL1.2";
  BuiltKernel b;
  const std::string cache_key = cache ? ProgramKey("opencl", cache_device_id, key, kOptions) : "";
  if (cache) {
    // A binary the driver refuses (another driver wrote it, it is corrupt) is built from source below.
    if (const auto binary = cache->Load("opencl", cache_key)) b.program = ProgramFromBinary(*binary, kOptions);
    if (b.program.get()) ++cache->counters().disk_hits;
  }
  if (!b.program.get()) {
    b.program = ProgramFromSource(source, key, kOptions);
    if (cache) {
      ++cache->counters().builds;
      cache->Store("opencl", cache_key, BinaryOf(b.program.get()));
    }
  }
  cl_int err = CL_SUCCESS;
  b.kernel = Kernel(clCreateKernel(b.program.get(), source.entry_point.c_str(), &err));
  Check(err, "build", "clCreateKernel '" + source.entry_point + "' of kernel " + key);
  return built.emplace(key, std::move(b)).first->second.kernel.get();
}

Memory OpenClRunner::Impl::Buffer(cl_mem_flags flags, std::size_t bytes, const void* data, const std::string& what) {
  cl_int err = CL_SUCCESS;
  if (bytes == 0) Fail("launch", "buffer '" + what + "' is empty");
  Memory m(clCreateBuffer(context.get(), flags | (data ? CL_MEM_COPY_HOST_PTR : 0), bytes, const_cast<void*>(data),
                          &err));
  Check(err, "launch", "clCreateBuffer '" + what + "' (" + std::to_string(bytes) + " bytes)");
  return m;
}

// The K palettes of an instanced run may exceed what the device allows a
// __constant buffer or an image1d_buffer; say which limit, before launching.
void OpenClRunner::Impl::CheckPaletteFits(const Variant& variant, std::size_t palette_bytes) const {
  if (variant.storage == PaletteStorage::kConstant) {
    cl_ulong limit = 0;
    clGetDeviceInfo(device, CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE, sizeof limit, &limit, nullptr);
    if (limit != 0 && palette_bytes > limit)
      Fail("launch", variant.Key() + ": the palettes (" + std::to_string(palette_bytes) +
                         " bytes) exceed CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE " + std::to_string(limit) + " of " + name);
  } else if (variant.storage == PaletteStorage::kImage) {
    std::size_t limit = 0;
    clGetDeviceInfo(device, CL_DEVICE_IMAGE_MAX_BUFFER_SIZE, sizeof limit, &limit, nullptr);
    if (limit != 0 && palette_bytes / 16 > limit)
      Fail("launch", variant.Key() + ": the palettes (" + std::to_string(palette_bytes / 16) +
                         " texels) exceed CL_DEVICE_IMAGE_MAX_BUFFER_SIZE " + std::to_string(limit) + " of " + name);
  }
}

void OpenClRunner::Build(const KernelSource& source) { impl_->KernelFor(source); }

OpenClRunResult OpenClRunner::Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette) {
  return Run(mesh, EmitLaunchKernels(mesh), palette);
}

OpenClRunResult OpenClRunner::RunInstanced(const PackedMesh& mesh, int instances,
                                           std::span<const std::uint8_t> palettes) {
  return Run(mesh, EmitLaunchKernels(mesh, instances), palettes, instances);
}

OpenClRunResult OpenClRunner::Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                  std::span<const std::uint8_t> palettes, int instances) {
  Impl& im = *impl_;
  const Variant& variant = mesh.variant;
  const std::vector<std::uint8_t> palette = PalettesOrMeshPalette(mesh, palettes, instances);
  const RunShape shape = CheckRunShape(mesh, kernels, palette.size(), instances, "OpenCL");
  im.CheckPaletteFits(variant, palette.size());
  const cl_uint vertex_count = static_cast<cl_uint>(mesh.vertex_count);

  // Palette (and its image view for `image` storage).
  Memory palette_buffer = im.Buffer(CL_MEM_READ_ONLY, palette.size(), palette.data(), "palette");
  Memory palette_image;
  if (variant.storage == PaletteStorage::kImage) {
    cl_image_format format{CL_RGBA, CL_FLOAT};
    cl_image_desc desc{};
    desc.image_type = CL_MEM_OBJECT_IMAGE1D_BUFFER;
    desc.image_width = palette.size() / 16;
    desc.buffer = palette_buffer.get();
    cl_int err = CL_SUCCESS;
    palette_image = Memory(clCreateImage(im.context.get(), CL_MEM_READ_ONLY, &format, &desc, nullptr, &err));
    Check(err, "launch", "clCreateImage (image1d_buffer of " + std::to_string(desc.image_width) + " texels)");
  }

  // Outputs (K instances, one after another): poisoned, each followed by its guard.
  const std::size_t out_bytes = shape.out_bytes;
  const std::vector<std::uint8_t> fill = PoisonedOutput(out_bytes);
  Memory out_positions = im.Buffer(CL_MEM_READ_WRITE, fill.size(), fill.data(), "out_positions");
  Memory out_normals;
  if (variant.normals)
    out_normals = im.Buffer(CL_MEM_READ_WRITE, fill.size(), fill.data(), "out_normals");

  std::vector<Memory> inputs;  // kept alive until the queue is finished
  std::vector<Event> events;
  for (std::size_t l = 0; l < mesh.launches.size(); ++l) {
    const Launch& launch = mesh.launches[l];
    const KernelSource& source = kernels[l];
    if (launch.count == 0) continue;
    const cl_kernel kernel = im.KernelFor(source);
    const std::string where = "launch " + std::to_string(l) + " of " + variant.Key();
    for (std::size_t a = 0; a < source.arguments.size(); ++a) {
      const KernelArgument& arg = source.arguments[a];
      const auto index = static_cast<cl_uint>(a);
      cl_int err = CL_SUCCESS;
      cl_mem mem = nullptr;
      if (arg.name == "n") {
        err = clSetKernelArg(kernel, index, sizeof(cl_uint), &launch.count);
      } else if (arg.name == "first") {
        err = clSetKernelArg(kernel, index, sizeof(cl_uint), &launch.first);
      } else if (arg.name == "vertex_count") {
        err = clSetKernelArg(kernel, index, sizeof(cl_uint), &vertex_count);
      } else {
        if (arg.name == "palette") {
          mem = palette_image.get() ? palette_image.get() : palette_buffer.get();
        } else if (arg.name == "out_positions") {
          mem = out_positions.get();
        } else if (arg.name == "out_normals") {
          mem = out_normals.get();
        } else {
          auto input = std::find_if(launch.inputs.begin(), launch.inputs.end(),
                                    [&](const PackedBuffer& b) { return b.name == arg.name; });
          if (input == launch.inputs.end()) Fail("launch", where + ": no packed buffer for argument '" + arg.name + "'");
          inputs.push_back(im.Buffer(CL_MEM_READ_ONLY, input->bytes.size(), input->bytes.data(), arg.name));
          mem = inputs.back().get();
        }
        if (!mem) Fail("launch", where + ": nothing to bind to argument '" + arg.name + "'");
        err = clSetKernelArg(kernel, index, sizeof(cl_mem), &mem);
      }
      Check(err, "launch", where + ": clSetKernelArg " + std::to_string(a) + " '" + arg.name + "'");
    }
    // Instanced: the second dimension is the instance.
    const std::size_t global[2] = {source.launch.GlobalItems(launch.count), static_cast<std::size_t>(shape.instances)};
    const std::size_t local[2] = {static_cast<std::size_t>(source.launch.wg_size), 1};
    const cl_uint dimensions = shape.instanced ? 2 : 1;
    cl_event event = nullptr;
    Check(clEnqueueNDRangeKernel(im.queue.get(), kernel, dimensions, nullptr, global, local, 0, nullptr, &event),
          "launch",
          where + ": clEnqueueNDRangeKernel (" + std::to_string(global[0]) + " items x " + std::to_string(global[1]) +
              " instances, groups of " + std::to_string(local[0]) + ")");
    events.emplace_back(event);
  }
  Check(clFinish(im.queue.get()), "launch", "clFinish after " + variant.Key());

  OpenClRunResult result;
  for (const Event& e : events) {
    cl_ulong start = 0, end = 0;
    clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_START, sizeof start, &start, nullptr);
    clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_END, sizeof end, &end, nullptr);
    result.launch_ms.push_back(static_cast<double>(end - start) * 1e-6);
  }

  // Read back, check the guards, count vertices never written.
  auto read_back = [&](const Memory& buffer, const char* what, std::vector<std::uint8_t>& out) {
    std::vector<std::uint8_t> bytes(out_bytes + kGuardBytes);
    Check(clEnqueueReadBuffer(im.queue.get(), buffer.get(), CL_TRUE, 0, bytes.size(), bytes.data(), 0, nullptr, nullptr),
          "launch", std::string("clEnqueueReadBuffer '") + what + "'");
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

struct OpenClPrepared::Impl {
  struct LaunchPlan {
    KernelSource source;
    cl_kernel kernel = nullptr;  // owned by the runner
    std::uint32_t count = 0, first = 0, vertex_count = 0;
    cl_uint dimensions = 1;  // 2: instanced, the second dimension is the instance
    std::size_t global[2] = {0, 1}, local[2] = {0, 1};
  };
  // One set: its buffers, and per launch the memory object of each kernel
  // argument (null for the scalars n, first and vertex_count).
  struct Set {
    std::vector<Memory> buffers;
    std::vector<std::vector<cl_mem>> arguments;
    cl_mem palette = nullptr, out_positions = nullptr, out_normals = nullptr;
    std::vector<std::uint8_t> staging;  // the palette being uploaded (WritePalette)
    Event upload;                       // its write, while in flight
  };
  std::string key;
  std::vector<LaunchPlan> launches;
  std::vector<Set> sets;
  std::size_t bytes_per_set = 0;
  std::size_t palette_bytes = 0, out_bytes = 0;
};

namespace {

// Enqueues every launch of set `set` (positions into `out_positions` when not
// null), each launch's event into `events` when given.
void EnqueueFrame(cl_command_queue queue, const OpenClPrepared::Impl& p, std::size_t set, cl_mem out_positions,
                  std::vector<Event>* events) {
  const std::vector<std::vector<cl_mem>>& arguments = p.sets[set].arguments;
  for (std::size_t l = 0; l < p.launches.size(); ++l) {
    const OpenClPrepared::Impl::LaunchPlan& plan = p.launches[l];
    const std::string where = "launch " + std::to_string(l) + " of " + p.key;
    for (std::size_t a = 0; a < plan.source.arguments.size(); ++a) {
      const KernelArgument& arg = plan.source.arguments[a];
      const auto index = static_cast<cl_uint>(a);
      cl_int err = CL_SUCCESS;
      if (arg.name == "n") {
        err = clSetKernelArg(plan.kernel, index, sizeof(cl_uint), &plan.count);
      } else if (arg.name == "first") {
        err = clSetKernelArg(plan.kernel, index, sizeof(cl_uint), &plan.first);
      } else if (arg.name == "vertex_count") {
        err = clSetKernelArg(plan.kernel, index, sizeof(cl_uint), &plan.vertex_count);
      } else if (arg.name == "out_positions" && out_positions) {
        err = clSetKernelArg(plan.kernel, index, sizeof(cl_mem), &out_positions);
      } else {
        err = clSetKernelArg(plan.kernel, index, sizeof(cl_mem), &arguments[l][a]);
      }
      if (err != CL_SUCCESS) Check(err, "launch", where + ": clSetKernelArg " + std::to_string(a) + " '" + arg.name + "'");
    }
    cl_event event = nullptr;
    Check(clEnqueueNDRangeKernel(queue, plan.kernel, plan.dimensions, nullptr, plan.global, plan.local, 0, nullptr,
                                 events ? &event : nullptr),
          "launch", where + ": clEnqueueNDRangeKernel (" + std::to_string(plan.global[0]) + " items x " +
                        std::to_string(plan.global[1]) + " instances, groups of " + std::to_string(plan.local[0]) +
                        ")");
    if (events) events->emplace_back(event);
  }
}

}  // namespace

OpenClPrepared::OpenClPrepared() : impl_(std::make_unique<Impl>()) {}
OpenClPrepared::~OpenClPrepared() = default;
OpenClPrepared::OpenClPrepared(OpenClPrepared&&) noexcept = default;
OpenClPrepared& OpenClPrepared::operator=(OpenClPrepared&&) noexcept = default;
int OpenClPrepared::input_sets() const { return impl_ ? static_cast<int>(impl_->sets.size()) : 0; }
std::size_t OpenClPrepared::bytes_per_set() const { return impl_ ? impl_->bytes_per_set : 0; }

OpenClPrepared OpenClRunner::Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                     std::span<const std::vector<std::uint8_t>> palettes, int instances) {
  Impl& im = *impl_;
  const Variant& variant = mesh.variant;
  if (palettes.empty()) Fail("launch", "no palette (input set) to time " + variant.Key() + " with");
  RunShape shape;
  for (const std::vector<std::uint8_t>& palette : palettes)
    shape = CheckRunShape(mesh, kernels, palette.size(), instances, "OpenCL");
  im.CheckPaletteFits(variant, palettes.front().size());

  OpenClPrepared prepared;
  OpenClPrepared::Impl& p = *prepared.impl_;
  p.key = variant.Key();
  for (std::size_t l = 0; l < mesh.launches.size(); ++l) {
    const Launch& launch = mesh.launches[l];
    if (launch.count == 0) continue;
    OpenClPrepared::Impl::LaunchPlan plan;
    plan.kernel = im.KernelFor(kernels[l]);  // build errors before any upload
    plan.source = kernels[l];
    plan.count = launch.count;
    plan.first = launch.first;
    plan.vertex_count = static_cast<std::uint32_t>(mesh.vertex_count);
    plan.dimensions = shape.instanced ? 2 : 1;
    plan.global[0] = kernels[l].launch.GlobalItems(launch.count);
    plan.global[1] = static_cast<std::size_t>(shape.instances);
    plan.local[0] = static_cast<std::size_t>(kernels[l].launch.wg_size);
    p.launches.push_back(std::move(plan));
  }

  const std::size_t out_bytes = shape.out_bytes;
  const std::vector<std::uint8_t> poison = PoisonedOutput(out_bytes);  // the first out_bytes are used
  p.palette_bytes = palettes.front().size();
  p.out_bytes = out_bytes;
  for (std::size_t k = 0; k < palettes.size(); ++k) {
    OpenClPrepared::Impl::Set set;
    std::size_t bytes = 0;
    auto add = [&](Memory m, std::size_t size) {
      bytes += size;
      set.buffers.push_back(std::move(m));
      return set.buffers.back().get();
    };
    const std::string suffix = " (input set " + std::to_string(k) + ")";
    const std::vector<std::uint8_t>& palette = palettes[k];
    const cl_mem palette_buffer =
        add(im.Buffer(CL_MEM_READ_ONLY, palette.size(), palette.data(), "palette" + suffix), palette.size());
    cl_mem palette_mem = palette_buffer;
    if (variant.storage == PaletteStorage::kImage) {
      cl_image_format format{CL_RGBA, CL_FLOAT};
      cl_image_desc desc{};
      desc.image_type = CL_MEM_OBJECT_IMAGE1D_BUFFER;
      desc.image_width = palette.size() / 16;
      desc.buffer = palette_buffer;
      cl_int err = CL_SUCCESS;
      Memory image(clCreateImage(im.context.get(), CL_MEM_READ_ONLY, &format, &desc, nullptr, &err));
      Check(err, "launch", "clCreateImage (image1d_buffer of " + std::to_string(desc.image_width) + " texels)" + suffix);
      palette_mem = add(std::move(image), 0);
    }
    const cl_mem out_positions =
        add(im.Buffer(CL_MEM_READ_WRITE, out_bytes, poison.data(), "out_positions" + suffix), out_bytes);
    cl_mem out_normals = nullptr;
    if (variant.normals)
      out_normals = add(im.Buffer(CL_MEM_READ_WRITE, out_bytes, poison.data(), "out_normals" + suffix), out_bytes);
    set.palette = palette_buffer;
    set.out_positions = out_positions;
    set.out_normals = out_normals;

    std::size_t plan_index = 0;
    for (std::size_t l = 0; l < mesh.launches.size(); ++l) {
      const Launch& launch = mesh.launches[l];
      if (launch.count == 0) continue;
      const KernelSource& source = p.launches[plan_index++].source;
      const std::string where = "launch " + std::to_string(l) + " of " + variant.Key();
      std::vector<cl_mem> arguments;
      for (const KernelArgument& arg : source.arguments) {
        cl_mem mem = nullptr;
        if (arg.kind == ArgumentKind::kScalar) {
          arguments.push_back(nullptr);
          continue;
        } else if (arg.name == "palette") {
          mem = palette_mem;
        } else if (arg.name == "out_positions") {
          mem = out_positions;
        } else if (arg.name == "out_normals") {
          mem = out_normals;
        } else {
          auto input = std::find_if(launch.inputs.begin(), launch.inputs.end(),
                                    [&](const PackedBuffer& b) { return b.name == arg.name; });
          if (input == launch.inputs.end()) Fail("launch", where + ": no packed buffer for argument '" + arg.name + "'");
          mem = add(im.Buffer(CL_MEM_READ_ONLY, input->bytes.size(), input->bytes.data(), arg.name + suffix),
                    input->bytes.size());
        }
        if (!mem) Fail("launch", where + ": nothing to bind to argument '" + arg.name + "'");
        arguments.push_back(mem);
      }
      set.arguments.push_back(std::move(arguments));
    }
    p.bytes_per_set = bytes;
    p.sets.push_back(std::move(set));
  }
  // The uploads are done before anything is timed.
  Check(clFinish(im.queue.get()), "launch", "clFinish after uploading the input sets of " + variant.Key());
  return prepared;
}

std::vector<double> OpenClRunner::Time(const OpenClPrepared& prepared, int warmup, int repetitions) {
  Impl& im = *impl_;
  const OpenClPrepared::Impl& p = *prepared.impl_;
  if (p.sets.empty()) Fail("launch", "Time: nothing prepared");
  warmup = std::max(warmup, 0);
  repetitions = std::max(repetitions, 0);
  std::vector<std::vector<Event>> events(static_cast<std::size_t>(repetitions));
  for (int frame = 0; frame < warmup + repetitions; ++frame) {
    const bool timed = frame >= warmup;
    EnqueueFrame(im.queue.get(), p, static_cast<std::size_t>(frame) % p.sets.size(), nullptr,
                 timed ? &events[static_cast<std::size_t>(frame - warmup)] : nullptr);
  }
  Check(clFinish(im.queue.get()), "launch", "clFinish after timing " + p.key);
  std::vector<double> ms;
  for (const std::vector<Event>& frame : events) {
    double total = 0.0;
    for (const Event& e : frame) {
      cl_ulong start = 0, end = 0;
      Check(clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_START, sizeof start, &start, nullptr), "launch",
            "clGetEventProfilingInfo (start) of " + p.key);
      Check(clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_END, sizeof end, &end, nullptr), "launch",
            "clGetEventProfilingInfo (end) of " + p.key);
      total += static_cast<double>(end - start) * 1e-6;
    }
    ms.push_back(total);
  }
  return ms;
}

namespace {

OpenClPrepared::Impl::Set& SetOf(const OpenClPrepared& prepared, OpenClPrepared::Impl* impl, int set) {
  if (!impl || set < 0 || static_cast<std::size_t>(set) >= impl->sets.size())
    Fail("launch", "no input set " + std::to_string(set) + " (" + std::to_string(prepared.input_sets()) + " prepared)");
  return impl->sets[static_cast<std::size_t>(set)];
}

}  // namespace

void OpenClRunner::WritePalette(OpenClPrepared& prepared, int set, std::span<const std::uint8_t> palette) {
  OpenClPrepared::Impl* p = prepared.impl_.get();
  OpenClPrepared::Impl::Set& s = SetOf(prepared, p, set);
  if (palette.size() != p->palette_bytes)
    Fail("launch", "palette has " + std::to_string(palette.size()) + " bytes, expected " + std::to_string(p->palette_bytes));
  if (s.upload.get()) {  // the staging copy is still being read by the previous upload
    const cl_event previous = s.upload.get();
    Check(clWaitForEvents(1, &previous), "launch", "waiting for the previous palette upload of " + p->key);
  }
  s.staging.assign(palette.begin(), palette.end());
  cl_event event = nullptr;
  Check(clEnqueueWriteBuffer(impl_->queue.get(), s.palette, CL_FALSE, 0, s.staging.size(), s.staging.data(), 0,
                             nullptr, &event),
        "launch", "clEnqueueWriteBuffer 'palette' of " + p->key);
  s.upload = Event(event);
}

void OpenClRunner::LaunchSet(const OpenClPrepared& prepared, int set, void* out_positions) {
  SetOf(prepared, prepared.impl_.get(), set);
  EnqueueFrame(impl_->queue.get(), *prepared.impl_, static_cast<std::size_t>(set), static_cast<cl_mem>(out_positions),
               nullptr);
}

void OpenClRunner::ReadOutput(const OpenClPrepared& prepared, int set, bool normals, std::span<std::uint8_t> out) {
  const OpenClPrepared::Impl* p = prepared.impl_.get();
  const OpenClPrepared::Impl::Set& s = SetOf(prepared, prepared.impl_.get(), set);
  const cl_mem buffer = normals ? s.out_normals : s.out_positions;
  if (!buffer) Fail("launch", std::string("no ") + (normals ? "normals" : "positions") + " output in " + p->key);
  if (out.size() != p->out_bytes)
    Fail("launch", "read-back of " + std::to_string(out.size()) + " bytes, the output has " + std::to_string(p->out_bytes));
  Check(clEnqueueReadBuffer(impl_->queue.get(), buffer, CL_TRUE, 0, out.size(), out.data(), 0, nullptr, nullptr),
        "launch", std::string("clEnqueueReadBuffer '") + (normals ? "out_normals" : "out_positions") + "' of " + p->key);
}

void* OpenClRunner::OutputBuffer(const OpenClPrepared& prepared, int set, bool normals) const {
  const OpenClPrepared::Impl::Set& s = SetOf(prepared, prepared.impl_.get(), set);
  return normals ? s.out_normals : s.out_positions;
}

void OpenClRunner::Finish() { Check(clFinish(impl_->queue.get()), "launch", "clFinish"); }

namespace {

constexpr const char* kCopyKernel = R"(// skintune copy bandwidth kernel
__kernel void skintune_copy(__global const uint4* restrict in, __global uint4* restrict out, const ulong n) {
  const size_t i = get_global_id(0);
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

std::vector<double> OpenClRunner::TimeCopy(std::size_t bytes, int warmup, int repetitions) {
  Impl& im = *impl_;
  bytes -= bytes % 16;
  if (bytes == 0) Fail("launch", "copy of less than 16 bytes");
  KernelSource source;
  source.lang = Lang::kOpenCl;
  source.entry_point = "skintune_copy";
  source.text = kCopyKernel;
  source.source_hash = SourceHash(source.text);
  const cl_kernel kernel = im.KernelFor(source);
  const std::vector<std::uint32_t> pattern = CopyPattern(bytes / 4);
  Memory in = im.Buffer(CL_MEM_READ_ONLY, bytes, pattern.data(), "copy source");
  Memory out = im.Buffer(CL_MEM_WRITE_ONLY, bytes, nullptr, "copy destination");
  const cl_ulong n = bytes / 16;
  const cl_mem in_mem = in.get(), out_mem = out.get();
  Check(clSetKernelArg(kernel, 0, sizeof(cl_mem), &in_mem), "launch", "clSetKernelArg 0 of the copy kernel");
  Check(clSetKernelArg(kernel, 1, sizeof(cl_mem), &out_mem), "launch", "clSetKernelArg 1 of the copy kernel");
  Check(clSetKernelArg(kernel, 2, sizeof(cl_ulong), &n), "launch", "clSetKernelArg 2 of the copy kernel");
  const std::size_t global = (n + 255) / 256 * 256;
  std::vector<Event> events;
  for (int r = 0; r < std::max(warmup, 0) + std::max(repetitions, 0); ++r) {
    const bool timed = r >= warmup;
    cl_event event = nullptr;
    Check(clEnqueueNDRangeKernel(im.queue.get(), kernel, 1, nullptr, &global, nullptr, 0, nullptr,
                                 timed ? &event : nullptr),
          "launch", "clEnqueueNDRangeKernel of the copy kernel (" + std::to_string(global) + " items)");
    if (timed) events.emplace_back(event);
  }
  Check(clFinish(im.queue.get()), "launch", "clFinish after the copy kernel");
  std::vector<double> ms;
  for (const Event& e : events) {
    cl_ulong start = 0, end = 0;
    clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_START, sizeof start, &start, nullptr);
    clGetEventProfilingInfo(e.get(), CL_PROFILING_COMMAND_END, sizeof end, &end, nullptr);
    ms.push_back(static_cast<double>(end - start) * 1e-6);
  }
  return ms;
}

}  // namespace skintune
