// skintune (internal): CUDA, loaded at run time.
//
// skintune builds without any CUDA toolkit: NVRTC (libnvrtc) and the driver
// API (libcuda) are opened with dlopen when first needed, and the few types
// and functions used are declared here, checked against CUDA 13's cuda.h and
// nvrtc.h (the driver ABI they follow has been stable since CUDA 4). A
// machine without CUDA still builds and runs everything else; these functions
// then say what is missing.
//
// - NVRTC: SKINTUNE_NVRTC_LIBRARY (a path or soname) when set, and then only
//   it; otherwise libnvrtc.so, libnvrtc.so.13, .12, .11.2, then
//   $CUDA_HOME/lib64/libnvrtc.so and /usr/local/cuda/lib64/libnvrtc.so.
//   NvrtcCandidates() lists them in that order.
// - Driver: libcuda.so.1, then libcuda.so (never the toolkit's stubs/, which
//   only link). cuInit(0) must succeed.
// Both are loaded once per process, thread-safely, and never unloaded.
#pragma once

#include <cstddef>
#include <string>
#include <type_traits>
#include <vector>

namespace skintune::internal {

struct CudaAvailability {
  bool nvrtc = false;                // NVRTC loaded and answered nvrtcVersion
  std::string nvrtc_library;         // the candidate that loaded
  int nvrtc_major = 0, nvrtc_minor = 0;
  std::string nvrtc_missing;         // why not: each candidate tried with dlopen's answer
  bool driver = false;               // libcuda loaded and cuInit(0) succeeded
  std::string driver_library;
  int driver_version = 0;            // cuDriverGetVersion: 13000 = CUDA 13.0
  int device_count = 0;
  std::string driver_missing;        // why no driver (or why cuInit failed)

  bool CanRun() const { return nvrtc && driver && device_count > 0; }
  // One line: what was found, or what is missing and why.
  std::string Describe() const;
};

// Loads (once) and reports. Never throws.
CudaAvailability Probe();

// The NVRTC libraries tried, in order (see the top of this file).
std::vector<std::string> NvrtcCandidates();

struct CompileResult {
  bool ok = false;
  std::string ptx;    // NUL-free PTX text when ok
  std::string log;    // NVRTC's whole log (warnings appear here even when ok)
  std::string error;  // when !ok: "NVRTC compile of NAME for ARCH failed (RESULT); log:" + the log's
                      // first 20 lines, or why NVRTC could not be loaded
  double seconds = 0.0;  // wall time of nvrtcCompileProgram
};

// Compiles CUDA C++ `source` (program name `name`, used in the log's
// locations) to PTX for `arch`, a virtual architecture such as "compute_90".
// Extra NVRTC `options` follow -arch. Never throws: errors are in the result.
CompileResult CompileWithNvrtc(const std::string& source, const std::string& arch,
                               const std::string& name = "skin.cu", const std::vector<std::string>& options = {});

// The virtual architecture NVRTC should compile for on a device of compute
// capability major.minor: "compute_<major><minor>" when NVRTC supports it,
// else the newest one it supports below that (the driver JIT-compiles PTX
// forward), else "" (the device is older than anything NVRTC supports).
// Without NVRTC's list (NVRTC < 11.2) the device's own.
std::string NvrtcArchFor(int major, int minor);

// ---------------------------------------------------------------- driver API
//
// The part of CUDA's driver API (cuda.h) that CudaRunner uses, declared here.
namespace cuda {

using Result = int;  // CUresult; 0 = CUDA_SUCCESS
using Device = int;
using Context = struct CUctx_st*;
using Module = struct CUmod_st*;
using Function = struct CUfunc_st*;
using Stream = struct CUstream_st*;
using Event = struct CUevent_st*;
using DevicePtr = unsigned long long;  // CUdeviceptr (64-bit)
using GraphicsResource = struct CUgraphicsResource_st*;
using TexObject = unsigned long long;  // CUtexObject = cudaTextureObject_t

inline constexpr Result kSuccess = 0;
inline constexpr unsigned kStreamNonBlocking = 1;  // CU_STREAM_NON_BLOCKING
inline constexpr unsigned kEventDisableTiming = 2;  // CU_EVENT_DISABLE_TIMING
inline constexpr unsigned kMemHostAllocWriteCombined = 4;  // CU_MEMHOSTALLOC_WRITECOMBINED
inline constexpr int kAttributeMaxThreadsPerBlock = 1;
inline constexpr int kAttributeMaxSharedMemoryPerBlock = 8;   // static __shared__ (48 KiB)
inline constexpr int kAttributeTotalConstantMemory = 9;
inline constexpr int kAttributeMaxTexture1dLinearWidth = 69;  // texels of a linear texture object
inline constexpr int kAttributeComputeCapabilityMajor = 75;
inline constexpr int kAttributeComputeCapabilityMinor = 76;
inline constexpr int kJitInfoLogBuffer = 3;            // CU_JIT_INFO_LOG_BUFFER
inline constexpr int kJitInfoLogBufferSizeBytes = 4;
inline constexpr int kJitErrorLogBuffer = 5;           // CU_JIT_ERROR_LOG_BUFFER
inline constexpr int kJitErrorLogBufferSizeBytes = 6;
inline constexpr int kResourceTypeLinear = 2;          // CU_RESOURCE_TYPE_LINEAR
inline constexpr int kArrayFormatFloat = 0x20;         // CU_AD_FORMAT_FLOAT
inline constexpr int kFilterModePoint = 0;             // CU_TR_FILTER_MODE_POINT
inline constexpr int kAddressModeClamp = 1;            // CU_TR_ADDRESS_MODE_CLAMP
inline constexpr unsigned kGraphicsRegisterWriteDiscard = 2;  // CU_GRAPHICS_REGISTER_FLAGS_WRITE_DISCARD
inline constexpr Result kErrorInvalidValue = 1;               // CUDA_ERROR_INVALID_VALUE
inline constexpr Result kErrorInvalidHandle = 400;            // CUDA_ERROR_INVALID_HANDLE
inline constexpr Result kErrorNotReady = 600;                 // CUDA_ERROR_NOT_READY: cuEventQuery on an event not yet complete

// CUDA_RESOURCE_DESC with its `linear` member (the only one used).
struct ResourceDesc {
  int resType = 0;
  struct Linear {
    DevicePtr devPtr;
    int format;
    unsigned int numChannels;
    std::size_t sizeInBytes;
  };
  union {
    Linear linear;
    int reserved[32];
  } res{};
  unsigned int flags = 0;
};
static_assert(sizeof(ResourceDesc) == 144, "CUDA_RESOURCE_DESC is 144 bytes");

// CUDA_TEXTURE_DESC.
struct TextureDesc {
  int addressMode[3] = {0, 0, 0};
  int filterMode = 0;
  unsigned int flags = 0;
  unsigned int maxAnisotropy = 0;
  int mipmapFilterMode = 0;
  float mipmapLevelBias = 0.0f;
  float minMipmapLevelClamp = 0.0f;
  float maxMipmapLevelClamp = 0.0f;
  float borderColor[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  int reserved[12] = {};
};
static_assert(sizeof(TextureDesc) == 104, "CUDA_TEXTURE_DESC is 104 bytes");

// Function pointers by their driver symbol (the _v2 names cuda.h maps to).
struct DriverApi {
  Result (*cuInit)(unsigned int flags);
  Result (*cuDriverGetVersion)(int* version);
  Result (*cuGetErrorName)(Result error, const char** name);
  Result (*cuGetErrorString)(Result error, const char** text);
  Result (*cuDeviceGetCount)(int* count);
  Result (*cuDeviceGet)(Device* device, int ordinal);
  Result (*cuDeviceGetName)(char* name, int length, Device device);
  Result (*cuDeviceGetAttribute)(int* value, int attribute, Device device);
  Result (*cuDevicePrimaryCtxRetain)(Context* context, Device device);
  Result (*cuDevicePrimaryCtxRelease)(Device device);                  // _v2
  Result (*cuCtxSetCurrent)(Context context);
  // A context of a runner's own (CudaRunner::OwnContext); null where the
  // driver lacks them, and such runners are then not offered.
  Result (*cuCtxCreate)(Context* context, unsigned int flags, Device device);  // _v2
  Result (*cuCtxDestroy)(Context context);                                     // _v2
  Result (*cuCtxSynchronize)();
  Result (*cuModuleLoadDataEx)(Module* module, const void* image, unsigned int option_count, int* options,
                               void** option_values);
  Result (*cuModuleUnload)(Module module);
  Result (*cuModuleGetFunction)(Function* function, Module module, const char* name);
  Result (*cuModuleGetGlobal)(DevicePtr* pointer, std::size_t* bytes, Module module, const char* name);  // _v2
  Result (*cuMemAlloc)(DevicePtr* pointer, std::size_t bytes);                                          // _v2
  Result (*cuMemFree)(DevicePtr pointer);                                                               // _v2
  Result (*cuMemcpyHtoD)(DevicePtr to, const void* from, std::size_t bytes);                            // _v2
  Result (*cuMemcpyDtoH)(void* to, DevicePtr from, std::size_t bytes);                                  // _v2
  Result (*cuLaunchKernel)(Function function, unsigned int grid_x, unsigned int grid_y, unsigned int grid_z,
                           unsigned int block_x, unsigned int block_y, unsigned int block_z,
                           unsigned int shared_bytes, Stream stream, void** parameters, void** extra);
  Result (*cuEventCreate)(Event* event, unsigned int flags);
  Result (*cuEventRecord)(Event event, Stream stream);
  Result (*cuEventSynchronize)(Event event);
  Result (*cuEventQuery)(Event event);  // kSuccess when complete, CUDA_ERROR_NOT_READY (600) while not
  Result (*cuEventElapsedTime)(float* ms, Event start, Event end);  // _v2 where the driver has it
  Result (*cuEventDestroy)(Event event);                            // _v2
  Result (*cuTexObjectCreate)(TexObject* object, const ResourceDesc* resource, const TextureDesc* texture,
                              const void* view);
  Result (*cuTexObjectDestroy)(TexObject object);
  // For the runtime's Skinner on a caller's context and stream.
  Result (*cuCtxGetDevice)(Device* device);
  Result (*cuStreamSynchronize)(Stream stream);
  Result (*cuMemcpyHtoDAsync)(DevicePtr to, const void* from, std::size_t bytes, Stream stream);  // _v2
  Result (*cuMemcpyDtoDAsync)(DevicePtr to, DevicePtr from, std::size_t bytes, Stream stream);    // _v2
  // The device's UUID (CUuuid: 16 bytes), to match it with the same chip in
  // other APIs; null where the driver has neither _v2 nor the plain symbol.
  Result (*cuDeviceGetUuid)(unsigned char* uuid16, Device device);
  // Timing's two lanes (runtime/backends/cuda/cuda_runner.cpp RunTimed).
  Result (*cuStreamCreate)(Stream* stream, unsigned int flags);
  Result (*cuStreamDestroy)(Stream stream);  // _v2
  Result (*cuStreamWaitEvent)(Stream stream, Event event, unsigned int flags);
  // The Skinner's page-locked staging (palette uploads, read-backs).
  Result (*cuMemcpyDtoHAsync)(void* to, DevicePtr from, std::size_t bytes, Stream stream);  // _v2
  Result (*cuMemHostAlloc)(void** pointer, std::size_t bytes, unsigned int flags);
  Result (*cuMemFreeHost)(void* pointer);
  // CUDA-OpenGL interop (Skinner::SkinIntoGlBuffer on a CUDA device, the
  // paper's section 4.1 path); null where the driver lacks them.
  Result (*cuGraphicsGLRegisterBuffer)(GraphicsResource* resource, unsigned int gl_buffer, unsigned int flags);
  Result (*cuGraphicsUnregisterResource)(GraphicsResource resource);
  Result (*cuGraphicsMapResources)(unsigned int count, GraphicsResource* resources, Stream stream);
  Result (*cuGraphicsUnmapResources)(unsigned int count, GraphicsResource* resources, Stream stream);
  Result (*cuGraphicsResourceGetMappedPointer)(DevicePtr* pointer, std::size_t* bytes, GraphicsResource resource);  // _v2
};

// The driver, loaded and initialised once; null, with the reason in `why`
// (when given), where there is none or cuInit fails.
const DriverApi* Driver(std::string* why = nullptr);

// "CUDA_ERROR_NAME (code): description" for a driver result.
std::string ErrorText(Result result);

// The driver results after which the context is unusable for good ("any
// further CUDA work will return the same error; the process must be
// terminated", the driver API's documentation): a kernel's illegal address,
// instruction or stack, misaligned or wrong-space access, bad PC, a failed or
// timed-out launch.
inline constexpr Result kContextLostResults[] = {700, 702, 714, 715, 716, 717, 718, 719};
constexpr bool ContextLost(Result r) {
  for (const Result lost : kContextLostResults)
    if (r == lost) return true;
  return false;
}

// Throws Error("CUDA <stage>: <message>"): the stages the tuner and the
// runtime map to statuses and error codes ("setup", "build", "launch", "guard",
// and "lost": Check's stage for a result of kContextLostResults, whatever the
// caller's).
[[noreturn]] void Fail(const std::string& stage, const std::string& message);
// Fail(stage, "<what> failed: <ErrorText(r)>") unless `r` is success.
void Check(Result r, const std::string& stage, const std::string& what);
// The same with the message built only on failure: the frame loop's calls
// (SetPalette, Skin) build no strings.
template <typename Message>
  requires std::is_invocable_r_v<std::string, Message>
void Check(Result r, const char* stage, Message&& what) {
  if (r != kSuccess) Check(r, stage, what());
}

}  // namespace cuda
}  // namespace skintune::internal
