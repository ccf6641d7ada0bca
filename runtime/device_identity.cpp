#include "runtime/device_identity.h"

#include <dlfcn.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <sstream>

namespace skintune {

namespace {

// The kernel driver's version ("580.159.04"): from /proc/driver/nvidia/version,
// else from NVML (libnvidia-ml, loaded at run time like the rest of CUDA;
// containers often have no /proc entry), else empty (the CUDA version then
// stands alone). Looked up once per process.
std::string KernelDriverVersion() {
  static const std::string version = []() -> std::string {
    std::ifstream in("/proc/driver/nvidia/version");
    std::string line;
    if (std::getline(in, line)) {
      // "NVRM version: NVIDIA UNIX x86_64 Kernel Module  580.159.04  Tue ..."
      std::istringstream words(line);
      std::string word, previous;
      while (words >> word) {
        if (previous == "Module" && std::isdigit(static_cast<unsigned char>(word[0]))) return word;
        previous = word;
      }
    }
    void* nvml = dlopen("libnvidia-ml.so.1", RTLD_LAZY | RTLD_LOCAL);
    if (!nvml) return "";  // kept loaded when found: never unloaded, like libcuda
    using Call = int (*)();
    using DriverVersion = int (*)(char*, unsigned int);
    const auto init = reinterpret_cast<Call>(dlsym(nvml, "nvmlInit_v2"));
    const auto driver_version = reinterpret_cast<DriverVersion>(dlsym(nvml, "nvmlSystemGetDriverVersion"));
    const auto shutdown = reinterpret_cast<Call>(dlsym(nvml, "nvmlShutdown"));
    std::string found;
    if (init && driver_version && init() == 0) {  // NVML_SUCCESS
      char text[96] = {};
      if (driver_version(text, sizeof text - 1) == 0) found = text;
      if (shutdown) shutdown();
    }
    return found;
  }();
  return version;
}

std::string CudaVersion(int version) {
  return "CUDA " + std::to_string(version / 1000) + "." + std::to_string(version % 1000 / 10);
}

}  // namespace

std::string CudaDriverVersionText(int cuda_driver_version) {
  const std::string kernel_driver = KernelDriverVersion();
  const std::string cuda = CudaVersion(cuda_driver_version);
  return kernel_driver.empty() ? cuda : kernel_driver + " (" + cuda + ")";
}

std::string GlDeviceType(const std::string& renderer) {
  std::string lower = renderer;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const char* cpu : {"llvmpipe", "softpipe", "swrast", "software"})
    if (lower.find(cpu) != std::string::npos) return "cpu";
  return "gpu";
}

}  // namespace skintune
