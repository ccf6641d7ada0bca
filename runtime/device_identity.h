// skintune (internal): the parts of a device's identity that the tuner
// records and the runtime matches on (winners database keys), computed in one
// place so both agree: DeviceIdentity::Id() in the tuner and DeviceInfo::id in
// the runtime are "<backend>:<platform>/<name>/<driver_version>" with these.
#pragma once

#include <string>

namespace skintune {

// The CUDA device's driver version: "<kernel driver> (CUDA <major>.<minor>)",
// e.g. "580.159.04 (CUDA 13.0)", or "CUDA 13.0" alone when the kernel driver's
// version cannot be found (/proc/driver/nvidia/version, else NVML loaded at
// run time). `cuda_driver_version` is cuDriverGetVersion's (13000 = 13.0).
std::string CudaDriverVersionText(int cuda_driver_version);

// "cpu" for Mesa's software rasterisers (llvmpipe, softpipe, swrast, any
// renderer saying "software"), else "gpu".
std::string GlDeviceType(const std::string& renderer);

}  // namespace skintune
