#include "runtime/run_shape.h"

#include <algorithm>
#include <cstdint>
#include <limits>

#include "base/error.h"

namespace skintune::internal {

RunShape CheckRunShape(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::size_t palettes_bytes,
                       int instances, const std::string& api) {
  const auto fail = [&api](const std::string& message) { throw Error(api + " launch: " + message); };
  const Variant& variant = mesh.variant;
  if (kernels.size() != mesh.launches.size())
    fail(std::to_string(kernels.size()) + " kernels for " + std::to_string(mesh.launches.size()) + " launches of " +
         variant.Key());
  RunShape shape;
  shape.instanced = !kernels.empty() && kernels.front().instanced;
  for (const KernelSource& k : kernels) {
    if (k.instanced != shape.instanced) fail("instanced and plain kernels mixed in one run of " + variant.Key());
  }
  if (instances < 1) fail(std::to_string(instances) + " instances (at least 1)");
  if (!shape.instanced && instances != 1)
    fail(std::to_string(instances) + " instances with plain kernels (emit them instanced: EmitOptions::instanced)");
  for (const KernelSource& k : kernels) {
    if (k.max_instances > 0 && instances > k.max_instances)
      fail(std::to_string(instances) + " instances, but the kernel's constant palette holds " +
           std::to_string(k.max_instances) + " (emitted with max_instances " + std::to_string(k.max_instances) + ")");
  }
  const auto k = static_cast<std::size_t>(instances);
  if (mesh.vertex_count > std::numeric_limits<std::uint32_t>::max() / k)
    fail(std::to_string(instances) + " instances of " + std::to_string(mesh.vertex_count) +
         " vertices exceed 32-bit output indices");
  shape.instances = instances;
  const std::size_t rows = BytesOf(variant.palette) / 16;
  shape.palette_bytes = mesh.palette_joints * rows * 16;
  if (palettes_bytes != k * shape.palette_bytes)
    fail("palette has " + std::to_string(palettes_bytes) + " bytes, expected " +
         (k > 1 ? std::to_string(k) + " instances x " : std::string()) + std::to_string(mesh.palette_joints) +
         " joints x " + std::to_string(rows) + " rows x 16");
  shape.out_vertices = k * mesh.vertex_count;
  shape.out_bytes = shape.out_vertices * mesh.output_stride_bytes;
  for (const OutputSpec& o : kOutputs)
    if (Writes(variant, o.output))
      shape.output_bytes[static_cast<std::size_t>(o.output)] = shape.out_vertices * OutputStrideBytes(variant, o.output);
  return shape;
}

std::vector<KernelSource> EmitLaunchKernels(const PackedMesh& mesh, int instances) {
  EmitOptions options;
  options.instanced = instances > 0;
  options.max_instances = std::max(instances, 0);
  options.morph_targets = mesh.morph_targets;
  std::vector<KernelSource> kernels;
  for (const Launch& launch : mesh.launches)
    kernels.push_back(Emit(mesh.variant, launch.influences, static_cast<int>(mesh.palette_joints), options));
  return kernels;
}

std::vector<std::uint8_t> PalettesOrMeshPalette(const PackedMesh& mesh, std::span<const std::uint8_t> palettes,
                                                int instances) {
  if (!palettes.empty()) return {palettes.begin(), palettes.end()};
  std::vector<std::uint8_t> repeated;
  for (int i = 0; i < std::max(instances, 1); ++i) repeated.insert(repeated.end(), mesh.palette.begin(), mesh.palette.end());
  return repeated;
}

}  // namespace skintune::internal
