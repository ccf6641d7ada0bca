// skintune (internal): runs emitted OpenCL kernels on a packed mesh, with the
// checks a tuner needs to trust a result.
//
// - Build: each distinct KernelSource is built once per runner; a failure
//   throws Error("OpenCL build ...") with the first lines of the build log.
// - Outputs are POISONED before every run (every 32-bit word 0x7fc00000, a
//   quiet NaN), so a vertex a kernel forgets to write reads back as NaN and
//   fails the comparison with the gold instead of passing on stale data.
// - Each output buffer is followed by a GUARD of kGuardBytes filled with a
//   known pattern; a kernel that writes past the end throws Error("OpenCL
//   guard ...") after the run. (Poison and guard: runtime/output_check.h.)
// - Every Launch of the PackedMesh runs with its own kernel (bucketed: one
//   specialised per influence count), arguments bound by name from the
//   kernel's argument list (docs/VARIANTS.md order), palette as a buffer or,
//   for `image` storage, an image1d_buffer (CL_RGBA / CL_FLOAT) over it.
// Errors name the stage: "OpenCL setup", "build", "launch" or "guard".
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"

namespace skintune {

struct OpenClRunResult {
  std::vector<std::uint8_t> positions;  // vertex_count x output_stride_bytes, packed order (Unpack it)
  std::vector<std::uint8_t> normals;    // likewise; empty without normals
  std::vector<double> launch_ms;        // per launch, profiling end - start
  std::size_t poisoned_vertices = 0;    // output vectors (positions, normals) still holding the poison
};

class OpenClRunner {
 public:
  // The device `device_index` of platform `platform_index` (as enumerated by
  // EnumerateOpenCl). Throws Error("OpenCL setup: ...") when it does not exist.
  OpenClRunner(int platform_index, int device_index);
  ~OpenClRunner();
  OpenClRunner(const OpenClRunner&) = delete;
  OpenClRunner& operator=(const OpenClRunner&) = delete;

  const std::string& device_name() const;

  // Builds (or finds already built) `source`; throws Error("OpenCL build ...").
  void Build(const KernelSource& source);

  // Emits the variant's kernel for every launch (Emit(variant, launch.influences,
  // palette_joints)) and runs them. `palette`: PackPalette bytes; empty = mesh.palette.
  OpenClRunResult Run(const PackedMesh& mesh, std::span<const std::uint8_t> palette = {});

  // Runs with the given kernels, one per launch, in launch order.
  OpenClRunResult Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                      std::span<const std::uint8_t> palette = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace skintune
