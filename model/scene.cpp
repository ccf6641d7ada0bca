// skintune: scenes (see scene.h).
#include "model/scene.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <filesystem>
#include <string_view>

#include "base/error.h"
#include "model/gltf_import.h"
#include "model/synthetic.h"

namespace skintune::internal {

namespace {

// A glTF data set's TANGENT where every primitive has it, so that tangent variants can be tuned on it.
GltfImportOptions WithTangentsWhenPresent() {
  GltfImportOptions options;
  options.tangents_when_present = true;
  return options;
}

constexpr int kMaxInstances = 65536;
constexpr int kMaxJoints = 65536;  // SkinnedMesh stores joint indices in 16 bits
constexpr int kMixMinBones = 20;
constexpr int kMixMaxBones = 77;

[[noreturn]] void BadScene(const std::string& key, const std::string& what) {
  throw Error("scene '" + key + "': " + what);
}

// splitmix64: the mix's sizes, bone counts and seeds, the same on every machine.
std::uint64_t NextRandom(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// "mix<N>-b<B>[-seed<S>][-random][-normals]" -> the synthetic keys of its meshes.
std::vector<std::string> MixMeshes(const std::string& scene_key, const std::string& mix) {
  const std::string rest = mix.substr(3);
  if (rest.find("bones") != std::string::npos)
    BadScene(scene_key, "'" + mix + "': a mix chooses each mesh's bone count (" + std::to_string(kMixMinBones) + ".." +
                            std::to_string(kMixMaxBones) + "); '-bones' is not an option of it");
  DatasetSpec spec;
  try {
    spec = ParseDatasetKey(rest);
  } catch (const Error& e) {
    BadScene(scene_key, "'" + mix + "': expected mix<vertices>-b<influences>[-seed<S>][-random][-normals]: " + e.what());
  }
  if (spec.vertices < 2 * kMixMinVertices)
    BadScene(scene_key, "'" + mix + "': a mix holds at least two meshes of " + std::to_string(kMixMinVertices) +
                            " vertices (" + std::to_string(2 * kMixMinVertices) + " in all)");
  std::uint64_t state = spec.seed * 0xA24BAED4963EE407ull + spec.vertices;
  std::vector<std::string> keys;
  std::size_t remaining = spec.vertices;
  auto add = [&](std::size_t vertices) {
    DatasetSpec mesh = spec;
    mesh.vertices = vertices;
    mesh.influences = 1 + static_cast<int>(keys.size() % static_cast<std::size_t>(spec.influences));
    mesh.bones = kMixMinBones + static_cast<int>(NextRandom(state) % (kMixMaxBones - kMixMinBones + 1));
    mesh.influences = std::min(mesh.influences, mesh.bones);
    mesh.seed = spec.seed * 1000 + keys.size() + 1;
    keys.push_back(mesh.Key());
    remaining -= vertices;
  };
  // Each mesh leaves at least kMixMinVertices for the last, which is at most kMixMaxVertices.
  while (remaining > kMixMaxVertices) {
    const std::size_t most = std::min(kMixMaxVertices, remaining - kMixMinVertices);
    add(kMixMinVertices + NextRandom(state) % (most - kMixMinVertices + 1));
  }
  if (keys.empty()) {  // at most kMixMaxVertices in all: two meshes
    add(kMixMinVertices + NextRandom(state) % (remaining - 2 * kMixMinVertices + 1));
  }
  add(remaining);
  return keys;
}

// A mesh of a scene: a synthetic key (checked now) or a glTF path (read by LoadScene).
void CheckMesh(const std::string& scene_key, const std::string& mesh) {
  if (IsGltfFile(mesh)) return;
  try {
    (void)ParseDatasetKey(mesh);
  } catch (const Error&) {
    if (mesh == scene_key) throw;  // a scene of one mesh: the dataset's own message
    throw;
  }
}

}  // namespace

bool IsGltfFile(const std::string& key) {
  std::string extension = std::filesystem::path(key).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension == ".gltf" || extension == ".glb";
}

SceneSpec ParseSceneKey(const std::string& key) {
  SceneSpec spec;
  spec.key = key;
  if (key.empty()) BadScene(key, "empty key");
  for (const std::string_view suffix : {std::string_view("-anim"), std::string_view("-animblend")}) {
    if (key.size() <= suffix.size() || !key.ends_with(suffix)) continue;
    spec.animated = true;
    spec.blended = suffix == "-animblend";
  }
  const std::size_t suffix = spec.animated ? (spec.blended ? 10 : 5) : 0;
  const std::string meshes = key.substr(0, key.size() - suffix);
  if (spec.animated && (meshes.find('+') != std::string::npos || meshes.rfind("mix", 0) == 0))
    BadScene(key, "'" + key.substr(key.size() - suffix) + "' animates a scene of one mesh or its instances, not a batch");
  std::vector<std::string> parts;
  for (std::size_t start = 0;;) {
    const std::size_t plus = meshes.find('+', start);
    parts.push_back(meshes.substr(start, plus == std::string::npos ? std::string::npos : plus - start));
    if (plus == std::string::npos) break;
    start = plus + 1;
  }
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    if (part.empty()) BadScene(key, "meshes[" + std::to_string(i) + "] is empty (a stray '+')");
    // "-x<K>": instances, only of a scene of one mesh.
    const std::size_t dash = part.rfind("-x");
    const bool instanced = dash != std::string::npos && dash + 2 < part.size() && !IsGltfFile(part) &&
                           std::all_of(part.begin() + static_cast<std::ptrdiff_t>(dash + 2), part.end(),
                                       [](unsigned char c) { return std::isdigit(c); });
    if (instanced) {
      if (parts.size() > 1)
        BadScene(key, "meshes[" + std::to_string(i) + "] '" + part +
                          "': a batch's meshes are skinned once each (instances '-x<K>' only of a scene of one mesh)");
      const std::string count = part.substr(dash + 2);
      if (count.size() > 6 || std::stoul(count) < 2 || std::stoul(count) > kMaxInstances)
        BadScene(key, "instances '" + count + "' outside 2.." + std::to_string(kMaxInstances));
      spec.instances = static_cast<int>(std::stoul(count));
      spec.meshes.push_back(part.substr(0, dash));
      CheckMesh(key, spec.meshes.back());
      continue;
    }
    if (part.rfind("mix", 0) == 0 && !IsGltfFile(part)) {
      for (std::string& mesh : MixMeshes(key, part)) spec.meshes.push_back(std::move(mesh));
      spec.batch = true;
      continue;
    }
    CheckMesh(key, part);
    spec.meshes.push_back(part);
  }
  if (parts.size() > 1) spec.batch = true;
  return spec;
}

MeshBatch ConcatenateMeshes(std::span<const SkinnedMesh* const> meshes) {
  if (meshes.empty()) throw Error("meshes: the batch is empty");
  MeshBatch batch;
  SkinnedMesh& out = batch.mesh;
  out.name = "batch";
  std::size_t vertices = 0;
  long long joints = 0;
  bool normals = true, tangents = true;
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const SkinnedMesh& mesh = *meshes[m];
    const std::string where = "meshes[" + std::to_string(m) + "]";
    if (mesh.vertex_count() == 0) throw Error(where + ": no vertices");
    if (mesh.joint_count < 1) throw Error(where + ": no joints");
    if (mesh.has_morph())
      throw Error(where + ": " + std::to_string(mesh.morph.count()) +
                  " morph targets: a batch skins meshes without morph targets");
    batch.vertex_offsets.push_back(vertices);
    batch.joint_offsets.push_back(static_cast<int>(joints));
    vertices += mesh.vertex_count();
    joints += mesh.joint_count;
    if (joints > kMaxJoints)
      throw Error(where + ": the batch's joints reach " + std::to_string(joints) + " with this mesh's " +
                  std::to_string(mesh.joint_count) + ", above " + std::to_string(kMaxJoints) +
                  " (joint indices are 16-bit)");
    out.influences = std::max(out.influences, mesh.influences);
    normals = normals && mesh.has_normals();
    tangents = tangents && mesh.has_tangents();
  }
  tangents = tangents && normals;
  batch.vertex_offsets.push_back(vertices);
  batch.joint_offsets.push_back(static_cast<int>(joints));
  out.joint_count = static_cast<int>(joints);
  const auto b = static_cast<std::size_t>(out.influences);
  out.positions.reserve(vertices);
  if (normals) out.normals.reserve(vertices);
  if (tangents) out.tangents.reserve(vertices);
  out.joints.reserve(vertices * b);
  out.weights.reserve(vertices * b);
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const SkinnedMesh& mesh = *meshes[m];
    const auto offset = static_cast<std::uint16_t>(batch.joint_offsets[m]);
    const auto mb = static_cast<std::size_t>(mesh.influences);
    out.positions.insert(out.positions.end(), mesh.positions.begin(), mesh.positions.end());
    if (normals) out.normals.insert(out.normals.end(), mesh.normals.begin(), mesh.normals.end());
    if (tangents) out.tangents.insert(out.tangents.end(), mesh.tangents.begin(), mesh.tangents.end());
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      for (std::size_t i = 0; i < b; ++i) {
        // Padding slots: weight 0 on the mesh's own first joint.
        out.joints.push_back(static_cast<std::uint16_t>(offset + (i < mb ? mesh.joints[v * mb + i] : 0)));
        out.weights.push_back(i < mb ? mesh.weights[v * mb + i] : 0.0f);
      }
    }
  }
  return batch;
}

namespace {

// A mesh whose morph targets are animated and whose default weights are all
// 0 would be verified with none of them applied: it takes the first clip's
// weights at its middle (where the tuner's bad-input check samples the
// palette), so the tuner verifies the morph arithmetic.
void WeighMorphTargetsForTuning(SkinnedAsset& asset) {
  MorphTargets& morph = asset.mesh.morph;
  if (!asset.mesh.has_morph() || asset.animations.empty()) return;
  if (std::any_of(morph.weights.begin(), morph.weights.end(), [](double w) { return w != 0.0; })) return;
  const AnimationClip& clip = asset.animations.front();
  morph.weights = asset.MorphWeightsAt(0, clip.start + clip.duration() * 0.5);
}

}  // namespace

SkinnedScene LoadScene(const SceneSpec& spec) {
  SkinnedScene scene;
  scene.spec = spec;
  for (std::size_t m = 0; m < spec.meshes.size(); ++m) {
    const std::string& key = spec.meshes[m];
    try {
      scene.assets.push_back(IsGltfFile(key) ? ImportGltf(key, WithTangentsWhenPresent()).asset
                                           : GenerateDataset(ParseDatasetKey(key)));
      WeighMorphTargetsForTuning(scene.assets.back());
    } catch (const Error& e) {
      if (spec.meshes.size() == 1) throw;  // a scene of one mesh: the mesh's own message
      throw Error("scene '" + spec.key + "': meshes[" + std::to_string(m) + "] '" + key + "': " + e.what());
    }
  }
  if (spec.animated && scene.assets.front().animations.empty())
    throw Error("scene '" + spec.key + "': an animated scene plays the model's clips, and '" + spec.meshes.front() + "' has none");
  if (!spec.batch) {
    // An animated scene's asset keeps its mesh: baking measures its error on it (BakeAnimation).
    scene.batch.mesh = spec.animated ? scene.assets.front().mesh : std::move(scene.assets.front().mesh);
    scene.batch.vertex_offsets = {0, scene.batch.mesh.vertex_count()};
    scene.batch.joint_offsets = {0, scene.batch.mesh.joint_count};
    return scene;
  }
  std::vector<const SkinnedMesh*> meshes;
  for (const SkinnedAsset& asset : scene.assets) meshes.push_back(&asset.mesh);
  try {
    scene.batch = ConcatenateMeshes(meshes);
  } catch (const Error& e) {
    throw Error("scene '" + spec.key + "': " + e.what());
  }
  for (SkinnedAsset& asset : scene.assets) asset.mesh = SkinnedMesh{};  // in the batch now: no second copy
  return scene;
}

}  // namespace skintune::internal
