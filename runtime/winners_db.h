// skintune (internal): the winners database, as `skintune tune` and
// `skintune db merge` write it and the runtime reads it
// (configs/winners-db.schema.json, docs/TUNING.md "Winners database").
//
//   {"schema_version": "1.3.0", "kind": "skintune-winners-db", "entries": [...]}
//
// One entry per (device id, language, influences, measured vertex count,
// scene shape (1.4.0: single, instances x K, batch of M meshes), precision class): the fastest verified variant the tuner found on a dataset
// of that many vertices in each weight format, with its error against the
// unquantised source (since 1.3.0: a caller's error budget chooses among the
// classes; 1.2.0 databases kept one entry per key, whatever its format, and
// their entries' errors are unknown). Since 1.2.0 per measured vertex count
// ( 1.0.0 and 1.1.0 databases kept one per vertex bucket, so a run
// over 1600k-b4 and 6400k-b4 kept only one of them, and their entries load
// with the bucket's nominal count: 25000, 100000, 400000 or 1600000). The device id
// "<backend>:<platform>/<name>/<driver_version>" includes the driver, so a new
// driver is a new device. Since 1.1.0 each entry also names the device's
// platform, vendor, name, driver and type, which the runtime's fallback chain
// matches on (Selection::Find); 1.0.0 entries load too: platform, name and
// driver come from the id, vendor and type stay unknown ("").
//
// The tuner (tuner/report.cpp) writes and merges with these definitions; the
// runtime reads with them: the format lives in one place.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/variant.h"
#include "runtime/source_error.h"

namespace skintune::internal {

inline constexpr const char* kWinnersDbKind = "skintune-winners-db";
// 1.3.0: x_copy, source_error; 1.4.0: the scene shape (shape, instances, meshes).
inline constexpr const char* kWinnersDbSchemaVersion = "1.13.0";

// The scene shapes a winner was tuned on (docs/RUNTIME.md "Scene shapes"):
// the public SceneShape (skintune/skintune.h) inside skintune, whose headers
// (the tuner's) cannot include the public one; the same values in the same
// order (static_asserts in runtime/api_winners.cpp). Listed once, here.
enum class SceneKind { kSingle, kInstances, kBatch };
inline constexpr std::array<SceneKind, 3> kSceneKinds{SceneKind::kSingle, SceneKind::kInstances, SceneKind::kBatch};
// "single", "instances", "batch" (SceneShapeName returns these).
const char* SceneKindName(SceneKind kind);
// The shape named `name`; throws Error listing the names for another.
SceneKind SceneKindFromName(const std::string& name);
// "" for a single mesh, " instances x64", " batch of 31 meshes": how entries and tables name a scene.
std::string SceneSuffix(SceneKind kind, int instances, int meshes);
// " morph 8" for a mesh with 8 morph targets; "" for none.
std::string MorphSuffix(int morph_targets);
// " normals oct16" for a row of packed normals (their format is the row's), "" for f32.
std::string NormalFormatSuffix(NormalFormat format);

// The parts of a device id "<backend>:<platform>/<name>/<driver_version>".
struct DeviceIdParts {
  std::string backend, platform, name, driver_version;
};
std::string JoinDeviceId(const DeviceIdParts& parts);
// The backend ends at the first ':', the platform at the first '/' after it,
// the driver starts after the last '/': a device name may contain '/', a
// platform or driver version may not. Throws Error for an id without
// "<backend>:" or without two '/'.
DeviceIdParts SplitDeviceId(const std::string& id);

// The paper's vertex counts name the buckets: "25k" (< 50k), "100k" (< 200k),
// "400k" (< 800k), "1600k" (the rest).
std::string VertexBucket(std::size_t vertices);
// 0..3 in the order above; -1 for an unknown name.
int VertexBucketIndex(const std::string& bucket);
// The vertex count a bucket is named after (25k -> 25000); 0 for an unknown name.
std::size_t NominalVertices(const std::string& bucket);
// How messages and tables name a vertex count: "1600k" for 1600000, "6400k",
// "5003" for a count that is not a whole number of thousands.
std::string VertexCountName(std::size_t vertices);
// How entries and tables name a row after its B: "100k", "100k instances x64
// morph 8 normals oct16". W is a WinnersEntry or the tuner's Winner.
template <typename W>
std::string RowName(const W& w) {
  return VertexCountName(w.vertices) + SceneSuffix(w.shape, w.instances, w.meshes) + MorphSuffix(w.morph_targets) +
         NormalFormatSuffix(w.variant.normal_format) +
         (!AnimatesOnDevice(w.variant) ? "" : w.cross_fades ? " animated, cross-fading" : " animated");
}
// How far a winner measured on `measured` vertices is from a mesh of `mesh`
// vertices: max/min of the two (1 = the same count; a factor, so 25k is as far
// from 50k as 1600k from 3200k). Both must be > 0.
double VertexCountDistance(std::size_t measured, std::size_t mesh);

// `created` is UTC ISO 8601: "YYYY-MM-DDTHH:MM:SS", optional fractional
// seconds, then "Z" or "+00:00". Returns it, or throws Error naming it.
std::string CheckedCreated(const std::string& created);
// Whether `a` is earlier than `b` (both valid), fractional seconds included.
bool CreatedBefore(const std::string& a, const std::string& b);

struct WinnersEntry {
  std::string device_id;       // "<backend>:<platform>/<name>/<driver_version>"
  std::string backend;         // "opencl", "cuda", "gl"
  std::string platform;        // as in the id
  std::string vendor;          // "" when the database does not say (1.0.0 entries)
  std::string device_name;     // as in the id
  std::string driver_version;  // as in the id
  std::string device_type;     // "gpu", "cpu", ...; "" when the database does not say
  Lang lang = Lang::kOpenCl;
  int influences = 0;          // the variant's B
  std::size_t vertices = 0;    // the vertex count of the dataset the winner was measured on (a scene's total)
  // The scene it was tuned on (1.4.0; older entries: single): one mesh, K
  // instances of one mesh (`instances`), or a batch of `meshes` meshes.
  SceneKind shape = SceneKind::kSingle;
  int instances = 1;
  int meshes = 1;
  // The morph targets of the mesh it was tuned on (1.7.0; 0: none, and
  // entries before it): an entry whose variant applies morph targets serves
  // meshes with them, the nearest count first.
  int morph_targets = 0;
  // Its crowd cross-faded two clips (a "-animblend" scene; 1.10.0, animated
  // entries only): a Skinner whose crowd cross-fades takes such entries
  // first, and never another's baked palette records (SelectionRequest::cross_fades).
  bool cross_fades = false;
  std::string vertex_bucket;   // VertexBucket(vertices), kept for readers of 1.0/1.1
  std::string dataset;         // what the winning time was measured on
  Variant variant;
  double median_ms = 0.0;
  double gbps = 0.0;
  double copy_fraction = 0.0;  // gbps / the device's copy bandwidth (0 when unknown)
  double x_copy = 0.0;         // median_ms / the same-size copy's, timed the same way (0: unknown; before 1.3.0)
  // Its error against the unquantised source on `dataset` (unknown in entries
  // before 1.3.0); the precision class is variant.weight.
  SourceError source_error;
  double max_relative_error = 0.0;  // against the gold of its quantised weights (0 when not recorded)
  std::string created;         // of the report it came from
  std::string source;          // that report's config and strategy, e.g. "default (exhaustive)"
};

// Whether the entry fits a budget: its kernel adds only rounding to what its
// weights cost (KernelAddsOnlyRounding), and f32 (no quantisation), a weight
// format in `exact` (it holds the caller's weights exactly), or a recorded
// quantisation error within `max_error`. Half morph offsets and baked clips
// always take the recorded error (they quantise the mesh's own offsets, the
// model's clips).
bool EntryWithinBudget(const WinnersEntry& entry, double max_error, const std::vector<WeightFormat>& exact);

// "<device id> <lang> b<B> <vertices>[ <shape>]": how messages name an entry
// (the variant key names its weight format).
std::string Describe(const WinnersEntry& entry);

// A winner's row: what keeps winners apart as no rivals of each other
// (device id, lang, influences, vertices, scene shape, instances, meshes, dual
// quaternions, morph targets, normal format, palettes made on the device:
// an animated scene's forms race each other, not the host's; a crowd that
// cross-fades clips, whose baked palette records lose what an unblended
// crowd's do not). A row holds one winner per
// precision class (the tuner's merge, `emit --db`'s kernels). W is a
// WinnersEntry or the tuner's Winner (the same fields).
using WinnerRow = std::tuple<std::string, int, int, std::size_t, int, int, int, bool, int, int, bool, bool>;
template <typename W>
WinnerRow RowOf(const W& w) {
  return {w.device_id,
          static_cast<int>(w.lang),
          w.influences,
          w.vertices,
          static_cast<int>(w.shape),
          w.instances,
          w.meshes,
          w.variant.blend == Blend::kDualQuaternion,
          SkinsMorph(w.variant) ? std::max(w.morph_targets, 1) : 0,
          static_cast<int>(w.variant.normal_format),
          AnimatesOnDevice(w.variant),
          w.cross_fades};
}

// Writes every field; vendor and device_type only when known.
nlohmann::json WinnersEntryToJson(const WinnersEntry& entry);
// Throws Error("'field' ...") naming the first bad field, or "impossible
// figures: ..." for a time that cannot be (runtime/recorded_time.h: a
// median_ms that is not positive and finite; a gbps or copy_fraction that is
// negative or not finite). Platform, name and driver default to the id's parts; an
// entry that states them must agree with its id.
WinnersEntry WinnersEntryFromJson(const nlohmann::json& json);

// The whole database, entries in the given order.
nlohmann::json WinnersDbJson(const std::vector<WinnersEntry>& entries);
// Throws Error("<name>: <element>: ...") for anything but a 1.x winners
// database; a tuning report is refused with a hint on how to get its database.
std::vector<WinnersEntry> WinnersDbFromJson(const nlohmann::json& json, const std::string& name);

}  // namespace skintune::internal
