// skintune: the tuner's data sets: scenes, golds, palettes and packings (tuner/datasets.h).
#include "tuner/datasets.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <span>
#if defined(__GLIBC__)
#include <malloc.h>  // malloc_trim
#endif

#include <glm/gtc/type_ptr.hpp>

#include "base/error.h"
#include "templates/embedded_support.h"  // DualQuaternionOf

namespace skintune::internal::tuner_internal {

std::vector<std::vector<glm::mat4>> FramePalettes(const SkinnedAsset& asset, int count) {
  count = std::max(count, 1);
  std::vector<std::vector<glm::mat4>> palettes;
  if (asset.animations.empty()) {
    const std::vector<glm::mat4> rest = asset.PaletteAt(-1, 0.0);
    palettes.assign(static_cast<std::size_t>(count), rest);
    return palettes;
  }
  const AnimationClip& clip = asset.animations.front();
  for (int k = 0; k < count; ++k) {
    const double t = clip.start + clip.duration() * (k + 0.5) / count;
    palettes.push_back(asset.PaletteAt(0, t));
  }
  return palettes;
}

std::vector<std::vector<glm::mat4>> ScenePalettes(const SkinnedScene& scene, int count) {
  count = std::max(count, 1);
  const int k = scene.spec.instances;
  std::vector<std::vector<glm::mat4>> frames(static_cast<std::size_t>(count));
  if (!scene.spec.batch) {
    // K instances: K x count different frames, instance after instance within a set.
    const std::vector<std::vector<glm::mat4>> pool = FramePalettes(scene.assets.front(), count * k);
    for (std::size_t f = 0; f < pool.size(); ++f)
      frames[f / static_cast<std::size_t>(k)].insert(frames[f / static_cast<std::size_t>(k)].end(), pool[f].begin(),
                                                     pool[f].end());
    return frames;
  }
  for (const SkinnedAsset& asset : scene.assets) {
    const std::vector<std::vector<glm::mat4>> own = FramePalettes(asset, count);
    for (std::size_t f = 0; f < frames.size(); ++f) frames[f].insert(frames[f].end(), own[f].begin(), own[f].end());
  }
  return frames;
}

bool AllRigid(std::span<const glm::mat4> palette) {
  return std::all_of(palette.begin(), palette.end(), [](const glm::mat4& m) {
    float dq[8];
    return skintune_kernels::DualQuaternionOf(&m[0][0], dq);
  });
}

bool PalettesRigid(const SkinnedScene& scene) {
  if (scene.spec.animated) return AllRigid(CrowdPalettes(scene, CrowdStates(scene, kVerificationSet)));
  return AllRigid(ScenePalettes(scene, 1).front());
}

std::vector<AnimInstance> CrowdStates(const SkinnedScene& scene, int set) {
  const SkinnedAsset& asset = scene.assets.front();
  const int k = scene.spec.instances;
  const auto clips = static_cast<int>(asset.animations.size());
  std::vector<AnimInstance> states(static_cast<std::size_t>(k));
  for (int i = 0; i < k && clips > 0; ++i) {
    const long long n = static_cast<long long>(set) * k + i;
    const int c = static_cast<int>(n % clips);
    const AnimationClip& clip = asset.animations[static_cast<std::size_t>(c)];
    const double phase = std::fmod(0.6180339887 * static_cast<double>(n) + 0.25, 1.0);
    AnimInstance& s = states[static_cast<std::size_t>(i)];
    s.clip = static_cast<std::uint16_t>(c);  // PackAnimation(asset) packs every clip in order
    s.time = static_cast<float>(clip.start + phase * clip.duration());
    if (scene.spec.blended && n % 3 == 2) {  // a cross-fade to the next clip (the same one, elsewhere in it, for a model of one clip)
      const int c2 = (c + 1) % clips;
      const AnimationClip& other = asset.animations[static_cast<std::size_t>(c2)];
      s.clip2 = static_cast<std::uint16_t>(c2);
      s.time2 = static_cast<float>(other.start + std::fmod(phase + 0.5, 1.0) * other.duration());
      s.weight = 0.35f;
    }
  }
  return states;
}

std::vector<glm::mat4> CrowdPalettes(const SkinnedScene& scene, std::span<const AnimInstance> states) {
  std::vector<glm::mat4> palettes;
  const SkinnedAsset& asset = scene.assets.front();
  for (const AnimInstance& s : states) {
    const std::vector<glm::mat4> one =
        asset.skeleton.Palette(asset.BlendedPoseAt(s.clip, s.time, s.weight != 0.0f ? s.clip2 : -1, s.time2, s.weight));
    palettes.insert(palettes.end(), one.begin(), one.end());
  }
  return palettes;
}

DatasetCache::Entry& DatasetCache::Get(const std::string& key) {
  if (auto found = entries_.find(key); found != entries_.end()) return *found->second;
  auto entry = std::make_unique<Entry>();
#if defined(__GLIBC__)
  // The tune worker keeps freed blocks (KeepLargeBlocks, tuner/worker.cpp):
  // hand them back before a new data set's memory check reads MemAvailable.
  malloc_trim(0);
#endif
  // Import warnings (renormalised weights) are the importer's to report.
  entry->scene = LoadScene(ParseSceneKey(key));
  if (entry->scene.spec.animated) {
    entry->verification_states = CrowdStates(entry->scene, kVerificationSet);
    entry->verification_palette = CrowdPalettes(entry->scene, entry->verification_states);
  } else {
    entry->verification_palette = ScenePalettes(entry->scene, 1).front();
  }
  entry->rigid_joints = AllRigid(entry->verification_palette);
  const SkinnedScene& scene = entry->scene;
  const std::vector<glm::vec3>& positions = scene.mesh().positions;
  const std::size_t n = scene.mesh().vertex_count();
  if (scene.spec.instances > 1) {
    const double diagonal = BoundingBoxDiagonal(positions);
    for (int i = 0; i < scene.spec.instances; ++i)
      entry->parts.push_back({"instance " + std::to_string(i), static_cast<std::size_t>(i) * n, n, diagonal});
  } else {
    const std::vector<std::size_t>& offsets = scene.batch.vertex_offsets;
    for (std::size_t m = 0; m + 1 < offsets.size(); ++m) {
      const std::size_t count = offsets[m + 1] - offsets[m];
      const std::string name = scene.spec.batch ? "meshes[" + std::to_string(m) + "] (" +
                                                      std::filesystem::path(scene.spec.meshes[m]).filename().string() + ")"
                                                : "";
      entry->parts.push_back(
          {name, offsets[m], count, BoundingBoxDiagonal(std::span(positions).subspan(offsets[m], count))});
    }
  }
  return *entries_.emplace(key, std::move(entry)).first->second;
}

namespace {

// The gold of the whole scene on `mesh` (the scene's, quantised or not): one
// run over the mesh and its palette; K instances: one per instance's palette.
// Dual-quaternion variants against the dual-quaternion gold.
GoldResult SceneGold(const DatasetCache::Entry& entry, const SkinnedMesh& mesh, const Variant& variant,
                     std::span<const glm::mat4> palette) {
  const int k = entry.instances();
  const bool with_normals = SkinsNormals(variant), with_tangents = SkinsTangents(variant);
  const auto gold = variant.blend == Blend::kDualQuaternion ? &SkinGoldDualQuaternion : &SkinGold;
  if (k == 1) return gold(mesh, palette, with_normals, with_tangents);
  GoldResult all;
  const std::size_t joints = static_cast<std::size_t>(mesh.joint_count);
  for (int i = 0; i < k; ++i) {
    GoldResult one = gold(mesh, palette.subspan(i * joints, joints), with_normals, with_tangents);
    all.positions.insert(all.positions.end(), one.positions.begin(), one.positions.end());
    all.normals.insert(all.normals.end(), one.normals.begin(), one.normals.end());
    all.tangents.insert(all.tangents.end(), one.tangents.begin(), one.tangents.end());
  }
  return all;
}

}  // namespace

namespace {

DatasetCache::GoldKey KeyOf(const Variant& variant, int weight) {
  const bool baked = weight >= 0 && BakeRateOf(variant.animation) > 0.0;  // the source is sampled
  return {weight, variant.normals, variant.blend == Blend::kDualQuaternion, weight >= 0 && MorphHalf(variant),
          baked ? static_cast<int>(variant.animation) : 0};
}

}  // namespace

const GoldResult& DatasetCache::Gold(Entry& entry, const Variant& variant) {
  const GoldKey key = KeyOf(variant, static_cast<int>(variant.weight));
  if (auto found = entry.gold.find(key); found != entry.gold.end()) return found->second;
  GoldResult gold = SceneGold(entry, QuantisedMesh(entry.mesh(), variant), variant, VerificationPalette(entry, variant));
  return entry.gold.emplace(key, std::move(gold)).first->second;
}

const GoldResult& DatasetCache::SourceGold(Entry& entry, const Variant& variant) {
  const GoldKey key = KeyOf(variant, -1);
  if (auto found = entry.source_gold.find(key); found != entry.source_gold.end()) return found->second;
  GoldResult gold = SceneGold(entry, entry.mesh(), variant, entry.verification_palette);
  return entry.source_gold.emplace(key, std::move(gold)).first->second;
}

double Relative(double abs, double diagonal) { return diagonal > 0.0 ? abs / diagonal : (abs > 0.0 ? 1.0 : 0.0); }

double DatasetCache::QuantisationError(Entry& entry, const Variant& variant) {
  const GoldKey key = KeyOf(variant, static_cast<int>(variant.weight));
  if (auto found = entry.quantisation.find(key); found != entry.quantisation.end()) return found->second;
  const std::span<const glm::dvec3> gold = Gold(entry, variant).positions;
  const std::span<const glm::dvec3> source = SourceGold(entry, variant).positions;
  double error = 0.0;
  for (const Part& part : entry.parts)
    error = std::max(error, Relative(MaxDistance(gold.subspan(part.first, part.count),
                                                 source.subspan(part.first, part.count)),
                                     part.diagonal));
  return entry.quantisation.emplace(key, error).first->second;
}

const PackedAnimation& DatasetCache::Clips(Entry& entry, Animation form) {
  if (!entry.scene.spec.animated) throw Error("scene '" + entry.scene.spec.key + "' is not animated on the device");
  if (auto found = entry.animations.find(form); found != entry.animations.end()) return found->second;
  return entry.animations.emplace(form, PackForm(entry.scene.assets.front(), form)).first->second;
}

std::span<const glm::mat4> DatasetCache::VerificationPalette(Entry& entry, const Variant& variant) {
  if (!entry.scene.spec.animated || BakeRateOf(variant.animation) == 0.0) return entry.verification_palette;
  if (auto found = entry.baked_palettes.find(variant.animation); found != entry.baked_palettes.end()) return found->second;
  const PackedAnimation& baked = Clips(entry, variant.animation);
  constexpr int kRows = 4;
  std::vector<float> rows(entry.verification_states.size() * baked.joints.size() * kRows * 4);
  RunPaletteKernel(baked.View(), entry.verification_states, rows.data(), kRows);
  std::vector<glm::mat4> palette(rows.size() / 16);
  for (std::size_t j = 0; j < palette.size(); ++j) palette[j] = glm::transpose(glm::make_mat4(&rows[j * 16]));  // rows, not columns
  return entry.baked_palettes.emplace(variant.animation, std::move(palette)).first->second;
}

const std::vector<std::vector<glm::mat4>>& DatasetCache::Frames(Entry& entry, int count) {
  if (auto found = entry.frames.find(count); found != entry.frames.end()) return found->second;
  return entry.frames.emplace(count, ScenePalettes(entry.scene, count)).first->second;
}

std::string PackingKey(Variant v) {
  // Kernel-only axes (packer.cpp reads none of them).
  v.lang = Lang::kOpenCl;
  v.storage = PaletteStorage::kGlobal;
  v.blend = Blend::kMatrix;
  v.vertices_per_item = 1;
  v.assignment = Assignment::kContiguous;
  v.wg_size = 128;
  return v.Key();
}

const PackedMesh& DatasetCache::Packed(Entry& entry, const Variant& variant) {
  // A few: an exhaustive space walks its storage and work-group values within one packing.
  constexpr std::size_t kPackingsKept = 4;
  const std::string key = PackingKey(variant);
  auto found = std::find_if(entry.packings.begin(), entry.packings.end(), [&](const auto& p) { return p.first == key; });
  if (found == entry.packings.end()) {
    // Only the data set being measured keeps packings (a 6400k-vertex one is ~200 MB each).
    for (auto& [name, other] : entries_)
      if (other.get() != &entry) other->packings.clear();
    if (entry.packings.size() >= kPackingsKept) entry.packings.erase(entry.packings.begin());
    entry.packings.emplace_back(key, Pack(entry.mesh(), variant));  // errors name `variant`
    found = entry.packings.end() - 1;
  }
  found->second.variant = variant;
  return found->second;
}

const PackedMesh& PackScene(DatasetCache& datasets, DatasetCache::Entry& entry, const Variant& variant,
                            std::vector<KernelSource>& kernels) {
  const PackedMesh& packed = datasets.Packed(entry, variant);
  EmitOptions emit;  // K instances: the instanced kernels (docs/VARIANTS.md "Instancing")
  emit.instanced = entry.instances() > 1;
  emit.max_instances = emit.instanced ? entry.instances() : 0;
  emit.morph_targets = packed.morph_targets;
  kernels.clear();
  for (const Launch& launch : packed.launches)
    kernels.push_back(Emit(variant, launch.influences, static_cast<int>(packed.palette_joints), emit));
  return packed;
}

namespace {
// The bytes of the launches' inputs: the mesh every instance reads.
std::uint64_t InputBytes(const PackedMesh& packed) {
  std::uint64_t bytes = 0;
  for (const Launch& launch : packed.launches)
    for (const PackedBuffer& b : launch.inputs) bytes += b.bytes.size();
  return bytes;
}
}  // namespace

std::uint64_t FrameBytes(const PackedMesh& packed, int instances) {
  std::uint64_t bytes = InputBytes(packed);
  for (const OutputSpec& output : kOutputs)
    if (Writes(packed.variant, output.output)) bytes += packed.vertex_count * OutputStrideBytes(packed.variant, output.output);
  bytes += packed.palette.size();
  return bytes * static_cast<std::uint64_t>(instances);
}

std::uint64_t FloorBytes(const PackedMesh& packed, int instances) {
  return FrameBytes(packed, instances) - InputBytes(packed) * static_cast<std::uint64_t>(std::max(instances - 1, 0));
}

std::vector<std::vector<std::uint8_t>> TimedPalettes(DatasetCache& datasets, DatasetCache::Entry& data,
                                                     const Variant& variant, int sets) {
  std::vector<std::vector<std::uint8_t>> palettes;
  for (const std::vector<glm::mat4>& palette : datasets.Frames(data, sets)) palettes.push_back(PackPalette(palette, variant));
  return palettes;
}

}  // namespace skintune::internal::tuner_internal
