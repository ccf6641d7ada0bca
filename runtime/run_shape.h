// skintune (internal): what one run of a packed mesh covers, checked once for
// the three kernel runners (OpenClRunner, CudaRunner, GlRunner).
//
// A run skins K instances of the mesh (docs/VARIANTS.md "Instancing"): with
// plain kernels K is 1; with instanced kernels (EmitOptions::instanced) each
// launch covers all K instances (a 2-D grid, or an instanced draw), reading K
// palettes one after another and writing K x vertex_count output vertices,
// instance after instance.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"

namespace skintune::internal {

struct RunShape {
  int instances = 1;              // K
  bool instanced = false;         // the kernels are instanced
  std::size_t palette_bytes = 0;  // one instance's palette
  std::size_t out_vertices = 0;   // K x vertex_count
  std::size_t out_bytes = 0;      // positions: out_vertices x output_stride_bytes (the guard follows)
  std::array<std::size_t, kOutputCount> output_bytes{};  // by Output: out_vertices x its stride; 0 where none is written
};

// Checks `kernels` (one per launch), `instances` and the bytes of the K
// palettes of a run and says what it covers. Throws Error("<api> launch: ...")
// for: a kernel count other than the launch count; instanced and plain kernels
// mixed; instances below 1; plain kernels with instances other than 1; K above
// a kernel's max_instances; K x vertex_count beyond 32-bit indices; and
// "palette has N bytes, expected ..." when `palettes_bytes` is not K palettes.
RunShape CheckRunShape(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::size_t palettes_bytes,
                       int instances, const std::string& api);

// The kernel of every launch: Emit(variant, launch.influences, palette_joints),
// instanced for `instances` (max_instances = instances) when instances > 0.
std::vector<KernelSource> EmitLaunchKernels(const PackedMesh& mesh, int instances = 0);

// `palettes`, or when empty the mesh's own palette once per instance.
std::vector<std::uint8_t> PalettesOrMeshPalette(const PackedMesh& mesh, std::span<const std::uint8_t> palettes,
                                                int instances);

}  // namespace skintune::internal
