#include <iostream>

#include "model/gltf_import.h"
#include "base/memory_limit.h"
#include "model/synthetic.h"
#include "tools/commands.h"

namespace skintune::internal::tools {

void AddMeshSourceOptions(CLI::App& sub, MeshSource& source) {
  auto* dataset = sub.add_option("--dataset", source.dataset,
                                 "synthetic dataset key: <vertices>-b<influences>[-bones<N>][-random][-seed<S>]"
                                 "[-rigid][-morph<T>][-normals|-tangents], e.g. 100k-b2, 1600k-b4-random; "
                                 "'default' = 100k-b2");
  auto* mesh = sub.add_option("--mesh", source.mesh_file, "glTF 2.0 file (.gltf or .glb) with a skinned mesh")
                   ->check(NonEmptyPath());
  dataset->excludes(mesh);
  mesh->excludes(dataset);
  sub.add_option("--mesh-name", source.mesh_name, "node or mesh name in the glTF file (default: first skinned)")
      ->needs(mesh);
  sub.add_flag("--strict", source.strict,
               "reject glTF weights that do not sum to 1 (default: renormalise them and warn)");
}

SkinnedAsset LoadAsset(const MeshSource& source, std::uint64_t work_bytes_per_vertex, const std::string& work) {
  if (!source.mesh_file.empty()) {
    GltfImportOptions options;
    options.mesh = source.mesh_name;
    options.strict = source.strict;
    options.normals = source.normals;
    options.tangents = source.tangents;
    GltfImportResult result = ImportGltf(source.mesh_file, options);
    for (const std::string& warning : result.warnings) std::cerr << "skintune: warning: " << warning << "\n";
    return std::move(result.asset);
  }
  if (source.tangents)
    throw Error("dataset '" + (source.dataset.empty() ? std::string("default") : source.dataset) +
                "': synthetic datasets have no tangents (--tangents needs a glTF mesh with TANGENT)");
  DatasetSpec spec = ParseDatasetKey(source.dataset.empty() ? "default" : source.dataset);
  spec.normals = spec.normals || source.normals;
  if (work_bytes_per_vertex > 0) {
    // The command's own needs on top of the mesh, before generating it.
    const std::uint64_t mesh = DatasetBytesPerVertex(spec);
    CheckMemoryFor("dataset '" + spec.Key() + "'", spec.vertices, mesh + work_bytes_per_vertex,
                   "mesh " + std::to_string(mesh) + " B + " + work + " " + std::to_string(work_bytes_per_vertex) +
                       " B per vertex",
                   HostMemoryAvailable());
  }
  return GenerateDataset(spec);
}

}  // namespace skintune::internal::tools
