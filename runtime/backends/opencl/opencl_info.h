// skintune (internal): an OpenCL platform's or device's string answer, read
// whole, for the backend's files that query one (its inventory, its runner,
// its GL sharing). Defined in opencl_devices.cpp.
#pragma once

#ifndef CL_TARGET_OPENCL_VERSION
#define CL_TARGET_OPENCL_VERSION 120
#endif
#include <CL/cl.h>

#include <string>

namespace skintune::internal {

// The answer to `what` up to its terminating NUL; "" where the query fails.
std::string PlatformString(cl_platform_id platform, cl_platform_info what);
std::string DeviceString(cl_device_id device, cl_device_info what);

}  // namespace skintune::internal
