// skintune (internal): what a Skinner is made of.
//
// Skinner::Create (skinner.cpp) does everything that is the same on every
// backend: it validates the MeshView into a SkinnedMesh, chooses the variant
// (Select with the constraints of the real device and mesh), packs the mesh
// and emits the kernels. A SkinnerBackend (skinner_opencl.cpp, ...) then owns
// the device buffers: it uploads the packed inputs once through its runner's
// Prepare, and per frame writes the palette, launches and reads back, all in
// the packed vertex order; Skinner puts read-backs into the mesh's order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"
#include "runtime/device.h"
#include "skintune/skintune.h"

namespace skintune {

class SkinnerBackend {
 public:
  virtual ~SkinnerBackend() = default;
  // Throws ApiError(kInvalidState) when the backend cannot be used now (GL:
  // its context is not current on this thread).
  virtual void CheckUsable() const {}
  // Every instance's palette, one after another (PackPalette of K x J matrices).
  virtual void WritePalette(std::span<const std::uint8_t> packed_palettes) = 0;
  virtual void Skin() = 0;
  // Waits until every Skin() so far has completed on the device.
  virtual void Finish() = 0;
  // The positions (or normals) in packed order, instance after instance:
  // instances x vertex_count x output stride.
  virtual void Read(bool normals, std::span<std::uint8_t> out) = 0;
  virtual void* DevicePositions() const = 0;
  // Default: kUnavailable.
  virtual void SkinIntoGlBuffer(unsigned int gl_buffer);
};

// Each throws ApiError: kBuildFailed when a kernel does not compile,
// kDeviceError when the device refuses (allocation, launch set-up).
// `kernels`: one per launch, instanced when `instances` > 1.
std::unique_ptr<SkinnerBackend> MakeOpenClSkinner(DeviceState& device, const PackedMesh& mesh,
                                                  const std::vector<KernelSource>& kernels, int instances);

std::unique_ptr<SkinnerBackend> MakeCudaSkinner(DeviceState& device, const PackedMesh& mesh,
                                                const std::vector<KernelSource>& kernels, int instances);

std::unique_ptr<SkinnerBackend> MakeGlSkinner(DeviceState& device, const PackedMesh& mesh,
                                              const std::vector<KernelSource>& kernels, int instances);

// The code for a runner's Error: its message names the stage ("OpenCL
// build: ...", "CUDA setup: ..."): build -> kBuildFailed, else kDeviceError.
ErrorCode CodeOfRunnerError(const std::string& message);

struct Skinner::Impl {
  std::shared_ptr<DeviceState> device;  // keeps the runner (and its programs) alive
  Selection selection;
  Variant variant;
  std::size_t vertex_count = 0;
  int joint_count = 0;
  int instances = 1;
  std::size_t output_stride = 0;
  std::vector<std::uint32_t> order;     // packed position p holds mesh vertex order[p]
  bool palette_set = false;
  bool skinned = false;
  std::vector<std::uint8_t> scratch;    // read-back in packed order
  std::unique_ptr<SkinnerBackend> backend;  // declared last: destroyed before `device`
};

}  // namespace skintune
