// The `skintune` command, tested on its exit codes and exact messages.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "generator/emit.h"  // kGeneratorVersion
#include "generator/languages.h"
#include "reference/mesh_io.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "run_command.h"
#include "tests/common/scratch_dir.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;
using testing::CountLines;
using testing::ReadAll;
using testing::RunSkintune;

const std::string kData = SKINTUNE_TEST_DATA_DIR;

fs::path Scratch() { return skintune::internal::testing::ScratchDir("skintune_cli_test"); }

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

// The --lang help texts come from the language table (generator/languages.h): a
// new language is listed without editing them.
TEST(SkintuneCli, LangHelpListsEveryLanguageOfTheTable) {
  for (const char* command : {"tune", "run", "paper", "variants"}) {
    const auto r = RunSkintune({command, "--help"});
    ASSERT_EQ(r.exit_code, 0) << command << ": " << r.err;
    const std::size_t at = r.out.find("--lang");
    ASSERT_NE(at, std::string::npos) << command << ": " << r.out;
    const std::string line = r.out.substr(at, r.out.find('\n', at) - at);
    for (const Language& language : kLanguages)
      EXPECT_NE(line.find(language.name), std::string::npos) << command << " --help: " << line;
  }
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

// Every device of every API by its id, or why an API has none (runtime/backend_table.h).
TEST(SkintuneCli, DevicesListsEveryApisDevicesByIdOrWhyNone) {
  const auto r = RunSkintune({"devices", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out).at("skintune");
  std::set<std::string> apis;
  for (const auto& d : j.at("devices")) {
    apis.insert(d.at("backend").get<std::string>());
    EXPECT_EQ(d.at("id"), d.at("backend").get<std::string>() + ":" + d.at("platform").get<std::string>() + "/" +
                              d.at("name").get<std::string>() + "/" + d.at("driver_version").get<std::string>());
  }
  for (const auto& s : j.at("skipped")) apis.insert(s.get<std::string>().substr(0, s.get<std::string>().find(':')));
  EXPECT_EQ(apis, (std::set<std::string>{"opencl", "cuda", "gl", "vulkan", "cpu"})) << j.dump(2);
  const auto text = RunSkintune({"devices"});
  EXPECT_NE(text.out.find("Devices (OpenCL, CUDA, GL, Vulkan or CPU):"), std::string::npos) << text.out;
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
  EXPECT_EQ(r.err, "skintune: error: /nonexistent/model.gltf: cannot open file (No such file or directory)\n");
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

// vulkan: the GLSL, its SPIR-V (starting with the SPIR-V magic number) and a
// sidecar naming both, with the descriptor set and push-constant layout.
TEST(SkintuneCli, EmitWritesAVulkanKernelsSpirvBesideItsGlsl) {
  const fs::path dir = Scratch() / "kernels";
  const std::string key = "vulkan.b2.padded.soa.float4.u16.f32.mat3x4.image.matrix.v1c.wg64.nonormals";
  const auto r = RunSkintune({"emit", "--variant", key, "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(ReadAll(dir / (key + ".vk.comp")).find("#define STORAGE 3"), std::string::npos);
  const std::string spirv = ReadAll(dir / (key + ".spv"));
  ASSERT_GE(spirv.size(), 20u);
  EXPECT_EQ(spirv.size() % 4, 0u);
  EXPECT_EQ(spirv.substr(0, 4), std::string("\x03\x02\x23\x07", 4));  // 0x07230203, little-endian
  const nlohmann::json sidecar = nlohmann::json::parse(ReadAll(dir / (key + ".json")));
  EXPECT_EQ(sidecar.at("spirv_file"), key + ".spv");
  EXPECT_EQ(sidecar.at("arguments")[1].at("push_constant_offset"), 4);
  EXPECT_EQ(sidecar.at("arguments")[5].at("descriptor_type"), "VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER");
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

// One dataset grammar for every command: `variants` takes the scene keys
// `tune` takes ("unknown option 'x16'" before), and the instances count
// against the storages that hold every palette.
TEST(SkintuneCli, VariantsTakesASceneKeyAndItsInstancesCount) {
  auto valid = [](const std::string& key) {
    const auto r = RunSkintune({"variants", "--lang", "opencl", "--dataset", key, "--json"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out.empty() ? "{}" : r.out);
    EXPECT_EQ(j.value("mesh", ""), "scene '" + key + "'");
    return j.value("valid", std::uint64_t{0});
  };
  const std::uint64_t one = valid("5k-b4");
  const std::uint64_t crowd = valid("5k-b4-x16");
  const std::uint64_t big_crowd = valid("5k-b4-x64");
  EXPECT_GT(one, 0u);
  EXPECT_GE(one, crowd);
  EXPECT_GT(crowd, big_crowd) << "64 palettes of 77 joints do not fit constant storage";
}

// `variants --config` without --dataset or --mesh counts the space on each of
// the config's data sets, as `tune` would measure them: the animated-crowds
// space is all forms animated on the device, which the paper's rig (a mesh
// whose palettes come from the host) would cut to nothing.
TEST(SkintuneCli, VariantsOfAConfigCountsItsSpaceOnEachOfItsDataSets) {
  const auto r = RunSkintune({"variants", "--config", "animated-crowds", "--lang", "cuda", "--json", "--list"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json out = nlohmann::json::parse(r.out);
  ASSERT_TRUE(out.is_array());
  ASSERT_EQ(out.size(), 2u);
  EXPECT_NE(out[0].at("mesh").get<std::string>().find("25k-b4-x64-anim"), std::string::npos);
  EXPECT_NE(out[1].at("mesh").get<std::string>().find("5k-b4-x1024-animblend"), std::string::npos);
  for (const nlohmann::json& mesh : out) {
    // At the data set's B, as tune plans it: the 832 points and 528 valid
    // variants a language the config's description states.
    EXPECT_EQ(mesh.at("total").get<std::uint64_t>(), 832u) << mesh.at("mesh");
    EXPECT_EQ(mesh.at("valid").get<std::uint64_t>(), 528u) << mesh.at("mesh");
    bool fused = false;
    for (const nlohmann::json& key : mesh.at("variants")) fused = fused || key.get<std::string>().ends_with("anim-fused240");
    EXPECT_TRUE(fused) << mesh.at("mesh");
  }
  // A data set given picks one mesh, and the output is its object, as before.
  const auto one = RunSkintune({"variants", "--config", "animated-crowds", "--lang", "cuda", "--dataset",
                                "25k-b4-x64-anim", "--json"});
  ASSERT_EQ(one.exit_code, 0) << one.err;
  EXPECT_TRUE(nlohmann::json::parse(one.out).is_object());
}

// `variants --config` takes the built-in names `tune` takes; a dual-quaternion
// space counts its variants valid on a rigid animation and invalid
// (joints_not_rigid) on one whose joints scale.
TEST(SkintuneCli, VariantsTakesABuiltInConfigAndJudgesDualQuaternionsByTheDataSetsJoints) {
  auto count = [](const std::string& dataset) {
    const auto r = RunSkintune({"variants", "--config", "dual-quaternions", "--lang", "opencl", "--dataset", dataset,
                                "--json"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return nlohmann::json::parse(r.out.empty() ? "{}" : r.out);
  };
  const nlohmann::json rigid = count("5k-b4-rigid"), scaled = count("5k-b4");
  EXPECT_GT(rigid.value("valid", std::uint64_t{0}), 0u);
  EXPECT_EQ(scaled.value("valid", std::uint64_t{1}), 0u);
  EXPECT_GT(scaled.at("invalid_by").value("joints_not_rigid", std::uint64_t{0}), 0u);
}

TEST(SkintuneCli, VariantsWithAnUnknownDeviceIsAnError) {
  const auto r = RunSkintune({"variants", "--device", "no-such-device-xyz"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: --device 'no-such-device-xyz': no OpenCL device matches (see skintune devices)\n");
}

// ------------------------------------------------------------------ emit --db

const std::string kEmbedDb = kData + "/embed-winners-db.json";
// tests/data/embed-winners-db.json: 22 winners, 21 distinct variants (CUDA b3 wins 100k and 1600k).
constexpr std::size_t kEmbedWinners = 22, kEmbedVariants = 21;
const std::string kCudaB3 = "cuda.b3.padded.aos.float3.i32.unorm16.mat3x4.image.matrix.v2c.wg96.nonormals";
const std::string kBucketedWinner = "opencl.b4.bucketed.soa.float4.i32.f32.mat3x4.image.matrix.v4s.wg256.nonormals";
const std::string kBucketedTwin = "opencl.b4.padded.soa.float4.i32.f32.mat3x4.image.matrix.v4s.wg256.nonormals";

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> FilesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

nlohmann::json ReadJson(const fs::path& file) { return nlohmann::json::parse(ReadAll(file)); }

// The fixture database with `edit` applied, written into `dir`.
fs::path EditedDb(const fs::path& dir, const std::function<void(nlohmann::json&)>& edit) {
  nlohmann::json db = ReadJson(kEmbedDb);
  edit(db);
  const fs::path file = dir / "edited-db.json";
  std::ofstream(file) << db.dump(2);
  return file;
}

std::string HeaderKernelCount(const fs::path& header) {
  const std::string text = ReadAll(header);
  const std::string marker = "inline constexpr int kKernelCount = ";
  const std::size_t at = text.find(marker);
  return at == std::string::npos ? "" : text.substr(at + marker.size(), text.find(';', at) - at - marker.size());
}

TEST(SkintuneCli, EmitDbWritesEachDistinctWinnersKernelAndSidecarThenTheHeader) {
  const fs::path dir = Scratch() / "kernels";
  const auto r = RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const std::vector<std::string> lines = Lines(r.out);
  ASSERT_EQ(lines.size(), 2 * kEmbedVariants + 1) << r.out;
  EXPECT_EQ(lines.back(), (dir / "skintune_kernels.h").string());
  std::vector<std::string> printed;
  for (const std::string& line : lines) {
    EXPECT_TRUE(fs::is_regular_file(line)) << line;
    printed.push_back(fs::path(line).filename().string());
  }
  std::sort(printed.begin(), printed.end());
  EXPECT_EQ(FilesIn(dir), printed);  // nothing else, no temporary file left
  for (std::size_t i = 0; i + 1 < lines.size(); i += 2) {
    const nlohmann::json sidecar = ReadJson(lines[i + 1]);
    EXPECT_EQ(fs::path(lines[i + 1]).stem().string(), sidecar.at("variant")) << lines[i + 1];
    EXPECT_EQ(sidecar.at("source_file"), fs::path(lines[i]).filename().string());
    EXPECT_EQ(sidecar.at("joints"), 77);
    EXPECT_NE(ReadAll(lines[i]).find("#define JOINTS 77\n"), std::string::npos) << lines[i];
  }
  const std::string header = ReadAll(dir / "skintune_kernels.h");
  EXPECT_NE(header.find("\nnamespace skintune_kernels {\n"), std::string::npos);
  EXPECT_EQ(HeaderKernelCount(dir / "skintune_kernels.h"), std::to_string(kEmbedWinners));
  EXPECT_EQ(header.find("#include <CL/"), std::string::npos);
  EXPECT_EQ(header.find("#include \"generator/"), std::string::npos);
}

TEST(SkintuneCli, EmitDbKernelAndSidecarAreThoseOfEmitVariantPlusTheWinners) {
  const fs::path dir = Scratch();
  const std::string key = "opencl.b2.padded.soa-split.float4.u16.unorm16.mat4.local.point.v2c.wg128.normals";
  ASSERT_EQ(RunSkintune({"emit", "--db", kEmbedDb, "--device", "AMD", "--out", dir / "db"}).exit_code, 0);
  ASSERT_EQ(RunSkintune({"emit", "--variant", key, "--out", dir / "variant"}).exit_code, 0);
  EXPECT_EQ(ReadAll(dir / "db" / (key + ".cl")), ReadAll(dir / "variant" / (key + ".cl")));
  nlohmann::json sidecar = ReadJson(dir / "db" / (key + ".json"));
  ASSERT_EQ(sidecar.at("winners").size(), 1u);
  EXPECT_EQ(sidecar.at("max_error"), 1e-4);  // the default budget
  sidecar.erase("winners");
  sidecar.erase("max_error");
  EXPECT_EQ(sidecar, ReadJson(dir / "variant" / (key + ".json")));
}

TEST(SkintuneCli, EmitDbSidecarNamesEveryWinnerOfItsVariant) {
  const fs::path dir = Scratch();
  ASSERT_EQ(RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--out", dir}).exit_code, 0);
  const nlohmann::json winners = ReadJson(dir / (kCudaB3 + ".json")).at("winners");
  ASSERT_EQ(winners.size(), 2u);
  EXPECT_EQ(winners[0].at("vertex_bucket"), "100k");
  EXPECT_EQ(winners[1].at("vertex_bucket"), "1600k");
  EXPECT_EQ(winners[1].at("device_id"), "cuda:CUDA/NVIDIA GeForce RTX 4090/550.54.14 (CUDA 12.4)");
  EXPECT_EQ(winners[1].at("device_name"), "NVIDIA GeForce RTX 4090");
  EXPECT_EQ(winners[1].at("vendor"), "NVIDIA Corporation");
  EXPECT_EQ(winners[1].at("platform"), "CUDA");
  EXPECT_EQ(winners[1].at("driver_version"), "550.54.14 (CUDA 12.4)");
  EXPECT_EQ(winners[1].at("device_type"), "gpu");
  EXPECT_EQ(winners[1].at("lang"), "cuda");
  EXPECT_EQ(winners[1].at("influences"), 3);
  EXPECT_EQ(winners[1].at("dataset"), "1600k-b3");
  EXPECT_EQ(winners[1].at("median_ms"), 0.75);
  EXPECT_FALSE(winners[1].contains("variant"));  // the sidecar's own "variant" is the emitted kernel
  EXPECT_EQ(winners[1].at("gbps"), 700.0);
  EXPECT_EQ(winners[1].at("copy_fraction"), 0.7);
  EXPECT_EQ(HeaderKernelCount(dir / "skintune_kernels.h"), std::to_string(kEmbedWinners));  // both in the header
}

TEST(SkintuneCli, EmitDbWritesABucketedWinnerAsItsPaddedTwinAndSaysSo) {
  const fs::path dir = Scratch();
  ASSERT_EQ(RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--out", dir}).exit_code, 0);
  EXPECT_FALSE(fs::exists(dir / (kBucketedWinner + ".cl")));
  ASSERT_TRUE(fs::exists(dir / (kBucketedTwin + ".cl")));
  EXPECT_NE(ReadAll(dir / (kBucketedTwin + ".cl")).find("// Generated by skintune " + std::string(kGeneratorVersion) + ": " + kBucketedTwin + "\n"),
            std::string::npos);
  const nlohmann::json sidecar = ReadJson(dir / (kBucketedTwin + ".json"));
  EXPECT_EQ(sidecar.at("variant"), kBucketedTwin);
  EXPECT_NE(sidecar.value("note", "").find("bucketed"), std::string::npos) << sidecar.dump(2);
  EXPECT_EQ(sidecar.at("winners")[0].at("tuned_variant"), kBucketedWinner);
  EXPECT_FALSE(ReadJson(dir / (kCudaB3 + ".json")).contains("note"));
}

TEST(SkintuneCli, EmitDbMatchesTheDeviceCaseInsensitivelyInIdNameVendorOrPlatform) {
  const auto kernels = [](const std::string& pattern) {
    const auto r = RunSkintune({"emit", "--db", kEmbedDb, "--device", pattern, "--out", Scratch()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    std::vector<std::string> exts;
    for (const std::string& line : Lines(r.out)) {
      if (fs::path(line).extension() != ".json" && fs::path(line).extension() != ".h")
        exts.push_back(fs::path(line).extension().string());
    }
    return exts;
  };
  EXPECT_EQ(kernels("GEFORCE rtx"), std::vector<std::string>(6, ".cu"));                      // name
  EXPECT_EQ(kernels("advanced micro"), std::vector<std::string>(8, ".cl"));                   // vendor only
  EXPECT_EQ(kernels("accelerated PARALLEL"), std::vector<std::string>(8, ".cl"));             // platform
  EXPECT_EQ(kernels("mesa 23.2"),
            (std::vector<std::string>{".comp", ".comp", ".vert", ".vert", ".comp", ".comp", ".vert"}));  // id
}

TEST(SkintuneCli, EmitDbLangKeepsOnlyThoseLanguagesInTheHeaderAndNamespaceAsked) {
  const fs::path dir = Scratch();
  const auto r = RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--lang", "glsl-compute", "--lang",
                              "glsl-vertex", "--header", "gl_kernels.h", "--namespace", "game::gpu", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(Lines(r.out).size(), 2 * 7 + 1u) << r.out;
  for (const std::string& name : FilesIn(dir)) {
    const std::string ext = fs::path(name).extension().string();
    EXPECT_TRUE(ext == ".comp" || ext == ".vert" || ext == ".json" || name == "gl_kernels.h") << name;
  }
  EXPECT_FALSE(fs::exists(dir / "skintune_kernels.h"));
  EXPECT_NE(ReadAll(dir / "gl_kernels.h").find("\nnamespace game::gpu {\n"), std::string::npos);
  EXPECT_EQ(HeaderKernelCount(dir / "gl_kernels.h"), "7");
}

TEST(SkintuneCli, EmitDbWithNoMatchingDeviceListsTheDatabasesDevicesAndWritesNothing) {
  const fs::path root = Scratch();
  const fs::path dir = root / "kernels";
  const std::string devices =
      " (the database has: 'cuda:CUDA/NVIDIA GeForce RTX 4090/550.54.14 (CUDA 12.4)' (cuda), "
      "'gl:device/Mesa Intel(R) UHD Graphics 630 (CFL GT2)/4.6 (Core Profile) Mesa 23.2.1' (glsl-compute, "
      "glsl-vertex), 'opencl:AMD Accelerated Parallel Processing/gfx1100 \"Navi 31\" \\ ?\?=/3635.0 (HSA1.1,LC)' "
      "(opencl))\n";
  auto r = RunSkintune({"emit", "--db", kEmbedDb, "--device", "radeon", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: " + kEmbedDb + ": no winner matches --device 'radeon'" + devices);
  EXPECT_EQ(r.out, "");
  r = RunSkintune({"emit", "--db", kEmbedDb, "--device", "geforce", "--lang", "opencl", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: " + kEmbedDb + ": no winner matches --device 'geforce' and --lang opencl" +
                       devices);
  const fs::path empty = EditedDb(root, [](nlohmann::json& db) { db["entries"] = nlohmann::json::array(); });
  r = RunSkintune({"emit", "--db", empty, "--device", "", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: " + empty.string() + ": no winner matches --device '' (the database has no "
                   "entries)\n");
  EXPECT_FALSE(fs::exists(dir));
}

// Crowd and batch winners are emitted with the single-mesh ones: a crowd's
// instanced kernel for its K instances (<key>.x8; of its two precision
// classes the faster within the budget), a batch's plain kernel holding its
// meshes' palettes together (<key>.batch3: 3 x 77 joints), each file pair
// named by its scene and listing its winners; the header's rows say the scene.
TEST(SkintuneCli, EmitDbEmitsCrowdAndBatchWinnersNamedByTheirScene) {
  const fs::path root = Scratch();
  const nlohmann::json fixture = ReadJson(kEmbedDb);
  const std::string crowd_key = fixture["entries"][0]["variant"]["key"];  // cuda b2, constant palette
  const std::string batch_key = fixture["entries"][9]["variant"]["key"];  // opencl b2, local palette
  const fs::path db = EditedDb(root, [](nlohmann::json& d) {
    nlohmann::json crowd = d["entries"][0];
    crowd["shape"] = "instances";
    crowd["instances"] = 8;
    nlohmann::json slower = crowd;
    std::string key = slower["variant"]["key"];
    key.replace(key.find(".unorm8."), 8, ".f32.");
    slower["variant"]["weight"] = "f32";
    slower["variant"]["key"] = key;
    slower["median_ms"] = 0.5;
    nlohmann::json batch = d["entries"][9];
    batch["shape"] = "batch";
    batch["meshes"] = 3;
    for (const nlohmann::json& e : {crowd, slower, batch}) d["entries"].push_back(e);
  });
  const fs::path dir = root / "kernels";
  const auto r = RunSkintune({"emit", "--db", db, "--device", "", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(HeaderKernelCount(dir / "skintune_kernels.h"), std::to_string(kEmbedWinners + 2));
  EXPECT_EQ(Lines(r.out).size(), 2 * (kEmbedVariants + 2) + 1) << r.out;
  const nlohmann::json crowd = ReadJson(dir / (crowd_key + ".x8.json"));
  EXPECT_EQ(crowd.at("source_file"), crowd_key + ".x8.cu");
  EXPECT_EQ(crowd.at("instancing").at("max_instances"), 8);
  ASSERT_EQ(crowd.at("winners").size(), 1u);
  EXPECT_EQ(crowd.at("winners")[0].at("instances"), 8);
  EXPECT_NE(ReadAll(dir / (crowd_key + ".x8.cu")).find("#define INSTANCED 1\n"), std::string::npos);
  const nlohmann::json batch = ReadJson(dir / (batch_key + ".batch3.json"));
  EXPECT_EQ(batch.at("joints"), 3 * 77);
  EXPECT_FALSE(batch.contains("instancing"));
  EXPECT_EQ(batch.at("winners")[0].at("meshes"), 3);
  EXPECT_NE(ReadAll(dir / (batch_key + ".batch3.cl")).find("#define JOINTS 231\n"), std::string::npos);
  const std::string header = ReadAll(dir / "skintune_kernels.h");
  EXPECT_NE(header.find("\"instances\", 8, 1, true, 8,"), std::string::npos);
  EXPECT_NE(header.find("\"batch\", 1, 3, false, 0,"), std::string::npos);
  EXPECT_NE(header.find("b2 25k instances x8: " + crowd_key + " instanced, 77 joints"), std::string::npos);
}

TEST(SkintuneCli, EmitDbSkipsWinnersThatCannotTakeTheJointCountWithOneWarningEach) {
  const fs::path dir = Scratch();
  const auto r = RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--joints", "300", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::vector<std::string> warnings = Lines(r.err);
  ASSERT_EQ(warnings.size(), 4u) << r.err;  // the four u8 winners
  for (const std::string& w : warnings) {
    EXPECT_EQ(w.rfind("skintune: warning: skipping ", 0), 0u) << w;
    EXPECT_NE(w.find(".u8."), std::string::npos) << w;
    EXPECT_NE(w.find("cannot be emitted for 300 joints"), std::string::npos) << w;
    EXPECT_NE(w.find("(constraint index_range)"), std::string::npos) << w;
  }
  EXPECT_EQ(HeaderKernelCount(dir / "skintune_kernels.h"), std::to_string(kEmbedWinners - 4));
  for (const std::string& name : FilesIn(dir)) EXPECT_EQ(name.find(".u8."), std::string::npos) << name;
}

TEST(SkintuneCli, EmitDbWhenEveryMatchIsSkippedIsAnErrorAndWritesNothing) {
  const fs::path root = Scratch();
  const fs::path u8_only = EditedDb(root, [](nlohmann::json& db) {
    nlohmann::json kept = nlohmann::json::array();
    for (const auto& e : db["entries"])
      if (e["variant"]["index"] == "u8") kept.push_back(e);
    db["entries"] = kept;
  });
  const fs::path dir = root / "kernels";
  const auto r = RunSkintune({"emit", "--db", u8_only, "--device", "", "--joints", "257", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  const std::vector<std::string> lines = Lines(r.err);
  ASSERT_EQ(lines.size(), 5u) << r.err;
  EXPECT_EQ(lines.back(), "skintune: error: " + u8_only.string() +
                              ": none of the 4 winner(s) matching --device '' can be emitted for 257 joints (see the "
                              "warnings above)");
  EXPECT_FALSE(fs::exists(dir));
}

// --max-error: the fixture's unorm16 winners cost 3.1e-6 of the diagonal and
// its half morph offsets 5e-6 (its unorm8 ones 0, f32 0): a budget of 1e-6
// skips the 4 unorm16 ones and the 2 half ones, each with a warning naming
// its error; the sidecars record every winner's source_error.
TEST(SkintuneCli, EmitDbKeepsTheWinnersWithinTheErrorBudget) {
  const fs::path root = Scratch();
  const fs::path dir = root / "kernels";
  const auto r = RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--max-error", "1e-6", "--out", dir});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(Lines(r.err).size(), 6u) << r.err;
  for (const std::string& line : Lines(r.err)) {
    EXPECT_EQ(line.rfind("skintune: warning: skipping ", 0), 0u) << line;
    const bool half = line.find("-half") != std::string::npos;
    EXPECT_NE(line.find(half ? ".f32." : ".unorm16."), std::string::npos) << line;
    EXPECT_NE(line.find(half ? "its weights and half morph offsets cost 5e-06 of the bounding-box diagonal, over "
                               "--max-error 1e-06"
                             : "its weights cost 3.1e-06 of the bounding-box diagonal, over --max-error 1e-06"),
              std::string::npos)
        << line;
  }
  EXPECT_EQ(HeaderKernelCount(dir / "skintune_kernels.h"), std::to_string(kEmbedWinners - 6));
  EXPECT_FALSE(fs::exists(dir / (kCudaB3 + ".json")));  // a unorm16 winner
  // The header and every sidecar record the budget they were emitted under.
  const std::string header = ReadAll(dir / "skintune_kernels.h");
  EXPECT_NE(header.find("\n// Error budget (--max-error): 1e-06 of the bounding-box diagonal;"), std::string::npos);
  EXPECT_NE(header.find("\ninline constexpr double kMaxError = 1e-06;\n"), std::string::npos);
  for (const std::string& name : FilesIn(dir)) {
    if (name.size() < 5 || name.substr(name.size() - 5) != ".json") continue;
    EXPECT_EQ(ReadJson(dir / name).at("max_error"), 1e-6) << name;
    for (const nlohmann::json& w : ReadJson(dir / name).at("winners"))
      EXPECT_TRUE(w.contains("source_error")) << name;
  }
  // A database before 1.3.0 records no error: its unorm entries are over any budget.
  const fs::path old = EditedDb(root, [](nlohmann::json& db) {
    db["schema_version"] = "1.2.0";
    for (auto& e : db["entries"]) {
      e.erase("source_error");
      e.erase("max_relative_error");
    }
  });
  const auto unknown = RunSkintune({"emit", "--db", old, "--device", "", "--out", root / "old"});
  ASSERT_EQ(unknown.exit_code, 0) << unknown.err;
  EXPECT_EQ(Lines(unknown.err).size(), 13u) << unknown.err;  // 7 unorm8 + 4 unorm16 + 2 half morph offsets
  EXPECT_NE(unknown.err.find("its quantisation error is not recorded"), std::string::npos) << unknown.err;
  // A bad budget is one line naming the flag, and nothing is written.
  const fs::path none = root / "none";
  const auto bad = RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--max-error", "-1", "--out", none});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_EQ(bad.err.rfind("skintune: error: --max-error '-1': is -1: must be a finite number >= 0", 0), 0u) << bad.err;
  EXPECT_FALSE(fs::exists(none));
}

TEST(SkintuneCli, EmitDbMalformedDatabaseIsOneLineNamingTheFileAndTheElement) {
  const fs::path root = Scratch();
  const fs::path dir = root / "kernels";
  const fs::path bad = EditedDb(root, [](nlohmann::json& db) { db["entries"][2]["vertex_bucket"] = "3k"; });
  auto r = RunSkintune({"emit", "--db", bad, "--device", "", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "skintune: error: " + bad.string() +
                       ": entries[2]: 'vertex_bucket' has unknown value '3k' (expected 25k, 100k, 400k or 1600k)\n");
  const fs::path not_json = root / "not.json";
  std::ofstream(not_json) << "{\"entries\": [";
  r = RunSkintune({"emit", "--db", not_json, "--device", "", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("skintune: error: " + not_json.string() + ": not valid JSON (", 0), 0u) << r.err;
  r = RunSkintune({"emit", "--db", root / "missing.json", "--device", "", "--out", dir});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("missing.json: cannot open file"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir));
}

TEST(SkintuneCli, EmitNeedsExactlyOneOfVariantAndDbAndDbOptionsOnlyWithDb) {
  const fs::path dir = Scratch() / "kernels";
  const std::string out = dir.string();
  const std::vector<std::vector<std::string>> usage_errors = {
      {"emit", "--variant", "opencl.b1", "--db", kEmbedDb, "--device", "", "--out", out},  // both
      {"emit", "--out", out},                                                           // neither
      {"emit", "--db", kEmbedDb, "--out", out},                                         // --db without --device
      {"emit", "--variant", "opencl.b1", "--device", "amd", "--out", out},              // --device without --db
      {"emit", "--variant", "opencl.b1", "--lang", "cuda", "--out", out},
      {"emit", "--db", kEmbedDb, "--device", "", "--instances", "4", "--out", out},
      {"emit", "--db", kEmbedDb, "--device", "", "--lang", "metal", "--out", out},
      {"emit", "--db", kEmbedDb, "--device", "", "--namespace", "class", "--out", out},
      {"emit", "--db", kEmbedDb, "--device", "", "--namespace", "a::", "--out", out},
      {"emit", "--db", kEmbedDb, "--device", "", "--header", "sub/k.h", "--out", out},
      {"emit", "--db", kEmbedDb, "--device", "", "--joints", "0", "--out", out},
  };
  for (const auto& args : usage_errors) {
    const auto r = RunSkintune(args);
    EXPECT_EQ(r.exit_code, 2) << args[1] << " " << args[args.size() - 3] << ": " << r.err;
    EXPECT_EQ(CountLines(r.err), 1) << r.err;
  }
  EXPECT_EQ(RunSkintune({"emit", "--out", out}).err, "skintune: emit: give --variant KEY or --db DB.json (try --help)\n");
  EXPECT_FALSE(fs::exists(dir));
}

TEST(SkintuneCli, EmitDbFailureLeavesExistingOutputsUntouched) {
  const fs::path root = Scratch();
  const fs::path dir = root / "kernels";
  fs::create_directories(dir);
  const std::string kernel = kCudaB3 + ".cu";
  std::ofstream(dir / "skintune_kernels.h") << "old header";
  std::ofstream(dir / kernel) << "old kernel";
  const fs::path bad = EditedDb(root, [](nlohmann::json& db) { db["entries"][12]["created"] = "yesterday"; });
  EXPECT_EQ(RunSkintune({"emit", "--db", bad, "--device", "", "--out", dir}).exit_code, 1);
  EXPECT_EQ(RunSkintune({"emit", "--db", kEmbedDb, "--device", "nvidia", "--lang", "glsl-vertex", "--out", dir})
                .exit_code,
            1);
  EXPECT_EQ(RunSkintune({"emit", "--db", kEmbedDb, "--device", "", "--header", kernel, "--out", dir}).exit_code, 1);
  EXPECT_EQ(ReadAll(dir / "skintune_kernels.h"), "old header");
  EXPECT_EQ(ReadAll(dir / kernel), "old kernel");
  EXPECT_EQ(FilesIn(dir), (std::vector<std::string>{kernel, "skintune_kernels.h"}));
  // The same folder is written when the run succeeds.
  ASSERT_EQ(RunSkintune({"emit", "--db", kEmbedDb, "--device", "nvidia", "--out", dir}).exit_code, 0);
  EXPECT_NE(ReadAll(dir / "skintune_kernels.h"), "old header");
  EXPECT_NE(ReadAll(dir / kernel), "old kernel");
}

}  // namespace
}  // namespace skintune::internal
