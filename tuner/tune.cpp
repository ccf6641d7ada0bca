// skintune: a tuning run.
//
// The parent discovers the devices only for their identities, limits and
// languages, then measures every device through its own child process
// (worker.h): devices that share hardware one after another, so that no two
// measurements share a chip, and devices that share none (a CPU device and a
// GPU: schedule.h) at the same time. For each device x language x dataset:
//   - the space's points with B = the dataset's influences are checked
//     against the device's limits and the dataset's shape; an invalid point is
//     recorded (status invalid, with every constraint it breaks; at most
//     kMaxInvalidRecords per device x language x dataset). Other B are not
//     tried on that dataset: a larger B only pads with zero weights (the same
//     output, more bytes), and winners are kept per B;
//   - the strategy searches the valid points; each evaluation takes the cache's
//     record when there is one, else measures in the child and appends the
//     result to the cache before going on.
#include "tuner/host_lock.h"
#include "tuner/tune.h"

#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <fstream>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "generator/emit.h"
#include "base/error.h"
#include "model/gltf_import.h"
#include "base/memory_limit.h"
#include "model/scene.h"
#include "model/synthetic.h"
#include "tuner/measurement.h"
#include "tuner/race.h"
#include "tuner/schedule.h"
#include "tuner/worker.h"

namespace skintune::internal {

struct EmbeddedConfigFile {
  const char* name;
  const unsigned char* data;
  std::size_t size;
};
extern const EmbeddedConfigFile kEmbeddedConfigs[];
extern const std::size_t kEmbeddedConfigCount;

namespace {

constexpr std::size_t kMaxInvalidRecords = 10000;

bool IsGltfPath(const std::string& key) {
  std::string lower = key;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  auto ends_with = [&](const std::string& suffix) {
    return lower.size() >= suffix.size() && lower.compare(lower.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  return ends_with(".gltf") || ends_with(".glb");
}

// A positive number at most `most` (a bound stated in the error).
double PositiveNumber(const nlohmann::json& value, const std::string& where,
                      double most = std::numeric_limits<double>::max()) {
  if (!value.is_number()) throw Error(where + ": expected a number (got " + Excerpt(value.dump()) + ")");
  const double v = value.get<double>();
  if (!(v > 0.0) || v == std::numeric_limits<double>::infinity()) {
    throw Error(where + ": must be a positive number (got " + value.dump() + ")");
  }
  if (v > most) {  // absurd: a setting that cannot work (exit 2)
    std::ostringstream bound;
    bound << most;
    throw UsageError(where + ": must be a positive number at most " + bound.str() + " (got " + value.dump() + ")");
  }
  return v;
}

void CheckFields(const nlohmann::json& object, const std::string& where, const std::set<std::string>& known) {
  if (!object.is_object()) throw Error(where + ": expected an object");
  for (const auto& [field, value] : object.items()) {
    if (known.count(field)) continue;
    std::string list;
    for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
    throw Error(where + "." + field + ": unknown field (expected one of " + list + ")");
  }
}

TimingOptions TimingFromConfig(const nlohmann::json& in, const std::string& context) {
  return TimingOptionsFromJson(in, context + ": timing");
}

void ValidateStrategy(const StrategyOptions& s, const std::string& where) {
  if (s.name != "exhaustive" && s.name != "random" && s.name != "coordinate") {
    throw Error(where + ".name: unknown strategy '" + s.name + "' (expected one of exhaustive, random, coordinate)");
  }
  if (s.name == "random" && s.budget == 0) {
    throw Error(where + ".budget: the random strategy needs a budget (evaluations per device, language and dataset)");
  }
}

StrategyOptions StrategyFromConfig(const nlohmann::json& in, const std::string& context) {
  const std::string where = context + ": strategy";
  CheckFields(in, where, {"name", "budget", "seed"});
  StrategyOptions s;
  if (in.contains("name")) {
    if (!in["name"].is_string()) throw Error(where + ".name: expected a string");
    s.name = in["name"].get<std::string>();
  }
  if (in.contains("budget")) {
    if (!in["budget"].is_number_unsigned() || in["budget"].get<std::uint64_t>() > kMaxBudget)
      throw Error(where + ".budget: must be a whole number from 0 to " + std::to_string(kMaxBudget) + " (got " +
                  in["budget"].dump() + ")");
    s.budget = in["budget"].get<std::size_t>();
  }
  if (in.contains("seed")) {
    if (!in["seed"].is_number_unsigned()) throw Error(where + ".seed: must be an integer >= 0");
    s.seed = in["seed"].get<std::uint64_t>();
  }
  ValidateStrategy(s, where);
  return s;
}

std::vector<std::string> DatasetsFromConfig(const nlohmann::json& in, const std::string& context) {
  const std::string where = context + ": datasets";
  if (!in.is_array()) throw Error(where + ": expected a list of dataset keys");
  if (in.empty()) throw Error(where + ": is empty");
  std::vector<std::string> keys;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const std::string item = where + "[" + std::to_string(i) + "]";
    const nlohmann::json& d = in[i];
    std::string key;
    if (d.is_string()) {
      key = d.get<std::string>();
    } else if (d.is_object()) {
      // {"key": ..., "name", "vertices", "influences", "bones", "description"}: the
      // numbers, when given, must agree with the key.
      CheckFields(d, item, {"key", "name", "vertices", "influences", "bones", "description"});
      if (!d.contains("key") || !d["key"].is_string()) throw Error(item + ".key: missing (a dataset key or glTF path)");
      key = d["key"].get<std::string>();
    } else {
      throw Error(item + ": expected a dataset key (string) or an object with \"key\"");
    }
    SceneSpec scene;
    try {
      scene = ParseSceneKey(key);  // a dataset key, a glTF path, instances or a batch (model/scene.h)
    } catch (const Error& e) {
      throw Error(item + ": " + e.what());
    }
    if (d.is_object()) {
      const bool synthetic = !scene.batch && scene.instances == 1 && !IsGltfPath(key);
      const DatasetSpec spec = synthetic ? ParseDatasetKey(key) : DatasetSpec{};
      auto check = [&](const char* field, long long expected) {
        if (!d.contains(field)) return;
        if (!synthetic)
          throw Error(item + "." + field + ": only a synthetic dataset of one mesh states its numbers ('" + key +
                      "' is not one)");
        if (!d[field].is_number_integer() || d[field].get<long long>() != expected) {
          throw Error(item + "." + field + ": " + d[field].dump() + " does not match the key '" + key + "' (" +
                      std::to_string(expected) + ")");
        }
      };
      check("vertices", static_cast<long long>(spec.vertices));
      check("influences", spec.influences);
      check("bones", spec.bones);
    }
    if (std::find(keys.begin(), keys.end(), key) != keys.end()) throw Error(item + ": '" + key + "' is listed twice");
    keys.push_back(key);
  }
  return keys;
}

// ------------------------------------------------------------------ run

struct LoadedDataset {
  DatasetInfo info;
  ProblemShape shape;
};

// What measuring one variant takes per vertex, beyond the mesh: in the
// worker, the float64 gold and the unpacked output (positions, normals), the
// packed inputs in the widest formats (float4, u16 + f32 per slot) and the
// read-back (float4); on the device, those inputs and the output.
std::uint64_t PackedBytesPerVertex(int influences, bool normals) {
  return 16 + 6 * static_cast<std::uint64_t>(influences) + (normals ? 16 : 0);
}
std::uint64_t WorkerBytesPerVertex(int influences, bool normals) {
  const std::uint64_t sides = normals ? 2 : 1;
  return sides * (24 + 12) + PackedBytesPerVertex(influences, normals) + sides * 16;
}
std::uint64_t DeviceBytesPerVertex(int influences, bool normals) {
  return PackedBytesPerVertex(influences, normals) + (normals ? 2 : 1) * 16;
}

LoadedDataset LoadDataset(const std::string& key) {
  const SceneSpec spec = ParseSceneKey(key);
  // Before anything is generated: the synthetic meshes (twice for a batch:
  // its meshes and their concatenation) and a worker's measurement of the
  // whole scene in this machine's memory (the device is checked once it is known).
  std::uint64_t synthetic_vertices = 0, mesh_bytes = 0;
  int widest_slots = 1;
  bool normals = false;
  for (const std::string& mesh : spec.meshes) {
    if (IsGltfPath(mesh)) continue;
    const DatasetSpec dataset = ParseDatasetKey(mesh);
    synthetic_vertices += dataset.vertices;
    mesh_bytes += dataset.vertices * DatasetBytesPerVertex(dataset) * (spec.batch ? 2 : 1);
    widest_slots = std::max(widest_slots, dataset.influences);
    normals = normals || dataset.normals;
  }
  if (synthetic_vertices > 0) {
    const std::uint64_t scene_vertices = synthetic_vertices * static_cast<std::uint64_t>(spec.instances);
    const std::uint64_t work = WorkerBytesPerVertex(widest_slots, normals);
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
  LoadedDataset d;
  d.info.key = key;
  d.info.vertices = scene.total_vertices();
  d.info.influences = mesh.influences;
  d.info.joints = mesh.joint_count;
  d.info.shape = spec.batch ? SceneKind::kBatch : spec.instances > 1 ? SceneKind::kInstances : SceneKind::kSingle;
  d.info.instances = spec.instances;
  d.info.meshes = static_cast<int>(spec.meshes.size());
  d.shape = ProblemShape{mesh.joint_count, widest, mesh.has_normals(), spec.instances};
  return d;
}

std::string ReadFirstMatch(const std::string& path, const std::string& prefix) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) != 0) continue;
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::size_t start = line.find_first_not_of(" \t", colon + 1);
    return start == std::string::npos ? std::string() : line.substr(start);
  }
  return {};
}

nlohmann::json MachineInfo() {
  nlohmann::json m = nlohmann::json::object();
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) == 0) m["hostname"] = host;
  struct utsname u {};
  if (::uname(&u) == 0) {
    m["os"] = std::string(u.sysname) + " " + u.release + " " + u.version + " " + u.machine;
  }
  m["cpu_model"] = ReadFirstMatch("/proc/cpuinfo", "model name");
  m["logical_cpus"] = ::sysconf(_SC_NPROCESSORS_ONLN);
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGE_SIZE);
  m["memory_bytes"] = pages > 0 && page_size > 0 ? static_cast<std::uint64_t>(pages) * page_size : 0;
  return m;
}

struct Device {
  DeviceIdentity identity;
  DeviceLimits limits;
  std::vector<Lang> languages;
};

// One device x language x dataset: its valid variants and its invalid points.
struct Task {
  std::size_t device = 0;
  Lang lang = Lang::kOpenCl;
  std::size_t dataset = 0;
  std::vector<Variant> candidates;
  std::vector<Variant> baselines;     // measured before the search (TuneConfig::baselines)
  std::vector<Measurement> invalid;
  std::size_t planned = 0;  // evaluations expected (for progress)
};

std::string ShortStatus(const Measurement& m) {
  std::string text = Name(m.status);
  if (IsTimed(m.status)) {
    char ms[96];
    std::snprintf(ms, sizeof ms, " %.3f ms, error %.1e of the diagonal (%s)", m.timing.median_ms,
                  m.source_error.position_rel, Name(m.variant.weight));
    text += ms;
  } else if (!m.detail.empty()) {
    std::string detail = m.detail.substr(0, m.detail.find('\n'));
    if (detail.size() > 120) detail = detail.substr(0, 120) + "...";
    text += " (" + detail + ")";
  }
  return text;
}

// The measurement cache's key of `variant` on a device and data set, by this generator.
std::string CacheKeyOf(const std::string& device_id, const std::string& dataset, const Variant& variant) {
  Measurement probe;
  probe.device_id = device_id;
  probe.dataset = dataset;
  probe.variant = variant;
  probe.generator_version = kGeneratorVersion;
  return probe.CacheKey();
}

// The bytes each of the probe copy's source and destination hold: together
// four times the last-level cache, so the copy streams from memory (a larger
// one cost a CPU device seconds of allocation and first touch).
std::size_t CopyBytes(const DeviceIdentity& d) {
  std::uint64_t bytes = std::max<std::uint64_t>(64ull << 20, 2 * d.last_level_cache_bytes);
  if (d.global_memory_bytes > 0) bytes = std::min<std::uint64_t>(bytes, d.global_memory_bytes / 4);
  return static_cast<std::size_t>(bytes);
}

}  // namespace

TuneConfig ConfigFromJson(const nlohmann::json& json, const std::string& context) {
  if (!json.is_object()) throw Error(context + ": a tune config must be a JSON object");
  // "paper", "figure1", "paper_kernels" and "reported" are fields of configs/paper.json
  // read by `skintune paper` (report/paper_result.h).
  static const std::set<std::string> kKnown = {"description", "space",    "datasets", "timing",
                                               "strategy",    "variant_timeout_s", "max_error", "paper", "figure1",
                                               "paper_kernels", "reported"};
  for (const auto& [field, value] : json.items()) {
    if (kKnown.count(field)) continue;
    throw Error(context + ": " + field +
                ": unknown field (expected description, space, datasets, timing, strategy, variant_timeout_s, "
                "max_error)");
  }
  if (json.contains("description") && !json["description"].is_string()) {
    throw Error(context + ": description: expected a string");
  }
  if (!json.contains("space")) throw Error(context + ": space: missing (an object of axis -> list of values)");
  if (!json.contains("datasets")) throw Error(context + ": datasets: missing (a list of dataset keys)");
  TuneConfig c;
  c.name = context;
  c.space = SpaceFromJson(json["space"], context);
  c.space.Validate(context);
  c.datasets = DatasetsFromConfig(json["datasets"], context);
  if (json.contains("timing")) c.timing = TimingFromConfig(json["timing"], context);
  if (json.contains("strategy")) c.strategy = StrategyFromConfig(json["strategy"], context);
  if (json.contains("variant_timeout_s")) {
    c.variant_timeout_s = PositiveNumber(json["variant_timeout_s"], context + ": variant_timeout_s", kMaxVariantTimeoutS);
  }
  if (json.contains("max_error")) {
    const nlohmann::json& value = json["max_error"];
    if (!value.is_number()) throw Error(context + ": max_error: expected a number (got " + value.dump() + ")");
    c.max_error = value.get<double>();
    if (const std::string bad = BadMaxError(c.max_error); !bad.empty()) throw Error(context + ": max_error: " + bad);
  }
  return c;
}

std::string EmbeddedConfig(const std::string& name) {
  std::string names;
  for (std::size_t i = 0; i < kEmbeddedConfigCount; ++i) {
    if (name == kEmbeddedConfigs[i].name) {
      return std::string(reinterpret_cast<const char*>(kEmbeddedConfigs[i].data), kEmbeddedConfigs[i].size);
    }
    names += (names.empty() ? "" : ", ") + std::string(kEmbeddedConfigs[i].name);
  }
  throw Error("no built-in config '" + name + "' (built in: " + names + ")");
}

namespace {

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

TuningReport RunTuning(const TuneConfig& config, const TuneOptions& options) {
  ValidateStrategy(config.strategy, "strategy");
  config.space.Validate(config.name);
  if (!(config.variant_timeout_s > 0.0 && config.variant_timeout_s <= kMaxVariantTimeoutS))
    throw Error("variant_timeout_s: must be a positive number at most " + std::to_string(kMaxVariantTimeoutS));
  if (!(config.timing.tolerance > 0.0 && config.timing.tolerance <= kMaxTolerance))
    throw Error("timing.tolerance: must be a positive number at most " + std::to_string(kMaxTolerance));
  if (const std::string bad = BadMaxError(config.max_error); !bad.empty()) throw Error("max_error: " + bad);
  if (options.worker_executable.empty()) throw Error("RunTuning: no worker executable");

  MeasurementCache cache(options.cache_path);
  auto progress = [&](std::size_t done, std::size_t total, const std::string& what) {
    if (options.progress) options.progress(done, total, what);
  };

  TuningReport report;
  report.created = UtcTimestamp();
  report.config = config.name;
  report.strategy = config.strategy.name;
  report.max_error = config.max_error;
  report.tie_margin = config.timing.tie_margin;
  report.host_tie_margin = config.timing.host_tie_margin;
  report.machine = MachineInfo();

  // Datasets first: a bad key or glTF file is bad input, found before any device work.
  // Its errors (memory, a glTF of a scene) name the config and the element too.
  std::vector<LoadedDataset> datasets;
  for (std::size_t i = 0; i < config.datasets.size(); ++i) {
    const std::string& key = config.datasets[i];
    progress(0, 0, "loading dataset " + key);
    datasets.push_back(InConfig(config, i, [&] { return LoadDataset(key); }));
    report.datasets.push_back(datasets.back().info);
  }

  std::vector<Device> devices;
  {
    progress(0, 0, "discovering devices");
    Discovery discovery = DiscoverBackends();
    report.skipped = discovery.skipped;
    for (const auto& backend : discovery.backends) {
      devices.push_back({backend->identity(), backend->limits(), backend->languages()});
    }
  }  // the parent's own contexts go away: the children measure
  if (devices.empty()) {
    std::string why;
    for (const std::string& s : report.skipped) why += (why.empty() ? "" : "; ") + s;
    throw Error("no device to tune on" + (why.empty() ? std::string() : ": " + why));
  }
  if (!options.device_pattern.empty()) {
    std::vector<Device> matching;
    std::string all;
    for (Device& d : devices) {
      all += (all.empty() ? "" : "; ") + d.identity.backend + ": " + d.identity.platform + " / " + d.identity.name;
      if (MatchesDevice(options.device_pattern, d.identity)) matching.push_back(std::move(d));
    }
    if (matching.empty()) throw Error("--device '" + options.device_pattern + "': no device matches (found: " + all + ")");
    devices = std::move(matching);
  }

  // Every dataset fits every device's memory (one set of inputs and the output).
  for (const Device& d : devices) {
    for (std::size_t i = 0; i < datasets.size(); ++i) {
      const LoadedDataset& dataset = datasets[i];
      const std::uint64_t per_vertex = DeviceBytesPerVertex(dataset.info.influences, dataset.shape.has_normals);
      InConfig(config, i, [&] {
        CheckMemoryFor("dataset '" + dataset.info.key + "' on " + d.identity.backend + " device '" + d.identity.name + "'",
                     dataset.info.vertices, per_vertex,
                     "inputs and output of a variant (--device selects other devices)",
                     {d.identity.global_memory_bytes, "the device's global memory"});
      });
    }
  }

  // The tasks: device x language x dataset.
  std::vector<Task> tasks;
  std::map<Constraint, std::uint64_t> invalid_by;
  std::uint64_t points = 0;
  std::set<Lang> languages_seen;
  for (std::size_t di = 0; di < devices.size(); ++di) {
    const Device& device = devices[di];
    for (Lang lang : device.languages) {
      if (std::find(config.space.langs.begin(), config.space.langs.end(), lang) == config.space.langs.end()) continue;
      if (!options.languages.empty() &&
          std::find(options.languages.begin(), options.languages.end(), lang) == options.languages.end()) {
        continue;
      }
      languages_seen.insert(lang);
      for (std::size_t k = 0; k < datasets.size(); ++k) {
        const LoadedDataset& dataset = datasets[k];
        TuningSpace space = config.space;
        space.langs = {lang};
        if (std::find(space.influences.begin(), space.influences.end(), dataset.info.influences) ==
            space.influences.end()) {
          continue;
        }
        space.influences = {dataset.info.influences};
        Task task;
        task.device = di;
        task.lang = lang;
        task.dataset = k;
        std::set<std::string> invalid_keys;
        auto record_invalid = [&](const Variant& v, const std::vector<Violation>& violations) {
          if (task.invalid.size() >= kMaxInvalidRecords || !invalid_keys.insert(v.Key()).second) return;
          Measurement m;
          m.device_id = device.identity.Id();
          m.dataset = dataset.info.key;
          m.variant = v;
          m.status = MeasureStatus::kInvalid;
          for (const Violation& violation : violations) {
            m.detail += (m.detail.empty() ? "" : "; ") + std::string(Name(violation.constraint)) + ": " +
                        violation.message;
          }
          m.generator_version = kGeneratorVersion;
          m.timestamp = report.created;
          task.invalid.push_back(std::move(m));
        };
        for (Variant b : config.baselines) {
          if (b.lang != lang) continue;
          b.influences = dataset.info.influences;
          const std::vector<Violation> violations = CheckVariant(b, device.limits, dataset.shape);
          if (violations.empty()) {
            if (std::find(task.baselines.begin(), task.baselines.end(), b) == task.baselines.end()) {
              task.baselines.push_back(b);
            }
          } else {
            record_invalid(b, violations);
          }
        }
        space.ForEach([&](const Variant& v) {
          ++points;
          const std::vector<Violation> violations = CheckVariant(v, device.limits, dataset.shape);
          if (violations.empty()) {
            task.candidates.push_back(v);
            return;
          }
          ++invalid_by[violations.front().constraint];
          record_invalid(v, violations);
        });
        const std::size_t n = task.candidates.size();
        task.planned = (config.strategy.budget > 0 ? std::min(config.strategy.budget, n) : n) + task.baselines.size();
        tasks.push_back(std::move(task));
      }
    }
  }
  if (languages_seen.empty()) {
    std::string offered;
    for (const Device& d : devices) {
      for (Lang l : d.languages) offered += (offered.empty() ? "" : ", ") + std::string(Name(l));
    }
    throw Error("no device offers a language of the space" +
                std::string(options.languages.empty() ? "" : " and --lang") + " (the devices offer: " + offered + ")");
  }
  std::size_t total = 0;
  for (const Task& t : tasks) total += t.planned;
  if (total == 0) {
    std::string message = "no valid variant of the space on any device";
    if (points == 0) {
      std::string bs;
      for (const LoadedDataset& d : datasets) {
        bs += (bs.empty() ? "" : ", ") + d.info.key + ": B=" + std::to_string(d.info.influences);
      }
      message += ": the space's influences include no dataset's B (" + bs + ")";
    } else {
      message += ": all " + std::to_string(points) + " points break a constraint (";
      bool first = true;
      for (const auto& [constraint, n] : invalid_by) {
        message += (first ? "" : ", ") + std::string(Name(constraint)) + ": " + std::to_string(n);
        first = false;
      }
      message += ")";
      for (const Task& t : tasks) {
        if (!t.invalid.empty()) {
          message += "; e.g. " + t.invalid.front().variant.Key() + ": " + t.invalid.front().detail;
          break;
        }
      }
    }
    throw Error(message);
  }

  // The devices with work, tuned in groups that share no hardware
  // (schedule.h): the groups at the same time, each group's devices one after
  // another. Each device's results are kept apart and joined in device order,
  // so the report does not depend on the timing of the threads.
  struct DeviceRun {
    bool has_tasks = false;
    std::size_t planned = 0;     // evaluations expected on the device
    std::size_t done = 0;        // of them, done
    std::vector<Measurement> measurements;
    std::vector<RaceRecord> races;
    std::optional<double> copy_gbps;
    std::optional<std::string> given_up;
  };
  std::vector<DeviceRun> runs(devices.size());
  for (const Task& t : tasks) {
    runs[t.device].has_tasks = true;
    runs[t.device].planned += t.planned;
  }
  std::mutex shared;  // the cache, `done`, the progress callback
  std::size_t done = 0;
  // Moves device `run`'s progress to `device_done` (never back) and reports `what`.
  auto advance = [&](DeviceRun& run, std::size_t device_done, const std::string& what) {
    std::lock_guard<std::mutex> lock(shared);
    device_done = std::min(device_done, run.planned);
    if (device_done > run.done) {
      done += device_done - run.done;
      run.done = device_done;
    }
    if (!what.empty()) progress(done, total, what);
  };

  // Set below, before any device starts, when a CPU device is tuned beside
  // a GPU (tuner/host_lock.h).
  std::unique_ptr<tuner_internal::HostLockFile> host_lock;
  auto tune_device = [&](std::size_t di) {
    const Device& device = devices[di];
    DeviceRun& run = runs[di];
    const std::string id = device.identity.Id();
    IsolatedBackend worker(options.worker_executable, device.identity, config.variant_timeout_s);
    // This device's timing: its tie margin (a CPU's is wider: TimingOptions::MarginFor).
    TimingOptions timing = config.timing;
    timing.tie_margin = config.timing.MarginFor(device.identity);
    if (host_lock) worker.UseHostLock(host_lock->path());
    const std::string device_name = device.identity.backend + " " + device.identity.name;
    try {
      advance(run, 0, device_name + ": copy bandwidth");
      std::string why_not;
      if (const std::optional<double> gbps = worker.CopyBandwidthGBps(CopyBytes(device.identity), &why_not)) {
        run.copy_gbps = *gbps;
      } else {
        advance(run, 0, device_name + ": copy bandwidth not measured: " + why_not);
      }
      std::size_t task_start = 0;
      for (Task& task : tasks) {
        if (task.device != di || (task.candidates.empty() && task.baselines.empty())) continue;
        const std::string& key = datasets[task.dataset].info.key;
        std::size_t task_done = 0;
        std::set<std::string> seen;
        auto cache_key_of = [&](const Variant& v) { return CacheKeyOf(id, key, v); };
        // The cache is input: a record this run cannot trust is measured again.
        auto cached = [&](const std::string& cache_key) -> std::optional<Measurement> {
          std::lock_guard<std::mutex> lock(shared);
          const Measurement* found = cache.Find(cache_key);
          if (found && MeasuredAgainOnResume(*found, config.timing.tolerance).empty()) return *found;
          return std::nullopt;
        };
        // Compile ahead: the variants the task will measure next and the
        // cache has not (the baselines, then what the strategy announces),
        // built in parallel by the worker before any of them is timed.
        const bool compiles_ahead = CompilesAhead(device.identity);
        const LookAhead compile_ahead = [&](const std::vector<Variant>& next) {
          std::vector<Variant> ahead;
          for (const Variant& v : next)
            if (!cached(cache_key_of(v))) ahead.push_back(v);
          if (ahead.size() < 2 || !compiles_ahead) return;  // one kernel: built by its measurement
          advance(run, task_start + task_done,
                  device_name + ": compiling " + std::to_string(ahead.size()) + " kernels for " + key);
          worker.CompileAhead(ahead, TuningDataset{key});
        };
        compile_ahead(task.baselines);
        const Evaluator evaluate = [&](const Variant& v) -> std::optional<double> {
          const std::string cache_key = cache_key_of(v);
          Measurement m;
          const std::optional<Measurement> found = cached(cache_key);
          if (found) {
            m = *found;
            ApplyBudget(m, config.max_error);  // this run's budget, whatever the record's was
          } else {
            m = worker.Measure(v, TuningDataset{key}, timing);
            ApplyBudget(m, config.max_error);
            if (run.copy_gbps) RejectOverCeiling(m, *run.copy_gbps);
            std::lock_guard<std::mutex> lock(shared);
            cache.Append(m);  // on disk before the next variant
          }
          if (seen.insert(cache_key).second) {
            run.measurements.push_back(m);
            task_done = std::min(task_done + 1, task.planned);
            // The variant and its result first: a progress bar cuts the end of long lines.
            advance(run, task_start + task_done,
                    v.Key() + ": " + ShortStatus(m) + " [" + device_name + ", " + key + "]" +
                        (found ? " (cached)" : ""));
          }
          if (m.status != MeasureStatus::kOk) return std::nullopt;
          return m.timing.median_ms;
        };
        const std::size_t first_of_task = run.measurements.size();
        for (const Variant& b : task.baselines) evaluate(b);
        StrategyOptions strategy = config.strategy;
        strategy.margin = timing.tie_margin;  // moves beyond noise only (strategy.h)
        if (!task.candidates.empty()) Search(task.candidates, evaluate, strategy, compile_ahead);
        // The search settled by races of its leader's neighbourhood, in this device's worker (race.h).
        const auto measured = [&] {
          return std::vector<Measurement>(run.measurements.begin() + static_cast<std::ptrdiff_t>(first_of_task),
                                          run.measurements.end());
        };
        if (!measured().empty()) {
          advance(run, task_start + task_done, device_name + ": racing the leaders of " + key);
          RaceMemo memo;
          memo.find = [&](const std::string& race_key) -> std::optional<RaceRecord> {
            std::lock_guard<std::mutex> lock(shared);
            const RaceRecord* found = cache.FindRace(race_key);
            return found ? std::optional<RaceRecord>(*found) : std::nullopt;
          };
          memo.keep = [&](const std::string& race_key, const RaceRecord& race) {
            std::lock_guard<std::mutex> lock(shared);
            cache.AppendRace(race_key, race);
          };
          bool cached_race = false;
          // The walk may spend the search's budget once more (docs/TUNING.md "Races and ties").
          const SearchToSettle search{task.candidates, evaluate, measured, compile_ahead,
                                      config.strategy.budget > 0 ? config.strategy.budget : kSettleWalkDefault};
          const Racer racer = [&](const std::vector<Variant>& variants, std::string* why) {
            std::vector<RaceSamples> legs;
            for (int leg = 0; leg < RaceLegsFor(device.identity); ++leg) {
              if (leg > 0) worker.Restart();  // the next leg in a fresh process
              std::optional<RaceSamples> samples = worker.Race(variants, TuningDataset{key}, timing, why);
              if (!samples) return std::optional<std::vector<RaceSamples>>();
              legs.push_back(std::move(*samples));
            }
            return std::optional<std::vector<RaceSamples>>(std::move(legs));
          };
          run.races.push_back(SettleSearch(racer, search, id, task.lang, key, timing, memo, &cached_race));
          if (cached_race) advance(run, task_start + task_done, device_name + ": the race of " + key + " (cached)");
        }
        task_start += task.planned;
        advance(run, task_start, "");
      }
    } catch (const WorkerError& e) {
      // This device cannot be used: the run goes on with the others.
      run.given_up = e.what();
      advance(run, run.planned, device_name + ": given up: " + e.what());
    }
    advance(run, run.planned, "");
  };

  std::vector<std::size_t> with_work;
  for (std::size_t di = 0; di < devices.size(); ++di) {
    if (!runs[di].has_tasks) continue;  // none of the space's languages: not measured, not reported
    report.devices.push_back(devices[di].identity);
    if (runs[di].planned > 0) with_work.push_back(di);  // else only invalid points: recorded, nothing to measure
  }
  std::vector<DeviceIdentity> identities;
  for (std::size_t di : with_work) identities.push_back(devices[di].identity);
  std::vector<std::vector<std::size_t>> groups = IndependentGroups(identities);
  if (!options.parallel_devices && groups.size() > 1) {
    std::vector<std::size_t> all;
    for (const auto& g : groups) all.insert(all.end(), g.begin(), g.end());
    std::sort(all.begin(), all.end());
    groups = {all};
  }
  // A CPU device tuned at the same time as another group: the workers share
  // a lock on the host's cores, so that no GPU's host work runs while a CPU
  // device is timing.
  const auto is_cpu = [&](std::size_t i) { return identities[i].type.find("cpu") != std::string::npos; };
  bool cpu_beside_other = false;
  for (const auto& g : groups)
    cpu_beside_other = cpu_beside_other || (groups.size() > 1 && std::any_of(g.begin(), g.end(), is_cpu));
  if (cpu_beside_other) {
    host_lock = std::make_unique<tuner_internal::HostLockFile>();
    if (host_lock->path().empty()) host_lock.reset();
  }
  // A group of GPU devices (the APIs of one GPU: they share it) is tuned one
  // device after another. While one is measured, workers of their own
  // compile the later devices' kernels into the program cache (host work:
  // the shared host lock), so each device starts with its compiles done, as
  // in a warm run (on the H100 a cold `skintune run` spent about 20 s more
  // than a warm one, most of it compiling one API after another). Every
  // candidate not yet measured is compiled: the search's choices are not
  // known ahead. Not for CPU devices (their compiles would take the cores
  // they and their neighbours time on), nor on hosts of fewer than 8 threads.
  const auto precompiles = [&](const std::vector<std::size_t>& group) {
    return group.size() > 1 && std::thread::hardware_concurrency() >= 8 &&
           std::none_of(group.begin(), group.end(), is_cpu);
  };
  auto precompile = [&](const std::vector<std::size_t>& group, const std::atomic<std::size_t>& reached) {
    for (std::size_t k = 1; k < group.size(); ++k) {
      if (reached.load() >= k) continue;  // its turn came: it compiles its own
      const Device& device = devices[with_work[group[k]]];
      if (!CompilesAhead(device.identity)) continue;
      try {
        IsolatedBackend worker(options.worker_executable, device.identity, config.variant_timeout_s);
        if (host_lock) worker.UseHostLock(host_lock->path());
        for (const Task& task : tasks) {
          if (task.device != with_work[group[k]] || reached.load() >= k) continue;
          const std::string& key = datasets[task.dataset].info.key;
          std::vector<Variant> ahead;
          for (const std::vector<Variant>* list : {&task.baselines, &task.candidates})
            for (const Variant& v : *list) {
              const std::string cache_key = CacheKeyOf(device.identity.Id(), key, v);
              std::lock_guard<std::mutex> lock(shared);
              if (!cache.Find(cache_key)) ahead.push_back(v);
            }
          if (ahead.size() >= 2) worker.CompileAhead(ahead, TuningDataset{key});
        }
      } catch (...) {
        // Only a head start lost: the device's own worker compiles and records any failure.
      }
    }
  };
  std::vector<std::exception_ptr> errors(groups.size());
  auto tune_group = [&](std::size_t g) {
    std::atomic<std::size_t> reached{0};
    std::thread ahead;
    try {
      if (precompiles(groups[g])) ahead = std::thread(precompile, std::cref(groups[g]), std::cref(reached));
      for (std::size_t k = 0; k < groups[g].size(); ++k) {
        reached = k;
        tune_device(with_work[groups[g][k]]);
      }
    } catch (...) {
      errors[g] = std::current_exception();
    }
    reached = groups[g].size();
    if (ahead.joinable()) ahead.join();
  };
  std::vector<std::thread> threads;
  for (std::size_t g = 1; g < groups.size(); ++g) threads.emplace_back(tune_group, g);
  if (!groups.empty()) tune_group(0);
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);

  std::size_t devices_failed = 0;
  for (std::size_t di = 0; di < devices.size(); ++di) {
    const DeviceRun& run = runs[di];
    if (!run.has_tasks) continue;
    for (const Task& t : tasks)
      if (t.device == di) report.measurements.insert(report.measurements.end(), t.invalid.begin(), t.invalid.end());
    report.measurements.insert(report.measurements.end(), run.measurements.begin(), run.measurements.end());
    report.races.insert(report.races.end(), run.races.begin(), run.races.end());
    if (run.copy_gbps) report.copy_bandwidth_gbps[devices[di].identity.Id()] = *run.copy_gbps;
    if (run.given_up) {
      ++devices_failed;
      report.skipped.push_back(devices[di].identity.Id() + ": " + *run.given_up);
    }
  }
  if (!with_work.empty() && devices_failed == with_work.size()) {
    std::string why;
    for (const std::string& s : report.skipped) why += (why.empty() ? "" : "; ") + s;
    throw Error("no device could be tuned: " + why);
  }
  report.created = UtcTimestamp();  // when the run finished
  progress(total, total, "done");
  return report;
}

}  // namespace skintune::internal
