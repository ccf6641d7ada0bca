#include "runtime/backends/cuda/cuda_api.h"

#include <dlfcn.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>

#include "base/error.h"
#include "runtime/output_check.h"

namespace skintune::internal {

namespace {

// ---------------------------------------------------------------- loading

// dlopen's answer for the last failure, or a placeholder.
std::string DlError() {
  const char* e = dlerror();
  return e ? e : "unknown dlopen error";
}

// Opens the first library of `candidates` that loads; `tried` collects
// "candidate: why not" for the others.
void* OpenFirst(const std::vector<std::string>& candidates, std::string& loaded, std::string& tried) {
  for (const std::string& c : candidates) {
    if (void* handle = dlopen(c.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      loaded = c;
      return handle;
    }
    tried += (tried.empty() ? "" : "; ") + DlError();
  }
  return nullptr;
}

// Resolves `name` in `handle` into `pointer`; appends to `missing` when absent.
template <typename F>
void Resolve(void* handle, const char* name, F& pointer, std::string& missing) {
  pointer = reinterpret_cast<F>(dlsym(handle, name));
  if (!pointer) missing += std::string(missing.empty() ? "" : ", ") + name;
}

// NVRTC's C API (nvrtc.h), as function pointers.
using NvrtcResult = int;  // 0 = NVRTC_SUCCESS
using NvrtcProgram = struct _nvrtcProgram*;
struct NvrtcApi {
  NvrtcResult (*nvrtcVersion)(int* major, int* minor);
  const char* (*nvrtcGetErrorString)(NvrtcResult result);
  NvrtcResult (*nvrtcCreateProgram)(NvrtcProgram* program, const char* source, const char* name, int header_count,
                                    const char* const* headers, const char* const* include_names);
  NvrtcResult (*nvrtcDestroyProgram)(NvrtcProgram* program);
  NvrtcResult (*nvrtcCompileProgram)(NvrtcProgram program, int option_count, const char* const* options);
  NvrtcResult (*nvrtcGetProgramLogSize)(NvrtcProgram program, std::size_t* bytes);
  NvrtcResult (*nvrtcGetProgramLog)(NvrtcProgram program, char* log);
  NvrtcResult (*nvrtcGetPTXSize)(NvrtcProgram program, std::size_t* bytes);
  NvrtcResult (*nvrtcGetPTX)(NvrtcProgram program, char* ptx);
  // Optional (NVRTC 11.2+).
  NvrtcResult (*nvrtcGetNumSupportedArchs)(int* count);
  NvrtcResult (*nvrtcGetSupportedArchs)(int* archs);
};

struct LoadedNvrtc {
  NvrtcApi api{};
  bool ok = false;
  std::string library, missing;
  int major = 0, minor = 0;
  std::vector<int> archs;  // supported compute capabilities (e.g. 90), ascending; empty if unknown
};

const LoadedNvrtc& Nvrtc() {
  static const LoadedNvrtc loaded = [] {
    LoadedNvrtc n;
    std::string tried;
    void* handle = OpenFirst(NvrtcCandidates(), n.library, tried);
    if (!handle) {
      n.missing = "NVRTC not found (tried " + tried + ")";
      return n;
    }
    std::string absent;
    NvrtcApi& a = n.api;
    Resolve(handle, "nvrtcVersion", a.nvrtcVersion, absent);
    Resolve(handle, "nvrtcGetErrorString", a.nvrtcGetErrorString, absent);
    Resolve(handle, "nvrtcCreateProgram", a.nvrtcCreateProgram, absent);
    Resolve(handle, "nvrtcDestroyProgram", a.nvrtcDestroyProgram, absent);
    Resolve(handle, "nvrtcCompileProgram", a.nvrtcCompileProgram, absent);
    Resolve(handle, "nvrtcGetProgramLogSize", a.nvrtcGetProgramLogSize, absent);
    Resolve(handle, "nvrtcGetProgramLog", a.nvrtcGetProgramLog, absent);
    Resolve(handle, "nvrtcGetPTXSize", a.nvrtcGetPTXSize, absent);
    Resolve(handle, "nvrtcGetPTX", a.nvrtcGetPTX, absent);
    if (!absent.empty()) {
      n.missing = n.library + " lacks " + absent;
      return n;
    }
    std::string optional;
    Resolve(handle, "nvrtcGetNumSupportedArchs", a.nvrtcGetNumSupportedArchs, optional);
    Resolve(handle, "nvrtcGetSupportedArchs", a.nvrtcGetSupportedArchs, optional);
    if (a.nvrtcVersion(&n.major, &n.minor) != 0) {
      n.missing = n.library + ": nvrtcVersion failed";
      return n;
    }
    int count = 0;
    if (a.nvrtcGetNumSupportedArchs && a.nvrtcGetSupportedArchs && a.nvrtcGetNumSupportedArchs(&count) == 0 &&
        count > 0) {
      n.archs.resize(static_cast<std::size_t>(count));
      if (a.nvrtcGetSupportedArchs(n.archs.data()) != 0) n.archs.clear();
      std::sort(n.archs.begin(), n.archs.end());
    }
    n.ok = true;
    return n;
  }();
  return loaded;
}

// "NAME (code): description" through the driver's own error tables.
std::string DriverErrorText(const cuda::DriverApi& a, cuda::Result result) {
  const char* name = nullptr;
  const char* text = nullptr;
  if (a.cuGetErrorName) a.cuGetErrorName(result, &name);
  if (a.cuGetErrorString) a.cuGetErrorString(result, &text);
  return std::string(name ? name : "CUDA error") + " (" + std::to_string(result) + ")" +
         (text ? std::string(": ") + text : std::string());
}

struct LoadedDriver {
  cuda::DriverApi api{};
  bool ok = false;
  std::string library, missing;
  int version = 0;
};

const LoadedDriver& DriverLibrary() {
  static const LoadedDriver loaded = [] {
    LoadedDriver d;
    std::string tried;
    void* handle = OpenFirst({"libcuda.so.1", "libcuda.so"}, d.library, tried);
    if (!handle) {
      d.missing = "no CUDA driver (tried " + tried + ")";
      return d;
    }
    std::string absent;
    cuda::DriverApi& a = d.api;
    Resolve(handle, "cuInit", a.cuInit, absent);
    Resolve(handle, "cuDriverGetVersion", a.cuDriverGetVersion, absent);
    Resolve(handle, "cuGetErrorName", a.cuGetErrorName, absent);
    Resolve(handle, "cuGetErrorString", a.cuGetErrorString, absent);
    Resolve(handle, "cuDeviceGetCount", a.cuDeviceGetCount, absent);
    Resolve(handle, "cuDeviceGet", a.cuDeviceGet, absent);
    Resolve(handle, "cuDeviceGetName", a.cuDeviceGetName, absent);
    Resolve(handle, "cuDeviceGetAttribute", a.cuDeviceGetAttribute, absent);
    Resolve(handle, "cuDevicePrimaryCtxRetain", a.cuDevicePrimaryCtxRetain, absent);
    Resolve(handle, "cuDevicePrimaryCtxRelease_v2", a.cuDevicePrimaryCtxRelease, absent);
    Resolve(handle, "cuCtxSetCurrent", a.cuCtxSetCurrent, absent);
    Resolve(handle, "cuCtxSynchronize", a.cuCtxSynchronize, absent);
    std::string no_own_contexts;  // optional: CudaRunner::OwnContext then fails to open
    Resolve(handle, "cuCtxCreate_v2", a.cuCtxCreate, no_own_contexts);
    Resolve(handle, "cuCtxDestroy_v2", a.cuCtxDestroy, no_own_contexts);
    Resolve(handle, "cuModuleLoadDataEx", a.cuModuleLoadDataEx, absent);
    Resolve(handle, "cuModuleUnload", a.cuModuleUnload, absent);
    Resolve(handle, "cuModuleGetFunction", a.cuModuleGetFunction, absent);
    Resolve(handle, "cuModuleGetGlobal_v2", a.cuModuleGetGlobal, absent);
    Resolve(handle, "cuMemAlloc_v2", a.cuMemAlloc, absent);
    Resolve(handle, "cuMemFree_v2", a.cuMemFree, absent);
    Resolve(handle, "cuMemcpyHtoD_v2", a.cuMemcpyHtoD, absent);
    Resolve(handle, "cuMemcpyDtoH_v2", a.cuMemcpyDtoH, absent);
    Resolve(handle, "cuLaunchKernel", a.cuLaunchKernel, absent);
    Resolve(handle, "cuEventCreate", a.cuEventCreate, absent);
    Resolve(handle, "cuEventRecord", a.cuEventRecord, absent);
    Resolve(handle, "cuEventSynchronize", a.cuEventSynchronize, absent);
    Resolve(handle, "cuEventQuery", a.cuEventQuery, absent);
    std::string old_driver;
    Resolve(handle, "cuEventElapsedTime_v2", a.cuEventElapsedTime, old_driver);  // CUDA 12.8+
    if (!a.cuEventElapsedTime) Resolve(handle, "cuEventElapsedTime", a.cuEventElapsedTime, absent);
    Resolve(handle, "cuEventDestroy_v2", a.cuEventDestroy, absent);
    Resolve(handle, "cuTexObjectCreate", a.cuTexObjectCreate, absent);
    Resolve(handle, "cuTexObjectDestroy", a.cuTexObjectDestroy, absent);
    Resolve(handle, "cuCtxGetDevice", a.cuCtxGetDevice, absent);
    Resolve(handle, "cuStreamSynchronize", a.cuStreamSynchronize, absent);
    Resolve(handle, "cuMemcpyHtoDAsync_v2", a.cuMemcpyHtoDAsync, absent);
    Resolve(handle, "cuStreamCreate", a.cuStreamCreate, absent);
    Resolve(handle, "cuStreamDestroy_v2", a.cuStreamDestroy, absent);
    Resolve(handle, "cuStreamWaitEvent", a.cuStreamWaitEvent, absent);
    std::string no_uuid;  // optional: the device is then matched by PCI bus id
    Resolve(handle, "cuDeviceGetUuid_v2", a.cuDeviceGetUuid, no_uuid);
    if (!a.cuDeviceGetUuid) Resolve(handle, "cuDeviceGetUuid", a.cuDeviceGetUuid, no_uuid);
    Resolve(handle, "cuMemcpyDtoDAsync_v2", a.cuMemcpyDtoDAsync, absent);
    Resolve(handle, "cuMemcpyDtoHAsync_v2", a.cuMemcpyDtoHAsync, absent);
    Resolve(handle, "cuMemHostAlloc", a.cuMemHostAlloc, absent);
    Resolve(handle, "cuMemFreeHost", a.cuMemFreeHost, absent);
    std::string no_gl;  // optional: SkinIntoGlBuffer on CUDA then says kUnavailable
    Resolve(handle, "cuGraphicsGLRegisterBuffer", a.cuGraphicsGLRegisterBuffer, no_gl);
    Resolve(handle, "cuGraphicsUnregisterResource", a.cuGraphicsUnregisterResource, no_gl);
    Resolve(handle, "cuGraphicsMapResources", a.cuGraphicsMapResources, no_gl);
    Resolve(handle, "cuGraphicsUnmapResources", a.cuGraphicsUnmapResources, no_gl);
    Resolve(handle, "cuGraphicsResourceGetMappedPointer_v2", a.cuGraphicsResourceGetMappedPointer, no_gl);
    if (!absent.empty()) {
      d.missing = d.library + " lacks " + absent;
      return d;
    }
    if (a.cuDriverGetVersion(&d.version) != cuda::kSuccess) d.version = 0;
    // Where the library loads but cannot serve (no GPU, the toolkit's stub), cuInit says why.
    const cuda::Result init = a.cuInit(0);
    if (init != cuda::kSuccess) {
      d.missing = "cuInit failed in " + d.library + ": " + DriverErrorText(a, init);
      return d;
    }
    d.ok = true;
    return d;
  }();
  return loaded;
}

}  // namespace

std::vector<std::string> NvrtcCandidates() {
  if (const char* pinned = std::getenv("SKINTUNE_NVRTC_LIBRARY"); pinned && *pinned) return {pinned};
  std::vector<std::string> c = {"libnvrtc.so", "libnvrtc.so.13", "libnvrtc.so.12", "libnvrtc.so.11.2"};
  if (const char* home = std::getenv("CUDA_HOME"); home && *home) c.push_back(std::string(home) + "/lib64/libnvrtc.so");
  c.push_back("/usr/local/cuda/lib64/libnvrtc.so");
  return c;
}

std::string CudaAvailability::Describe() const {
  std::string s = nvrtc ? "NVRTC " + std::to_string(nvrtc_major) + "." + std::to_string(nvrtc_minor) + " (" +
                              nvrtc_library + ")"
                        : nvrtc_missing;
  s += "; ";
  if (driver) {
    s += "CUDA driver " + std::to_string(driver_version / 1000) + "." + std::to_string(driver_version % 1000 / 10) +
         " (" + driver_library + "), " + std::to_string(device_count) + " device(s)";
  } else {
    s += driver_missing;
  }
  return s;
}

CudaAvailability Probe() {
  CudaAvailability a;
  const LoadedNvrtc& n = Nvrtc();
  a.nvrtc = n.ok;
  a.nvrtc_library = n.library;
  a.nvrtc_major = n.major;
  a.nvrtc_minor = n.minor;
  a.nvrtc_missing = n.missing;
  const LoadedDriver& d = DriverLibrary();
  a.driver_library = d.library;
  a.driver_version = d.version;
  a.driver_missing = d.missing;
  if (d.ok) {
    int count = 0;
    const cuda::Result r = d.api.cuDeviceGetCount(&count);
    if (r != cuda::kSuccess) {
      a.driver_missing = "cuDeviceGetCount failed: " + cuda::ErrorText(r);
    } else {
      a.driver = true;
      a.device_count = count;
      if (count == 0) a.driver_missing = "the CUDA driver sees no device";
    }
  }
  return a;
}

CompileResult CompileWithNvrtc(const std::string& source, const std::string& arch, const std::string& name,
                               const std::vector<std::string>& options) {
  CompileResult result;
  const LoadedNvrtc& n = Nvrtc();
  if (!n.ok) {
    result.error = n.missing;
    return result;
  }
  const NvrtcApi& a = n.api;
  const std::string where = "NVRTC compile of " + name + " for " + arch;
  NvrtcProgram program = nullptr;
  NvrtcResult r = a.nvrtcCreateProgram(&program, source.c_str(), name.c_str(), 0, nullptr, nullptr);
  if (r != 0) {
    result.error = where + ": nvrtcCreateProgram failed (" + a.nvrtcGetErrorString(r) + ")";
    return result;
  }
  std::vector<std::string> all = {"-arch=" + arch};
  all.insert(all.end(), options.begin(), options.end());
  std::vector<const char*> argv;
  for (const std::string& o : all) argv.push_back(o.c_str());

  const auto start = std::chrono::steady_clock::now();
  r = a.nvrtcCompileProgram(program, static_cast<int>(argv.size()), argv.data());
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  std::size_t size = 0;
  if (a.nvrtcGetProgramLogSize(program, &size) == 0 && size > 1) {
    result.log.assign(size, '\0');
    a.nvrtcGetProgramLog(program, result.log.data());
    result.log.resize(size - 1);  // the size counts the terminating NUL
  }
  if (r != 0) {
    result.error = where + " failed (" + a.nvrtcGetErrorString(r) + "); log:" + FirstLines(result.log, 20);
  } else if (a.nvrtcGetPTXSize(program, &size) != 0 || size == 0) {
    result.error = where + ": no PTX";
  } else {
    result.ptx.assign(size, '\0');
    a.nvrtcGetPTX(program, result.ptx.data());
    result.ptx.resize(size - 1);
    result.ok = true;
  }
  a.nvrtcDestroyProgram(&program);
  return result;
}

std::string NvrtcArchFor(int major, int minor) {
  const int wanted = major * 10 + minor;
  const LoadedNvrtc& n = Nvrtc();
  if (n.ok && !n.archs.empty()) {
    int best = 0;
    for (const int a : n.archs)
      if (a <= wanted) best = a;
    if (best == 0) return "";
    return "compute_" + std::to_string(best);
  }
  return "compute_" + std::to_string(wanted);
}

namespace cuda {

const DriverApi* Driver(std::string* why) {
  const LoadedDriver& d = DriverLibrary();
  if (!d.ok) {
    if (why) *why = d.missing;
    return nullptr;
  }
  return &d.api;
}

std::string ErrorText(Result result) { return DriverErrorText(DriverLibrary().api, result); }

void Fail(const std::string& stage, const std::string& message) { throw Error("CUDA " + stage + ": " + message); }

void Check(Result r, const std::string& stage, const std::string& what) {
  if (r != kSuccess) Fail(ContextLost(r) ? "lost" : stage, what + " failed: " + ErrorText(r));
}

}  // namespace cuda
}  // namespace skintune::internal
