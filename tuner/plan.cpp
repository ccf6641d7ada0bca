// skintune: the plan of a tuning run (tuner/plan.h).
#include "tuner/plan.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <set>
#include <utility>

#include "generator/emit.h"  // kGeneratorVersion

#include "base/error.h"
#include "base/memory_limit.h"
#include "model/scene.h"
#include "model/synthetic.h"
#include "tuner/datasets.h"  // PalettesRigid
#include "tuner/schedule.h"  // IsSoftwareRasterizer
#include "tuner/tuned_device.h"

namespace skintune::internal {

namespace {

// What measuring one variant takes per vertex, beyond the mesh: in the
// worker, the float64 gold and the unpacked output (positions, normals,
// tangents: `vectors` of them, 1 to 3; a tangent's w counted with its xyz),
// the packed inputs in the widest formats (float4, u16 + f32 per slot) and
// the read-back (float4); on the device, those inputs and the outputs.
std::uint64_t VectorsOf(Normals normals) { return normals == Normals::kTangents ? 3 : normals == Normals::kNormals ? 2 : 1; }
std::uint64_t PackedBytesPerVertex(int influences, std::uint64_t vectors) {
  return 6 * static_cast<std::uint64_t>(influences) + vectors * 16;
}
std::uint64_t WorkerBytesPerVertex(int influences, std::uint64_t vectors) {
  return vectors * (32 + 16) + PackedBytesPerVertex(influences, vectors) + vectors * 16;
}
std::uint64_t DeviceBytesPerVertex(int influences, std::uint64_t vectors) {
  return PackedBytesPerVertex(influences, vectors) + vectors * 16;
}

// `call`'s Error prefixed with the config and its dataset: "c.json: datasets[1]: ...".
template <typename F>
auto InConfig(const TuneConfig& config, std::size_t dataset, F&& call) -> decltype(call()) {
  try {
    return call();
  } catch (const Error& e) {
    throw Error(config.name + ": datasets[" + std::to_string(dataset) + "]: " + e.what());
  }
}

}  // namespace

void ValidateRun(const TuneConfig& config, const TuneOptions& options) {
  ValidateConfig(config);
  if (options.worker_executable.empty()) throw Error("RunTuning: no worker executable");
}

PlannedDataset PlanDataset(const std::string& key) {
  const SceneSpec spec = ParseSceneKey(key);
  // Before anything is generated: the synthetic meshes (twice for a batch:
  // its meshes and their concatenation) and a worker's measurement of the
  // whole scene in this machine's memory (the device is checked once it is known).
  std::uint64_t synthetic_vertices = 0, mesh_bytes = 0;
  int widest_slots = 1;
  std::uint64_t vectors = 1;
  for (const std::string& mesh : spec.meshes) {
    if (IsGltfFile(mesh)) continue;
    const DatasetSpec dataset = ParseDatasetKey(mesh);
    synthetic_vertices += dataset.vertices;
    mesh_bytes += dataset.vertices * DatasetBytesPerVertex(dataset) * (spec.batch ? 2 : 1);
    widest_slots = std::max(widest_slots, dataset.influences);
    vectors = std::max(vectors, VectorsOf(NormalsFor(dataset.normals, dataset.tangents)));
  }
  if (synthetic_vertices > 0) {
    const std::uint64_t scene_vertices = synthetic_vertices * static_cast<std::uint64_t>(spec.instances);
    const std::uint64_t work = WorkerBytesPerVertex(widest_slots, vectors);
    const std::uint64_t per_vertex = (mesh_bytes + scene_vertices * work + scene_vertices - 1) / scene_vertices;
    CheckMemoryFor((spec.meshes.size() == 1 && spec.instances == 1 ? "dataset '" : "scene '") + key + "'",
                   scene_vertices, per_vertex,
                   "mesh " + std::to_string(mesh_bytes / synthetic_vertices) + " B per mesh vertex + measuring a variant " +
                       std::to_string(work) + " B per scene vertex",
                   HostMemoryAvailable());
  }
  const SkinnedScene scene = LoadScene(spec);
  // Every palette the workers start from must be finite (Skeleton::Palette):
  // bad input, found here rather than as a device failure.
  for (const SkinnedAsset& asset : scene.assets) {
    (void)asset.PaletteAt(-1, 0.0);
    if (!asset.animations.empty()) {
      const AnimationClip& clip = asset.animations.front();
      (void)asset.PaletteAt(0, clip.start + clip.duration() * 0.5);
    }
  }
  const SkinnedMesh& mesh = scene.mesh();
  int widest = 1;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) widest = std::max(widest, mesh.InfluencesOf(v));
  PlannedDataset d;
  d.info.key = key;
  d.info.vertices = scene.total_vertices();
  d.info.influences = mesh.influences;
  d.info.joints = mesh.joint_count;
  d.info.shape = spec.batch ? SceneKind::kBatch : spec.instances > 1 ? SceneKind::kInstances : SceneKind::kSingle;
  d.info.instances = spec.instances;
  d.info.meshes = static_cast<int>(spec.meshes.size());
  d.info.morph_targets = static_cast<int>(scene.mesh().morph.count());
  d.info.cross_fades = spec.blended;
  d.shape = WithMorphOf(ProblemShape{mesh.joint_count, widest, mesh.has_normals(), spec.instances,
                                     mesh.has_normals() && mesh.has_tangents(), tuner_internal::PalettesRigid(scene)},
                        mesh.morph);
  d.shape.animated = spec.animated;
  return d;
}

namespace {

// The datasets of the config, loaded in order (PlanDataset).
std::vector<PlannedDataset> PlanDatasets(const TuneConfig& config, const PlanProgress& progress) {
  std::vector<PlannedDataset> datasets;
  for (std::size_t i = 0; i < config.datasets.size(); ++i) {
    const std::string& key = config.datasets[i];
    progress("loading dataset " + key);
    datasets.push_back(InConfig(config, i, [&] { return PlanDataset(key); }));
  }
  return datasets;
}

// The devices discovery finds, as the plan needs them (their contexts go
// away with the discovery: the children measure), into `plan`.
void PlanDevices(TuningPlan& plan, const TuneOptions& options) {
  std::vector<PlannedDevice> found;
  {
    Discovery discovery = DiscoverTunedDevices();
    plan.skipped = discovery.skipped;
    for (const auto& device : discovery.devices)
      found.push_back({device->identity(), device->limits(), device->languages()});
  }
  if (found.empty()) {
    std::string why;
    for (const std::string& s : plan.skipped) why += (why.empty() ? "" : "; ") + s;
    throw Error("no device to tune on" + (why.empty() ? std::string() : ": " + why));
  }
  plan.devices = SelectDevices(std::move(found), options, plan.skipped);
}

}  // namespace

std::vector<PlannedDevice> SelectDevices(std::vector<PlannedDevice> found, const TuneOptions& options,
                                         std::vector<std::string>& skipped) {
  std::vector<PlannedDevice> kept;
  if (!options.device_pattern.empty()) {
    std::string all;
    for (PlannedDevice& d : found) {
      all += (all.empty() ? "" : "; ") + d.identity.backend + ": " + d.identity.platform + " / " + d.identity.name;
      if (MatchesDevice(options.device_pattern, d.identity)) kept.push_back(std::move(d));
    }
    if (kept.empty())
      throw Error("--device '" + options.device_pattern + "': no device matches (found: " + all + ")");
    return kept;
  }
  if (options.software_rasterizers) return found;
  // Software rasterizers are left out unless asked for, or all there is:
  // their winners serve no build that ships, and on a machine without a GPU
  // they took 121 of a default run's 203 s (2-core machine, 2026-11-28).
  std::vector<std::string> left_out;
  for (PlannedDevice& d : found) {
    if (IsSoftwareRasterizer(d.identity))
      left_out.push_back(d.identity.Id() + ": a software rasterizer (the host's CPU running " + d.identity.backend +
                         "), tuned only when asked for: --software-rasterizers, or a --device naming it");
    else
      kept.push_back(std::move(d));
  }
  if (kept.empty()) return found;
  skipped.insert(skipped.end(), left_out.begin(), left_out.end());
  return kept;
}

namespace {

// Every dataset fits every device's memory (one set of inputs and the output).
void CheckDeviceMemory(const TuneConfig& config, const TuningPlan& plan) {
  for (const PlannedDevice& d : plan.devices) {
    for (std::size_t i = 0; i < plan.datasets.size(); ++i) {
      const PlannedDataset& dataset = plan.datasets[i];
      const std::uint64_t per_vertex = DeviceBytesPerVertex(
          dataset.info.influences, VectorsOf(NormalsFor(dataset.shape.has_normals, dataset.shape.has_tangents)));
      InConfig(config, i, [&] {
        CheckMemoryFor("dataset '" + dataset.info.key + "' on " + d.identity.backend + " device '" + d.identity.name + "'",
                       dataset.info.vertices, per_vertex,
                       "inputs and output of a variant (--device selects other devices)",
                       {d.identity.global_memory_bytes, "the device's global memory"});
      });
    }
  }
}

// The points the tasks' spaces had, and the first constraint each invalid one broke.
struct PointCounts {
  std::uint64_t points = 0;
  std::map<Constraint, std::uint64_t> invalid_by;
};

// A task's record of an invalid point: once per variant, at most kMaxInvalidRecords.
void RecordInvalid(Task& task, std::set<std::string>& keys, const Variant& v, const std::vector<Violation>& violations,
                   const PlannedDevice& device, const PlannedDataset& dataset, const std::string& created) {
  if (task.invalid.size() >= kMaxInvalidRecords || !keys.insert(v.Key()).second) return;
  Measurement m;
  m.device_id = device.identity.Id();
  m.dataset = dataset.info.key;
  m.variant = v;
  m.status = MeasureStatus::kInvalid;
  for (const Violation& violation : violations)
    m.detail += (m.detail.empty() ? "" : "; ") + std::string(Name(violation.constraint)) + ": " + violation.message;
  m.generator_version = kGeneratorVersion;
  m.timestamp = created;
  task.invalid.push_back(std::move(m));
}

// One device x language x dataset: the baselines of the language (with the
// dataset's B) and the space's points that run there, the others recorded.
Task PlanTask(const TuneConfig& config, Task task, const PlannedDevice& device, const PlannedDataset& dataset,
              const std::string& created, PointCounts& counts) {
  std::set<std::string> invalid_keys;
  for (Variant b : config.baselines) {
    if (b.lang != task.lang) continue;
    b.influences = dataset.info.influences;
    // A data set whose morph targets move it: the baseline applies them with float32 offsets.
    if (dataset.shape.morph_moves && b.morph == Morph::kNone) b.morph = Morph::kDense;
    // A scene animated on the device: the baseline's palettes are sampled there.
    if (dataset.shape.animated && b.animation == Animation::kHost) b.animation = Animation::kSampled;
    const std::vector<Violation> violations = CheckVariant(b, device.limits, dataset.shape);
    if (!violations.empty()) {
      RecordInvalid(task, invalid_keys, b, violations, device, dataset, created);
    } else if (std::find(task.baselines.begin(), task.baselines.end(), b) == task.baselines.end()) {
      task.baselines.push_back(b);
    }
  }
  TuningSpace space = ForDataSet(config.space, dataset.shape);
  space.langs = {task.lang};
  space.influences = {dataset.info.influences};
  space.ForEach([&](const Variant& v) {
    ++counts.points;
    const std::vector<Violation> violations = CheckVariant(v, device.limits, dataset.shape);
    if (violations.empty()) {
      task.candidates.push_back(v);
      return;
    }
    ++counts.invalid_by[violations.front().constraint];
    RecordInvalid(task, invalid_keys, v, violations, device, dataset, created);
  });
  const std::size_t n = task.candidates.size();
  task.planned = (config.strategy.budget > 0 ? std::min(config.strategy.budget, n) : n) + task.baselines.size();
  return task;
}

template <typename T>
bool Contains(const std::vector<T>& list, const T& value) {
  return std::find(list.begin(), list.end(), value) != list.end();
}

// Why no task has a valid variant: the datasets' B outside the space, or
// the constraints that ruled out every point (with an example).
std::string NothingValid(const std::vector<Task>& tasks, const std::vector<PlannedDataset>& datasets,
                         const PointCounts& counts) {
  std::string message = "no valid variant of the space on any device";
  if (counts.points == 0) {
    std::string bs;
    for (const PlannedDataset& d : datasets) bs += (bs.empty() ? "" : ", ") + d.info.key + ": B=" + std::to_string(d.info.influences);
    return message + ": the space's influences include no dataset's B (" + bs + ")";
  }
  message += ": all " + std::to_string(counts.points) + " points break a constraint (";
  bool first = true;
  for (const auto& [constraint, n] : counts.invalid_by) {
    message += (first ? "" : ", ") + std::string(Name(constraint)) + ": " + std::to_string(n);
    first = false;
  }
  message += ")";
  for (const Task& t : tasks)
    if (!t.invalid.empty()) return message + "; e.g. " + t.invalid.front().variant.Key() + ": " + t.invalid.front().detail;
  return message;
}

}  // namespace

std::vector<Task> PlanTasks(const TuneConfig& config, const std::vector<Lang>& languages,
                            const std::vector<PlannedDataset>& datasets, const std::vector<PlannedDevice>& devices,
                            const std::string& created) {
  std::vector<Task> tasks;
  PointCounts counts;
  bool any_language = false;
  for (std::size_t di = 0; di < devices.size(); ++di) {
    for (Lang lang : devices[di].languages) {
      if (!Contains(config.space.langs, lang) || (!languages.empty() && !Contains(languages, lang))) continue;
      any_language = true;
      for (std::size_t k = 0; k < datasets.size(); ++k) {
        if (!Contains(config.space.influences, datasets[k].info.influences)) continue;
        Task task;
        task.device = di;
        task.lang = lang;
        task.dataset = k;
        tasks.push_back(PlanTask(config, std::move(task), devices[di], datasets[k], created, counts));
      }
    }
  }
  if (!any_language) {
    std::string offered;
    for (const PlannedDevice& d : devices)
      for (Lang l : d.languages) offered += (offered.empty() ? "" : ", ") + std::string(Name(l));
    throw Error("no device offers a language of the space" + std::string(languages.empty() ? "" : " and --lang") +
                " (the devices offer: " + offered + ")");
  }
  std::size_t total = 0;
  for (const Task& t : tasks) total += t.planned;
  if (total == 0) throw Error(NothingValid(tasks, datasets, counts));
  return tasks;
}

TuningPlan PlanTuning(const TuneConfig& config, const TuneOptions& options, const std::string& created,
                      const PlanProgress& progress) {
  TuningPlan plan;
  // Datasets first: a bad key or glTF file is bad input, found before any device work.
  plan.datasets = PlanDatasets(config, progress);
  progress("discovering devices");
  PlanDevices(plan, options);
  CheckDeviceMemory(config, plan);
  plan.tasks = PlanTasks(config, options.languages, plan.datasets, plan.devices, created);
  for (const Task& t : plan.tasks) plan.total += t.planned;
  return plan;
}

std::size_t TuningPlan::PlannedOn(std::size_t d) const {
  std::size_t planned = 0;
  for (const Task& t : tasks)
    if (t.device == d) planned += t.planned;
  return planned;
}

bool TuningPlan::HasTasks(std::size_t d) const {
  return std::any_of(tasks.begin(), tasks.end(), [&](const Task& t) { return t.device == d; });
}

}  // namespace skintune::internal
