// The public Device (skintune/skintune.h): discovery, opening, and adopting
// handles the caller already has.
#include "runtime/device.h"

#include <algorithm>
#include <cctype>
#include <functional>
#include <utility>

#include "runtime/api_errors.h"
#include "runtime/backends/cuda/cuda_api.h"
#include "runtime/device_identity.h"
#include "runtime/backends/gl/gl_context.h"
#include "runtime/backends/opencl/opencl_gl_sharing.h"
#include "runtime/selection.h"
#include "runtime/winners_db.h"

namespace skintune {

namespace {

// A device of Device::List() and how to open it.
struct Listed {
  DeviceInfo info;
  std::function<void(DeviceState&)> open;  // sets the runner and limits; throws Error
};

// A DeviceInfo with its id "<backend>:<platform>/<name>/<driver>" (the database key).
DeviceInfo Info(Backend backend, std::string platform, std::string vendor, std::string name, std::string driver,
                std::string type) {
  DeviceInfo i;
  i.backend = backend;
  i.platform = std::move(platform);
  i.vendor = std::move(vendor);
  i.name = std::move(name);
  i.driver_version = std::move(driver);
  i.type = std::move(type);
  i.id = JoinDeviceId({BackendName(backend), i.platform, i.name, i.driver_version});
  return i;
}

DeviceInfo CudaInfo(const CudaDeviceInfo& d) {
  return Info(Backend::kCuda, "CUDA", "NVIDIA", d.name, CudaDriverVersionText(d.driver_version), "gpu");
}

DeviceInfo GlInfo(const GlContextInfo& c) {
  // GL_VERSION names the driver: "4.5 (Core Profile) Mesa 22.3.6"
  return Info(Backend::kGl, c.egl_platform, c.vendor, c.renderer, c.version, GlDeviceType(c.renderer));
}

// Every device, or only those of `only` (the others are not even looked for).
std::vector<Listed> Discover(const Backend* only = nullptr) {
  auto wanted = [&](Backend b) { return !only || *only == b; };
  std::vector<Listed> out;
  for (const OpenClDeviceInfo& d : wanted(Backend::kOpenCl) ? EnumerateOpenCl().devices : std::vector<OpenClDeviceInfo>{}) {
    out.push_back({PublicInfo(d), [d](DeviceState& s) {
                     s.opencl = std::make_unique<OpenClRunner>(d.platform_index, d.device_index);
                     s.limits = LimitsOf(d);
                   }});
  }
  if (wanted(Backend::kCuda) && Probe().CanRun()) {
    for (int c = 0; c < Probe().device_count; ++c) {
      try {
        const CudaDeviceInfo d = QueryCudaDevice(c);
        out.push_back({CudaInfo(d), [c](DeviceState& s) {
                         s.cuda = std::make_unique<CudaRunner>(c);
                         s.limits = s.cuda->limits();
                       }});
      } catch (const Error&) {
        // A device the driver cannot describe is not offered.
      }
    }
  }
  if (wanted(Backend::kGl)) {
    CurrentGlRestorer keep_callers_context;
    GlContext context;
    if (context.ok()) {
      out.push_back({GlInfo(context.info()), [](DeviceState& s) {
                       s.gl = std::make_unique<GlRunner>();
                       s.limits = LimitsOf(s.gl->info());
                     }});
    }
  }
  return out;
}

// OpenBest's order: GPUs first (CUDA, then OpenCL, then GL), then OpenCL CPUs,
// then other OpenCL devices, then GL on a CPU.
int Preference(const DeviceInfo& d) {
  const bool gpu = d.type.find("gpu") != std::string::npos;
  switch (d.backend) {
    case Backend::kCuda: return 0;
    case Backend::kOpenCl: return gpu ? 1 : d.type.find("cpu") != std::string::npos ? 3 : 4;
    case Backend::kGl: return gpu ? 2 : 5;
  }
  return 6;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

Device Opened(const Listed& listed, const DeviceOptions& options) {
  auto state = std::make_shared<DeviceState>(options);
  state->info = listed.info;
  state->langs = LanguagesOf(listed.info.backend);
  listed.open(*state);
  if (state->opencl) state->opencl->UseProgramCache(&state->cache, state->info.id);
  if (state->cuda) state->cuda->UseProgramCache(&state->cache, state->info.id);
  if (state->gl) state->gl->UseProgramCache(&state->cache, state->info.id);
  return DeviceAccess::Make(std::move(state));
}

std::string Names(const std::vector<Listed>& devices) {
  std::string out;
  for (const Listed& d : devices) out += (out.empty() ? "" : ", ") + d.info.id;
  return out.empty() ? "none found" : out;
}

}  // namespace

DeviceInfo PublicInfo(const OpenClDeviceInfo& d) {
  return Info(Backend::kOpenCl, d.platform_name, d.vendor, d.name, d.driver_version, d.type);
}

Device::Device() = default;
Device::~Device() = default;
Device::Device(Device&&) noexcept = default;
Device& Device::operator=(Device&&) noexcept = default;

Device DeviceAccess::Make(std::shared_ptr<DeviceState> state) {
  Device device;
  device.impl_ = std::make_unique<Device::Impl>();
  device.impl_->state = std::move(state);
  return device;
}

const std::shared_ptr<DeviceState>* DeviceAccess::State(const Device& device) {
  return device.impl_ ? &device.impl_->state : nullptr;
}

const DeviceInfo& Device::info() const {
  static const DeviceInfo none;
  return impl_ ? impl_->state->info : none;
}

ProgramCacheStats Device::cache_stats() const {
  if (!impl_) return {};
  const ProgramCacheCounters& c = impl_->state->cache.counters();
  return {c.builds, c.disk_hits, c.memory_hits};
}

bool Device::has_gl_sharing() const { return impl_ && impl_->state->gl_sharing; }

std::vector<DeviceInfo> Device::List() {
  std::vector<DeviceInfo> out;
  try {
    for (const Listed& d : Discover()) out.push_back(d.info);
  } catch (...) {
    // Discovery reports absent backends by leaving them out; it never fails.
  }
  return out;
}

Result<Device> Device::OpenBest(const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    std::vector<Listed> devices = Discover();
    if (devices.empty())
      FailWith(ErrorCode::kNotFound, "Device::OpenBest: no OpenCL, CUDA or GL device on this machine");
    std::stable_sort(devices.begin(), devices.end(),
                     [](const Listed& a, const Listed& b) { return Preference(a.info) < Preference(b.info); });
    std::string failures;
    for (const Listed& d : devices) {
      try {
        return Opened(d, options);
      } catch (const Error& e) {
        failures += std::string(failures.empty() ? "" : "; ") + d.info.id + ": " + e.what();
      }
    }
    FailWith(ErrorCode::kDeviceError, "Device::OpenBest: no device could be opened: " + failures);
  });
}

Result<Device> Device::Open(const std::string& pattern, const Backend* backend, const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    const std::vector<Listed> devices = Discover(backend);
    const std::string wanted = Lower(pattern);
    for (const Listed& d : devices) {
      if (backend && d.info.backend != *backend) continue;
      const DeviceInfo& i = d.info;
      for (const std::string& field : {i.id, i.name, i.vendor, i.platform}) {
        if (Lower(field).find(wanted) != std::string::npos) return Opened(d, options);
      }
    }
    FailWith(ErrorCode::kNotFound, "Device::Open: no " + (backend ? std::string(BackendName(*backend)) + " " : "") +
                                       "device matches '" + pattern + "' (devices: " + Names(devices) + ")");
  });
}

Result<Device> Device::FromOpenCl(void* cl_device, void* cl_context, void* cl_queue, const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kInvalidArgument, [&] {
    auto state = std::make_shared<DeviceState>(options);
    const OpenClDeviceInfo described = DescribeOpenClDevice(cl_device);
    state->opencl = std::make_unique<OpenClRunner>(cl_device, cl_context, cl_queue);
    state->info = PublicInfo(described);
    state->limits = LimitsOf(described);
    state->langs = LanguagesOf(Backend::kOpenCl);
    state->gl_sharing = OpenClContextSharesGl(cl_context);
    state->opencl->UseProgramCache(&state->cache, state->info.id);
    return DeviceAccess::Make(std::move(state));
  });
}

}  // namespace skintune

namespace skintune {

Result<Device> Device::FromCuda(void* cu_context, void* cu_stream, const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    const CudaAvailability available = Probe();
    if (!available.driver) FailWith(ErrorCode::kUnavailable, "Device::FromCuda: " + available.driver_missing);
    if (!available.nvrtc) FailWith(ErrorCode::kUnavailable, "Device::FromCuda: " + available.nvrtc_missing);
    if (!cu_context) FailWith(ErrorCode::kInvalidArgument, "Device::FromCuda: a null CUcontext");
    auto state = std::make_shared<DeviceState>(options);
    state->cuda = std::make_unique<CudaRunner>(cu_context, cu_stream);
    state->info = CudaInfo(state->cuda->info());
    state->limits = state->cuda->limits();
    state->langs = LanguagesOf(Backend::kCuda);
    state->cuda->UseProgramCache(&state->cache, state->info.id);
    return DeviceAccess::Make(std::move(state));
  });
}

Result<Device> Device::OpenClForCurrentGl(const DeviceOptions& options) {
  std::string why;
  const OpenClGlHandles handles = OpenClContextForCurrentGl(why);
  if (!handles.context) return Status(ErrorCode::kUnavailable, "Device::OpenClForCurrentGl: " + why);
  Result<Device> device = FromOpenCl(handles.device, handles.context, handles.queue, options);
  Release(handles);  // the Device holds its own references
  return device;
}

Result<Device> Device::FromCurrentGl(const DeviceOptions& options) {
  return GuardedResult<Device>(ErrorCode::kDeviceError, [&] {
    std::unique_ptr<GlContext> context = GlContext::AdoptCurrent();
    if (!context->ok()) FailWith(ErrorCode::kUnavailable, "Device::FromCurrentGl: " + context->reason());
    auto state = std::make_shared<DeviceState>(options);
    state->info = GlInfo(context->info());
    state->limits = LimitsOf(context->info());
    state->langs = LanguagesOf(Backend::kGl);
    state->gl = std::make_unique<GlRunner>(std::move(context));
    state->gl->UseProgramCache(&state->cache, state->info.id);
    return DeviceAccess::Make(std::move(state));
  });
}

}  // namespace skintune
