#include "runtime/winners_db.h"

#include <algorithm>
#include <array>
#include <regex>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "model/mesh.h"
#include "runtime/backend_table.h"
#include "runtime/json_fields.h"
#include "runtime/recorded_time.h"

namespace skintune::internal {

namespace {

using namespace json_fields;

constexpr std::array<const char*, 4> kBuckets{"25k", "100k", "400k", "1600k"};
constexpr const char* kReportKind = "skintune-report";

const std::regex& CreatedPattern() {
  static const std::regex pattern(R"(^(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2})(\.\d+)?(Z|\+00:00)$)");
  return pattern;
}

// `value` of field `name` must equal `expected` (the part of the device id) when present.
std::string Agreeing(const nlohmann::json& j, const char* name, const std::string& expected) {
  if (!j.contains(name)) return expected;
  const std::string value = String(j, name);
  if (value != expected)
    throw Error(std::string("'") + name + "' is '" + value + "' but 'device_id' says '" + expected + "'");
  return value;
}

}  // namespace

std::string JoinDeviceId(const DeviceIdParts& p) {
  return p.backend + ":" + p.platform + "/" + p.name + "/" + p.driver_version;
}


DeviceIdParts SplitDeviceId(const std::string& id) {
  const std::size_t colon = id.find(':');
  const std::size_t first = colon == std::string::npos ? std::string::npos : id.find('/', colon + 1);
  const std::size_t last = id.rfind('/');
  if (colon == std::string::npos || colon == 0 || first == std::string::npos || last == first)
    throw Error("device id '" + id + "' is not \"<backend>:<platform>/<name>/<driver_version>\"");
  return {id.substr(0, colon), id.substr(colon + 1, first - colon - 1), id.substr(first + 1, last - first - 1),
          id.substr(last + 1)};
}

std::string VertexBucket(std::size_t vertices) {
  if (vertices < 50000) return kBuckets[0];
  if (vertices < 200000) return kBuckets[1];
  if (vertices < 800000) return kBuckets[2];
  return kBuckets[3];
}

int VertexBucketIndex(const std::string& bucket) {
  for (std::size_t i = 0; i < kBuckets.size(); ++i)
    if (bucket == kBuckets[i]) return static_cast<int>(i);
  return -1;
}

std::size_t NominalVertices(const std::string& bucket) {
  constexpr std::array<std::size_t, 4> kNominal{25000, 100000, 400000, 1600000};
  const int i = VertexBucketIndex(bucket);
  return i < 0 ? 0 : kNominal[static_cast<std::size_t>(i)];
}

std::string VertexCountName(std::size_t vertices) {
  if (vertices >= 1000 && vertices % 1000 == 0) return std::to_string(vertices / 1000) + "k";
  return std::to_string(vertices);
}

double VertexCountDistance(std::size_t measured, std::size_t mesh) {
  const double a = static_cast<double>(std::max<std::size_t>(measured, 1));
  const double b = static_cast<double>(std::max<std::size_t>(mesh, 1));
  return std::max(a, b) / std::min(a, b);
}

std::string CheckedCreated(const std::string& created) {
  if (!std::regex_match(created, CreatedPattern())) {
    throw Error("'created' is '" + created + "', expected UTC ISO 8601 such as 2025-01-31T12:00:00Z");
  }
  return created;
}

bool CreatedBefore(const std::string& a, const std::string& b) {
  std::smatch ma;
  std::smatch mb;
  std::regex_match(a, ma, CreatedPattern());
  std::regex_match(b, mb, CreatedPattern());
  if (ma[1].str() != mb[1].str()) return ma[1].str() < mb[1].str();
  // Fractional seconds: compare the digits padded to the same length.
  std::string fa = ma[2].matched ? ma[2].str().substr(1) : "";
  std::string fb = mb[2].matched ? mb[2].str().substr(1) : "";
  const std::size_t n = std::max(fa.size(), fb.size());
  fa.resize(n, '0');
  fb.resize(n, '0');
  return fa < fb;
}

const char* SceneKindName(SceneKind kind) {
  switch (kind) {
    case SceneKind::kSingle: return "single";
    case SceneKind::kInstances: return "instances";
    case SceneKind::kBatch: return "batch";
  }
  return "unknown";
}

SceneKind SceneKindFromName(const std::string& name) {
  std::string names;
  for (SceneKind kind : kSceneKinds) {
    if (name == SceneKindName(kind)) return kind;
    names += (names.empty() ? "" : ", ") + std::string(SceneKindName(kind));
  }
  throw Error("'shape' has unknown value '" + name + "' (expected " + names + ")");
}

std::string SceneSuffix(SceneKind kind, int instances, int meshes) {
  switch (kind) {
    case SceneKind::kSingle: return "";
    case SceneKind::kInstances: return " instances x" + std::to_string(instances);
    case SceneKind::kBatch: return " batch of " + std::to_string(meshes) + " meshes";
  }
  return "";
}

std::string MorphSuffix(int morph_targets) {
  return morph_targets > 0 ? " morph " + std::to_string(morph_targets) : "";
}

std::string NormalFormatSuffix(NormalFormat format) {
  return format != NormalFormat::kF32 ? std::string(" normals ") + Name(format) : "";
}

std::string Describe(const WinnersEntry& e) {
  return e.device_id + " " + Name(e.lang) + " b" + std::to_string(e.influences) + " " + RowName(e);
}

bool EntryWithinBudget(const WinnersEntry& e, double max_error, const std::vector<WeightFormat>& exact) {
  if (!KernelAddsOnlyRounding(e.source_error)) return false;  // an exact format's kernel may still be off
  // Half offsets and baked clips cost what they cost, whatever the weights.
  if (MorphHalf(e.variant) || BakeRateOf(e.variant.animation) > 0.0) return WithinBudget(e.source_error, max_error);
  if (e.variant.weight == WeightFormat::kF32) return true;
  if (std::find(exact.begin(), exact.end(), e.variant.weight) != exact.end()) return true;
  return WithinBudget(e.source_error, max_error);
}

nlohmann::json WinnersEntryToJson(const WinnersEntry& e) {
  nlohmann::json j = {{"device_id", e.device_id},
                      {"backend", e.backend},
                      {"platform", e.platform},
                      {"device_name", e.device_name},
                      {"driver_version", e.driver_version},
                      {"lang", Name(e.lang)},
                      {"influences", e.influences},
                      {"vertices", e.vertices},
                      {"vertex_bucket", e.vertex_bucket},
                      {"shape", SceneKindName(e.shape)},
                      {"instances", e.instances},
                      {"meshes", e.meshes},
                      {"morph_targets", e.morph_targets},
                      {"cross_fades", e.cross_fades},
                      {"dataset", e.dataset},
                      {"variant", e.variant},
                      {"median_ms", e.median_ms},
                      {"gbps", e.gbps},
                      {"copy_fraction", e.copy_fraction},
                      {"x_copy", e.x_copy},
                      {"created", e.created},
                      {"source", e.source}};
  if (e.source_error.known) {
    j["source_error"] = SourceErrorJson(e.source_error);
    j["max_relative_error"] = e.max_relative_error;
  }
  if (!e.vendor.empty()) j["vendor"] = e.vendor;
  if (!e.device_type.empty()) j["device_type"] = e.device_type;
  return j;
}

WinnersEntry WinnersEntryFromJson(const nlohmann::json& j) {
  if (!j.is_object()) throw Error("expected an object");
  WinnersEntry e;
  e.device_id = String(j, "device_id");
  const DeviceIdParts parts = SplitDeviceId(e.device_id);
  e.backend = Agreeing(j, "backend", parts.backend);
  if (!FindBackend(e.backend))
    throw Error("'backend' has unknown value '" + e.backend + "' (expected " + JoinedBackendNames() + ")");
  e.platform = Agreeing(j, "platform", parts.platform);
  e.device_name = Agreeing(j, "device_name", parts.name);
  e.driver_version = Agreeing(j, "driver_version", parts.driver_version);
  e.vendor = OptionalString(j, "vendor");
  e.device_type = OptionalString(j, "device_type");
  const std::string lang = String(j, "lang");
  std::vector<Lang> langs;  // every backend's
  for (const BackendEntry& b : Backends()) langs.insert(langs.end(), b.languages.begin(), b.languages.end());
  const auto l = std::find_if(langs.begin(), langs.end(), [&](Lang x) { return lang == Name(x); });
  if (l == langs.end()) {
    throw Error("'lang' has unknown value '" + lang + "' (expected " +
                OneOf(langs, [](Lang x) { return std::string(Name(x)); }) + ")");
  }
  e.lang = *l;
  e.influences = static_cast<int>(Integer(j, "influences"));
  e.vertex_bucket = String(j, "vertex_bucket");
  if (VertexBucketIndex(e.vertex_bucket) < 0) {
    throw Error("'vertex_bucket' has unknown value '" + e.vertex_bucket + "' (expected 25k, 100k, 400k or 1600k)");
  }
  if (j.contains("vertices")) {
    const std::int64_t vertices = Integer(j, "vertices");
    if (vertices < 1) throw Error("'vertices' is " + std::to_string(vertices) + ", expected at least 1");
    e.vertices = static_cast<std::size_t>(vertices);
    if (VertexBucket(e.vertices) != e.vertex_bucket)
      throw Error("'vertex_bucket' " + e.vertex_bucket + " does not match 'vertices' " + std::to_string(vertices) +
                  " (bucket " + VertexBucket(e.vertices) + ")");
  } else {
    e.vertices = NominalVertices(e.vertex_bucket);  // 1.0.0 / 1.1.0: one entry per bucket
  }
  if (j.contains("shape")) {  // 1.4.0; older entries are of one mesh
    e.shape = SceneKindFromName(String(j, "shape"));
    e.instances = j.contains("instances") ? static_cast<int>(Integer(j, "instances")) : 1;
    e.meshes = j.contains("meshes") ? static_cast<int>(Integer(j, "meshes")) : 1;
    if (e.instances < 1 || e.meshes < 1)
      throw Error("'instances' and 'meshes' must be at least 1 (got " + std::to_string(e.instances) + " and " +
                  std::to_string(e.meshes) + ")");
    const bool fits = e.shape == SceneKind::kBatch ||
                      (e.meshes == 1 && (e.shape == SceneKind::kInstances) == (e.instances > 1));
    if (!fits)
      throw Error("'shape' " + std::string(SceneKindName(e.shape)) + " does not match 'instances' " +
                  std::to_string(e.instances) + " and 'meshes' " + std::to_string(e.meshes));
  }
  if (j.contains("morph_targets")) {  // 1.7.0
    e.morph_targets = static_cast<int>(Integer(j, "morph_targets"));
    if (e.morph_targets < 0 || e.morph_targets > kMaxMorphTargets)
      throw Error("'morph_targets' is " + std::to_string(e.morph_targets) + ", expected 0.." +
                  std::to_string(kMaxMorphTargets));
  }
  e.dataset = String(j, "dataset");
  e.variant = Field(j, "variant").get<Variant>();
  if (j.contains("cross_fades")) {  // 1.10.0
    e.cross_fades = Boolean(j, "cross_fades");
    if (e.cross_fades && !AnimatesOnDevice(e.variant))
      throw Error("'cross_fades' is true, and 'variant' " + e.variant.Key() +
                  " was tuned with the host's palettes (only a crowd animated on the device cross-fades clips)");
  }
  if (e.variant.lang != e.lang || e.variant.influences != e.influences) {
    throw Error("'variant' " + e.variant.Key() + " does not match 'lang' and 'influences'");
  }
  if (SkinsMorph(e.variant) && e.morph_targets == 0)
    throw Error("'variant' " + e.variant.Key() + " applies morph targets, and 'morph_targets' does not say how many");
  if (!SkinsMorph(e.variant) && e.morph_targets > 0)
    throw Error("'variant' " + e.variant.Key() + " does not apply the " + std::to_string(e.morph_targets) +
                " morph targets of the mesh it was tuned on");
  e.median_ms = Number(j, "median_ms");
  e.gbps = Number(j, "gbps");
  e.copy_fraction = Number(j, "copy_fraction");
  e.x_copy = j.contains("x_copy") ? Number(j, "x_copy") : 0.0;  // 1.3.0
  // The time ranks entries (Selection, merges): it must be possible. The
  // bandwidths are only shown: finite and not negative.
  RecordedTime time;
  time.median_ms = e.median_ms;
  std::string problem = ImpossibleTime(time);
  if (problem.empty()) problem = NotFiniteNonNegative("gbps", e.gbps);
  if (problem.empty()) problem = NotFiniteNonNegative("copy_fraction", e.copy_fraction);
  if (problem.empty()) problem = NotFiniteNonNegative("x_copy", e.x_copy);
  if (j.contains("source_error")) {
    try {
      e.source_error = SourceErrorFromJson(j["source_error"]);
    } catch (const Error& error) {
      throw Error(std::string("'source_error': ") + error.what());
    }
    if (j.contains("max_relative_error")) e.max_relative_error = Number(j, "max_relative_error");
    if (problem.empty()) problem = ImpossibleSourceError(e.source_error);
    if (problem.empty()) problem = NotFiniteNonNegative("max_relative_error", e.max_relative_error);
  }
  if (!problem.empty()) throw Error("impossible figures: " + problem);
  e.created = CheckedCreated(String(j, "created"));
  e.source = String(j, "source");
  return e;
}

nlohmann::json WinnersDbJson(const std::vector<WinnersEntry>& entries) {
  nlohmann::json db = {{"schema_version", kWinnersDbSchemaVersion},
                       {"kind", kWinnersDbKind},
                       {"entries", nlohmann::json::array()}};
  for (const WinnersEntry& e : entries) db["entries"].push_back(WinnersEntryToJson(e));
  return db;
}

std::vector<WinnersEntry> WinnersDbFromJson(const nlohmann::json& json, const std::string& name) {
  if (json.is_object() && json.contains("kind") && json["kind"] == kReportKind) {
    throw Error(name + ": a tuning report, not a winners database: use the winners-db.json that `skintune tune` "
                       "wrote next to it, or make one with `skintune db merge " + name + " -o winners-db.json`");
  }
  CheckHeader(json, name, kWinnersDbKind, kWinnersDbSchemaVersion);
  const nlohmann::json& list = At(name, "entries", [&]() -> const nlohmann::json& { return Array(json, "entries"); });
  std::vector<WinnersEntry> entries;
  for (std::size_t i = 0; i < list.size(); ++i)
    entries.push_back(At(name, "entries[" + std::to_string(i) + "]", [&] { return WinnersEntryFromJson(list[i]); }));
  return entries;
}

}  // namespace skintune::internal
