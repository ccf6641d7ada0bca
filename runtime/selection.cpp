#include "runtime/selection.h"

#include <algorithm>
#include <cstdlib>
#include <sstream>
#include <tuple>

#include "generator/axes.h"
#include "runtime/api_errors.h"
#include "runtime/backend_table.h"

namespace skintune::internal {

namespace {

bool Contains(const std::vector<Lang>& langs, Lang lang) {
  return std::find(langs.begin(), langs.end(), lang) != langs.end();
}

const char* BackendKey(Backend backend) { return BackendName(backend); }

// Whether `e` belongs to `level` for `device` (each level excludes the ones before it).
bool AtLevel(const WinnersEntry& e, const DeviceInfo& device, MatchLevel level) {
  const bool exact = e.device_id == device.id;
  const bool same_backend = e.backend == BackendKey(device.backend);
  const bool same_name = same_backend && e.device_name == device.name;
  const bool same_vendor_type = same_backend && !e.vendor.empty() && !e.device_type.empty() &&
                                e.vendor == device.vendor && e.device_type == device.type;
  switch (level) {
    case MatchLevel::kExactDevice: return exact;
    case MatchLevel::kSameDeviceName: return !exact && same_name;
    case MatchLevel::kSameVendorType: return !exact && !same_name && same_vendor_type;
    case MatchLevel::kGenericDefault:
    case MatchLevel::kForced: return false;
  }
  return false;
}

// Whether `e` may serve a scene of the request's shape: its own shape, or a
// single mesh (the fallback at the same total size).
bool ShapeServes(const WinnersEntry& e, const SelectionRequest& r) {
  return e.shape == r.shape || e.shape == SceneKind::kSingle;
}

// The instance or mesh count's distance (a factor) within the request's shape; 1 otherwise.
double CountDistance(const WinnersEntry& e, const SelectionRequest& r) {
  if (e.shape != r.shape || (r.shape == SceneKind::kInstances ? r.instances : r.meshes) < 1) return 1.0;  // 0: unknown
  if (r.shape == SceneKind::kInstances)
    return VertexCountDistance(static_cast<std::size_t>(e.instances), static_cast<std::size_t>(r.instances));
  if (r.shape == SceneKind::kBatch)
    return VertexCountDistance(static_cast<std::size_t>(e.meshes), static_cast<std::size_t>(r.meshes));
  return 1.0;
}

// The normal format a variant for `r` writes: the asked one with normals, else float32.
NormalFormat FormatFor(const SelectionRequest& r) {
  return r.normals == Normals::kNone ? NormalFormat::kF32 : r.normal_format;
}

// Smaller is better: an entry tuned in another normal format, animated elsewhere than the request
// (on the device or by the host), a crowd that cross-fades where the request's does not (or the
// reverse), another shape than the request's (the single-mesh
// fallback), B above the mesh's, the distance (a factor) from the measured
// vertex count to the scene's, the instance or mesh count's, the morph
// target count's (a mesh with them), the larger vertex count on a tie, then the newest `created` and the smallest time (compared
// separately).
std::tuple<bool, bool, bool, bool, int, double, double, double, long long> Rank(const WinnersEntry& e,
                                                                               const SelectionRequest& r) {
  const double morph = r.morph ? VertexCountDistance(static_cast<std::size_t>(std::max(e.morph_targets, 1)),
                                                     static_cast<std::size_t>(std::max(r.morph_targets, 1)))
                               : 1.0;
  return {e.variant.normal_format != FormatFor(r), AnimatesOnDevice(e.variant) != r.animated,
          AnimatesOnDevice(e.variant) && e.cross_fades != r.cross_fades, e.shape != r.shape,
          e.influences - r.influences,
          VertexCountDistance(e.vertices, r.vertex_count), CountDistance(e, r), morph,
          -static_cast<long long>(e.vertices)};
}

bool Better(const WinnersEntry& a, const WinnersEntry& b, const SelectionRequest& request) {
  const auto ra = Rank(a, request);
  const auto rb = Rank(b, request);
  if (ra != rb) return ra < rb;
  if (a.created != b.created) return CreatedBefore(b.created, a.created);
  return a.median_ms < b.median_ms;
}

std::string LevelReason(MatchLevel level, const WinnersEntry& e, const DeviceInfo& device) {
  switch (level) {
    case MatchLevel::kExactDevice:
      return "tuned on this device and driver";
    case MatchLevel::kSameDeviceName:
      return "no entry for this driver (" + device.driver_version + "); same device name '" + device.name +
             "', tuned with driver " + e.driver_version + (e.platform != device.platform ? " on " + e.platform : "");
    case MatchLevel::kSameVendorType:
      return "no entry for '" + device.name + "'; same vendor and type: " + device.vendor + " " + device.type +
             " (tuned on '" + e.device_name + "')";
    case MatchLevel::kGenericDefault:
    case MatchLevel::kForced:
      break;
  }
  return "";
}

std::string OverBudget(const WinnersEntry& e, const SelectionRequest& r) {
  const SourceError& error = e.source_error;
  std::ostringstream text;
  text.precision(2);
  text << std::scientific;
  if (!error.known) {
    text << "its quantisation error is not recorded (a database older than 1.3.0), so it is over any budget";
  } else if (!KernelAddsOnlyRounding(error)) {
    text << "its kernel is off the source by " << error.position_rel << " of the diagonal, more than its weights cost ("
         << error.quantisation_rel << ") and float32 rounding: no budget admits it";
  } else {
    text << "quantisation error " << error.quantisation_rel << " of the diagonal, over the budget " << r.max_error_name
         << " " << r.max_error << " (raising it to " << error.quantisation_rel << " admits it)";
  }
  return text.str();
}

// An entry skipped for the budget or the check, and why.
struct Skipped {
  const WinnersEntry* entry;
  MatchLevel level;
  std::string why;
};

// "; skipped A; skipped B": the skipped entries that could have served
// instead of `chosen` (at `level`; null for the built-in default): every one
// of an earlier level, and those of its level that rank no worse than it.
std::string SkippedText(const std::vector<Skipped>& skipped, const WinnersEntry* chosen, MatchLevel level,
                        const SelectionRequest& r) {
  std::string text;
  for (const Skipped& s : skipped) {
    if (chosen != nullptr && s.level == level && Rank(*chosen, r) < Rank(*s.entry, r)) continue;
    text += "; skipped " + s.why;
  }
  return text;
}

std::string Langs(const std::vector<Lang>& langs) {
  std::string out;
  for (Lang l : langs) out += (out.empty() ? "" : " or ") + std::string(Name(l));
  return out;
}

}  // namespace

std::vector<Lang> LanguagesOf(Backend backend) {
  const BackendEntry* entry = FindBackend(BackendName(backend));
  return entry ? entry->languages : std::vector<Lang>{};
}

Variant GenericDefault(Lang lang, int influences, Normals normals, const DeviceLimits& limits, bool morph,
                       bool dual_quaternions) {
  Variant v;
  v.lang = lang;
  v.influences = influences;
  v.mixed = MixedCounts::kPadded;
  v.layout = Layout::kSoa;
  v.position = PositionFormat::kFloat4;
  v.index = IndexFormat::kI32;
  v.weight = WeightFormat::kF32;
  v.palette = PaletteFormat::kMat4;
  v.storage = PaletteStorage::kGlobal;
  v.blend = Blend::kMatrix;
  v.vertices_per_item = 1;
  v.assignment = Assignment::kContiguous;
  v.wg_size = !HasWorkGroups(lang) ? 0 : limits.max_wg_size >= 64 ? 64 : 32;
  v.normals = normals;
  if (dual_quaternions) v.palette = PaletteFormat::kDualQuaternion, v.blend = Blend::kDualQuaternion;
  if (morph) v.morph = Morph::kDense;  // float32 offsets: exact
  return v;
}

Chosen Select(const std::vector<WinnersEntry>& entries, const SelectionRequest& request) {
  const DeviceInfo& device = request.device;
  auto check = [&](const Variant& v) { return request.check ? request.check(v) : std::string(); };
  std::vector<Skipped> skipped;

  for (MatchLevel level : {MatchLevel::kExactDevice, MatchLevel::kSameDeviceName, MatchLevel::kSameVendorType}) {
    std::vector<const WinnersEntry*> candidates;
    for (const WinnersEntry& e : entries) {
      if (!AtLevel(e, device, level) || !Contains(request.langs, e.lang) || e.influences < request.influences ||
          !ShapeServes(e, request) || (e.variant.blend == Blend::kDualQuaternion) != request.dual_quaternions ||
          SkinsMorph(e.variant) != request.morph || (AnimatesOnDevice(e.variant) && !request.animated))
        continue;
      if (request.animated && request.cross_fades && request.tuned_form && !e.cross_fades &&
          BakeRateOf(e.variant.animation) > 0.0 && !BakesLocally(e.variant.animation)) {
        skipped.push_back({&e, level, Describe(e) + " " + Name(e.variant.animation) +
                                          ": palette records baked for a crowd that does not cross-fade clips (their "
                                          "recorded error holds no blend's; SkinnerOptions::cross_fades)"});
        continue;
      }
      if (!EntryWithinBudget(e, request.max_error, request.exact_formats)) {
        skipped.push_back({&e, level, Describe(e) + " " + Name(e.variant.weight) + ": " + OverBudget(e, request)});
        continue;
      }
      candidates.push_back(&e);
    }
    std::stable_sort(candidates.begin(), candidates.end(), [&](const WinnersEntry* a, const WinnersEntry* b) {
      return Better(*a, *b, request);
    });
    for (const WinnersEntry* e : candidates) {
      Variant v = e->variant;
      v.normals = request.normals;
      v.normal_format = FormatFor(request);
      const std::string why = check(v);
      if (!why.empty()) {
        skipped.push_back({e, level, Describe(*e) + ": " + why});
        continue;
      }
      Chosen chosen;
      chosen.variant = v;
      chosen.selection.variant = v.Key();
      chosen.selection.level = level;
      chosen.selection.entry = Describe(*e);
      std::string reason = LevelReason(level, *e, device);
      if (e->influences != request.influences || e->vertices != request.vertex_count) {
        reason += "; tuned for b" + std::to_string(e->influences) + " at " + VertexCountName(e->vertices) +
                  " vertices (the mesh: b" +
                  std::to_string(request.influences) + ", " + std::to_string(request.vertex_count) + " vertices)";
      }
      if (e->variant.normal_format != v.normal_format)
        reason += std::string("; tuned with ") + Name(e->variant.normal_format) + " normals, run with " +
                  Name(v.normal_format) + " (no entry of that format)";
      if (request.animated && !AnimatesOnDevice(e->variant))
        reason += "; tuned with the host's palettes (no entry of a scene animated on the device)";
      if (request.animated && AnimatesOnDevice(e->variant) && e->cross_fades != request.cross_fades)
        reason += e->cross_fades ? "; tuned on a crowd that cross-fades clips (this one does not)"
                                 : "; tuned on a crowd that does not cross-fade clips (no entry of one that does)";
      if (e->shape != request.shape)
        reason += "; no " + std::string(SceneKindName(request.shape)) +
                  " entry: the single-mesh entry of the scene's total size (" +
                  std::to_string(request.vertex_count) + " vertices)";
      chosen.selection.reason = reason + SkippedText(skipped, e, level, request);
      return chosen;
    }
  }

  std::string tried;
  for (Lang lang : request.langs) {
    Variant v =
        GenericDefault(lang, request.influences, request.normals, request.limits, request.morph, request.dual_quaternions);
    v.normal_format = FormatFor(request);
    const std::string why = check(v);
    if (!why.empty()) {
      tried += (tried.empty() ? "" : "; ") + v.Key() + ": " + why;
      continue;
    }
    Chosen chosen;
    chosen.variant = v;
    chosen.selection.variant = v.Key();
    chosen.selection.level = MatchLevel::kGenericDefault;
    chosen.selection.entry = "built-in default";
    std::string reason = "no " + Langs(request.langs) + " entry with b" + std::to_string(request.influences) +
                         " or more for this device, its name '" + device.name + "' or its vendor and type (" +
                         device.vendor + " " + device.type + "): the built-in default, correct on every device";
    reason += SkippedText(skipped, nullptr, MatchLevel::kGenericDefault, request);
    if (!tried.empty()) reason += "; also skipped " + tried;
    chosen.selection.reason = reason;
    return chosen;
  }
  FailWith(ErrorCode::kUnavailable, "no variant can run on " + device.id + ": " + tried);
}

}  // namespace skintune::internal
