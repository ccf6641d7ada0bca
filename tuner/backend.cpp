// skintune: discovery of every device (the runtime's, runtime/backend_table.h),
// the injected faults, and the one Measure procedure (tuner/backends_internal.h).
#include "tuner/backend.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <limits>
#include <sstream>
#if defined(__GLIBC__)
#include <malloc.h>  // malloc_trim
#endif

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "model/gltf_import.h"
#include "model/synthetic.h"
#include "tuner/backends_internal.h"
#include "tuner/host_lock.h"

namespace skintune::internal {

// ---------------------------------------------------------------- injected faults

namespace {

// "compile, wrong, hang, crash or lost"
std::string FaultKindList() {
  return OneOf(kInjectedFaultKinds, [](const char* kind) { return std::string(kind); });
}

}  // namespace

InjectedFault InjectedFaultFromEnvironment() {
  const char* env = std::getenv("SKINTUNE_INJECT_FAULT");
  if (!env || !*env) return {};
  const std::string text = env;
  const std::size_t at = text.rfind('=');
  const std::string why = "SKINTUNE_INJECT_FAULT='" + text + "': ";
  if (at == std::string::npos || at == 0) throw Error(why + "expected <variant key>=<kind>, the kind " + FaultKindList());
  InjectedFault fault;
  fault.kind = text.substr(at + 1);
  if (std::find(std::begin(kInjectedFaultKinds), std::end(kInjectedFaultKinds), fault.kind) == std::end(kInjectedFaultKinds))
    throw Error(why + "unknown fault '" + fault.kind + "' (" + FaultKindList() + ")");
  // The canonical key, so that the tokens may be given in any order.
  fault.variant_key = ParseVariantKey(text.substr(0, at)).Key();
  return fault;
}

// ---------------------------------------------------------------- timing options

namespace {

// The fields of TimingOptions, declared once for the reader and the writer.
struct TimingField {
  const char* name;
  enum Kind { kInt, kCount, kNumber } kind;
  int* as_int;
  std::size_t* as_count;
  double* as_number;
};

std::vector<TimingField> Fields(TimingOptions& t) {
  return {{"warmup", TimingField::kInt, &t.warmup, nullptr, nullptr},
          {"repetitions", TimingField::kInt, &t.repetitions, nullptr, nullptr},
          {"max_input_sets", TimingField::kInt, &t.max_input_sets, nullptr, nullptr},
          {"tolerance", TimingField::kNumber, nullptr, nullptr, &t.tolerance},
          {"burst_ms", TimingField::kNumber, nullptr, nullptr, &t.burst_ms},
          {"interval", TimingField::kNumber, nullptr, nullptr, &t.stop.interval},
          {"min_samples", TimingField::kCount, nullptr, &t.stop.min_samples, nullptr},
          {"max_samples", TimingField::kCount, nullptr, &t.stop.max_samples, nullptr},
          {"sample_batch", TimingField::kCount, nullptr, &t.stop.batch, nullptr},
          {"sample_ms", TimingField::kNumber, nullptr, nullptr, &t.stop.max_ms},
          {"race", TimingField::kInt, &t.race, nullptr, nullptr},
          {"tie_margin", TimingField::kNumber, nullptr, nullptr, &t.tie_margin},
          {"host_tie_margin", TimingField::kNumber, nullptr, nullptr, &t.host_tie_margin}};
}

std::string Dumped(const nlohmann::json& v) {
  std::string text = v.dump();
  return text.size() > 40 ? text.substr(0, 40) + "..." : text;
}

}  // namespace

TimingOptions TimingOptionsFromJson(const nlohmann::json& in, const std::string& where) {
  if (!in.is_object()) throw Error(where + ": expected an object");
  TimingOptions t;
  std::vector<TimingField> fields = Fields(t);
  for (const auto& [name, value] : in.items()) {
    const auto field = std::find_if(fields.begin(), fields.end(), [&key = name](const TimingField& f) { return key == f.name; });
    if (field == fields.end()) {
      std::string list;
      for (const TimingField& f : fields) list += (list.empty() ? "" : ", ") + std::string(f.name);
      throw Error(where + "." + name + ": unknown field (expected one of " + list + ")");
    }
    const std::string at = where + "." + name;
    if (field->kind == TimingField::kNumber) {
      if (!value.is_number()) throw Error(at + ": expected a number (got " + Dumped(value) + ")");
      *field->as_number = value.get<double>();
      if (!std::isfinite(*field->as_number)) throw Error(at + ": must be finite (got " + Dumped(value) + ")");
      continue;
    }
    if (!value.is_number_integer()) throw Error(at + ": expected an integer (got " + Dumped(value) + ")");
    const long long v = value.get<long long>();
    const long long least = field->kind == TimingField::kCount || name == "repetitions" || name == "max_input_sets" ? 1 : 0;
    if (v < least || v > 1000000)
      throw Error(at + ": must be an integer from " + std::to_string(least) + " to 1000000 (got " + std::to_string(v) + ")");
    if (field->as_int) *field->as_int = static_cast<int>(v);
    if (field->as_count) *field->as_count = static_cast<std::size_t>(v);
  }
  for (const auto& [name, value] : {std::pair<const char*, double>{"burst_ms", t.burst_ms}, {"tolerance", t.tolerance}})
    if (!(value > 0.0)) throw Error(where + "." + name + ": must be a positive number (got " + Dumped(in.at(name)) + ")");
  // A verification that passes any output would let a wrong kernel win: a setting that cannot work.
  if (t.tolerance > kMaxTolerance)
    throw UsageError(where + ".tolerance: must be a positive number at most 0.001 (got " + Dumped(in.at("tolerance")) + ")");
  const std::string prefix = where.substr(where.rfind(' ') == std::string::npos ? 0 : where.rfind(' ') + 1) + ".";
  if (const std::string bad = BadStopRule(t.stop, prefix); !bad.empty()) throw UsageError(where + ": " + bad);
  for (const auto& [name, value] : {std::pair<const char*, double>{"tie_margin", t.tie_margin}, {"host_tie_margin", t.host_tie_margin}})
    if (!(value > 0.0) || value > 0.5)
      throw UsageError(where + ": '" + prefix + name + "' is " + Dumped(in.at(name)) +
                       ": a relative difference in (0, 0.5] (0.02: 2%)");
  return t;
}

double TimingOptions::MarginFor(const DeviceIdentity& device) const {
  return device.type.find("cpu") != std::string::npos ? host_tie_margin : tie_margin;
}

nlohmann::json ToJson(const TimingOptions& t) {
  TimingOptions copy = t;
  nlohmann::json out = nlohmann::json::object();
  for (const TimingField& f : Fields(copy)) {
    if (f.as_int) out[f.name] = *f.as_int;
    if (f.as_count) out[f.name] = *f.as_count;
    if (f.as_number) out[f.name] = *f.as_number;
  }
  return out;
}

// ---------------------------------------------------------------- discovery

Discovery DiscoverBackends() {
  using namespace tuner_internal;
  Discovered found = DiscoverDevices();
  Discovery discovery;
  discovery.skipped = std::move(found.skipped);
  int index = 0;
  for (FoundDevice& device : found.devices) {
    const BackendEntry* entry = FindBackend(device.identity.backend);
    discovery.backends.push_back(MakeDeviceBackend(std::move(device), entry->languages, index++));
  }
  return discovery;
}

// ---------------------------------------------------------------- shared by the backends

namespace tuner_internal {

int InputSetsFor(std::uint64_t last_level_cache_bytes, std::uint64_t bytes_per_set, int max_input_sets) {
  const std::uint64_t llc = last_level_cache_bytes ? last_level_cache_bytes : kUnknownLastLevelCacheBytes;
  const int most = std::max(max_input_sets, 1);
  if (bytes_per_set == 0) return most;
  const std::uint64_t wanted = (2 * llc + bytes_per_set - 1) / bytes_per_set;
  int sets = static_cast<int>(std::clamp<std::uint64_t>(wanted, 1, static_cast<std::uint64_t>(most)));
  // Even: CUDA's and OpenCL's two lanes take frames in turn, frame f set
  // f % sets, so each lane keeps to sets of its own parity and the lanes,
  // which may drift apart within a burst, never read one set at once (with
  // 3 sets NVIDIA's OpenCL timed a 43 MB copy at 3.7 TB/s, over HBM3's peak).
  if (sets > 1 && sets % 2 == 1) sets = sets + 1 <= most ? sets + 1 : sets - 1;
  return sets;
}

bool IsGltfPath(const std::string& key) {
  std::string extension = std::filesystem::path(key).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension == ".gltf" || extension == ".glb";
}

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
  entry->verification_palette = ScenePalettes(entry->scene, 1).front();
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
GoldResult SceneGold(const DatasetCache::Entry& entry, const SkinnedMesh& mesh, bool normals) {
  const int k = entry.instances();
  if (k == 1) return SkinGold(mesh, entry.verification_palette, normals);
  GoldResult all;
  const std::size_t joints = static_cast<std::size_t>(mesh.joint_count);
  for (int i = 0; i < k; ++i) {
    GoldResult one = SkinGold(mesh, std::span(entry.verification_palette).subspan(i * joints, joints), normals);
    all.positions.insert(all.positions.end(), one.positions.begin(), one.positions.end());
    all.normals.insert(all.normals.end(), one.normals.begin(), one.normals.end());
  }
  return all;
}

}  // namespace

const GoldResult& DatasetCache::Gold(Entry& entry, const Variant& variant) {
  const std::pair<int, bool> key{static_cast<int>(variant.weight), variant.normals};
  if (auto found = entry.gold.find(key); found != entry.gold.end()) return found->second;
  GoldResult gold = SceneGold(entry, QuantisedMesh(entry.mesh(), variant), variant.normals);
  return entry.gold.emplace(key, std::move(gold)).first->second;
}

const GoldResult& DatasetCache::SourceGold(Entry& entry, bool normals) {
  if (auto found = entry.source_gold.find(normals); found != entry.source_gold.end()) return found->second;
  GoldResult gold = SceneGold(entry, entry.mesh(), normals);
  return entry.source_gold.emplace(normals, std::move(gold)).first->second;
}

namespace {

// abs / diagonal; a part of one point (diagonal 0): any error is all of it.
double Relative(double abs, double diagonal) { return diagonal > 0.0 ? abs / diagonal : (abs > 0.0 ? 1.0 : 0.0); }

}  // namespace

double DatasetCache::QuantisationError(Entry& entry, const Variant& variant) {
  const std::pair<int, bool> key{static_cast<int>(variant.weight), variant.normals};
  if (auto found = entry.quantisation.find(key); found != entry.quantisation.end()) return found->second;
  const std::span<const glm::dvec3> gold = Gold(entry, variant).positions;
  const std::span<const glm::dvec3> source = SourceGold(entry, variant.normals).positions;
  double error = 0.0;
  for (const Part& part : entry.parts)
    error = std::max(error, Relative(MaxDistance(gold.subspan(part.first, part.count),
                                                 source.subspan(part.first, part.count)),
                                     part.diagonal));
  return entry.quantisation.emplace(key, error).first->second;
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
  kernels.clear();
  for (const Launch& launch : packed.launches)
    kernels.push_back(Emit(variant, launch.influences, static_cast<int>(packed.palette_joints), emit));
  return packed;
}

namespace {

// The stage a runner's Error names ("<API> <stage>: ..."), or "".
std::string RunnerErrorStage(const std::string& message) {
  // The API is one word ("OpenCL", "CUDA", "GL").
  const std::size_t space = message.find(' ');
  const std::size_t colon = message.find(':');
  if (space == std::string::npos || colon == std::string::npos || space > colon) return "";
  return message.substr(space + 1, colon - space - 1);
}

}  // namespace

MeasureStatus StatusOfRunnerError(const std::string& message) {
  const std::string stage = RunnerErrorStage(message);
  if (stage == "build") return MeasureStatus::kCompileFailed;
  if (stage == "guard") return MeasureStatus::kVerifyFailed;
  return MeasureStatus::kLaunchFailed;
}

bool DeviceLostIn(const std::string& detail) {
  const std::string timing = "timing: ";
  return RunnerErrorStage(detail.rfind(timing, 0) == 0 ? detail.substr(timing.size()) : detail) == "lost";
}

namespace {

// Replaces the one occurrence of `marker` (the last one) in the kernel text
// with `replacement`; throws when the template has none.
void EditAt(KernelSource& source, const std::string& marker, const std::string& before, const std::string& after,
            const std::string& kind) {
  const std::size_t at = source.text.rfind(marker);
  if (at == std::string::npos)
    throw Error("injected fault '" + kind + "': the " + Name(source.lang) + " kernel has no '" + marker +
                "' any more (update InjectFault in tuner/backend.cpp)");
  const std::size_t line_start = source.text.rfind('\n', at) + 1;  // npos + 1 = 0
  std::size_t line_end = source.text.find('\n', at);
  if (line_end == std::string::npos) line_end = source.text.size();
  source.text.insert(line_end, after);
  source.text.insert(line_start, before);
}

// The injected hang: a loop no compiler can bound, with a side effect in
// every iteration. It spins while the first word of the first input is not
// 0xffffffff, which no input word ever is (a NaN position, joint 65535 in
// every slot...) and which the host never writes; the compiler cannot know
// that word. OpenCL and CUDA read it volatile and store to a volatile counter
// each iteration (C and C++ may assume that a loop without volatile access,
// atomics or I/O terminates).
//
// GLSL: Mesa's llvmpipe caps every shader invocation at 65535 loop
// iterations in all (gallivm's loop limiter, LP_MAX_TGSI_LOOP_ITERATIONS: a
// counter in the generated code), so no GLSL loop can spin forever there, and
// a spin on a volatile read alone finished in 0.6 s per run (5000 vertices)
// and passed as ok. Each iteration therefore makes 256 atomic adds to the
// input word after the one it tests, of 0, which the compiler cannot know:
// an atomic is never removed, and it makes the test be read again. Measured
// on 2 cores of llvmpipe: one atomic per iteration takes a run from 0.6 s to
// 2 s; 256 of them put a capped run at minutes (over 60 s measured), far
// beyond any variant time limit. Elsewhere the loop never ends.
std::string HangLoop(const KernelSource& source, const std::string& input) {
  const std::string mark = "  // skintune injected fault: hang\n";
  if (source.lang == Lang::kOpenCl) {
    return "    { volatile uint skintune_spins = 0u;\n"
           "      while (((volatile const __global uint*)" + input + ")[0] != 0xffffffffu) skintune_spins = skintune_spins + 1u; }" + mark;
  }
  if (source.lang == Lang::kCuda) {
    return "    { volatile unsigned int skintune_spins = 0u;\n"
           "      while (reinterpret_cast<const volatile unsigned int*>(" + input +
           ")[0] != 0xffffffffu) skintune_spins = skintune_spins + 1u; }" + mark;
  }
  std::string body;
  for (int i = 0; i < 256; ++i) body += "        atomicAdd(skintune_hang[1], skintune_zero);\n";
  return "    { const uint skintune_zero = skintune_hang[0] == 0xffffffffu ? 1u : 0u;\n"
         "      while (skintune_hang[0] != 0xffffffffu) {\n" + body + "      } }" + mark;
}

}  // namespace

void InjectFault(KernelSource& source, const Variant& variant, const std::string& kind) {
  if (source.lang == Lang::kCpu) {
    // The cpu kernel text is a parameter block (templates/skin.cpu): a line
    // that is not one fails its build; the wrong and hang faults are
    // parameters the cpu device honours (runtime/backends/cpu/cpu_runner.cpp).
    if (kind == "compile") {
      source.text += "\nskintune injected compile fault: this is not a parameter (\n";
    } else if (kind == "wrong" || kind == "hang") {
      source.text += std::string("#define ") + (kind == "wrong" ? "SKINTUNE_FAULT_WRONG" : "SKINTUNE_FAULT_HANG") +
                     " 1  // skintune injected fault: " + kind + "\n";
    } else {
      throw Error("injected fault: kind '" + kind + "' is not a kernel edit (compile, wrong or hang)");
    }
    source.source_hash = SourceHash(source.text);
    return;
  }
  const bool glsl = IsGlslText(source.lang);
  const std::string input = variant.layout == Layout::kAos ? "records" : "positions";
  // Every template skins a vertex with one call whose last two arguments are
  // the skinned position and normal, in the kernel's loop over its vertices
  // (v in scope), after the shared helpers: the last such line is in the
  // kernel body (GLSL: skin_vertex in main(); OpenCL/CUDA: blend).
  const std::string marker = glsl ? " skinned_position, skinned_normal);" : "&skinned_position, &skinned_normal);";
  if (kind == "compile") {
    source.text += "\nskintune injected compile fault: this is not a kernel language (\n";
  } else if (kind == "wrong") {
    const std::string one = glsl ? "1.0" : "1.0f";
    EditAt(source, marker, "", "\n    if (v == 0u) skinned_position.x += " + one + ";  // skintune injected fault: wrong",
           kind);
  } else if (kind == "hang") {
    const std::string loop = HangLoop(source, input);
    if (glsl) {
      // A writable view of binding 0 (the first input in every layout, at
      // least two words): its atomics add 0.
      const std::string block =
          "layout(std430, binding = 0) volatile buffer SkintuneHang { uint skintune_hang[]; };\n";
      const std::size_t main_at = source.text.rfind("void main()");
      if (main_at == std::string::npos)
        throw Error("injected fault 'hang': the GLSL kernel has no 'void main()' any more (update InjectFault)");
      source.text.insert(main_at, block);
    }
    EditAt(source, marker, loop, "", kind);
  } else {
    throw Error("injected fault: kind '" + kind + "' is not a kernel edit (compile, wrong or hang)");
  }
  source.source_hash = SourceHash(source.text);
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double CopyGBps(std::size_t bytes, const std::vector<double>& ms) {
  const double median = Median(ms);
  if (!(median > 0.0)) throw Error("copy kernel: no positive time measured");
  return 2.0 * static_cast<double>(bytes) / median / 1e6;
}

std::size_t CopyBytesCapped(std::size_t bytes, std::uint64_t max_allocation_bytes) {
  constexpr std::size_t kGranule = 4096;
  std::uint64_t capped = bytes;
  if (max_allocation_bytes > 0) capped = std::min<std::uint64_t>(capped, max_allocation_bytes / 4);
  capped -= capped % kGranule;
  return static_cast<std::size_t>(std::max<std::uint64_t>(capped, kGranule));
}

std::string UtcTimestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

namespace {

std::string Scientific(double value) {
  std::ostringstream out;
  out.precision(2);
  out << std::scientific << value;
  return out.str();
}

// "positions: max relative error 3.1e-02 at vertex 17" or the non-finite count;
// empty when within tolerance.
std::string Disagreement(const char* what, const GoldComparison& c, double tolerance) {
  if (c.non_finite > 0)
    return std::string(what) + ": " + std::to_string(c.non_finite) + " non-finite vertices, the first at vertex " +
           std::to_string(c.worst_vertex);
  if (c.max_relative > tolerance)
    return std::string(what) + ": max relative error " + Scientific(c.max_relative) + " at vertex " +
           std::to_string(c.worst_vertex) + " (tolerance " + Scientific(tolerance) + ")";
  return "";
}

// The outputs of K instances (packed order, instance after instance) as
// one vec3 per vertex in the mesh's order, instance after instance.
std::vector<glm::vec3> UnpackInstances(const PackedMesh& packed, std::span<const std::uint8_t> output, int instances) {
  if (instances == 1) return Unpack(packed, output);
  const std::size_t bytes = packed.vertex_count * packed.output_stride_bytes;
  if (output.size() != bytes * static_cast<std::size_t>(instances))
    throw Error("UnpackInstances: " + std::to_string(output.size()) + " output bytes for " + std::to_string(instances) +
                " instances of " + std::to_string(bytes));
  std::vector<glm::vec3> all;
  for (int i = 0; i < instances; ++i) {
    const std::vector<glm::vec3> one = Unpack(packed, output.subspan(static_cast<std::size_t>(i) * bytes, bytes));
    all.insert(all.end(), one.begin(), one.end());
  }
  return all;
}

std::string DatasetName(const std::string& key) {
  return IsGltfPath(key) ? std::filesystem::path(key).filename().string() : key;
}

}  // namespace

Measurement MeasureWith(Executor& executor, DatasetCache& datasets, const DeviceIdentity& identity,
                        const DeviceLimits& limits, const std::vector<Lang>& languages, const Variant& variant,
                        const TuningDataset& dataset, const TimingOptions& options) {
  const InjectedFault fault = InjectedFaultFromEnvironment();
  const bool faulty = !fault.kind.empty() && fault.variant_key == variant.Key();
  if (faulty && fault.kind == "crash") std::abort();  // the test hook: the worker process must survive this
  // The test hook "lost": from this variant on, nothing measures in this process.
  static bool injected_lost = false;
  if (faulty && fault.kind == "lost") injected_lost = true;

  Measurement m;
  m.device_id = identity.Id();
  m.dataset = DatasetName(dataset.key);
  m.variant = variant;
  m.generator_version = kGeneratorVersion;
  m.timestamp = UtcTimestamp();
  auto finish = [&](MeasureStatus status, std::string detail) {
    m.status = status;
    m.detail = std::move(detail);
    return m;
  };

  if (injected_lost)
    return finish(MeasureStatus::kLaunchFailed, identity.backend + " lost: the device was lost in this process (injected fault 'lost')");

  DatasetCache::Entry& data = datasets.Get(dataset.key);
  const SkinnedMesh& mesh = data.mesh();
  const int instances = data.instances();

  // Can it run here at all?
  if (std::find(languages.begin(), languages.end(), variant.lang) == languages.end())
    return finish(MeasureStatus::kInvalid, std::string("language ") + Name(variant.lang) + " does not run on " +
                                        identity.backend + " device " + identity.name);
  const ProblemShape shape{mesh.joint_count, mesh.influences, mesh.has_normals(), instances};
  const std::vector<Violation> violations = CheckVariant(variant, limits, shape);
  if (!violations.empty()) {
    std::string detail;
    for (const Violation& v : violations) detail += (detail.empty() ? "" : "; ") + std::string(Name(v.constraint)) + ": " + v.message;
    return finish(MeasureStatus::kInvalid, detail);
  }
  // The host's cores (tuner/host_lock.h): a GPU's host-side work waits while
  // a CPU device beside it is timing; a CPU device's bursts hold them alone.
  const bool cpu_device = identity.type.find("cpu") != std::string::npos;
  HostLock host_work(HostWorkMode(cpu_device));
  // Each phase's wall time, for the timing log (SKINTUNE_TIMING_LOG).
  using Clock = std::chrono::steady_clock;
  auto mark = Clock::now();
  std::string phases;
  const auto phase = [&](const char* name) {
    const auto now = Clock::now();
    if (TimingLogPath())
      phases += std::string(phases.empty() ? "" : ", ") + name + " " +
                std::to_string(std::chrono::duration<double, std::milli>(now - mark).count()) + " ms";
    mark = now;
  };
  const PackedMesh* packed_at = nullptr;  // DatasetCache's packing: nothing packs again during this measurement
  std::vector<KernelSource> kernels;
  try {
    packed_at = &PackScene(datasets, data, variant, kernels);
  } catch (const Error& e) {
    return finish(MeasureStatus::kInvalid, e.what());
  }
  const PackedMesh& packed = *packed_at;
  if (faulty && fault.kind != "lost")
    for (KernelSource& k : kernels) InjectFault(k, variant, fault.kind);

  // Verify first: one run on poisoned outputs with guards, against the gold,
  // each part of the scene (an instance, a batch's mesh) against its own.
  phase("pack");
  Executor::Output output;
  try {
    output = executor.Run(packed, kernels, PackPalette(data.verification_palette, variant), instances);
  } catch (const Error& e) {
    return finish(StatusOfRunnerError(e.what()), e.what());
  }
  phase("run (build, upload, verification launch, read-back)");
  const GoldResult& gold = datasets.Gold(data, variant);
  const std::vector<glm::vec3> out_positions = UnpackInstances(packed, output.positions, instances);
  std::vector<glm::vec3> out_normals;
  if (variant.normals) out_normals = UnpackInstances(packed, output.normals, instances);
  std::string disagreement;
  for (const DatasetCache::Part& part : data.parts) {
    auto slice = [&](const auto& all) { return std::span(all).subspan(part.first, part.count); };
    const GoldComparison positions = CompareToGold(slice(gold.positions), slice(out_positions));
    m.max_relative_error = std::max(m.max_relative_error, positions.max_relative);
    std::string wrong = Disagreement("positions", positions, options.tolerance);
    if (variant.normals) {
      const GoldComparison normals = CompareToGold(slice(gold.normals), slice(out_normals));
      m.max_relative_error = std::max(m.max_relative_error, normals.max_relative);
      const std::string n = Disagreement("normals", normals, options.tolerance);
      if (!n.empty()) wrong += (wrong.empty() ? "" : "; ") + n;
    }
    // The first wrong part says enough (a scene may have 64 instances).
    if (!wrong.empty() && disagreement.empty()) disagreement = part.name.empty() ? wrong : part.name + ": " + wrong;
  }
  if (output.poisoned_vertices > 0)
    disagreement = std::to_string(output.poisoned_vertices) + " output vectors never written (still poisoned)" +
                   (disagreement.empty() ? "" : "; " + disagreement);
  if (!disagreement.empty()) return finish(MeasureStatus::kVerifyFailed, "wrong results against the float64 gold: " + disagreement);

  // Verified: what the output is worth against the unquantised source, the
  // worst part relative to its own diagonal.
  const GoldResult& source = datasets.SourceGold(data, variant.normals);
  SourceError& error = m.source_error;
  error.known = true;
  for (const DatasetCache::Part& part : data.parts) {
    auto slice = [&](const auto& all) { return std::span(all).subspan(part.first, part.count); };
    const double abs = CompareToGold(slice(source.positions), slice(out_positions)).max_absolute;
    if (&part == &data.parts.front() || Relative(abs, part.diagonal) > error.position_rel) {
      error.diagonal = part.diagonal;
      error.position_abs = abs;
      error.position_rel = Relative(abs, part.diagonal);
    }
    if (variant.normals)
      error.normal_abs = std::max(error.normal_abs, CompareToGold(slice(source.normals), slice(out_normals)).max_absolute);
  }
  error.quantisation_rel = datasets.QuantisationError(data, variant);

  // Then time: the kernel time (cold samples rotating among K input sets of
  // different frames, to the stop rule), the frame time, and the same-size
  // copy's kernel time by the same method.
  // The bytes of the scene's frame: K instances move what K copies of the
  // mesh would (so the same-size copy is that of one mesh of the scene's
  // total bytes, even when an instanced kernel finds its inputs in cache).
  const std::uint64_t bytes_per_frame = FrameBytes(packed, instances);
  m.bytes_per_frame = static_cast<double>(bytes_per_frame);
  const int sets = InputSetsFor(identity.last_level_cache_bytes, bytes_per_frame, options.max_input_sets);
  const std::vector<std::vector<std::uint8_t>> palettes = TimedPalettes(datasets, data, variant, sets);
  phase("check against the gold and the source");
  host_work.Release();
  const HostLock timed(TimedMode(cpu_device));  // through the copy's samples
  try {
    const std::unique_ptr<Executor::Timed> prepared = executor.Prepare(packed, kernels, palettes, instances);
    RecordKernelTime(m, SampleKernelTime(*prepared, options), executor, sets, prepared->bytes_per_set());
    m.timing.warmup = std::max(options.warmup, 1);  // SampleKernelTime runs at least one
    phase("kernel time");
    m.timing.frame_ms = SampleFrameTime(*prepared, options, &m.timing.burst_frames);
    phase("frame time");
  } catch (const Error& e) {
    return finish(StatusOfRunnerError(e.what()), std::string("timing: ") + e.what());
  }
  std::string copy_problem;
  try {
    const KernelTime& copy = executor.CopyTime(variant.lang, bytes_per_frame, sets, options);
    m.timing.copy_ms = copy.interval.median;
    m.x_copy = m.timing.median_ms / copy.interval.median;
  } catch (const Error& e) {
    copy_problem = std::string("the same-size copy failed: ") + e.what();
  }
  phase("copy");
  TimingLog([&] { return variant.Key() + " phases: " + phases; });
  return finish(MeasureStatus::kOk, copy_problem);  // a kernel without its copy is still measured
}

std::uint64_t FrameBytes(const PackedMesh& packed, int instances) {
  std::uint64_t bytes = 0;
  for (const Launch& launch : packed.launches)
    for (const PackedBuffer& b : launch.inputs) bytes += b.bytes.size();
  bytes += packed.vertex_count * packed.output_stride_bytes * (packed.variant.normals ? 2 : 1);
  bytes += packed.palette.size();
  return bytes * static_cast<std::uint64_t>(instances);
}

std::vector<std::vector<std::uint8_t>> TimedPalettes(DatasetCache& datasets, DatasetCache::Entry& data,
                                                     const Variant& variant, int sets) {
  std::vector<std::vector<std::uint8_t>> palettes;
  for (const std::vector<glm::mat4>& palette : datasets.Frames(data, sets)) palettes.push_back(PackPalette(palette, variant));
  return palettes;
}

std::vector<std::vector<double>> RaceWith(Executor& executor, DatasetCache& datasets, const DeviceIdentity& identity,
                                          const std::vector<Variant>& variants, const TuningDataset& dataset,
                                          const TimingOptions& options) {
  using Clock = std::chrono::steady_clock;
  DatasetCache::Entry& data = datasets.Get(dataset.key);
  const bool cpu_device = identity.type.find("cpu") != std::string::npos;
  std::vector<std::unique_ptr<Executor::Timed>> timed;
  std::vector<RaceEntry> entries;
  {
    const HostLock host_work(HostWorkMode(cpu_device));
    for (const Variant& v : variants) {
      std::vector<KernelSource> kernels;
      const PackedMesh& packed = PackScene(datasets, data, v, kernels);  // valid until the next packing
      const int sets = InputSetsFor(identity.last_level_cache_bytes, FrameBytes(packed, data.instances()), options.max_input_sets);
      timed.push_back(executor.Prepare(packed, kernels, TimedPalettes(datasets, data, v, sets), data.instances()));
      entries.push_back({v.Key(), {}, 0.0, 0.0});
    }
  }
  const HostLock timed_lock(TimedMode(cpu_device));
  const StopRule& rule = options.stop;
  for (const std::unique_ptr<Executor::Timed>& t : timed) (void)t->Cold(std::max(options.warmup, 1), 0);  // as SampleKernelTime
  const auto start = Clock::now();
  // Rounds of one batch each, candidate after candidate: a drift of the
  // device's clock or of its neighbours' load falls on every candidate alike.
  for (;;) {
    for (std::size_t i = 0; i < timed.size(); ++i) {
      const std::vector<double> batch = timed[i]->Cold(0, static_cast<int>(rule.batch));
      entries[i].samples.insert(entries[i].samples.end(), batch.begin(), batch.end());
    }
    std::size_t fewest = entries.front().samples.size();
    for (const RaceEntry& e : entries) fewest = std::min(fewest, e.samples.size());
    if (fewest == 0) throw Error("race: the device gave no kernel time");
    const RaceOutcome outcome = JudgeRace(entries, options.tie_margin);
    const double elapsed = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    if ((outcome.decided && fewest >= rule.min_samples) || fewest >= rule.max_samples ||
        elapsed >= rule.max_ms * static_cast<double>(entries.size()))
      break;
  }
  std::vector<std::vector<double>> samples;
  for (RaceEntry& e : entries) samples.push_back(std::move(e.samples));
  return samples;
}

KernelTime SampleKernelTime(Executor::Timed& timed, const TimingOptions& options) {
  using Clock = std::chrono::steady_clock;
  const StopRule& rule = options.stop;
  // The warm-up frames first, outside the time cap: they also prepare the
  // flush (its buffer is made on first use) and warm the device.
  (void)timed.Cold(std::max(options.warmup, 1), 0);
  const auto start = Clock::now();
  KernelTime t;
  for (;;) {
    const std::size_t want = std::min(rule.batch, rule.max_samples - std::min(rule.max_samples, t.samples.size()));
    const std::vector<double> batch = timed.Cold(0, static_cast<int>(std::max<std::size_t>(want, 1)));
    if (batch.empty()) throw Error("timing: the device gave no kernel time");
    t.samples.insert(t.samples.end(), batch.begin(), batch.end());
    for (const double s : batch)
      if (!(s > 0.0) || !std::isfinite(s))
        throw Error("timing: the device gave a kernel time of " + std::to_string(s) + " ms");
    t.interval = MedianInterval(t.samples);
    const double elapsed = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    if (ShouldStop(rule, t.interval, elapsed, &t.tight)) return t;
  }
}

double SampleFrameTime(Executor::Timed& timed, const TimingOptions& options, int* frames) {
  const double one = timed.FrameMs(std::max(options.warmup, 1), 1);
  const double wanted = one > 0.0 ? options.burst_ms / one : 1.0;
  // A power of two on a log scale, as the kernel's old bursts were, 1..kMaxBurstFrames.
  int n = 1;
  while (n < kMaxBurstFrames && n * std::sqrt(2.0) < wanted) n *= 2;
  std::vector<double> ms;
  for (int r = 0; r < std::max(options.repetitions, 1); ++r) ms.push_back(timed.FrameMs(0, n));
  if (frames) *frames = n;
  return Median(ms);
}

void RecordKernelTime(Measurement& m, const KernelTime& t, const Executor& executor, int sets, std::size_t bytes_per_set) {
  m.timing.median_ms = t.interval.median;
  m.timing.low_ms = t.interval.low;
  m.timing.high_ms = t.interval.high;
  m.timing.min_ms = *std::min_element(t.samples.begin(), t.samples.end());
  m.timing.max_ms = *std::max_element(t.samples.begin(), t.samples.end());
  m.timing.repetitions = static_cast<int>(t.samples.size());
  m.timing.tight = t.tight;
  m.timing.clock = executor.KernelClock();
  m.timing.input_sets = sets;
  m.timing.footprint_bytes = static_cast<double>(sets) * static_cast<double>(bytes_per_set);
  m.timing.flush_bytes = static_cast<double>(executor.FlushReadBytes());
  m.gbps = m.timing.median_ms > 0.0 ? m.bytes_per_frame / m.timing.median_ms / 1e6 : 0.0;
}

Executor::Output RunnerExecutor::Run(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                     std::span<const std::uint8_t> palette, int instances) {
  RunResult result = runner_.Run(mesh, kernels, palette, instances);
  return {std::move(result.positions), std::move(result.normals), result.poisoned_vertices};
}

namespace {

class RunnerTimed final : public Executor::Timed {
 public:
  RunnerTimed(Runner& runner, RunnerExecutor& executor, Prepared prepared, Lang lang)
      : runner_(runner), executor_(executor), prepared_(std::move(prepared)), lang_(lang) {}
  std::vector<double> Cold(int untimed, int samples) override {
    return runner_.TimeCold(prepared_, executor_.Flush(lang_), untimed, samples);
  }
  double FrameMs(int untimed, int frames) override { return runner_.FrameMs(prepared_, untimed, frames); }
  std::size_t bytes_per_set() const override { return prepared_.bytes_per_set(); }

 private:
  Runner& runner_;
  RunnerExecutor& executor_;
  Prepared prepared_;
  Lang lang_;
};

}  // namespace

const Prepared& RunnerExecutor::Flush(Lang lang) {
  if (const auto found = flushes_.find(lang); found != flushes_.end()) return found->second;
  return flushes_.emplace(lang, runner_.PrepareFlush(lang, flush_bytes_)).first->second;
}

std::unique_ptr<Executor::Timed> RunnerExecutor::Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                                         std::span<const std::vector<std::uint8_t>> palettes,
                                                         int instances) {
  const Lang lang = kernels.empty() ? mesh.variant.lang : kernels.front().lang;
  return std::make_unique<RunnerTimed>(runner_, *this, runner_.Prepare(mesh, kernels, palettes, instances), lang);
}

std::unique_ptr<Executor::Timed> RunnerExecutor::Copy(Lang lang, std::size_t bytes, int input_sets) {
  return std::make_unique<RunnerTimed>(runner_, *this, runner_.PrepareCopy(lang, bytes, input_sets),
                                       LanguageOf(lang).copy_lang);
}

const KernelTime& Executor::CopyTime(Lang lang, std::size_t bytes, int input_sets, const TimingOptions& options) {
  const std::string key = std::string(Name(lang)) + "|" + std::to_string(bytes / 32) + "|" + std::to_string(input_sets);
  if (const auto found = copy_times_.find(key); found != copy_times_.end()) return *found->second;
  const std::unique_ptr<Timed> copy = Copy(lang, bytes, input_sets);
  auto time = std::make_unique<KernelTime>(SampleKernelTime(*copy, options));
  return *copy_times_.emplace(key, std::move(time)).first->second;
}

}  // namespace tuner_internal
}  // namespace skintune::internal
