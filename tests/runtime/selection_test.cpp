// The database lookup's fallback chain (Selection::Find, runtime/selection.h):
// one test per level, then how entries are ranked and rejected, and the
// built-in default.
#include "runtime/selection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/constraints.h"
#include "base/error.h"
#include "runtime/winners_db.h"
#include "skintune/skintune.h"

namespace skintune::internal {
namespace {

DeviceInfo ThisDevice() {
  DeviceInfo d;
  d.backend = Backend::kOpenCl;
  d.platform = "Synthetic";
  d.vendor = "Example";
  d.name = "Model GPU";
  d.driver_version = "2.0";
  d.type = "gpu";
  d.id = "opencl:Synthetic/Model GPU/2.0";
  return d;
}

WinnersEntry Entry(const std::string& device_id, const std::string& vendor, const std::string& type,
                   const std::string& variant_key, const std::string& bucket = "100k", double ms = 1.0) {
  WinnersEntry e;
  e.device_id = device_id;
  const DeviceIdParts p = SplitDeviceId(device_id);
  e.backend = p.backend;
  e.platform = p.platform;
  e.device_name = p.name;
  e.driver_version = p.driver_version;
  e.vendor = vendor;
  e.device_type = type;
  e.variant = ParseVariantKey(variant_key);
  e.lang = e.variant.lang;
  e.influences = e.variant.influences;
  e.vertex_bucket = bucket;
  e.vertices = NominalVertices(bucket);
  e.dataset = bucket + "-b" + std::to_string(e.influences);
  e.median_ms = ms;
  e.created = "2025-01-31T12:00:00Z";
  e.source = "test";
  return e;
}

// Entries that must never be chosen for ThisDevice(): another vendor, another
// type, another backend with the same device name.
// A request of this device's OpenCL for a B = 2 mesh of 100k vertices.
SelectionRequest OpenClRequest() {
  SelectionRequest r;
  r.device = ThisDevice();
  r.langs = {Lang::kOpenCl};
  r.influences = 2;
  r.vertex_count = 100000;
  return r;
}

std::vector<WinnersEntry> Decoys() {
  return {Entry("opencl:Synthetic/Rival GPU/1.0", "Rival", "gpu", "opencl.b2.aos.wg32"),
          Entry("opencl:Synthetic/Example CPU/1.0", "Example", "cpu", "opencl.b2.aos.wg64"),
          Entry("cuda:CUDA/Model GPU/2.0", "Example", "gpu", "cuda.b2.aos.wg96")};
}

WinnersDb Db(std::vector<WinnersEntry> entries) {
  const Result<WinnersDb> db = WinnersDb::Parse(WinnersDbJson(entries).dump(), "test.json");
  EXPECT_TRUE(db.ok()) << db.status().message();
  return db.ok() ? *db : WinnersDb::Empty();
}

Selection Find(const WinnersDb& db, int influences = 2, std::size_t vertices = 100000,
               const DeviceInfo& device = ThisDevice()) {
  const Result<Selection> s = Selection::Find(db, device, influences, vertices);
  EXPECT_TRUE(s.ok()) << s.status().message();
  return s.ok() ? *s : Selection{};
}

const WinnersEntry kExact = Entry("opencl:Synthetic/Model GPU/2.0", "Example", "gpu", "opencl.b2.soa-split.wg256");
const WinnersEntry kOtherDriver = Entry("opencl:Synthetic/Model GPU/1.0", "Example", "gpu", "opencl.b2.soa.wg128");
const WinnersEntry kSameVendorType = Entry("opencl:Synthetic/Model GPU Pro/1.0", "Example", "gpu", "opencl.b2.aos.wg512");

// A mesh with morph targets takes only entries that apply them, the nearest
// target count first (half offsets only within the budget); a mesh without
// takes none of them; with no morph entry, the built-in default's dense twin.
TEST(Selection, MorphEntriesServeOnlyMeshesWithMorphTargetsTheNearestCountFirst) {
  const std::string id = ThisDevice().id;
  const WinnersEntry plain = Entry(id, "Example", "gpu", "opencl.b2.soa.wg64", "100k", 1.0);
  WinnersEntry few = Entry(id, "Example", "gpu", "opencl.b2.soa.wg128.morph-sparse", "100k", 2.0);
  few.morph_targets = 8;
  WinnersEntry many = Entry(id, "Example", "gpu", "opencl.b2.aos.wg256.morph-dense-half", "100k", 3.0);
  many.morph_targets = 32;
  many.source_error.known = true;
  many.source_error.quantisation_rel = 2e-6;
  many.source_error.position_rel = 2e-6;
  SelectionRequest r = OpenClRequest();
  const std::vector<WinnersEntry> entries = {many, few, plain};
  EXPECT_EQ(Select(entries, r).variant, plain.variant);
  r.morph = true;
  r.morph_targets = 10;
  EXPECT_EQ(Select(entries, r).variant, few.variant);
  r.morph_targets = 24;
  EXPECT_EQ(Select(entries, r).variant, many.variant);
  r.max_error = 1e-6;  // the half offsets' 2e-6 is over it
  const Chosen strict = Select(entries, r);
  EXPECT_EQ(strict.variant, few.variant);
  EXPECT_NE(strict.selection.reason.find("skipped"), std::string::npos) << strict.selection.reason;
  const Chosen fallback = Select({plain}, r);
  EXPECT_EQ(fallback.selection.level, MatchLevel::kGenericDefault);
  EXPECT_EQ(fallback.variant.morph, Morph::kDense) << fallback.variant.Key();
}

// Entries tuned on scenes animated on the device (their variant's
// animation: the palette kernel's form) serve only a Skinner that animates on
// the device, before the entries tuned with the host's palettes, whose skin
// kernel serves it too; a baked form over the error budget is skipped.
TEST(Selection, AnimatedEntriesServeOnlyAnimatedSkinnersAndThemFirst) {
  const std::string id = ThisDevice().id;
  const WinnersEntry host = Entry(id, "Example", "gpu", "opencl.b2.soa.wg64", "100k", 1.0);
  WinnersEntry baked = Entry(id, "Example", "gpu", "opencl.b2.aos.wg128.anim-baked30", "100k", 0.5);
  baked.source_error.known = true;
  baked.source_error.position_rel = 3e-3;  // what baking at 30 a second lost
  baked.source_error.quantisation_rel = 3e-3;  // the gold of its own palettes against the sampled ones
  WinnersEntry sampled = Entry(id, "Example", "gpu", "opencl.b2.soa-split.wg256.anim-sampled", "100k", 0.7);
  sampled.source_error.known = true;
  sampled.source_error.position_rel = 2e-7;
  SelectionRequest r = OpenClRequest();
  r.max_error = 1e-2;
  const std::vector<WinnersEntry> entries = {baked, sampled, host};
  EXPECT_EQ(Select(entries, r).variant, host.variant) << "a Skinner of SetPalette takes no animated entry";
  EXPECT_EQ(Select({baked, sampled}, r).selection.level, MatchLevel::kGenericDefault);
  r.animated = true;
  const Chosen first = Select(entries, r);
  EXPECT_EQ(first.variant.animation, Animation::kBaked30) << first.variant.Key() << ": the newest, then the fastest";
  r.max_error = 1e-3;  // baking at 30 a second lost more
  const Chosen strict = Select(entries, r);
  EXPECT_EQ(strict.variant, sampled.variant);
  EXPECT_NE(strict.selection.reason.find("skipped"), std::string::npos) << strict.selection.reason;
  const Chosen fallback = Select({host}, r);
  EXPECT_EQ(fallback.variant, host.variant);
  EXPECT_NE(fallback.selection.reason.find("tuned with the host's palettes"), std::string::npos)
      << fallback.selection.reason;
}

// A crowd that cross-fades clips (SelectionRequest::cross_fades) takes
// entries of crowds that did first; taking the tuned form, it never takes
// palette records baked on a crowd that did not (their recorded error holds
// no blend's), while local records and sampled clips of that crowd serve it.
// A crowd that does not cross-fade takes that crowd's entries first.
TEST(Selection, ACrossFadingCrowdTakesItsOwnEntriesFirstAndNoUnblendedPaletteRecords) {
  const std::string id = ThisDevice().id;
  WinnersEntry steady = Entry(id, "Example", "gpu", "opencl.b2.aos.wg128.anim-baked120", "100k", 0.5);
  steady.source_error.known = true;
  steady.source_error.position_rel = steady.source_error.quantisation_rel = 3e-4;
  WinnersEntry steady_local = Entry(id, "Example", "gpu", "opencl.b2.soa.wg64.anim-local120", "100k", 0.6);
  steady_local.source_error = steady.source_error;
  WinnersEntry fading = Entry(id, "Example", "gpu", "opencl.b2.soa-split.wg256.anim-local240", "100k", 0.7);
  fading.source_error = steady.source_error;
  fading.cross_fades = true;
  SelectionRequest r = OpenClRequest();
  r.max_error = 1e-3;
  r.animated = true;
  r.cross_fades = true;
  r.tuned_form = true;
  EXPECT_EQ(Select({steady, steady_local, fading}, r).variant, fading.variant);
  const Chosen local = Select({steady, steady_local}, r);
  EXPECT_EQ(local.variant, steady_local.variant);
  EXPECT_NE(local.selection.reason.find("palette records baked for a crowd that does not cross-fade clips"),
            std::string::npos)
      << local.selection.reason;
  EXPECT_NE(local.selection.reason.find("tuned on a crowd that does not cross-fade clips"), std::string::npos)
      << local.selection.reason;
  EXPECT_EQ(Select({steady}, r).selection.level, MatchLevel::kGenericDefault);
  // Hybrid records tuned on a steady crowd mix a cross-fade's local records: they serve it, as local ones do.
  WinnersEntry steady_hybrid = Entry(id, "Example", "gpu", "opencl.b2.soa.wg64.anim-hybrid120", "100k", 0.55);
  steady_hybrid.source_error = steady.source_error;
  EXPECT_EQ(Select({steady, steady_hybrid}, r).variant, steady_hybrid.variant);
  r.tuned_form = false;  // the caller's own form: only the skin kernel is the entry's
  EXPECT_EQ(Select({steady}, r).variant, steady.variant);
  r.cross_fades = false;
  r.tuned_form = true;
  EXPECT_EQ(Select({fading, steady}, r).variant, steady.variant);
  const Chosen other = Select({fading}, r);
  EXPECT_EQ(other.variant, fading.variant);
  EXPECT_NE(other.selection.reason.find("tuned on a crowd that cross-fades clips (this one does not)"), std::string::npos)
      << other.selection.reason;
}

// A Skinner's normal format takes the entry tuned in it first; without one,
// another entry serves with its variant's format changed, and the reason
// says so; without normals the format is float32.
TEST(Selection, EntriesOfTheAskedNormalFormatServeFirstOthersAreRunInIt) {
  const std::string id = ThisDevice().id;
  const WinnersEntry f32 = Entry(id, "Example", "gpu", "opencl.b2.soa.wg64.normals", "100k", 1.0);
  const WinnersEntry oct = Entry(id, "Example", "gpu", "opencl.b2.aos.wg128.normals.normals-oct16", "100k", 2.0);
  SelectionRequest r = OpenClRequest();
  r.normals = Normals::kNormals;
  EXPECT_EQ(Select({oct, f32}, r).variant, f32.variant);
  r.normal_format = NormalFormat::kOct16;
  EXPECT_EQ(Select({f32, oct}, r).variant, oct.variant);
  r.normal_format = NormalFormat::kSnorm8;
  const Chosen adapted = Select({f32, oct}, r);
  EXPECT_EQ(adapted.variant.normal_format, NormalFormat::kSnorm8) << adapted.variant.Key();
  EXPECT_NE(adapted.selection.reason.find("run with snorm8 (no entry of that format)"), std::string::npos)
      << adapted.selection.reason;
  EXPECT_EQ(Select({}, r).variant.normal_format, NormalFormat::kSnorm8);  // the built-in default too
  r.normals = Normals::kNone;
  EXPECT_EQ(Select({oct}, r).variant.normal_format, NormalFormat::kF32);
  EXPECT_EQ(Describe(oct), id + " opencl b2 100k normals oct16");
}

TEST(Selection, ExactDeviceAndDriverIsTheFirstLevel) {
  std::vector<WinnersEntry> entries = Decoys();
  entries.insert(entries.end(), {kSameVendorType, kOtherDriver, kExact});
  const Selection s = Find(Db(entries));
  EXPECT_EQ(s.level, MatchLevel::kExactDevice);
  EXPECT_EQ(s.variant, kExact.variant.Key());
  EXPECT_EQ(s.entry, "opencl:Synthetic/Model GPU/2.0 opencl b2 100k");
  EXPECT_STREQ(MatchLevelName(s.level), "exact-device");
}

TEST(Selection, SameDeviceNameWithAnotherDriverIsTheSecondLevel) {
  std::vector<WinnersEntry> entries = Decoys();
  entries.insert(entries.end(), {kSameVendorType, kOtherDriver});
  const Selection s = Find(Db(entries));
  EXPECT_EQ(s.level, MatchLevel::kSameDeviceName);
  EXPECT_EQ(s.variant, kOtherDriver.variant.Key());
  EXPECT_NE(s.reason.find("driver 1.0"), std::string::npos) << s.reason;
  EXPECT_STREQ(MatchLevelName(s.level), "same-device-name");
}

TEST(Selection, SameVendorAndDeviceTypeIsTheThirdLevel) {
  std::vector<WinnersEntry> entries = Decoys();
  entries.push_back(kSameVendorType);
  const Selection s = Find(Db(entries));
  EXPECT_EQ(s.level, MatchLevel::kSameVendorType);
  EXPECT_EQ(s.variant, kSameVendorType.variant.Key());
  EXPECT_NE(s.reason.find("Example gpu"), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("Model GPU Pro"), std::string::npos) << s.reason;
  EXPECT_STREQ(MatchLevelName(s.level), "same-vendor-type");
}

TEST(Selection, BuiltInDefaultWhenNoEntryMatches) {
  const Selection s = Find(Db(Decoys()));
  EXPECT_EQ(s.level, MatchLevel::kGenericDefault);
  EXPECT_EQ(s.variant, GenericDefault(Lang::kOpenCl, 2, Normals::kNone, DeviceLimits{}).Key());
  EXPECT_EQ(s.entry, "built-in default");
  EXPECT_STREQ(MatchLevelName(s.level), "generic-default");
  EXPECT_EQ(Find(WinnersDb::Empty()).level, MatchLevel::kGenericDefault);
}

TEST(Selection, EntriesWithoutVendorAndTypeNeverMatchTheVendorLevel) {
  WinnersEntry old = kSameVendorType;
  old.vendor.clear();
  old.device_type.clear();
  EXPECT_EQ(Find(Db({old})).level, MatchLevel::kGenericDefault);
}

TEST(Selection, SmallestSufficientInfluencesWinThenTheNearestBucket) {
  const std::string id = ThisDevice().id;
  const WinnersEntry b1 = Entry(id, "Example", "gpu", "opencl.b1.wg32");
  const WinnersEntry b4 = Entry(id, "Example", "gpu", "opencl.b4.wg64");
  const WinnersEntry b3 = Entry(id, "Example", "gpu", "opencl.b3.wg96");
  // B below the mesh's count can never hold it; of the rest the smallest B.
  Selection s = Find(Db({b1, b4, b3}), 2);
  EXPECT_EQ(s.variant, b3.variant.Key());
  EXPECT_NE(s.reason.find("tuned for b3"), std::string::npos) << s.reason;
  EXPECT_EQ(Find(Db({b1}), 2).level, MatchLevel::kGenericDefault);
  // Buckets: the nearest; between two as near, the larger.
  const WinnersEntry small = Entry(id, "Example", "gpu", "opencl.b2.wg32", "25k");
  const WinnersEntry mid = Entry(id, "Example", "gpu", "opencl.b2.wg64", "400k");
  const WinnersEntry big = Entry(id, "Example", "gpu", "opencl.b2.wg96", "1600k");
  EXPECT_EQ(Find(Db({small, mid, big}), 2, 1000).variant, small.variant.Key());
  EXPECT_EQ(Find(Db({small, mid, big}), 2, 100000).variant, mid.variant.Key());
  EXPECT_EQ(Find(Db({small, big}), 2, 300000).variant, big.variant.Key());
}

TEST(Selection, EveryMeasuredVertexCountKeepsItsWinnerAndTheNearestAsAFactorIsTaken) {
  const std::string id = ThisDevice().id;
  // 1600k and 6400k are one bucket; each keeps its own winner (database 1.2.0).
  WinnersEntry at1600k = Entry(id, "Example", "gpu", "opencl.b4.wg64", "1600k");
  WinnersEntry at6400k = Entry(id, "Example", "gpu", "opencl.b4.wg256", "1600k");
  at6400k.vertices = 6400000;
  at6400k.dataset = "6400k-b4";
  const WinnersDb db = Db({at1600k, at6400k});
  EXPECT_EQ(Find(db, 4, 1600000).variant, at1600k.variant.Key());
  EXPECT_EQ(Find(db, 4, 3000000).variant, at1600k.variant.Key());  // 1.9x from 1600k, 2.1x from 6400k
  EXPECT_EQ(Find(db, 4, 3300000).variant, at6400k.variant.Key());  // 2.06x from 1600k, 1.94x from 6400k
  const Selection s = Find(db, 4, 9000000);
  EXPECT_EQ(s.variant, at6400k.variant.Key());
  EXPECT_NE(s.reason.find("tuned for b4 at 6400k vertices"), std::string::npos) << s.reason;
  // The same count exactly: no "tuned for" note.
  EXPECT_EQ(Find(db, 4, 6400000).reason.find("tuned for"), std::string::npos);
}

TEST(Selection, NewestDriverWinsAmongSameNameEntries) {
  WinnersEntry older = kOtherDriver;
  WinnersEntry newer = Entry("opencl:Synthetic/Model GPU/1.5", "Example", "gpu", "opencl.b2.soa.wg512");
  newer.created = "2025-06-01T00:00:00Z";
  EXPECT_EQ(Find(Db({older, newer})).variant, newer.variant.Key());
  EXPECT_EQ(Find(Db({newer, older})).variant, newer.variant.Key());
}

TEST(Selection, GlDevicesTakeTheFasterOfComputeAndVertexShader) {
  DeviceInfo gl = ThisDevice();
  gl.backend = Backend::kGl;
  gl.platform = "device";
  gl.id = "gl:device/Model GPU/4.6";
  const WinnersEntry compute = Entry(gl.id, "Example", "gpu", "glsl-compute.b2.wg64", "100k", 2.0);
  const WinnersEntry vertex = Entry(gl.id, "Example", "gpu", "glsl-vertex.b2", "100k", 1.0);
  EXPECT_EQ(Find(Db({compute, vertex}), 2, 100000, gl).variant, vertex.variant.Key());
  EXPECT_EQ(Find(WinnersDb::Empty(), 2, 100000, gl).variant,
            GenericDefault(Lang::kGlslCompute, 2, Normals::kNone, DeviceLimits{}).Key());
}

TEST(Selection, RejectedEntriesFallThroughAndAreNamedInTheReason) {
  SelectionRequest request;
  request.device = ThisDevice();
  request.langs = {Lang::kOpenCl};
  request.influences = 2;
  request.vertex_count = 100000;
  request.check = [](const Variant& v) { return v.wg_size > 128 ? "wg_size too large here" : ""; };
  const Chosen chosen = Select({kExact, kOtherDriver}, request);
  EXPECT_EQ(chosen.selection.level, MatchLevel::kSameDeviceName);
  EXPECT_NE(chosen.selection.reason.find("skipped opencl:Synthetic/Model GPU/2.0 opencl b2 100k: wg_size too large here"),
            std::string::npos)
      << chosen.selection.reason;
  // Normals follow the request, whatever the entry was tuned with.
  request.normals = Normals::kNormals;
  EXPECT_EQ(Select({kOtherDriver}, request).variant.normals, Normals::kNormals);
  // Nothing at all can run: kUnavailable.
  request.check = [](const Variant&) { return "never"; };
  EXPECT_THROW(Select({kExact}, request), Error);
}

// A winner per precision class of one key (database 1.3.0), the unorm8 one the
// fastest, its quantisation error 1.2e-3 of the diagonal; unorm16 4e-6.
std::vector<WinnersEntry> PrecisionClasses() {
  const std::string id = "opencl:Synthetic/Model GPU/2.0";
  WinnersEntry f32 = Entry(id, "Example", "gpu", "opencl.b2.soa.f32.wg64", "100k", 3.0);
  WinnersEntry u16 = Entry(id, "Example", "gpu", "opencl.b2.soa.unorm16.wg64", "100k", 2.0);
  WinnersEntry u8 = Entry(id, "Example", "gpu", "opencl.b2.soa.unorm8.wg64", "100k", 1.0);
  for (auto [entry, q] : {std::pair{&f32, 0.0}, std::pair{&u16, 4e-6}, std::pair{&u8, 1.2e-3}}) {
    entry->source_error.known = true;
    entry->source_error.diagonal = 2.0;
    entry->source_error.quantisation_rel = q;
    entry->source_error.position_rel = q + 1e-7;
    entry->source_error.position_abs = 2.0 * (q + 1e-7);
  }
  return {f32, u16, u8};
}

TEST(Selection, TheBudgetChoosesAmongPrecisionClassesWithoutRetuning) {
  const WinnersDb db = Db(PrecisionClasses());
  auto find = [&](double max_error) {
    const Result<Selection> s = Selection::Find(db, ThisDevice(), 2, 100000, max_error);
    EXPECT_TRUE(s.ok()) << s.status().message();
    return s.ok() ? s->variant : std::string();
  };
  EXPECT_EQ(ParseVariantKey(find(kDefaultMaxError)).weight, WeightFormat::kUnorm16);  // unorm8 is over 1e-4
  EXPECT_EQ(ParseVariantKey(find(1e-2)).weight, WeightFormat::kUnorm8);
  EXPECT_EQ(ParseVariantKey(find(1e-6)).weight, WeightFormat::kF32);
  EXPECT_EQ(ParseVariantKey(find(0.0)).weight, WeightFormat::kF32);
  const Result<Selection> s = Selection::Find(db, ThisDevice(), 2, 100000);
  ASSERT_TRUE(s.ok());
  EXPECT_NE(s->reason.find("over the budget max_error 1.00e-04 (raising it to 1.20e-03 admits it)"), std::string::npos)
      << s->reason;
  for (double bad : {-1e-4, std::nan(""), HUGE_VAL}) {
    const Result<Selection> r = Selection::Find(db, ThisDevice(), 2, 100000, bad);
    EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument) << bad;
    EXPECT_NE(r.status().message().find("max_error"), std::string::npos) << r.status().message();
  }
}

// The reason names only the skipped entries that could have served this
// mesh (B = 2, 100k): the b2 100k unorm8 class over the budget, with the
// option that admits it, and not the unorm8 classes of b3, b4, another
// vertex count or another shape, which rank below the chosen b2 100k
// unorm16 whatever the budget.
TEST(Selection, TheReasonNamesOnlySkippedEntriesThatCouldServeAndTheBudgetThatAdmitsThem) {
  std::vector<WinnersEntry> entries = PrecisionClasses();  // b2 100k: f32, unorm16, unorm8 (1.2e-3)
  const auto over_budget = [&](const std::string& key, const std::string& bucket) {
    WinnersEntry e = entries[2];
    e.variant = ParseVariantKey(key);
    e.influences = e.variant.influences;
    e.vertex_bucket = bucket;
    e.vertices = NominalVertices(bucket);
    return e;
  };
  entries.push_back(over_budget("opencl.b3.soa.unorm8.wg64", "100k"));
  entries.push_back(over_budget("opencl.b4.soa.unorm8.wg64", "100k"));
  entries.push_back(over_budget("opencl.b2.soa.unorm8.wg128", "1600k"));
  SelectionRequest request;
  request.device = ThisDevice();
  request.langs = {Lang::kOpenCl};
  request.influences = 2;
  request.vertex_count = 100000;
  request.max_error_name = "SkinnerOptions::max_error";
  const std::string reason = Select(entries, request).selection.reason;
  EXPECT_NE(reason.find("skipped opencl:Synthetic/Model GPU/2.0 opencl b2 100k unorm8: quantisation error 1.20e-03 of "
                        "the diagonal, over the budget SkinnerOptions::max_error 1.00e-04 (raising it to 1.20e-03 "
                        "admits it)"),
            std::string::npos)
      << reason;
  for (const char* never : {" b3 ", " b4 ", " 1600k"}) EXPECT_EQ(reason.find(never), std::string::npos) << reason;
  // A crowd's own entries first: the single-mesh classes rank below them.
  std::vector<WinnersEntry> crowd = PrecisionClasses();
  for (WinnersEntry& e : crowd) {
    e.shape = SceneKind::kInstances;
    e.instances = 4;
  }
  crowd.push_back(entries[2]);
  request.shape = SceneKind::kInstances;
  request.instances = 4;
  const std::string crowd_reason = Select(crowd, request).selection.reason;
  EXPECT_NE(crowd_reason.find("b2 100k instances x4 unorm8"), std::string::npos) << crowd_reason;
  EXPECT_EQ(crowd_reason.find("b2 100k unorm8"), std::string::npos) << crowd_reason;
  // With nothing within the budget, every skipped entry could have served the mesh.
  request.shape = SceneKind::kSingle;
  const Chosen fallback = Select({entries.begin() + 2, entries.end()}, request);
  ASSERT_EQ(fallback.selection.level, MatchLevel::kGenericDefault);
  EXPECT_NE(fallback.selection.reason.find("b4 100k unorm8"), std::string::npos) << fallback.selection.reason;
}

// An entry whose kernel was off the source by far more than its weights cost
// (it verified under a loose tolerance) is within no budget, even as f32 or
// an exact format: it was selected because f32 skipped every check.
TEST(Selection, AnEntryWhoseKernelIsOffTheSourceIsWithinNoBudget) {
  std::vector<WinnersEntry> classes = PrecisionClasses();
  SelectionRequest request;
  request.device = ThisDevice();
  request.langs = {Lang::kOpenCl};
  request.influences = 2;
  request.vertex_count = 100000;
  request.max_error = 0.0;  // f32 alone
  EXPECT_EQ(Select(classes, request).selection.level, MatchLevel::kExactDevice);
  classes[0].source_error.position_rel = 0.39;
  classes[0].source_error.position_abs = 2.0 * 0.39;
  const Chosen chosen = Select(classes, request);
  EXPECT_EQ(chosen.selection.level, MatchLevel::kGenericDefault) << chosen.selection.reason;
  EXPECT_NE(chosen.selection.reason.find("b2 100k f32: its kernel is off the source by 3.90e-01 of the diagonal, more "
                                         "than its weights cost (0.00e+00) and float32 rounding: no budget admits it"),
            std::string::npos)
      << chosen.selection.reason;
  request.exact_formats = {WeightFormat::kUnorm16};  // an exact unorm16 entry still serves
  EXPECT_EQ(Select(classes, request).variant.weight, WeightFormat::kUnorm16);
}

TEST(Selection, ExactFormatsAndOlderEntriesWithoutAnError) {
  // Database 1.2.0 entries record no error: unorm8 is over any budget, f32 within every one.
  WinnersEntry old_u8 = Entry("opencl:Synthetic/Model GPU/2.0", "Example", "gpu", "opencl.b2.soa.unorm8.wg64");
  WinnersEntry old_f32 = Entry("opencl:Synthetic/Model GPU/2.0", "Example", "gpu", "opencl.b2.soa.f32.wg64",
                               "100k", 5.0);
  SelectionRequest request;
  request.device = ThisDevice();
  request.langs = {Lang::kOpenCl};
  request.influences = 2;
  request.vertex_count = 100000;
  Chosen chosen = Select({old_u8, old_f32}, request);
  EXPECT_EQ(chosen.variant.weight, WeightFormat::kF32);
  EXPECT_NE(chosen.selection.reason.find("not recorded"), std::string::npos) << chosen.selection.reason;
  // Weights exact in unorm8 (a glTF's unorm8 WEIGHTS): the format costs nothing, whatever was recorded.
  request.exact_formats = {WeightFormat::kUnorm8};
  EXPECT_EQ(Select({old_u8, old_f32}, request).variant.weight, WeightFormat::kUnorm8);
  std::vector<WinnersEntry> classes = PrecisionClasses();
  EXPECT_EQ(Select(classes, request).variant.weight, WeightFormat::kUnorm8);
  request.exact_formats.clear();
  EXPECT_EQ(Select(classes, request).variant.weight, WeightFormat::kUnorm16);
}

TEST(Selection, BuiltInDefaultSatisfiesEveryConstraintOnEveryDevice) {
  DeviceLimits tiny;
  tiny.max_wg_size = 32;
  tiny.local_memory_bytes = 0;
  tiny.constant_memory_bytes = 0;
  tiny.uniform_block_bytes = 0;
  tiny.image_support = false;
  tiny.image_buffer_max_texels = 0;
  for (Lang lang : {Lang::kOpenCl, Lang::kCuda, Lang::kGlslCompute, Lang::kGlslVertex}) {
    for (int b = 1; b <= 8; ++b) {
      for (const DeviceLimits& limits : {tiny, DeviceLimits{}}) {
        for (Normals normals : {Normals::kNone, Normals::kNormals, Normals::kTangents}) {
          const Variant v = GenericDefault(lang, b, normals, limits);
          EXPECT_EQ(v.mixed, MixedCounts::kPadded);
          const ProblemShape shape{65536, b, normals != Normals::kNone, 1, normals == Normals::kTangents};
          for (const Violation& violation : CheckVariant(v, limits, shape))
            ADD_FAILURE() << v.Key() << ": " << violation.message;
        }
      }
    }
  }
}

TEST(Selection, FindRejectsInfluencesOutsideOneToEightAndAMovedFromDatabase) {
  const WinnersDb db = WinnersDb::Empty();
  for (int b : {0, 9}) {
    const Result<Selection> s = Selection::Find(db, ThisDevice(), b, 100);
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.status().code(), ErrorCode::kInvalidArgument);
  }
  WinnersDb moved = WinnersDb::Empty();
  WinnersDb taker = std::move(moved);
  const Result<Selection> s = Selection::Find(moved, ThisDevice(), 2, 100);  // NOLINT(bugprone-use-after-move)
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), ErrorCode::kInvalidState);
}

// Scene shapes (database 1.4.0): an entry tuned on the scene's shape comes
// first, the nearest instance or mesh count among them; without one, the
// single-mesh entry of the scene's TOTAL size, and the reason says so.
// Entries of another non-single shape never serve.
TEST(Selection, EntriesOfTheScenesShapeFirstThenTheSingleMeshOfTheSameTotal) {
  const std::string id = ThisDevice().id;
  WinnersEntry single_1600k = Entry(id, "Example", "gpu", "opencl.b4.soa.wg256", "1600k");
  WinnersEntry single_25k = Entry(id, "Example", "gpu", "opencl.b4.aos.wg32", "25k");
  WinnersEntry crowd_64 = Entry(id, "Example", "gpu", "opencl.b4.soa-split.wg64", "1600k");
  crowd_64.shape = SceneKind::kInstances;
  crowd_64.instances = 64;
  WinnersEntry crowd_8 = Entry(id, "Example", "gpu", "opencl.b4.soa-split.wg128", "1600k");
  crowd_8.shape = SceneKind::kInstances;
  crowd_8.instances = 8;
  WinnersEntry mixed = Entry(id, "Example", "gpu", "opencl.b4.soa.float3.wg512", "1600k");
  mixed.shape = SceneKind::kBatch;
  mixed.meshes = 31;
  const WinnersDb db = Db({single_1600k, single_25k, crowd_64, crowd_8, mixed});

  auto find = [&](SceneShape shape) {
    const Result<Selection> s = Selection::Find(db, ThisDevice(), 4, 1600000, kDefaultMaxError, shape);
    EXPECT_TRUE(s.ok()) << s.status().message();
    return s.ok() ? *s : Selection{};
  };
  const Selection single = find(SceneShape::kSingle);
  EXPECT_EQ(single.variant, ParseVariantKey("opencl.b4.soa.wg256").Key());
  EXPECT_EQ(single.reason.find("no single"), std::string::npos) << single.reason;
  const Selection crowd = find(SceneShape::kInstances);
  EXPECT_EQ(crowd.variant, ParseVariantKey("opencl.b4.soa-split.wg64").Key()) << crowd.reason;
  EXPECT_NE(crowd.entry.find("instances x64"), std::string::npos) << crowd.entry;
  const Selection batch = find(SceneShape::kBatch);
  EXPECT_EQ(batch.variant, ParseVariantKey("opencl.b4.soa.float3.wg512").Key()) << batch.reason;
  EXPECT_NE(batch.entry.find("batch of 31 meshes"), std::string::npos) << batch.entry;

  // Without batch entries a batch takes the single mesh of its total size, saying so.
  const WinnersDb no_batch = Db({single_1600k, single_25k, crowd_64});
  const Result<Selection> fallback =
      Selection::Find(no_batch, ThisDevice(), 4, 1600000, kDefaultMaxError, SceneShape::kBatch);
  ASSERT_TRUE(fallback.ok());
  EXPECT_EQ(fallback->variant, ParseVariantKey("opencl.b4.soa.wg256").Key());
  EXPECT_NE(fallback->reason.find("no batch entry: the single-mesh entry of the scene's total size (1600000 vertices)"),
            std::string::npos)
      << fallback->reason;
  // A single mesh never takes an instances or batch entry.
  const Result<Selection> only_crowds =
      Selection::Find(Db({crowd_64, mixed}), ThisDevice(), 4, 1600000, kDefaultMaxError, SceneShape::kSingle);
  ASSERT_TRUE(only_crowds.ok());
  EXPECT_EQ(only_crowds->level, MatchLevel::kGenericDefault);
  // Among instances entries of the same total, the nearest instance count
  // (Skinner::Create asks with its K; Selection::Find has none).
  SelectionRequest request;
  request.device = ThisDevice();
  request.langs = {Lang::kOpenCl};
  request.influences = 4;
  request.vertex_count = 1600000;
  request.shape = SceneKind::kInstances;
  crowd_8.vertices = 1600000;
  request.instances = 10;
  EXPECT_EQ(Select({crowd_64, crowd_8}, request).variant.Key(), ParseVariantKey("opencl.b4.soa-split.wg128").Key());
  request.instances = 50;
  EXPECT_EQ(Select({crowd_64, crowd_8}, request).variant.Key(), ParseVariantKey("opencl.b4.soa-split.wg64").Key());
}

}  // namespace
}  // namespace skintune::internal
