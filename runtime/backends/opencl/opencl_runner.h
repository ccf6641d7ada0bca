// skintune (internal): the runner driver (runtime/runner.h) on an OpenCL
// device. Its DeviceApi (opencl_runner.cpp):
//
// - Build: clCreateProgramWithSource + clBuildProgram ("-cl-std=CL1.2"), or
//   the program binary from the program cache (CL_PROGRAM_BINARIES, loaded
//   with clCreateProgramWithBinary; a binary the driver refuses is rebuilt);
//   a failure throws Error("OpenCL build ...") with the first lines of the
//   build log.
// - Palette: a buffer; for `image` storage an image1d_buffer (CL_RGBA /
//   CL_FLOAT) over it. K palettes larger than the device's __constant buffer
//   or image buffer limit throw Error("OpenCL launch ...") naming the limit.
// - Launches: arguments set by name per launch (one cl_kernel per program,
//   shared by every input set); instanced kernels a 2-D NDRange (items, K).
// - Times: profiling events (the queue needs CL_QUEUE_PROFILING_ENABLE).
// - Skinning: each palette slot keeps a page-locked staging buffer
//   (CL_MEM_ALLOC_HOST_PTR, mapped once) that a non-blocking
//   clEnqueueWriteBuffer uploads from; read-backs go through one kept per
//   output; the ring's fences are marker events (and a clFlush); LaunchSet
//   may write the positions into another cl_mem (OpenCL-GL sharing:
//   opencl_gl_sharing.h).
// Errors name the stage: "OpenCL setup", "build", "launch" or "guard".
#pragma once

#include "runtime/runner.h"

namespace skintune::internal {

class OpenClApi;

class OpenClRunner final : public Runner {
 public:
  // The device `device_index` of platform `platform_index` (as enumerated by
  // EnumerateOpenCl). Throws Error("OpenCL setup: ...") when it does not exist.
  OpenClRunner(int platform_index, int device_index);
  // A device, context and in-order queue the caller made (cl_device_id,
  // cl_context, cl_command_queue): retained here, released by the
  // destructor. Throws Error("OpenCL setup: ...") for a null handle or a
  // device that is not in the context. Time needs a queue with profiling.
  OpenClRunner(void* cl_device, void* cl_context, void* cl_queue);

  void* device() const;   // cl_device_id
  void* context() const;  // cl_context
  void* queue() const;    // cl_command_queue

 private:
  const OpenClApi& cl() const;
};

using OpenClRunResult = RunResult;
using OpenClPrepared = Prepared;

}  // namespace skintune::internal
