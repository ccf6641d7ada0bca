// The header `skintune emit --db` generates, for crowd and batch winners:
// built at build time from tests/data/embed-scenes-winners-db.json (an
// OpenCL single-mesh winner, OpenCL crowds of 4 and 16 instances, an OpenCL
// batch of 4 meshes, a CUDA single-mesh winner and a CUDA crowd of 8 whose
// constant palette holds 8) into namespace scene_kernels. Its table and Find*
// are checked against the database, PackBatch and PackPalette of K instances
// against skintune's packer, and the crowd and batch kernels are run on the
// first OpenCL device (PoCL here) with the header's bytes, each instance and
// each mesh against its own float64 gold.
#include "scene_kernels.h"  // first: the generated header needs nothing before it

#include <gtest/gtest.h>

#include <cstring>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "generator/packer.h"
#include "model/scene.h"
#include "reference/skinning.h"
#include "runtime/source_error.h"
#include "runtime/winners_db.h"
#include "tests/common/test_asset.h"
#include "tests/tools/emit/embed_header_test_support.h"
#include "tests/runtime/first_opencl_runner.h"

namespace skintune::internal {
namespace {

namespace sk = scene_kernels;

constexpr int kJoints = 77;  // skintune emit's default --joints

const std::vector<WinnersEntry>& Fixture() {
  static const std::vector<WinnersEntry> entries = testing::TestDataWinnersDb("embed-scenes-winners-db.json");
  return entries;
}

// The kernels of the fixture, in its order.
const sk::Kernel& kSingle = sk::kKernels[0];      // opencl b4 25k
const sk::Kernel& kCrowd4 = sk::kKernels[1];      // opencl b4, 4 instances, image palette
const sk::Kernel& kCrowd16 = sk::kKernels[2];     // opencl b4, 16 instances, local palette, normals
const sk::Kernel& kBatch4 = sk::kKernels[3];      // opencl b4, a batch of 4 meshes, constant palette
const sk::Kernel& kCudaSingle = sk::kKernels[4];  // cuda b4 25k
const sk::Kernel& kCudaCrowd8 = sk::kKernels[5];  // cuda b4, 8 instances, __constant__ palette of 8
const sk::Kernel& kMorphCrowd4 = sk::kKernels[6];  // opencl b4, 4 instances, 6 morph targets as halves, normals

Variant VariantOf(const sk::Kernel& k) { return ParseVariantKey(k.variant); }

const SkinnedMesh& Cesium() { return testing::TestAsset("CesiumMan.gltf").mesh; }

// The batch's meshes (B 4, 4, 2, 1; 19, 24, 40, 12 joints) and a pose each.
const std::vector<std::string> kMeshes = {"CesiumMan.gltf", "Fox.gltf", "1500-b2-bones40-seed3", "2000-b1-bones12-seed2"};

std::vector<glm::mat4> PoseOf(const std::string& key, double phase) {
  const SkinnedAsset& asset = testing::TestAsset(key);
  const AnimationClip& clip = asset.animations.front();
  return asset.PaletteAt(0, clip.start + clip.duration() * phase);
}

std::vector<std::uint8_t> Bytes(const std::vector<float>& floats) {
  std::vector<std::uint8_t> out(floats.size() * sizeof(float));
  if (!floats.empty()) std::memcpy(out.data(), floats.data(), out.size());
  return out;
}

// ------------------------------------------------------------------ the table and Find*

TEST(EmbedHeaderScenes, EachKernelCarriesTheSceneItWonOnAndItsPaletteSize) {
  const std::vector<WinnersEntry>& entries = Fixture();
  ASSERT_EQ(static_cast<std::size_t>(sk::kKernelCount), entries.size());
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const sk::Kernel& k = sk::kKernels[i];
    const WinnersEntry& e = entries[i];
    SCOPED_TRACE(Describe(e));
    EXPECT_STREQ(k.shape, SceneKindName(e.shape));
    EXPECT_EQ(k.instances, e.instances);
    EXPECT_EQ(k.meshes, e.meshes);
    EXPECT_EQ(k.vertices, e.vertices);
    EXPECT_EQ(k.instanced, e.shape == SceneKind::kInstances);
    EXPECT_EQ(k.joints, e.shape == SceneKind::kBatch ? e.meshes * kJoints : kJoints);
    // The crowd kernel's text and arguments are the instanced ones.
    EXPECT_EQ(std::string(k.source).find("#define INSTANCED 1\n") != std::string::npos, k.instanced);
    EXPECT_EQ(std::string(k.arguments[2].name) == "vertex_count", k.instanced && std::string(k.lang) != "glsl-vertex");
  }
  // Only a compile-time palette array bounds the instances of a launch.
  EXPECT_EQ(kCudaCrowd8.max_instances, 8);
  for (const sk::Kernel* k : {&kSingle, &kCrowd4, &kCrowd16, &kBatch4, &kCudaSingle, &kMorphCrowd4})
    EXPECT_EQ(k->max_instances, 0);
  EXPECT_EQ(sk::kMaxError, kDefaultBudget);
}

TEST(EmbedHeaderScenes, FindKernelTakesSingleMeshKernelsOnly) {
  EXPECT_EQ(sk::FindKernel("opencl", 4, 26000, 19), &kSingle);   // not the crowd of 26000 vertices in all
  EXPECT_EQ(sk::FindKernel("opencl", 4, 8501, 19), &kSingle);    // nor the batch of 8501
  EXPECT_EQ(sk::FindKernel("opencl", 4, 8501, 78), nullptr);     // the batch kernel's 308 joints do not serve
}

TEST(EmbedHeaderScenes, FindCrowdKernelComparesTheCrowdsTotalThenItsInstanceCount) {
  const std::size_t n = Cesium().vertex_count();  // 3273
  EXPECT_EQ(sk::FindCrowdKernel("opencl", 4, n, 19, 4), &kCrowd4);     // 13k in all: nearer 26k than 104k
  EXPECT_EQ(sk::FindCrowdKernel("opencl", 4, n, 19, 32), &kCrowd16);   // 105k in all
  EXPECT_EQ(sk::FindCrowdKernel("opencl", 4, 26000, 19, 1), &kCrowd4);  // one instance of a crowd's size
  EXPECT_EQ(sk::FindCrowdKernel("opencl", 4, n, 78, 4), nullptr);       // 77 joints per instance
  EXPECT_EQ(sk::FindCrowdKernel("opencl", 4, n, 19, 0), nullptr);
  EXPECT_EQ(sk::FindCrowdKernel("opencl", 5, n, 19, 4), nullptr);
  // The CUDA crowd kernel's __constant__ palettes hold 8: no kernel for 9, and
  // the single-mesh CUDA kernel is not instanced.
  EXPECT_EQ(sk::FindCrowdKernel("cuda", 4, n, 19, 8), &kCudaCrowd8);
  EXPECT_EQ(sk::FindCrowdKernel("cuda", 4, n, 19, 9), nullptr);
}

TEST(EmbedHeaderScenes, FindBatchKernelTakesTheBatchKernelThenTheSingleMeshOfTheBatchsSize) {
  EXPECT_EQ(sk::FindBatchKernel("opencl", 4, 8501, 95, 4), &kBatch4);
  EXPECT_EQ(sk::FindBatchKernel("opencl", 4, 8501, 50, 4), &kBatch4);   // before the single-mesh one that also holds 50
  EXPECT_EQ(sk::FindBatchKernel("opencl", 4, 8501, 309, 4), nullptr);   // 4 x 77 joints at most
  EXPECT_EQ(sk::FindBatchKernel("cuda", 4, 8501, 60, 4), &kCudaSingle);  // no CUDA batch kernel: the fallback
  EXPECT_EQ(sk::FindBatchKernel("opencl", 4, 8501, 95, 0), nullptr);
}

// ------------------------------------------------------------------ packing

TEST(EmbedHeaderScenes, PackPaletteOfKInstancesIsEachInstancesPaletteOneAfterAnother) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> value(-3.0f, 3.0f);
  constexpr int kInstances = 4, kOwn = 19;
  std::vector<glm::mat4> matrices(kInstances * kOwn);
  for (glm::mat4& m : matrices)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m[c][r] = value(rng);
  for (const sk::Kernel* k : {&kCrowd4, &kCrowd16, &kCudaCrowd8}) {
    SCOPED_TRACE(k->variant);
    std::vector<glm::mat4> padded;  // what skintune's runtime packs: K palettes of k->joints entries
    for (int i = 0; i < kInstances; ++i) {
      padded.insert(padded.end(), matrices.begin() + i * kOwn, matrices.begin() + (i + 1) * kOwn);
      padded.resize(static_cast<std::size_t>((i + 1) * k->joints), glm::mat4(1.0f));
    }
    const std::vector<std::uint8_t> want = PackPalette(padded, VariantOf(*k));
    EXPECT_EQ(Bytes(sk::PackPalette(*k, &matrices[0][0][0], kOwn, kInstances)), want);
  }
  EXPECT_TRUE(sk::PackPalette(kSingle, &matrices[0][0][0], kOwn, 2).empty());        // not instanced
  EXPECT_TRUE(sk::PackPalette(kCudaCrowd8, &matrices[0][0][0], 1, 9).empty());       // holds 8 palettes
  EXPECT_TRUE(sk::PackPalette(kCrowd4, &matrices[0][0][0], kOwn, 0).empty());
  EXPECT_EQ(sk::PackPalette(kCudaCrowd8, &matrices[0][0][0], 1, 8).size(), 8u * 77u * 4u * 4u);
}

// The batch's meshes as PackBatch takes them.
struct BatchInput {
  std::vector<testing::MeshArrays> arrays;
  std::vector<sk::BatchMesh> meshes;
};

BatchInput BatchOf(const std::vector<const SkinnedMesh*>& meshes) {
  BatchInput in;
  for (const SkinnedMesh* m : meshes) in.arrays.push_back(testing::ArraysOf(*m));
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const testing::MeshArrays& a = in.arrays[m];
    in.meshes.push_back({meshes[m]->vertex_count(), meshes[m]->influences, meshes[m]->joint_count, a.positions.data(),
                         a.normals.empty() ? nullptr : a.normals.data(), a.joints.data(), a.weights.data()});
  }
  return in;
}

std::vector<const SkinnedMesh*> BatchMeshes() {
  std::vector<const SkinnedMesh*> meshes;
  for (const std::string& key : kMeshes) meshes.push_back(&testing::TestAsset(key).mesh);
  return meshes;
}

TEST(EmbedHeaderScenes, PackBatchIsByteIdenticalToSkintunesPackingOfTheConcatenatedMeshes) {
  const std::vector<const SkinnedMesh*> meshes = BatchMeshes();
  const MeshBatch want = ConcatenateMeshes(meshes);
  const BatchInput in = BatchOf(meshes);
  sk::PackedInputs packed;
  sk::BatchOffsets offsets;
  std::string error;
  ASSERT_TRUE(sk::PackBatch(kBatch4, in.meshes.data(), in.meshes.size(), &packed, &offsets, &error)) << error;
  testing::ExpectInputsOf(packed, Pack(want.mesh, VariantOf(kBatch4)).launches.at(0));
  EXPECT_EQ(offsets.vertices, want.vertex_offsets);
  EXPECT_EQ(offsets.joints, want.joint_offsets);
}

std::string BatchError(const std::vector<sk::BatchMesh>& meshes) {
  sk::PackedInputs packed;
  std::string error;
  EXPECT_FALSE(sk::PackBatch(kBatch4, meshes.empty() ? nullptr : meshes.data(), meshes.size(), &packed, nullptr,
                             &error));
  EXPECT_TRUE(packed.positions.empty() && packed.indices.empty() && packed.weights.empty());
  return error;
}

TEST(EmbedHeaderScenes, PackBatchRefusesABadMeshNamingIt) {
  const std::vector<const SkinnedMesh*> meshes = BatchMeshes();
  const BatchInput in = BatchOf(meshes);
  const std::string prefix = std::string("PackBatch ") + kBatch4.variant + ": ";
  EXPECT_EQ(BatchError({}), prefix + "no meshes");
  std::vector<sk::BatchMesh> bad = in.meshes;
  bad[2].vertex_count = 0;
  EXPECT_EQ(BatchError(bad), prefix + "meshes[2]: no vertices");
  bad = in.meshes;
  bad[1].joint_count = 2;  // the Fox's indices reach 23
  EXPECT_NE(BatchError(bad).find(prefix + "meshes[1]: vertex "), std::string::npos) << BatchError(bad);
  EXPECT_NE(BatchError(bad).find(" out of range (the mesh has 2 joints)"), std::string::npos) << BatchError(bad);
  bad = in.meshes;
  std::vector<float> weights = in.arrays[3].weights;
  weights[5] = -1.0f;
  bad[3].weights = weights.data();
  EXPECT_EQ(BatchError(bad), prefix + "meshes[3]: vertex 5 slot 0: weight -1 is negative");
  bad = in.meshes;
  bad[0].influences = 5;
  EXPECT_EQ(BatchError(bad), prefix + "meshes[0]: influences 5 outside 1..4 (the kernel's B)");
  bad = in.meshes;
  bad[3].joints = nullptr;
  EXPECT_EQ(BatchError(bad), prefix + "meshes[3]: positions, joints or weights is null");
  bad = in.meshes;
  bad[1].joint_count = bad[2].joint_count = 200;
  EXPECT_EQ(BatchError(bad), prefix + "meshes[2]: the batch's joints reach 419 with this mesh's, above the 308 the "
                                      "kernel holds (308 joints, u16 indices)");
}

// ------------------------------------------------------------------ on the OpenCL device

// The kernel as a program knows it from the header: text, arguments, launch.
KernelSource SourceOf(const sk::Kernel& k) {
  KernelSource s;
  s.lang = VariantOf(k).lang;
  s.entry_point = k.entry_point;
  s.text = k.source;
  s.influences = k.influences;
  s.joints = k.joints;
  s.instanced = k.instanced;
  s.max_instances = k.max_instances;
  for (int i = 0; i < k.argument_count; ++i) {
    const sk::Argument& a = k.arguments[i];
    s.arguments.push_back({a.name, a.format, a.element_bytes, a.stride_bytes, a.indexing,
                           a.output ? ArgumentDirection::kOut : ArgumentDirection::kIn,
                           a.scalar ? ArgumentKind::kScalar : a.image ? ArgumentKind::kImage : ArgumentKind::kBuffer});
  }
  s.launch.vertices_per_item = k.vertices_per_item;
  s.launch.strided = k.strided;
  s.launch.wg_size = k.wg_size;
  s.launch.instanced = k.instanced;
  s.launch.rule = k.launch_rule;
  s.source_hash = k.source_hash;
  return s;
}

// One launch of n vertices over the header's packed inputs, bound by the kernel's argument names.
PackedMesh PackedOf(const sk::Kernel& k, const sk::PackedInputs& inputs, std::size_t n) {
  PackedMesh p;
  p.variant = VariantOf(k);
  p.vertex_count = n;
  p.order.resize(n);
  std::iota(p.order.begin(), p.order.end(), 0u);
  p.palette_joints = static_cast<std::size_t>(k.joints);
  p.output_stride_bytes = sk::OutputStrideBytes(k);
  Launch launch;
  launch.count = static_cast<std::uint32_t>(n);
  launch.influences = k.influences;
  launch.slot_stride = static_cast<std::uint32_t>(sk::SlotStride(k, n));
  for (int i = 0; i < k.argument_count; ++i) {
    const sk::Argument& a = k.arguments[i];
    // The palette and the morph weights are a frame's: Run binds them itself.
    if (!a.output && !a.scalar && std::string(a.name) != "palette" && std::string(a.name) != kMorphWeightsArgument)
      launch.inputs.push_back({a.name, testing::Field(inputs, a.name)});
  }
  p.launches.push_back(std::move(launch));
  return p;
}

// Vertices [first, first + count) of a kernel output, read as the header's UnpackPositions reads it.
std::vector<glm::vec3> Unpacked(const sk::Kernel& k, const std::vector<std::uint8_t>& output, std::size_t first,
                                std::size_t count) {
  std::vector<float> xyz(3 * count);
  sk::UnpackPositions(k, output.data() + first * sk::OutputStrideBytes(k), count, xyz.data());
  std::vector<glm::vec3> out(count);
  for (std::size_t v = 0; v < count; ++v) out[v] = glm::vec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]);
  return out;
}

void ExpectGold(const std::vector<glm::dvec3>& gold, const std::vector<glm::vec3>& got, const std::string& what) {
  const GoldComparison c = CompareToGold(gold, got);
  EXPECT_EQ(c.non_finite, 0u) << what;
  EXPECT_LT(c.max_relative, 1e-5) << what << ": worst vertex " << c.worst_vertex;
}

// CesiumMan as `instances` instances, each at its own pose, through the
// header alone: FindCrowdKernel, PackMesh, PackPalette of K instances, the
// instanced launch; every instance against its float64 gold.
void ExpectCrowdMatchesTheGold(int instances, const sk::Kernel& expected) {
  SCOPED_TRACE(std::to_string(instances) + " instances");
  std::string why;
  OpenClRunner* runner = testing::FirstOpenClRunner(why);
  if (runner == nullptr) GTEST_SKIP() << why;
  const SkinnedMesh& mesh = Cesium();
  const std::size_t n = mesh.vertex_count();
  const sk::Kernel* k = sk::FindCrowdKernel("opencl", mesh.influences, n, mesh.joint_count, instances);
  ASSERT_EQ(k, &expected);
  const testing::MeshArrays a = testing::ArraysOf(mesh);
  sk::PackedInputs inputs;
  std::string error;
  ASSERT_TRUE(sk::PackMesh(*k, n, mesh.influences, a.positions.data(), a.normals.data(), a.joints.data(),
                           a.weights.data(), &inputs, &error))
      << error;
  std::vector<std::vector<glm::mat4>> poses;
  std::vector<glm::mat4> all;
  for (int i = 0; i < instances; ++i) {
    poses.push_back(PoseOf("CesiumMan.gltf", 0.1 + 0.8 * i / instances));
    all.insert(all.end(), poses.back().begin(), poses.back().end());
  }
  const std::vector<float> palettes = sk::PackPalette(*k, &all[0][0][0], mesh.joint_count, instances);
  const std::vector<KernelSource> kernels = {SourceOf(*k)};
  const RunResult result = runner->Run(PackedOf(*k, inputs, n), kernels, Bytes(palettes), instances);
  EXPECT_EQ(result.poisoned_vertices, 0u);
  const SkinnedMesh quantised = QuantisedMesh(mesh, VariantOf(*k));
  for (int i = 0; i < instances; ++i) {
    const GoldResult gold = SkinGold(quantised, poses[static_cast<std::size_t>(i)], k->normals);
    const std::size_t first = static_cast<std::size_t>(i) * n;
    ExpectGold(gold.positions, Unpacked(*k, result.positions, first, n), "instance " + std::to_string(i));
    if (k->normals) ExpectGold(gold.normals, Unpacked(*k, result.normals, first, n), "normals of " + std::to_string(i));
  }
}

TEST(EmbedHeaderScenes, CrowdKernelsRunOnOpenClLikeTheGoldOfEachInstance) {
  ExpectCrowdMatchesTheGold(4, kCrowd4);
  ExpectCrowdMatchesTheGold(24, kCrowd16);  // a local palette: any K
}

// CesiumMan with six morph targets (target 0 over every vertex, each other
// one over every sixth) as a crowd of 4, each instance its own pose and its
// own weights, through the header alone: FindMorphKernel, PackMesh,
// PackMorphTargets, PackPalette of K instances and K x T weights, one
// instanced launch; each instance against the float64 gold of the mesh
// morphed at its weights (the offsets rounded to binary16, as the kernel
// stores them), positions and normals.
TEST(EmbedHeaderScenes, AMorphCrowdKernelRunsOnOpenClLikeTheGoldOfEachInstance) {
  std::string why;
  OpenClRunner* runner = testing::FirstOpenClRunner(why);
  if (runner == nullptr) GTEST_SKIP() << why;
  constexpr int kTargets = 6, kInstances = 4;
  SkinnedMesh mesh = Cesium();
  const std::size_t n = mesh.vertex_count();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> offset(-0.05f, 0.05f), weight(-0.5f, 1.2f);
  MorphTargets& m = mesh.morph;
  std::vector<float> positions, normals;
  for (int t = 0; t < kTargets; ++t) {
    m.positions.emplace_back(n, glm::vec3(0.0f));
    m.normals.emplace_back(n, glm::vec3(0.0f));
    for (std::size_t v = 0; v < n; ++v) {
      if (t != 0 && v % kTargets != static_cast<std::size_t>(t)) continue;
      m.positions.back()[v] = {offset(rng), offset(rng), offset(rng)};
      m.normals.back()[v] = {offset(rng), offset(rng), offset(rng)};
    }
    for (std::size_t v = 0; v < n; ++v) {
      positions.insert(positions.end(), {m.positions.back()[v].x, m.positions.back()[v].y, m.positions.back()[v].z});
      normals.insert(normals.end(), {m.normals.back()[v].x, m.normals.back()[v].y, m.normals.back()[v].z});
    }
  }
  m.weights.assign(kTargets, 0.0);
  const sk::Kernel* k = sk::FindMorphKernel("opencl", mesh.influences, n, mesh.joint_count, kTargets, kInstances);
  ASSERT_EQ(k, &kMorphCrowd4);
  EXPECT_EQ(sk::FindCrowdKernel("opencl", mesh.influences, n, mesh.joint_count, kInstances), &kCrowd4);
  const testing::MeshArrays a = testing::ArraysOf(mesh);
  sk::PackedInputs inputs;
  std::string error;
  ASSERT_TRUE(sk::PackMesh(*k, n, mesh.influences, a.positions.data(), a.normals.data(), a.joints.data(),
                           a.weights.data(), &inputs, &error))
      << error;
  ASSERT_TRUE(sk::PackMorphTargets(*k, n, kTargets, positions.data(), normals.data(), nullptr, &inputs, &error))
      << error;
  std::vector<float> weights;
  std::vector<std::vector<glm::mat4>> poses;
  std::vector<glm::mat4> all;
  for (int i = 0; i < kInstances; ++i) {
    for (int t = 0; t < kTargets; ++t) weights.push_back(weight(rng));
    poses.push_back(PoseOf("CesiumMan.gltf", 0.15 + 0.7 * i / kInstances));
    all.insert(all.end(), poses.back().begin(), poses.back().end());
  }
  const std::vector<float> palettes = sk::PackPalette(*k, &all[0][0][0], mesh.joint_count, kInstances);
  PackedMesh packed = PackedOf(*k, inputs, n);
  packed.morph_targets = kTargets;
  packed.morph_weights = Bytes(weights);  // K x T: each instance's
  const std::vector<KernelSource> kernels = {SourceOf(*k)};
  const RunResult result = runner->Run(packed, kernels, Bytes(palettes), kInstances);
  EXPECT_EQ(result.poisoned_vertices, 0u);
  for (int i = 0; i < kInstances; ++i) {
    SkinnedMesh weighted = mesh;
    weighted.morph.weights.assign(weights.begin() + i * kTargets, weights.begin() + (i + 1) * kTargets);
    const GoldResult gold = SkinGold(QuantisedMesh(weighted, VariantOf(*k)), poses[static_cast<std::size_t>(i)], true);
    const std::size_t first = static_cast<std::size_t>(i) * n;
    ExpectGold(gold.positions, Unpacked(*k, result.positions, first, n), "instance " + std::to_string(i));
    ExpectGold(gold.normals, Unpacked(*k, result.normals, first, n), "normals of " + std::to_string(i));
    // Not vacuous: its weights move it away from the mesh without morph targets.
    SkinnedMesh plain = mesh;
    plain.morph = MorphTargets{};
    EXPECT_GT(MaxDistance(SkinGold(plain, poses[static_cast<std::size_t>(i)]).positions, gold.positions), 1e-3);
  }
}

// The four meshes as one batch through the header alone: PackBatch,
// FindBatchKernel with its totals, PackPalette of every mesh's pose one after
// another, one launch; each mesh against its own float64 gold.
TEST(EmbedHeaderScenes, BatchKernelRunsOnOpenClLikeTheGoldOfEachMesh) {
  std::string why;
  OpenClRunner* runner = testing::FirstOpenClRunner(why);
  if (runner == nullptr) GTEST_SKIP() << why;
  const std::vector<const SkinnedMesh*> meshes = BatchMeshes();
  const BatchInput in = BatchOf(meshes);
  sk::PackedInputs inputs;
  sk::BatchOffsets offsets;
  std::string error;
  ASSERT_TRUE(sk::PackBatch(kBatch4, in.meshes.data(), in.meshes.size(), &inputs, &offsets, &error)) << error;
  const sk::Kernel* k = sk::FindBatchKernel("opencl", 4, offsets.vertices.back(), offsets.joints.back(),
                                            static_cast<int>(meshes.size()));
  ASSERT_EQ(k, &kBatch4);
  std::vector<std::vector<glm::mat4>> poses;
  std::vector<glm::mat4> all;
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    poses.push_back(PoseOf(kMeshes[m], 0.2 + 0.15 * static_cast<double>(m)));
    all.insert(all.end(), poses.back().begin(), poses.back().end());
  }
  const std::vector<float> palette = sk::PackPalette(*k, &all[0][0][0], offsets.joints.back());
  const std::vector<KernelSource> kernels = {SourceOf(*k)};
  const RunResult result = runner->Run(PackedOf(*k, inputs, offsets.vertices.back()), kernels, Bytes(palette));
  EXPECT_EQ(result.poisoned_vertices, 0u);
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const GoldResult gold = SkinGold(QuantisedMesh(*meshes[m], VariantOf(*k)), poses[m]);
    ExpectGold(gold.positions, Unpacked(*k, result.positions, offsets.vertices[m], meshes[m]->vertex_count()),
               "meshes[" + std::to_string(m) + "] " + kMeshes[m]);
  }
}

}  // namespace
}  // namespace skintune::internal
