// What the kernel runner tests share (opencl_runner_test, cuda_test,
// gl_runner_test): the run's seed, the meshes and poses, the comparison with
// the float64 gold, the case tables' type, and kernels with a fault edited
// in. Templates over the runner (OpenClRunner, CudaRunner, GlRunner) and its
// result (OpenClRunResult, CudaRunResult, GlRunResult).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <initializer_list>
#include <map>
#include <ostream>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "generator/constraints.h"
#include "generator/covering.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "base/error.h"
#include "model/gltf_import.h"
#include "reference/skinning.h"
#include "model/synthetic.h"

namespace skintune::internal::testing {

inline constexpr double kTolerance = 1e-5;

// $SKINTUNE_TEST_SEED, else a fresh one per test program (the traces print it).
inline std::uint64_t Seed() {
  static const std::uint64_t seed = []() -> std::uint64_t {
    if (const char* env = std::getenv("SKINTUNE_TEST_SEED")) return static_cast<std::uint64_t>(std::strtoull(env, nullptr, 10));
    return static_cast<std::uint64_t>(std::random_device{}()) % 1000000 + 1;
  }();
  return seed;
}

// A variant key and the mesh it runs on: "cesium", or a synthetic dataset key
// suffix such as "b3" / "b3-random" (<influences> bone slots, optionally random bones).
struct Case {
  const char* key;
  const char* mesh;
};

inline void PrintTo(const Case& c, std::ostream* os) { *os << c.key << " on " << c.mesh; }

// "<index>_<key>_<mesh>", every other character than a letter or digit as '_'.
inline std::string CaseName(const ::testing::TestParamInfo<Case>& info) {
  std::string name = std::to_string(info.index) + "_" + info.param.key + "_" + info.param.mesh;
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return name;
}

// CesiumMan, or the synthetic dataset for `mesh` with this run's seed; made once.
inline const SkinnedAsset& Asset(const std::string& mesh) {
  static std::map<std::string, SkinnedAsset> cache;
  if (auto found = cache.find(mesh); found != cache.end()) return found->second;
  if (mesh == "cesium") {
    return cache[mesh] = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset;
  }
  // 5000 vertices plus a seed-dependent tail, so launches end mid-work-group (mid-block).
  const std::string key = std::to_string(5000 + Seed() % 97) + "-" + mesh + "-seed" + std::to_string(Seed()) +
                          "-tangents";
  return cache[mesh] = GenerateDataset(ParseDatasetKey(key));
}

// The bind pose, or the first clip at a seed-dependent time.
inline std::vector<glm::mat4> Palette(const SkinnedAsset& asset) {
  if (asset.animations.empty()) return asset.PaletteAt(-1, 0.0);
  const AnimationClip& clip = asset.animations.front();
  const double t = clip.start + (clip.end - clip.start) * static_cast<double>(Seed() % 1000) / 1000.0;
  return asset.PaletteAt(0, t);
}

// What each launch's time must be: any value (OpenCL), >= 0 (GL), > 0 (CUDA).
enum class LaunchTimes { kAny, kNonNegative, kPositive };

// `result` against the gold of `mesh` quantised as the variant stores it:
// nothing poisoned, positions (and normals) finite and within kTolerance,
// one time per launch.
template <typename RunResult>
void ExpectMatchesGold(const PackedMesh& packed, const RunResult& result, const SkinnedMesh& mesh,
                       std::span<const glm::mat4> palette, LaunchTimes times) {
  const SkinnedMesh quantised = QuantisedMesh(mesh, packed.variant);
  const auto skin_gold = packed.variant.blend == Blend::kDualQuaternion ? &SkinGoldDualQuaternion : &SkinGold;
  const GoldResult gold = skin_gold(quantised, palette, SkinsNormals(packed.variant), SkinsTangents(packed.variant));
  EXPECT_EQ(result.poisoned_vertices, 0u);
  const GoldComparison p = CompareToGold(gold.positions, Unpack(packed, result.positions));
  EXPECT_EQ(p.non_finite, 0u) << "first at vertex " << p.worst_vertex;
  EXPECT_LT(p.max_relative, kTolerance) << "positions, worst vertex " << p.worst_vertex;
  if (SkinsNormals(packed.variant)) {
    const GoldComparison n = CompareToGold(gold.normals, UnpackNormals(packed, result.normals));
    EXPECT_EQ(n.non_finite, 0u) << "first at vertex " << n.worst_vertex;
    EXPECT_LT(n.max_relative, kTolerance + NormalFormatBound(packed.variant.normal_format))
        << "normals, worst vertex " << n.worst_vertex;
  }
  if (SkinsTangents(packed.variant)) {
    const GoldComparison t = CompareTangentsToGold(gold.tangents, UnpackTangents(packed, result.tangents));
    EXPECT_EQ(t.non_finite, 0u) << "first at vertex " << t.worst_vertex;
    EXPECT_EQ(t.wrong_handedness, 0u) << "first at vertex " << t.worst_vertex;
    EXPECT_LT(t.max_relative, kTolerance + TangentFormatBound(packed.variant.normal_format))
        << "tangents, worst vertex " << t.worst_vertex;
  }
  EXPECT_EQ(result.launch_ms.size(), packed.launches.size());
  if (times == LaunchTimes::kNonNegative) {
    for (const double ms : result.launch_ms) EXPECT_GE(ms, 0.0);
  } else if (times == LaunchTimes::kPositive) {
    for (const double ms : result.launch_ms) EXPECT_GT(ms, 0.0);
  }
}

// The morph targets of the meshes morph variants skin (a synthetic -morph<T>).
inline constexpr const char* kMorphMesh = "morph4";
// The problem shape of covering sets: 77 joints, normals and tangents, rigid
// joints (dual quaternions), morph targets that a mesh may or may not apply.
inline ProblemShape CoveringShape() {
  ProblemShape shape{77, 1, true, 1, true, true};
  shape.morph_targets = 4;
  return shape;
}

// Packs Asset(mesh) for `variant`, runs it with Palette(asset) and expects the
// gold. A dual-quaternion variant skins the mesh's rigid twin (its animation
// without scale channels), whose palettes are rotations and translations; a
// morph variant the mesh's twin with morph targets (kMorphMesh).
template <typename Runner>
PackedMesh ExpectRunMatchesGold(Runner& runner, const Variant& variant, const std::string& mesh, LaunchTimes times) {
  const bool rigid = variant.blend == Blend::kDualQuaternion && mesh != "cesium";
  const bool morph = SkinsMorph(variant) && mesh != "cesium";
  const SkinnedAsset& asset = Asset(mesh + (rigid ? "-rigid" : "") + (morph ? "-" + std::string(kMorphMesh) : ""));
  const PackedMesh packed = Pack(asset.mesh, variant);
  const std::vector<glm::mat4> palette = Palette(asset);
  ExpectMatchesGold(packed, runner.Run(packed, PackPalette(palette, variant)), asset.mesh, palette, times);
  return packed;
}

// One case of a table (`variant` parsed from c.key): the gold, and one launch
// per influence count for a bucketed variant on CesiumMan.
template <typename Runner>
void ExpectCaseMatchesGold(Runner& runner, const Case& c, const Variant& variant, LaunchTimes times) {
  const PackedMesh packed = ExpectRunMatchesGold(runner, variant, c.mesh, times);
  if (variant.mixed == MixedCounts::kBucketed && std::string(c.mesh) == "cesium") {
    EXPECT_EQ(packed.launches.size(), 4u);  // CesiumMan: vertices with 1, 2, 3 and 4 bones
  }
}

// Every variant of a covering set against the gold, each on a fresh mesh
// with its own influence count (every other one with random bones).
template <typename Runner>
void ExpectCoveringSetMatchesGold(Runner& runner, const CoveringSet& set, LaunchTimes times) {
  for (std::size_t i = 0; i < set.variants.size(); ++i) {
    const Variant& variant = set.variants[i];
    const std::string mesh = "b" + std::to_string(variant.influences) + (i % 2 ? "-random" : "");
    SCOPED_TRACE(variant.Key() + " on " + mesh + ", seed " + std::to_string(Seed()));
    ExpectRunMatchesGold(runner, variant, mesh, times);
  }
}

// One launch of `key` on the "b2" mesh, with an edit of the emitted text (none
// when `from` is empty); `from` must occur once. `joints` > 0 emits the kernel
// for that many joints instead of the mesh's.
struct Faulty {
  PackedMesh packed;
  std::vector<glm::mat4> palette;
  std::vector<KernelSource> kernels;
};

// Replaces the one occurrence of `from` in the kernel's text by `to`.
inline void EditKernel(KernelSource& s, const std::string& from, const std::string& to) {
  const std::size_t at = s.text.find(from);
  EXPECT_NE(at, std::string::npos) << "'" << from << "' not in the template any more: update the test";
  EXPECT_EQ(s.text.find(from, at + 1), std::string::npos) << "'" << from << "' occurs twice";
  if (at != std::string::npos) s.text.replace(at, from.size(), to);
  s.source_hash = SourceHash(s.text);
}

inline Faulty WithFault(const std::string& key, const std::string& from, const std::string& to, int joints = 0) {
  Faulty f;
  const SkinnedAsset& asset = Asset("b2");
  f.packed = Pack(asset.mesh, ParseVariantKey(key));
  f.palette = Palette(asset);
  KernelSource s = Emit(f.packed.variant, 0, joints > 0 ? joints : static_cast<int>(f.packed.palette_joints));
  if (!from.empty()) EditKernel(s, from, to);
  f.kernels.push_back(std::move(s));
  return f;
}

// The second half of the vertices never written: poisoned, and non-finite against the gold.
template <typename RunResult>
void ExpectHalfPoisoned(const Faulty& f, const RunResult& result) {
  const std::size_t n = f.packed.vertex_count;
  EXPECT_EQ(result.poisoned_vertices, n - n / 2);
  const GoldResult gold = SkinGold(Asset("b2").mesh, f.palette);
  const GoldComparison c = CompareToGold(gold.positions, Unpack(f.packed, result.positions));
  EXPECT_EQ(c.non_finite, n - n / 2);
  EXPECT_FALSE(c.max_relative < kTolerance);
}

// Running `f` throws an Error whose message contains every one of `parts`;
// `not_caught` is the failure when it runs instead.
template <typename Runner>
void ExpectRunFails(Runner& runner, const Faulty& f, const std::string& not_caught,
                    std::initializer_list<const char*> parts) {
  try {
    runner.Run(f.packed, f.kernels, PackPalette(f.palette, f.packed.variant));
    ADD_FAILURE() << not_caught;
  } catch (const Error& e) {
    const std::string message = e.what();
    for (const char* part : parts) EXPECT_NE(message.find(part), std::string::npos) << message;
  }
}

// ---------------------------------------------------------------- instances

// A case of an instanced table: a variant key, its mesh ("cesium" or a small
// synthetic "b<B>[-random]" with 12 bones), and K.
struct InstanceCase {
  const char* key;
  const char* mesh;
  int instances;
};

inline void PrintTo(const InstanceCase& c, std::ostream* os) {
  *os << c.key << " on " << c.mesh << " x" << c.instances;
}

// Each of `cases` with K = 1, 7 and 64.
inline std::vector<InstanceCase> WithInstanceCounts(std::span<const Case> cases) {
  std::vector<InstanceCase> out;
  for (const Case& c : cases)
    for (const int k : {1, 7, 64}) out.push_back({c.key, c.mesh, k});
  return out;
}

inline std::string InstanceCaseName(const ::testing::TestParamInfo<InstanceCase>& info) {
  std::string name = std::to_string(info.index) + "_" + info.param.key + "_" + info.param.mesh + "_x" +
                     std::to_string(info.param.instances);
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return name;
}

// CesiumMan (3273 vertices, 19 joints), or a small synthetic mesh of this
// run's seed: 700 vertices plus a seed-dependent tail, 12 bones (so 64
// palettes fit a 64 KiB constant buffer / uniform block); made once.
inline const SkinnedAsset& SmallAsset(const std::string& mesh) {
  static std::map<std::string, SkinnedAsset> cache;
  if (mesh == "cesium") return Asset(mesh);
  if (auto found = cache.find(mesh); found != cache.end()) return found->second;
  const std::size_t dash = mesh.find('-');
  const std::string influences = mesh.substr(0, dash);
  const std::string rest = dash == std::string::npos ? "" : mesh.substr(dash);  // "-random"
  const std::string key = std::to_string(700 + Seed() % 97) + "-" + influences + "-bones12" + rest + "-seed" +
                          std::to_string(Seed()) + "-tangents";
  return cache[mesh] = GenerateDataset(ParseDatasetKey(key));
}

// Instance i's palette: Palette(asset) moved as a whole by its own random
// rotation and translation (seeded by the run's seed and i), as a crowd places
// its characters, so an instance that reads another instance's palette fails
// the comparison. (A whole-instance move keeps the blend as well conditioned
// as the pose itself; independent random moves per joint would not.)
inline std::vector<glm::mat4> InstancePalette(const SkinnedAsset& asset, int instance) {
  std::vector<glm::mat4> palette = Palette(asset);
  std::mt19937 rng(static_cast<std::uint32_t>(Seed() * 1009 + static_cast<std::uint64_t>(instance)));
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const glm::vec3 axis = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 1e-3f));
  // Moved by twice the model's reach, so no skinned vertex passes near the
  // origin: there CompareToGold's relative error (floor 1e-3 of the largest
  // |gold|) would turn float32 rounding (~1e-7 absolute) into a failure.
  float reach = 0.0f;
  for (const glm::vec3& p : asset.mesh.positions) reach = std::max(reach, glm::length(p));
  const glm::vec3 direction = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(1e-3f, 0.0f, 0.0f));
  const glm::vec3 move = direction * (2.0f * reach);
  const glm::mat4 place = glm::translate(glm::mat4(1.0f), move) * glm::rotate(glm::mat4(1.0f), 3.14159265f * u(rng), axis);
  for (glm::mat4& m : palette) m = place * m;
  return palette;
}

// One instanced run: the K palettes' PackPalette bytes one after another.
struct InstancedRun {
  PackedMesh packed;
  std::vector<std::vector<glm::mat4>> palettes;  // per instance
  std::vector<std::uint8_t> palette_bytes;        // all K, packed
};

inline InstancedRun InstancedInputs(const Variant& variant, const std::string& mesh, int instances) {
  InstancedRun r;
  const SkinnedAsset& asset = SmallAsset(mesh);
  r.packed = Pack(asset.mesh, variant);
  for (int i = 0; i < instances; ++i) {
    r.palettes.push_back(InstancePalette(asset, i));
    const std::vector<std::uint8_t> bytes = PackPalette(r.palettes.back(), variant);
    r.palette_bytes.insert(r.palette_bytes.end(), bytes.begin(), bytes.end());
  }
  return r;
}

// Each instance's part of an instanced run's `output` (K x vertex_count
// vertices, instance after instance), unpacked to the mesh's vertex order.
inline std::vector<glm::vec3> UnpackInstance(const PackedMesh& packed, std::span<const std::uint8_t> output,
                                             int instance) {
  const std::size_t bytes = packed.vertex_count * packed.output_stride_bytes;
  return Unpack(packed, output.subspan(static_cast<std::size_t>(instance) * bytes, bytes));
}

// Every instance of `result` against the gold of its own palette: nothing
// poisoned, every position (and normal) within kTolerance, one time per launch.
template <typename RunResult>
void ExpectInstancesMatchGold(const InstancedRun& run, const RunResult& result, const SkinnedMesh& mesh) {
  const Variant& variant = run.packed.variant;
  const SkinnedMesh quantised = QuantisedMesh(mesh, variant);
  const std::size_t k = run.palettes.size();
  EXPECT_EQ(result.poisoned_vertices, 0u);
  ASSERT_EQ(result.positions.size(), k * run.packed.vertex_count * run.packed.output_stride_bytes);
  if (SkinsNormals(variant)) {
    ASSERT_EQ(result.normals.size(), result.positions.size());
  }
  if (SkinsTangents(variant)) {
    ASSERT_EQ(result.tangents.size(), result.positions.size());
  }
  for (std::size_t i = 0; i < k; ++i) {
    SCOPED_TRACE("instance " + std::to_string(i) + " of " + std::to_string(k));
    const GoldResult gold = SkinGold(quantised, run.palettes[i], SkinsNormals(variant), SkinsTangents(variant));
    const GoldComparison p = CompareToGold(gold.positions, UnpackInstance(run.packed, result.positions, static_cast<int>(i)));
    EXPECT_EQ(p.non_finite, 0u) << "first at vertex " << p.worst_vertex;
    EXPECT_LT(p.max_relative, kTolerance) << "positions, worst vertex " << p.worst_vertex;
    if (SkinsNormals(variant)) {
      const GoldComparison n = CompareToGold(gold.normals, UnpackInstance(run.packed, result.normals, static_cast<int>(i)));
      EXPECT_EQ(n.non_finite, 0u) << "first at vertex " << n.worst_vertex;
      EXPECT_LT(n.max_relative, kTolerance) << "normals, worst vertex " << n.worst_vertex;
    }
    if (SkinsTangents(variant)) {
      const std::size_t bytes = run.packed.vertex_count * run.packed.output_stride_bytes;
      const GoldComparison t = CompareTangentsToGold(
          gold.tangents, UnpackTangents(run.packed, std::span(result.tangents).subspan(i * bytes, bytes)));
      EXPECT_EQ(t.non_finite, 0u) << "first at vertex " << t.worst_vertex;
      EXPECT_EQ(t.wrong_handedness, 0u) << "first at vertex " << t.worst_vertex;
      EXPECT_LT(t.max_relative, kTolerance) << "tangents, worst vertex " << t.worst_vertex;
    }
    if (::testing::Test::HasFailure()) return;  // one failing instance says enough
  }
  EXPECT_EQ(result.launch_ms.size(), run.packed.launches.size());  // one launch per bucket, whatever K
}

// Runs `c` instanced (RunInstanced) and expects every instance's gold; skips
// when the device cannot hold K palettes in the variant's storage.
template <typename Runner>
void ExpectInstanceCaseMatchesGold(Runner& runner, const InstanceCase& c, const DeviceLimits& limits) {
  const Variant variant = ParseVariantKey(c.key);
  const SkinnedAsset& asset = SmallAsset(c.mesh);
  const ProblemShape shape{asset.mesh.joint_count, 1, true, c.instances, asset.mesh.has_tangents()};
  const std::vector<Violation> violations = CheckVariant(variant, limits, shape);
  if (!violations.empty()) GTEST_SKIP() << "this device cannot run it: " << violations.front().message;
  const InstancedRun run = InstancedInputs(variant, c.mesh, c.instances);
  ExpectInstancesMatchGold(run, runner.RunInstanced(run.packed, c.instances, run.palette_bytes), asset.mesh);
  if (variant.mixed == MixedCounts::kBucketed && std::string(c.mesh) == "cesium") {
    EXPECT_EQ(run.packed.launches.size(), 4u);  // CesiumMan: vertices with 1, 2, 3 and 4 bones
  }
}

// `result` of a kernel that reads instance 0's palette for every instance:
// instance 0 matches its gold, every other instance fails it.
template <typename RunResult>
void ExpectOnlyInstanceZeroMatches(const InstancedRun& run, const RunResult& result) {
  const SkinnedMesh quantised = QuantisedMesh(SmallAsset("b2").mesh, run.packed.variant);
  for (std::size_t i = 0; i < run.palettes.size(); ++i) {
    const GoldComparison c = CompareToGold(SkinGold(quantised, run.palettes[i]).positions,
                                           UnpackInstance(run.packed, result.positions, static_cast<int>(i)));
    if (i == 0) {
      EXPECT_LT(c.max_relative, kTolerance);  // instance 0's palette is the one read
    } else {
      EXPECT_FALSE(c.max_relative < kTolerance) << "instance " << i << " passed with instance 0's palette";
    }
  }
}

// The message of the Error `f` throws, or "(no error)".
template <typename F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// An instanced kernel of `key` on the small "b2" mesh for K instances, with an
// edit of its text (as WithFault).
inline InstancedRun WithInstancedFault(const std::string& key, int instances, const std::string& from,
                                       const std::string& to, std::vector<KernelSource>& kernels) {
  InstancedRun run = InstancedInputs(ParseVariantKey(key), "b2", instances);
  EmitOptions options;
  options.instanced = true;
  options.max_instances = instances;
  KernelSource s = Emit(run.packed.variant, 0, static_cast<int>(run.packed.palette_joints), options);
  EditKernel(s, from, to);
  kernels = {std::move(s)};
  return run;
}

}  // namespace skintune::internal::testing
