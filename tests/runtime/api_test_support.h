// What the public-API tests share (skinner_opencl_test, skinner_gl_test,
// skinner_cuda_test, device_test): a MeshView over a SkinnedMesh, a fresh
// program-cache directory per test, and skinning through the API compared
// with the float64 gold.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "generator/packer.h"
#include "model/asset.h"
#include "reference/skinning.h"
#include "skintune/skintune.h"

namespace skintune::internal::testing {

// A MeshView of `mesh` (joint indices widened to 32 bits, kept here).
struct View {
  explicit View(const SkinnedMesh& m) : joints(m.joints.begin(), m.joints.end()) {
    mesh.vertex_count = m.vertex_count();
    mesh.influences = m.influences;
    mesh.joint_count = m.joint_count;
    mesh.positions = &m.positions.front().x;
    mesh.normals = m.has_normals() ? &m.normals.front().x : nullptr;
    mesh.tangents = m.has_tangents() ? &m.tangents.front().x : nullptr;
    mesh.joints = joints.data();
    mesh.weights = m.weights.data();
  }
  std::vector<std::uint32_t> joints;
  MeshView mesh;
};

// The MeshView of a mesh with its morph targets, over arrays it owns.
struct MorphView {
  explicit MorphView(const SkinnedMesh& m) : view(m) {
    const MorphTargets& morph = m.morph;
    for (const auto* stream : {&morph.positions, &morph.normals, &morph.tangents}) {
      std::vector<float>& out = stream == &morph.positions ? positions : stream == &morph.normals ? normals : tangents;
      for (const std::vector<glm::vec3>& target : *stream)
        for (const glm::vec3& d : target) out.insert(out.end(), {d.x, d.y, d.z});
    }
    for (const double w : morph.weights) weights.push_back(static_cast<float>(w));
    view.mesh.morph_target_count = static_cast<int>(morph.count());
    view.mesh.morph_positions = positions.data();
    view.mesh.morph_normals = normals.empty() ? nullptr : normals.data();
    view.mesh.morph_tangents = tangents.empty() ? nullptr : tangents.data();
    view.mesh.morph_weights = weights.data();
  }
  View view;
  std::vector<float> positions, normals, tangents, weights;
};

// A new empty directory under the system's temporary directory, removed at the end.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("skintune-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  std::string str() const { return path_.string(); }
  std::vector<std::filesystem::path> Files() const {
    std::vector<std::filesystem::path> out;
    for (const auto& entry : std::filesystem::directory_iterator(path_)) out.push_back(entry.path());
    return out;
  }

 private:
  std::filesystem::path path_;
};

inline DeviceOptions CacheIn(const TempDir& dir) {
  DeviceOptions options;
  options.program_cache_dir = dir.str();
  return options;
}

// The fixture of tests run once per backend: Case has a `backend`; SetUp
// opens that backend's device with a program cache of its own, or skips the
// test naming why (a machine without that API).
template <typename Case>
class BackendFixture : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    const Backend backend = this->GetParam().backend;
    Result<Device> device = Device::Open("", &backend, CacheIn(dir_));
    if (!device.ok()) GTEST_SKIP() << "no " << BackendName(backend) << " device: " << device.status().message();
    device_ = std::move(*device);
  }
  TempDir dir_;
  Device device_;
};

inline std::vector<float> Floats(std::span<const glm::mat4> palette) {
  std::vector<float> out;
  for (const glm::mat4& m : palette)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) out.push_back(m[c][r]);
  return out;
}

// A test parameter's name from a variant key and what follows it: every
// character that is not a letter or a digit becomes '_' (gtest's rule).
inline std::string ParameterName(std::string name) {
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
}

inline std::vector<glm::vec3> Vec3s(const std::vector<float>& floats) {
  std::vector<glm::vec3> out(floats.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = {floats[3 * i], floats[3 * i + 1], floats[3 * i + 2]};
  return out;
}

// Skins `mesh` with `palette` through `skinner` (SetPalette, Skin, Read*) and
// expects the gold of the mesh as the chosen variant quantises it, within 1e-5.
inline void ExpectSkinsLikeTheGold(Skinner& skinner, const SkinnedMesh& mesh, std::span<const glm::mat4> palette) {
  const Variant variant = ParseVariantKey(skinner.selection().variant);
  const std::vector<float> matrices = Floats(palette);
  ASSERT_TRUE(skinner.SetPalette(matrices.data(), matrices.size()).ok());
  const Status skinned = skinner.Skin();
  ASSERT_TRUE(skinned.ok()) << skinned.message();
  const auto skin_gold = variant.blend == Blend::kDualQuaternion ? &SkinGoldDualQuaternion : &SkinGold;
  const GoldResult gold =
      skin_gold(QuantisedMesh(mesh, variant), palette, SkinsNormals(variant), SkinsTangents(variant));
  std::vector<float> positions(mesh.vertex_count() * 3);
  const Status read = skinner.ReadPositions(positions.data(), positions.size());
  ASSERT_TRUE(read.ok()) << read.message();
  const GoldComparison p = CompareToGold(gold.positions, Vec3s(positions));
  EXPECT_EQ(p.non_finite, 0u) << variant.Key() << ": first at vertex " << p.worst_vertex;
  EXPECT_LT(p.max_relative, 1e-5) << variant.Key() << ": positions, worst vertex " << p.worst_vertex;
  if (SkinsNormals(variant)) {
    std::vector<float> normals(mesh.vertex_count() * 3);
    ASSERT_TRUE(skinner.ReadNormals(normals.data(), normals.size()).ok());
    const GoldComparison n = CompareToGold(gold.normals, Vec3s(normals));
    EXPECT_EQ(n.non_finite, 0u) << variant.Key();
    EXPECT_LT(n.max_relative, 1e-5) << variant.Key() << ": normals, worst vertex " << n.worst_vertex;
  }
  if (SkinsTangents(variant)) {
    std::vector<float> tangents(mesh.vertex_count() * 4);
    const Status read_tangents = skinner.ReadTangents(tangents.data(), tangents.size());
    ASSERT_TRUE(read_tangents.ok()) << read_tangents.message();
    std::vector<glm::vec4> t(mesh.vertex_count());
    std::memcpy(t.data(), tangents.data(), tangents.size() * sizeof(float));
    const GoldComparison c = CompareTangentsToGold(gold.tangents, t);
    EXPECT_EQ(c.non_finite, 0u) << variant.Key();
    EXPECT_EQ(c.wrong_handedness, 0u) << variant.Key() << ": first at vertex " << c.worst_vertex;
    EXPECT_LT(c.max_relative, 1e-5) << variant.Key() << ": tangents, worst vertex " << c.worst_vertex;
  }
}

// Skins `mesh` as palettes.size() instances in one Skin() (instance k with
// palettes[k]) and expects each instance's part of the read-back to be that
// palette's gold.
inline void ExpectInstancesLikeTheGold(Skinner& skinner, const SkinnedMesh& mesh,
                                       const std::vector<std::vector<glm::mat4>>& palettes) {
  const Variant variant = ParseVariantKey(skinner.selection().variant);
  ASSERT_EQ(static_cast<std::size_t>(skinner.instances()), palettes.size());
  std::vector<float> matrices;
  for (const std::vector<glm::mat4>& p : palettes) {
    const std::vector<float> f = Floats(p);
    matrices.insert(matrices.end(), f.begin(), f.end());
  }
  const Status set = skinner.SetPalette(matrices.data(), matrices.size());
  ASSERT_TRUE(set.ok()) << set.message();
  const Status skinned = skinner.Skin();
  ASSERT_TRUE(skinned.ok()) << skinned.message();
  const std::size_t n = mesh.vertex_count();
  std::vector<float> positions(palettes.size() * n * 3), normals(SkinsNormals(variant) ? positions.size() : 0);
  ASSERT_TRUE(skinner.ReadPositions(positions.data(), positions.size()).ok());
  if (SkinsNormals(variant)) {
    ASSERT_TRUE(skinner.ReadNormals(normals.data(), normals.size()).ok());
  }
  const SkinnedMesh quantised = QuantisedMesh(mesh, variant);
  for (std::size_t k = 0; k < palettes.size(); ++k) {
    SCOPED_TRACE("instance " + std::to_string(k) + " of " + std::to_string(palettes.size()));
    const GoldResult gold = SkinGold(quantised, palettes[k], SkinsNormals(variant));
    const std::vector<float> part(positions.begin() + static_cast<std::ptrdiff_t>(k * n * 3),
                                  positions.begin() + static_cast<std::ptrdiff_t>((k + 1) * n * 3));
    const GoldComparison p = CompareToGold(gold.positions, Vec3s(part));
    EXPECT_EQ(p.non_finite, 0u) << variant.Key();
    EXPECT_LT(p.max_relative, 1e-5) << variant.Key() << ": positions, worst vertex " << p.worst_vertex;
    if (SkinsNormals(variant)) {
      const std::vector<float> npart(normals.begin() + static_cast<std::ptrdiff_t>(k * n * 3),
                                     normals.begin() + static_cast<std::ptrdiff_t>((k + 1) * n * 3));
      const GoldComparison c = CompareToGold(gold.normals, Vec3s(npart));
      EXPECT_LT(c.max_relative, 1e-5) << variant.Key() << ": normals, worst vertex " << c.worst_vertex;
    }
  }
}

// K palettes of `asset`'s first clip at K different times.
inline std::vector<std::vector<glm::mat4>> Poses(const SkinnedAsset& asset, int instances) {
  const AnimationClip& clip = asset.animations.front();
  std::vector<std::vector<glm::mat4>> out;
  for (int k = 0; k < instances; ++k)
    out.push_back(asset.PaletteAt(0, clip.start + (clip.end - clip.start) * (k + 0.5) / instances));
  return out;
}

// `pose` with every joint of the mesh's last vertex scaled to 3e38: finite,
// but that vertex's output (and any other those joints move) overflows
// float32, so the read-back scans everything before copying.
inline std::vector<float> OverflowingLastVertex(const SkinnedMesh& mesh, std::span<const glm::mat4> pose) {
  std::vector<float> matrices = Floats(pose);
  const std::size_t last = mesh.vertex_count() - 1, b = static_cast<std::size_t>(mesh.influences);
  for (std::size_t i = 0; i < b; ++i) {
    if (mesh.weights[last * b + i] == 0.0f) continue;
    const std::size_t j = mesh.joints[last * b + i];
    for (int e = 0; e < 16; e += 5) matrices[j * 16 + e] = 3e38f;
  }
  return matrices;
}

// Skins with `matrices` (finite, but the output overflows float32) and
// expects ReadPositions to fail naming it, leaving the caller's array as it was.
inline void ExpectOverflowWritesNothing(Skinner& skinner, const std::vector<float>& matrices) {
  ASSERT_TRUE(skinner.SetPalette(matrices.data(), matrices.size()).ok());
  ASSERT_TRUE(skinner.Skin().ok());
  std::vector<float> out(skinner.vertex_count() * static_cast<std::size_t>(skinner.instances()) * 3, 7.0f);
  const Status read = skinner.ReadPositions(out.data(), out.size());
  EXPECT_EQ(read.code(), ErrorCode::kDeviceError);
  EXPECT_NE(read.message().find("not finite: the palette times the mesh overflows float32"), std::string::npos)
      << read.message();
  EXPECT_TRUE(std::all_of(out.begin(), out.end(), [](float v) { return v == 7.0f; }));
}

}  // namespace skintune::internal::testing
