// The `skintune` command, tested on its exit codes and exact messages.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "reference/mesh_io.h"
#include "reference/skinning.h"
#include "reference/synthetic.h"
#include "run_command.h"

namespace skintune {
namespace {

namespace fs = std::filesystem;
using testing::CountLines;
using testing::ReadAll;
using testing::RunSkintune;

const std::string kData = SKINTUNE_TEST_DATA_DIR;

fs::path Scratch() {
  const fs::path dir = fs::temp_directory_path() / ("skintune_cli_test_" + std::to_string(::getpid()) + "_" +
                                                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(SkintuneCli, VersionPrintsTheVersion) {
  const auto r = RunSkintune({"--version"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.out, "skintune 0.1.0\n");
}

TEST(SkintuneCli, HelpListsTheCommands) {
  const auto r = RunSkintune({"--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* cmd : {"run", "devices", "skin"}) EXPECT_NE(r.out.find(cmd), std::string::npos) << cmd;
  EXPECT_EQ(RunSkintune({"skin", "--help"}).exit_code, 0);
}

TEST(SkintuneCli, NoCommandIsAUsageError) {
  const auto r = RunSkintune({});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
}

TEST(SkintuneCli, DevicesListsOpenClOrSaysWhyNot) {
  const auto r = RunSkintune({"devices"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.out.find("OpenCL platform 0:") != std::string::npos ||
              r.out.find("OpenCL: skipped: ") != std::string::npos)
      << r.out;
}

TEST(SkintuneCli, DevicesJsonIsValidJsonWithDeviceIdentities) {
  const auto r = RunSkintune({"devices", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j.at("opencl").at("devices").is_array());
  for (const auto& d : j["opencl"]["devices"]) {
    for (const char* key : {"name", "vendor", "driver_version", "compute_units", "global_memory_bytes",
                            "local_memory_bytes", "constant_buffer_bytes"}) {
      EXPECT_TRUE(d.contains(key)) << key;
    }
  }
}

TEST(SkintuneCli, SkinDatasetWritesOneVLinePerVertexMatchingTheGold) {
  const fs::path out = Scratch() / "skinned.obj";
  const auto r = RunSkintune({"skin", "--dataset", "1000-b3", "--animation", "0", "--time", "0.25", "--out", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const SkinnedVertices written = ReadSkinnedVertices(out);
  ASSERT_EQ(written.positions.size(), 1000u);
  EXPECT_EQ(CountLines(ReadAll(out)), 1000);
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("1000-b3"));
  const GoldResult gold = SkinGold(asset.mesh, asset.PaletteAt(0, 0.25));
  EXPECT_LT(CompareToGold(gold.positions, written.positions).max_relative, 1e-6);
}

TEST(SkintuneCli, SkinEachImplementationWritesTheSameBinaryWithinTolerance) {
  const fs::path dir = Scratch();
  std::vector<SkinnedVertices> results;
  for (const char* impl : {"gold", "serial", "fast"}) {
    const fs::path out = dir / (std::string(impl) + ".stv");
    const auto r = RunSkintune({"skin", "--dataset", "3000-b4-normals", "--normals", "--time", "0.5", "--impl", impl,
                                "--out", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    results.push_back(ReadSkinnedVertices(out));
    EXPECT_EQ(results.back().normals.size(), 3000u);
  }
  const std::vector<glm::dvec3> gold(results[0].positions.begin(), results[0].positions.end());
  EXPECT_LT(CompareToGold(gold, results[1].positions).max_relative, 1e-5);
  EXPECT_LT(CompareToGold(gold, results[2].positions).max_relative, 1e-5);
}

TEST(SkintuneCli, SkinGltfRenormalisesCesiumManAndWarnsOnce) {
  const fs::path out = Scratch() / "cesium.stv";
  const auto r = RunSkintune({"skin", "--mesh", kData + "/CesiumMan.gltf", "--animation", "0", "--time", "1.0",
                              "--out", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("skintune: warning: "), std::string::npos);
  EXPECT_NE(r.err.find("210 vertices"), std::string::npos) << r.err;
  EXPECT_EQ(ReadSkinnedVertices(out).positions.size(), 3273u);
}

TEST(SkintuneCli, StrictRejectsCesiumManAndLeavesTheOutputUntouched) {
  const fs::path out = Scratch() / "existing.obj";
  std::ofstream(out) << "keep me\n";
  const auto r = RunSkintune({"skin", "--mesh", kData + "/CesiumMan.gltf", "--strict", "--out", out});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("skintune: error: " + kData + "/CesiumMan.gltf: ", 0), 0u) << r.err;
  EXPECT_EQ(ReadAll(out), "keep me\n");
}

TEST(SkintuneCli, MissingGltfFileIsOneLineNamingTheFile) {
  const auto r = RunSkintune({"skin", "--mesh", "/nonexistent/model.gltf", "--out", Scratch() / "x.obj"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: /nonexistent/model.gltf: cannot open file\n");
}

TEST(SkintuneCli, NotAGltfFileIsRejected) {
  const fs::path dir = Scratch();
  std::ofstream(dir / "junk.gltf") << "this is not json";
  const auto r = RunSkintune({"skin", "--mesh", dir / "junk.gltf", "--out", dir / "x.obj"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find((dir / "junk.gltf").string() + ": not a glTF 2.0 file"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x.obj"));
}

TEST(SkintuneCli, UnknownAnimationListsTheAvailableOnes) {
  const auto r = RunSkintune({"skin", "--mesh", kData + "/Fox.gltf", "--animation", "Fly", "--out", Scratch() / "x.obj"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: " + kData + "/Fox.gltf: no animation 'Fly' (it has: 0 'Survey', 1 'Walk', 2 'Run')\n");
}

TEST(SkintuneCli, MalformedDatasetKeyIsOneLine) {
  const auto r = RunSkintune({"skin", "--dataset", "lots-b2", "--out", Scratch() / "x.obj"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("skintune: error: dataset 'lots-b2': ", 0), 0u) << r.err;
}

TEST(SkintuneCli, UsageErrorsExitWithTwo) {
  const fs::path out = Scratch() / "x.obj";
  EXPECT_EQ(RunSkintune({"skin", "--dataset", "1k-b1"}).exit_code, 2);  // no --out
  EXPECT_EQ(RunSkintune({"skin", "--dataset", "1k-b1", "--mesh", "a.gltf", "--out", out}).exit_code, 2);
  EXPECT_EQ(RunSkintune({"skin", "--dataset", "1k-b1", "--time", "-1", "--out", out}).exit_code, 2);
  EXPECT_EQ(RunSkintune({"skin", "--dataset", "1k-b1", "--impl", "gpu", "--out", out}).exit_code, 2);
  EXPECT_EQ(RunSkintune({"frobnicate"}).exit_code, 2);
  EXPECT_FALSE(fs::exists(out));
}

TEST(SkintuneCli, SkinWithoutInputSaysWhatToGive) {
  const auto r = RunSkintune({"skin", "--out", Scratch() / "x.obj"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err, "skintune: error: skin: give --dataset NAME or --mesh FILE\n");
}

TEST(SkintuneCli, TimeWithoutAnimationOnAModelWithoutAnimationsIsAnError) {
  // Synthetic datasets have one clip; a NaN time is refused before any work.
  const auto r = RunSkintune({"skin", "--dataset", "1k-b1", "--time", "nan", "--out", Scratch() / "x.obj"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
}

TEST(SkintuneCli, RunChecksTheCpuImplementationsAgainstTheGold) {
  const auto r = RunSkintune({"run", "--dataset", "20k-b2"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("== devices"), std::string::npos);
  EXPECT_NE(r.out.find("ok: serial and fast agree with the float64 gold within 1e-5"), std::string::npos) << r.out;
}

TEST(SkintuneCli, EmitWritesTheKernelAndASidecarDescribingItsInterface) {
  const fs::path dir = Scratch() / "kernels";
  const std::string key = "opencl.b3.padded.soa-split.float4.u16.unorm16.mat3x4.local.matrix.v2c.wg64.nonormals";
  const auto r = RunSkintune({"emit", "--variant", key, "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(ReadAll(dir / (key + ".cl")).find("#define INFLUENCES 3"), std::string::npos);
  const nlohmann::json sidecar = nlohmann::json::parse(ReadAll(dir / (key + ".json")));
  EXPECT_EQ(sidecar.at("variant"), key);
  EXPECT_EQ(sidecar.at("entry_point"), "skin");
  EXPECT_EQ(sidecar.at("source_file"), key + ".cl");
  std::vector<std::string> names;
  for (const auto& a : sidecar.at("arguments")) names.push_back(a.at("name"));
  EXPECT_EQ(names, (std::vector<std::string>{"n", "first", "positions", "indices", "weights", "palette", "out_positions"}));
}

TEST(SkintuneCli, EmitInstancesWritesTheInstancedKernelBesideThePlainOne) {
  const fs::path dir = Scratch() / "kernels";
  const std::string key = "cuda.b2.padded.soa.float4.u16.f32.mat3x4.constant.matrix.v1c.wg128.nonormals";
  ASSERT_EQ(RunSkintune({"emit", "--variant", key, "--out", dir}).exit_code, 0);
  const auto r = RunSkintune({"emit", "--variant", key, "--out", dir, "--instances", "8", "--joints", "20"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(ReadAll(dir / (key + ".cu")).find("#define INSTANCED 1"), std::string::npos);
  const std::string kernel = ReadAll(dir / (key + ".instanced.cu"));
  EXPECT_NE(kernel.find("#define INSTANCED 1\n#define PALETTE_INSTANCES 8\n"), std::string::npos);
  const nlohmann::json sidecar = nlohmann::json::parse(ReadAll(dir / (key + ".instanced.json")));
  EXPECT_EQ(sidecar.at("source_file"), key + ".instanced.cu");
  EXPECT_EQ(sidecar.at("arguments")[2].at("name"), "vertex_count");
  EXPECT_EQ(sidecar.at("instancing").at("max_instances"), 8);
}

TEST(SkintuneCli, EmitWithAMalformedKeyIsOneClearLine) {
  const auto r = RunSkintune({"emit", "--variant", "opencl.b4.turbo", "--out", Scratch()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("skintune: error: variant 'opencl.b4.turbo': unknown token 'turbo' (expected ", 0), 0u) << r.err;
}

TEST(SkintuneCli, EmitRefusesAnInvalidVariantNamingTheConstraint) {
  const fs::path dir = Scratch();
  const auto r = RunSkintune({"emit", "--variant", "opencl.v1s", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("(constraint assignment_redundant)"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(SkintuneCli, EmitIntoAnUnwritableFolderIsAnError) {
  const fs::path file = Scratch() / "a-file";
  std::ofstream(file) << "x";
  const auto r = RunSkintune({"emit", "--variant", "opencl.b1", "--out", file / "sub"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("cannot create output folder"), std::string::npos) << r.err;
}

TEST(SkintuneCli, VariantsCountsTheSpaceAndTheInvalidPointsPerConstraint) {
  const auto r = RunSkintune({"variants", "--lang", "opencl", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  std::uint64_t invalid = 0;
  for (const auto& [name, n] : j.at("invalid_by").items()) invalid += n.get<std::uint64_t>();
  EXPECT_EQ(j.at("valid").get<std::uint64_t>() + invalid, j.at("total").get<std::uint64_t>());
  EXPECT_GT(j.at("invalid_by").at("assignment_redundant").get<std::uint64_t>(), 0u);
}

TEST(SkintuneCli, VariantsWithAnUnknownDeviceIsAnError) {
  const auto r = RunSkintune({"variants", "--device", "no-such-device-xyz"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: --device 'no-such-device-xyz': no OpenCL device matches (see skintune devices)\n");
}

}  // namespace
}  // namespace skintune
