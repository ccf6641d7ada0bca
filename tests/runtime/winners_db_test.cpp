// The winners database as the runtime reads it: WinnersDb::Load / Parse, and
// the errors for files that are not one (naming the file and the element).
#include "runtime/winners_db.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "skintune/skintune.h"

namespace skintune::internal {
namespace {

WinnersEntry SampleEntry() {
  WinnersEntry e;
  e.device_id = "opencl:Synthetic/Model GPU/1.0";
  e.backend = "opencl";
  e.platform = "Synthetic";
  e.vendor = "Example";
  e.device_name = "Model GPU";
  e.driver_version = "1.0";
  e.device_type = "gpu";
  e.lang = Lang::kOpenCl;
  e.influences = 4;
  e.vertex_bucket = "100k";
  e.vertices = 100000;
  e.dataset = "100k-b4";
  e.variant = ParseVariantKey("opencl.b4.soa-split.u8.unorm8.local.wg256");
  e.median_ms = 0.25;
  e.gbps = 400.0;
  e.copy_fraction = 0.2;
  e.created = "2025-01-31T12:00:00Z";
  e.source = "default (exhaustive)";
  return e;
}

std::string ParseError(const nlohmann::json& json, const std::string& name = "db.json") {
  const Result<WinnersDb> db = WinnersDb::Parse(json.dump(), name);
  EXPECT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), ErrorCode::kInvalidArgument) << db.status().message();
  return db.status().message();
}

// What WinnersEntryFromJson says of `entry` ("no error" where it reads it).
std::string EntryError(const nlohmann::json& entry) {
  try {
    (void)WinnersEntryFromJson(entry);
  } catch (const Error& e) {
    return std::string(e.what());
  }
  return std::string("no error");
}

TEST(WinnersDb, EntryRoundTripsThroughJson) {
  const WinnersEntry e = SampleEntry();
  const nlohmann::json j = WinnersEntryToJson(e);
  EXPECT_EQ(j["vendor"], "Example");
  EXPECT_EQ(j["device_type"], "gpu");
  const WinnersEntry back = WinnersEntryFromJson(nlohmann::json::parse(j.dump()));
  EXPECT_EQ(WinnersEntryToJson(back), j);
  EXPECT_EQ(back.variant, e.variant);
}

// Database 1.4.0: the scene shape round-trips; entries of older databases
// (no "shape") are single meshes; a shape that does not fit its counts is refused.
// A morph entry records its mesh's target count; older entries (no field)
// have none; a count that does not fit the variant is an error naming it.
TEST(WinnersDb, MorphTargetCountsRoundTripAndMustFitTheVariant) {
  WinnersEntry e = SampleEntry();
  e.variant.morph = Morph::kSparseHalf;
  e.morph_targets = 8;
  const nlohmann::json j = WinnersEntryToJson(e);
  EXPECT_EQ(j["morph_targets"], 8);
  const WinnersEntry back = WinnersEntryFromJson(nlohmann::json::parse(j.dump()));
  EXPECT_EQ(back.morph_targets, 8);
  EXPECT_EQ(back.variant.morph, Morph::kSparseHalf);
  EXPECT_NE(Describe(back).find(" morph 8"), std::string::npos) << Describe(back);
  nlohmann::json untold = j;
  untold.erase("morph_targets");
  EXPECT_NE(EntryError(untold).find("applies morph targets, and 'morph_targets' does not say how many"), std::string::npos);
  nlohmann::json plain = WinnersEntryToJson(SampleEntry());
  EXPECT_EQ(plain["morph_targets"], 0);
  plain.erase("morph_targets");
  EXPECT_EQ(WinnersEntryFromJson(plain).morph_targets, 0);  // an entry before the field
  plain["morph_targets"] = 4;
  EXPECT_NE(EntryError(plain).find("does not apply the 4 morph targets of the mesh it was tuned on"), std::string::npos);
  plain["morph_targets"] = -1;
  EXPECT_NE(EntryError(plain).find("'morph_targets' is -1, expected 0..256"), std::string::npos) << EntryError(plain);
}

// Database 1.10.0: an animated entry records whether its crowd cross-faded
// clips; its row and name keep it apart from one that did not; older
// entries (no field) did not; only an animated entry may, and only a boolean.
TEST(WinnersDb, CrossFadingCrowdsRoundTripAndKeepTheirOwnRow) {
  WinnersEntry e = SampleEntry();
  e.variant.animation = Animation::kLocal120;
  e.shape = SceneKind::kInstances;
  e.instances = 64;
  e.cross_fades = true;
  const nlohmann::json j = WinnersEntryToJson(e);
  EXPECT_EQ(j["cross_fades"], true);
  const WinnersEntry back = WinnersEntryFromJson(nlohmann::json::parse(j.dump()));
  EXPECT_TRUE(back.cross_fades);
  EXPECT_EQ(RowName(back), "100k instances x64 animated, cross-fading");
  WinnersEntry steady = back;
  steady.cross_fades = false;
  EXPECT_EQ(RowName(steady), "100k instances x64 animated");
  EXPECT_NE(RowOf(back), RowOf(steady));
  nlohmann::json older = j;
  older.erase("cross_fades");
  EXPECT_FALSE(WinnersEntryFromJson(older).cross_fades);
  nlohmann::json wrong = j;
  wrong["cross_fades"] = 1;
  EXPECT_EQ(EntryError(wrong), "'cross_fades' must be true or false");
  nlohmann::json host = WinnersEntryToJson(SampleEntry());
  host["cross_fades"] = true;
  EXPECT_NE(EntryError(host).find("'cross_fades' is true, and 'variant' opencl."), std::string::npos) << EntryError(host);
}

TEST(WinnersDb, SceneShapesRoundTripAndOlderEntriesAreSingleMeshes) {
  WinnersEntry e = SampleEntry();
  e.shape = SceneKind::kInstances;
  e.instances = 64;
  const nlohmann::json j = WinnersEntryToJson(e);
  EXPECT_EQ(j["shape"], "instances");
  EXPECT_EQ(j["instances"], 64);
  EXPECT_EQ(j["meshes"], 1);
  const WinnersEntry back = WinnersEntryFromJson(nlohmann::json::parse(j.dump()));
  EXPECT_EQ(back.shape, SceneKind::kInstances);
  EXPECT_EQ(back.instances, 64);
  EXPECT_EQ(WinnersEntryToJson(back), j);
  EXPECT_NE(Describe(back).find(" instances x64"), std::string::npos) << Describe(back);

  nlohmann::json old = j;
  old.erase("shape");
  old.erase("instances");
  old.erase("meshes");
  const WinnersEntry single = WinnersEntryFromJson(old);
  EXPECT_EQ(single.shape, SceneKind::kSingle);
  EXPECT_EQ(single.instances, 1);
  EXPECT_EQ(single.meshes, 1);
  nlohmann::json db = {{"schema_version", "1.3.0"}, {"kind", "skintune-winners-db"}, {"entries", {old}}};
  const Result<WinnersDb> loaded = WinnersDb::Parse(db.dump(), "old.json");
  EXPECT_TRUE(loaded.ok()) << loaded.status().message();
  EXPECT_EQ(WinnersDbJson({e})["schema_version"], kWinnersDbSchemaVersion);

  nlohmann::json bad = j;
  bad["instances"] = 1;
  db["entries"] = {bad};
  EXPECT_NE(ParseError(db).find("db.json: entries[0]: 'shape' instances does not match 'instances' 1 and 'meshes' 1"),
            std::string::npos)
      << ParseError(db);
  bad = j;
  bad["shape"] = "crowd";
  db["entries"] = {bad};
  EXPECT_NE(ParseError(db).find("'shape' has unknown value 'crowd' (expected single, instances, batch)"),
            std::string::npos);
}

TEST(WinnersDb, EntriesWithoutVendorAndTypeLoadWithTheIdsParts) {
  nlohmann::json j = WinnersEntryToJson(SampleEntry());
  for (const char* field : {"platform", "vendor", "device_name", "driver_version", "device_type"}) j.erase(field);
  const WinnersEntry e = WinnersEntryFromJson(j);
  EXPECT_EQ(e.platform, "Synthetic");
  EXPECT_EQ(e.device_name, "Model GPU");
  EXPECT_EQ(e.driver_version, "1.0");
  EXPECT_EQ(e.vendor, "");
  EXPECT_EQ(e.device_type, "");
  nlohmann::json db = WinnersDbJson({});
  db["schema_version"] = "1.0.0";
  db["entries"].push_back(j);
  const Result<WinnersDb> loaded = WinnersDb::Parse(db.dump(), "old.json");
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  EXPECT_EQ(loaded->size(), 1u);
}

TEST(WinnersDb, EntriesBefore1_2_0CountAsTheirBucketsNominalVertices) {
  nlohmann::json j = WinnersEntryToJson(SampleEntry());
  EXPECT_EQ(j.at("vertices"), 100000);
  j.erase("vertices");
  j["vertex_bucket"] = "1600k";
  EXPECT_EQ(WinnersEntryFromJson(j).vertices, 1600000u);
  // A count must agree with its bucket and be at least one vertex.
  j["vertices"] = 25000;
  EXPECT_THROW(WinnersEntryFromJson(j), Error);
  j["vertices"] = 0;
  j["vertex_bucket"] = "25k";
  EXPECT_THROW(WinnersEntryFromJson(j), Error);
  j["vertices"] = 6400000;
  j["vertex_bucket"] = "1600k";
  EXPECT_EQ(WinnersEntryFromJson(j).vertices, 6400000u);
  const std::string described = Describe(WinnersEntryFromJson(j));
  EXPECT_EQ(described.substr(described.rfind(" b4 ")), " b4 6400k") << described;
}

TEST(WinnersDb, DeviceIdSplitsAtTheFirstAndLastSlash) {
  const DeviceIdParts p = SplitDeviceId("gl:surfaceless/AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 15)/4.6 Mesa");
  EXPECT_EQ(p.backend, "gl");
  EXPECT_EQ(p.platform, "surfaceless");
  EXPECT_EQ(p.name, "AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 15)");
  EXPECT_EQ(p.driver_version, "4.6 Mesa");
  EXPECT_EQ(SplitDeviceId("cuda:CUDA/a/b/c/580.1").name, "a/b/c");
  EXPECT_EQ(JoinDeviceId(p), "gl:surfaceless/AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 15)/4.6 Mesa");
  EXPECT_THROW(SplitDeviceId("no-backend/a/b"), Error);
  EXPECT_THROW(SplitDeviceId("opencl:only-one/slash"), Error);
}

TEST(WinnersDb, LoadsAFileAndCountsItsEntries) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() / "skintune_winners_db_test.json";
  std::ofstream(path) << WinnersDbJson({SampleEntry(), SampleEntry()}).dump(2);
  const Result<WinnersDb> db = WinnersDb::Load(path.string());
  ASSERT_TRUE(db.ok()) << db.status().message();
  EXPECT_EQ(db->size(), 2u);
  std::filesystem::remove(path);
  EXPECT_EQ(WinnersDb::Empty().size(), 0u);
}

TEST(WinnersDb, MissingFileIsAnIoErrorNamingThePath) {
  const Result<WinnersDb> db = WinnersDb::Load("/nonexistent/skintune/db.json");
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), ErrorCode::kIoError);
  EXPECT_NE(db.status().message().find("/nonexistent/skintune/db.json"), std::string::npos) << db.status().message();
}

TEST(WinnersDb, NotJsonNamesTheFile) {
  const Result<WinnersDb> db = WinnersDb::Parse("{\"schema_version\": ", "broken.json");
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(db.status().message().rfind("broken.json: not valid JSON (", 0), 0u) << db.status().message();
}

// A number beyond double gave "internal error: ... number overflow" (kDeviceError).
TEST(WinnersDb, ANumberBeyondDoubleIsNotValidJsonNamingTheFile) {
  const Result<WinnersDb> db = WinnersDb::Parse("{\"schema_version\": 1e400}", "huge.json");
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(db.status().message().rfind("huge.json: not valid JSON (", 0), 0u) << db.status().message();
  EXPECT_NE(db.status().message().find("1e400"), std::string::npos) << db.status().message();
}

// A folder or a FIFO where the database should be: an I/O error naming it, never a hang.
TEST(WinnersDb, AFolderOrAFifoIsAnIoErrorNamingItWithoutBlocking) {
  const std::string dir = ::testing::TempDir() + "skintune-winners-db-fifo";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir + "/folder.json");
  ASSERT_EQ(::mkfifo((dir + "/fifo.json").c_str(), 0600), 0);
  ::alarm(30);  // a blocked open fails the test (SIGALRM) instead of hanging it
  for (const char* name : {"/folder.json", "/fifo.json"}) {
    const Result<WinnersDb> db = WinnersDb::Load(dir + name);
    ASSERT_FALSE(db.ok());
    EXPECT_EQ(db.status().code(), ErrorCode::kIoError);
    EXPECT_NE(db.status().message().find(dir + name + ": is a"), std::string::npos) << db.status().message();
  }
  ::alarm(0);
  std::filesystem::remove_all(dir);
}

TEST(WinnersDb, WrongKindOrVersionNamesTheFileAndTheField) {
  nlohmann::json db = WinnersDbJson({SampleEntry()});
  db["kind"] = "kernel-tuner-cache";
  EXPECT_EQ(ParseError(db), "db.json: kind is 'kernel-tuner-cache', expected 'skintune-winners-db'");
  db = WinnersDbJson({SampleEntry()});
  db["schema_version"] = "2.0.0";
  EXPECT_EQ(ParseError(db).rfind("db.json: schema_version '2.0.0' is not supported", 0), 0u);
  db.erase("schema_version");
  EXPECT_EQ(ParseError(db), "db.json: schema_version: missing 'schema_version'");
  EXPECT_EQ(ParseError(nlohmann::json::array()), "db.json: expected a JSON object");
}

TEST(WinnersDb, ATuningReportIsRefusedWithTheWayToItsDatabase) {
  const std::string message = ParseError({{"schema_version", "1.0.0"}, {"kind", "skintune-report"}}, "report.json");
  EXPECT_EQ(message.rfind("report.json: a tuning report, not a winners database", 0), 0u) << message;
  EXPECT_NE(message.find("skintune db merge report.json"), std::string::npos) << message;
}

TEST(WinnersDb, MalformedEntriesNameTheEntryAndTheField) {
  auto with = [](const char* field, const nlohmann::json& value) {
    nlohmann::json db = WinnersDbJson({SampleEntry(), SampleEntry()});
    if (value.is_null()) {
      db["entries"][1].erase(field);
    } else {
      db["entries"][1][field] = value;
    }
    return db;
  };
  EXPECT_EQ(ParseError(with("lang", nullptr)), "db.json: entries[1]: missing 'lang'");
  EXPECT_EQ(ParseError(with("lang", 3)), "db.json: entries[1]: 'lang' must be a string");
  EXPECT_EQ(ParseError(with("lang", "metal")).rfind("db.json: entries[1]: 'lang' has unknown value 'metal'", 0), 0u);
  EXPECT_EQ(ParseError(with("vertex_bucket", "3k")).rfind("db.json: entries[1]: 'vertex_bucket' has unknown value '3k'", 0),
            0u);
  EXPECT_EQ(ParseError(with("influences", 2)).rfind("db.json: entries[1]: 'variant' ", 0), 0u);
  EXPECT_EQ(ParseError(with("device_id", "Model GPU")).rfind("db.json: entries[1]: device id 'Model GPU' is not", 0), 0u);
  EXPECT_EQ(ParseError(with("device_name", "Other GPU")),
            "db.json: entries[1]: 'device_name' is 'Other GPU' but 'device_id' says 'Model GPU'");
  EXPECT_EQ(ParseError(with("created", "yesterday")).rfind("db.json: entries[1]: 'created' is 'yesterday'", 0), 0u);
  nlohmann::json bad_variant = with("variant", nlohmann::json{{"layout", "tiled"}});
  EXPECT_EQ(ParseError(bad_variant).rfind("db.json: entries[1]: variant JSON: 'layout' has unknown value 'tiled'", 0), 0u);
  nlohmann::json not_array = WinnersDbJson({});
  not_array["entries"] = 7;
  EXPECT_EQ(ParseError(not_array), "db.json: entries: 'entries' must be an array");
}

// docs/INPUTS.md "Measurements: one rule for every time": an impossible time in a database never reaches a
// Selection (the runtime) or a merge (the tuner): both read through here.
TEST(WinnersDb, ImpossibleTimesAreRefusedNamingTheEntry) {
  auto with = [](const char* field, const nlohmann::json& value) {
    nlohmann::json db = WinnersDbJson({SampleEntry(), SampleEntry()});
    db["entries"][1][field] = value;
    return db;
  };
  EXPECT_EQ(ParseError(with("median_ms", 0)),
            "db.json: entries[1]: impossible figures: 'median_ms' is 0: a time must be a positive, finite number");
  EXPECT_EQ(ParseError(with("median_ms", -5)),
            "db.json: entries[1]: impossible figures: 'median_ms' is -5: a time must be a positive, finite number");
  EXPECT_EQ(ParseError(with("gbps", -1)),
            "db.json: entries[1]: impossible figures: 'gbps' is -1: must be a finite number >= 0");
  EXPECT_EQ(ParseError(with("copy_fraction", -1)),
            "db.json: entries[1]: impossible figures: 'copy_fraction' is -1: must be a finite number >= 0");
}

TEST(WinnersDb, VertexBucketsFollowThePapersCounts) {
  EXPECT_EQ(VertexBucket(49999), "25k");
  EXPECT_EQ(VertexBucket(50000), "100k");
  EXPECT_EQ(VertexBucket(800000), "1600k");
  EXPECT_EQ(VertexBucketIndex("400k"), 2);
  EXPECT_EQ(VertexBucketIndex("3k"), -1);
}

}  // namespace
}  // namespace skintune::internal
