// The header `skintune emit --db` generates (tools/emit/embed_header.h,
// templates/embedded_support.h): built at build time from
// tests/data/embed-winners-db.json (every value of every axis, one bucketed
// winner, two winners sharing a variant) into namespace fixture_kernels, and
// checked against skintune itself: the packer, the palette packer, the launch
// geometry, Emit and the database it came from.
#include "skintune_kernels.h"  // first: the generated header needs nothing before it

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>

#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include "embed_header_second_tu.h"
#include "generator/axes.h"
#include "generator/emit.h"
#include "generator/packer.h"
#include "base/error.h"
#include "tools/emit/embed_header.h"
#include "runtime/winners_db.h"
#include "tests/common/scratch_dir.h"
#include "tests/tools/emit/embed_header_test_support.h"

namespace skintune::internal {
namespace {

namespace fk = fixture_kernels;
namespace fs = std::filesystem;

constexpr int kJoints = 77;  // the fixture header's palette size (skintune emit's default)
constexpr int kFixtureMorphTargets = 4;  // the morph winners' (tests/data/embed-winners-db.json)

const std::vector<WinnersEntry>& Fixture() {
  static const std::vector<WinnersEntry> entries = testing::TestDataWinnersDb("embed-winners-db.json");
  return entries;
}

Variant VariantOf(const fk::Kernel& k) { return ParseVariantKey(k.variant); }

std::string Context(const fk::Kernel& k) { return std::string(k.variant) + " (" + k.device_id + ")"; }

// The header's enum values by skintune's names for them.
const char* Name(fk::Layout v) {
  return v == fk::Layout::kAos ? "aos" : v == fk::Layout::kSoa ? "soa" : "soa-split";
}
const char* Name(fk::PositionFormat v) { return v == fk::PositionFormat::kFloat4 ? "float4" : "float3"; }
const char* Name(fk::IndexFormat v) {
  return v == fk::IndexFormat::kI32 ? "i32" : v == fk::IndexFormat::kU16 ? "u16" : "u8";
}
const char* Name(fk::WeightFormat v) {
  return v == fk::WeightFormat::kF32 ? "f32" : v == fk::WeightFormat::kUnorm16 ? "unorm16" : "unorm8";
}
const char* Name(fk::PaletteFormat v) {
  return v == fk::PaletteFormat::kMat4 ? "mat4" : v == fk::PaletteFormat::kMat3x4 ? "mat3x4" : "dualquat";
}
const char* Name(fk::Morph v) {
  switch (v) {
    case fk::Morph::kNone: return "none";
    case fk::Morph::kDense: return "dense";
    case fk::Morph::kSparse: return "sparse";
    case fk::Morph::kDenseHalf: return "dense-half";
    case fk::Morph::kSparseHalf: return "sparse-half";
  }
  return "?";
}
const char* Name(fk::PaletteStorage v) {
  switch (v) {
    case fk::PaletteStorage::kGlobal: return "global";
    case fk::PaletteStorage::kConstant: return "constant";
    case fk::PaletteStorage::kLocal: return "local";
    case fk::PaletteStorage::kImage: return "image";
  }
  return "?";
}

// ------------------------------------------------------------------ the table

// Emitted without --max-error: the default budget, recorded in the header.
TEST(EmbedHeader, RecordsTheErrorBudgetItWasEmittedUnder) {
  EXPECT_EQ(fk::kMaxError, kDefaultBudget);
  static_assert(fk::kMaxError > 0.0, "a constant expression, usable at compile time");
}

TEST(EmbedHeader, ListsEveryWinnerOfTheDatabaseInItsOrderWithItsDeviceAndTimes) {
  const std::vector<WinnersEntry>& entries = Fixture();
  ASSERT_EQ(static_cast<std::size_t>(fk::kKernelCount), entries.size());
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const WinnersEntry& e = entries[i];
    const fk::Kernel& k = fk::kKernels[i];
    EXPECT_EQ(k.device_id, e.device_id) << i;
    EXPECT_EQ(k.platform, e.platform) << i;
    EXPECT_EQ(k.vendor, e.vendor) << i;
    EXPECT_EQ(k.device_name, e.device_name) << i;
    EXPECT_EQ(k.driver_version, e.driver_version) << i;
    EXPECT_EQ(k.device_type, e.device_type) << i;
    EXPECT_EQ(k.lang, std::string(skintune::internal::Name(e.lang))) << i;
    EXPECT_EQ(k.influences, e.influences) << i;
    EXPECT_EQ(k.vertex_bucket, e.vertex_bucket) << i;
    EXPECT_EQ(k.vertices, e.vertices) << i;
    EXPECT_EQ(k.dataset, e.dataset) << i;
    EXPECT_EQ(k.median_ms, e.median_ms) << i;
    EXPECT_EQ(k.gbps, e.gbps) << i;
    EXPECT_EQ(k.copy_fraction, e.copy_fraction) << i;
    Variant padded = e.variant;
    padded.mixed = MixedCounts::kPadded;
    EXPECT_EQ(k.variant, padded.Key()) << i;
  }
}

TEST(EmbedHeader, DeviceStringsWithQuotesBackslashesAndTrigraphsSurviveEscaping) {
  bool found = false;
  for (int i = 0; i < fk::kKernelCount; ++i) {
    if (std::string(fk::kKernels[i].device_name) == "gfx1100 \"Navi 31\" \\ ?\?=") found = true;
  }
  EXPECT_TRUE(found) << "the fixture's AMD device name did not come through unchanged";
}

TEST(EmbedHeader, FixtureCoversEveryAxisValueAndOneBucketedWinner) {
  std::map<std::string, std::set<std::string>> seen;
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    seen["lang"].insert(k.lang);
    seen["layout"].insert(Name(k.layout));
    seen["position"].insert(Name(k.position));
    seen["index"].insert(Name(k.index));
    seen["weight"].insert(Name(k.weight));
    seen["palette"].insert(Name(k.palette));
    seen["storage"].insert(Name(k.storage));
    seen["blend"].insert(k.palette == fk::PaletteFormat::kDualquat ? "dq" : k.point_blend ? "point" : "matrix");
    seen["normals"].insert(k.tangents ? "tangents" : k.normals ? "normals" : "nonormals");
    seen["assignment"].insert(k.strided ? "strided" : "contiguous");
    seen["morph"].insert(Name(k.morph));
  }
  EXPECT_EQ(seen["lang"].size(), 4u);
  EXPECT_EQ(seen["layout"].size(), 3u);
  EXPECT_EQ(seen["position"].size(), 2u);
  EXPECT_EQ(seen["index"].size(), 3u);
  EXPECT_EQ(seen["weight"].size(), 3u);
  EXPECT_EQ(seen["palette"].size(), 3u);
  EXPECT_EQ(seen["storage"].size(), 4u);
  EXPECT_EQ(seen["blend"].size(), 3u);
  EXPECT_EQ(seen["normals"].size(), 3u);
  EXPECT_EQ(seen["assignment"].size(), 2u);
  EXPECT_EQ(seen["morph"].size(), 5u);
  int bucketed = 0;
  for (const WinnersEntry& e : Fixture()) bucketed += e.variant.mixed == MixedCounts::kBucketed;
  EXPECT_EQ(bucketed, 1);
}

// templates/embedded_support.h declares the header's enums by hand: each must
// hold every value of its axis of the table, spelt as KernelRow writes it.
TEST(EmbedHeader, SupportHeaderDeclaresEveryValueOfEveryEmbeddedAxis) {
  std::ifstream in(std::string(SKINTUNE_SOURCE_DIR) + "/templates/embedded_support.h");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  int enums = 0;
  for (const Axis& axis : kAxes) {
    if (axis.embedded_enum == nullptr) continue;
    ++enums;
    const std::string head = "enum class " + std::string(axis.embedded_enum) + " {";
    const std::size_t begin = text.find(head);
    ASSERT_NE(begin, std::string::npos) << head;
    std::istringstream body(text.substr(begin + head.size(), text.find('}', begin) - begin - head.size()));
    std::set<std::string> declared, expected;
    for (std::string name; std::getline(body >> std::ws, name, ',');) {
      declared.insert(std::string(axis.embedded_enum) + "::" + name.substr(0, name.find_last_not_of(" ") + 1));
    }
    for (const AxisValueSpec& value : axis.values) expected.insert(EmbeddedEnumerator(axis, value.code));
    EXPECT_EQ(declared, expected) << head;
  }
  EXPECT_GT(enums, 0);
}

TEST(EmbedHeader, KernelParametersAreTheVariantsAxes) {
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    const Variant v = VariantOf(k);
    SCOPED_TRACE(Context(k));
    EXPECT_EQ(v.mixed, MixedCounts::kPadded);
    EXPECT_EQ(k.lang, std::string(skintune::internal::Name(v.lang)));
    EXPECT_EQ(k.influences, v.influences);
    EXPECT_EQ(Name(k.layout), std::string(skintune::internal::Name(v.layout)));
    EXPECT_EQ(Name(k.position), std::string(skintune::internal::Name(v.position)));
    EXPECT_EQ(Name(k.index), std::string(skintune::internal::Name(v.index)));
    EXPECT_EQ(Name(k.weight), std::string(skintune::internal::Name(v.weight)));
    EXPECT_EQ(Name(k.palette), std::string(skintune::internal::Name(v.palette)));
    EXPECT_EQ(Name(k.storage), std::string(skintune::internal::Name(v.storage)));
    EXPECT_EQ(k.point_blend, v.blend == Blend::kPoint);
    EXPECT_EQ(k.palette == fk::PaletteFormat::kDualquat, v.blend == Blend::kDualQuaternion);
    EXPECT_EQ(k.normals, SkinsNormals(v));
    EXPECT_EQ(k.tangents, SkinsTangents(v));
    EXPECT_EQ(k.vertices_per_item, v.vertices_per_item);
    EXPECT_EQ(k.strided, v.assignment == Assignment::kStrided);
    EXPECT_EQ(k.wg_size, v.wg_size);
    EXPECT_EQ(k.joints, kJoints);
    EXPECT_EQ(Name(k.morph), std::string(skintune::internal::Name(v.morph)));
    EXPECT_EQ(k.morph_targets, SkinsMorph(v) ? kFixtureMorphTargets : 0);
  }
}

TEST(EmbedHeader, BucketedWinnerIsEmbeddedAsItsPaddedTwin) {
  const std::vector<WinnersEntry>& entries = Fixture();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (entries[i].variant.mixed != MixedCounts::kBucketed) continue;
    const std::string key = fk::kKernels[i].variant;
    EXPECT_NE(key.find(".padded."), std::string::npos) << key;
    Variant twin = entries[i].variant;
    twin.mixed = MixedCounts::kPadded;
    EXPECT_EQ(std::string(fk::kKernels[i].source), Emit(twin, 0, kJoints).text);
    EXPECT_NE(std::string(fk::kKernels[i].source), Emit(entries[i].variant, 0, kJoints).text);
  }
}

TEST(EmbedHeader, SourceIsTheEmittedKernelTextWithItsHashEntryPointAndLaunchRule) {
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    const KernelSource s = Emit(VariantOf(k), 0, kJoints, EmitOptions{.morph_targets = k.morph_targets});
    SCOPED_TRACE(Context(k));
    EXPECT_EQ(std::string(k.source), s.text);
    EXPECT_EQ(std::strlen(k.source), s.text.size());
    EXPECT_EQ(k.source_hash, s.source_hash);
    EXPECT_EQ(k.source_hash, SourceHash(k.source));
    EXPECT_EQ(k.entry_point, s.entry_point);
    EXPECT_EQ(k.launch_rule, s.launch.rule);
  }
}

TEST(EmbedHeader, WinnersOfTheSameVariantShareOneSourceLiteral) {
  int shared = 0;
  for (int i = 0; i < fk::kKernelCount; ++i) {
    for (int j = i + 1; j < fk::kKernelCount; ++j) {
      if (std::string(fk::kKernels[i].variant) != fk::kKernels[j].variant) continue;
      EXPECT_EQ(fk::kKernels[i].source, fk::kKernels[j].source);  // the same object
      EXPECT_EQ(fk::kKernels[i].arguments, fk::kKernels[j].arguments);
      EXPECT_NE(std::string(fk::kKernels[i].vertex_bucket), fk::kKernels[j].vertex_bucket);
      ++shared;
    }
  }
  EXPECT_EQ(shared, 1);  // the fixture's CUDA b3 winner of 100k and 1600k
}

TEST(EmbedHeader, ArgumentsAreTheEmittedInterfaceInKernelOrder) {
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    const KernelSource s = Emit(VariantOf(k), 0, kJoints, EmitOptions{.morph_targets = k.morph_targets});
    SCOPED_TRACE(Context(k));
    ASSERT_EQ(static_cast<std::size_t>(k.argument_count), s.arguments.size());
    for (std::size_t a = 0; a < s.arguments.size(); ++a) {
      const fk::Argument& got = k.arguments[a];
      const KernelArgument& want = s.arguments[a];
      EXPECT_EQ(got.name, want.name) << a;
      EXPECT_EQ(got.format, want.format) << a;
      EXPECT_EQ(got.element_bytes, want.element_bytes) << a;
      EXPECT_EQ(got.stride_bytes, want.stride_bytes) << a;
      EXPECT_EQ(got.indexing, want.indexing) << a;
      EXPECT_EQ(got.output, want.direction == ArgumentDirection::kOut) << a;
      EXPECT_EQ(got.scalar, want.kind == ArgumentKind::kScalar) << a;
      EXPECT_EQ(got.image, want.kind == ArgumentKind::kImage) << a;
    }
  }
}

// ------------------------------------------------------------------ launch geometry

TEST(EmbedHeader, GlobalWorkItemsSlotStrideAndOutputStrideFollowSkintunesRules) {
  const std::size_t counts[] = {0, 1, 31, 63, 64, 65, 127, 129, 255, 257, 1000, 4097, 100000, 1234567};
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    const Variant v = VariantOf(k);
    const KernelSource s = Emit(v, 0, kJoints, EmitOptions{.morph_targets = k.morph_targets});
    SCOPED_TRACE(Context(k));
    for (const std::size_t n : counts) {
      EXPECT_EQ(fk::GlobalWorkItems(k, n), s.launch.GlobalItems(n)) << n;
      const std::size_t stride =
          v.layout == Layout::kSoaSplit ? SoaSplitSlotStride(static_cast<std::uint32_t>(n), v) : 0;
      EXPECT_EQ(fk::SlotStride(k, n), stride) << n;
    }
    EXPECT_EQ(fk::OutputStrideBytes(k), BytesOf(v.position));
  }
}

// ------------------------------------------------------------------ packing

// A mesh with `slots` slots per vertex whose vertices use 1..slots bones, in
// varying slots (padded keeps them in place), some with equal weights (ties in
// the quantisation), joint indices in every slot.
SkinnedMesh RandomMesh(std::size_t n, int slots, bool normals, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coordinate(-2.0f, 2.0f), weight(0.05f, 1.0f);
  std::uniform_int_distribution<int> joint(0, kJoints - 1);
  SkinnedMesh mesh;
  mesh.name = "random";
  mesh.influences = slots;
  mesh.joint_count = kJoints;
  const auto b = static_cast<std::size_t>(slots);
  for (std::size_t v = 0; v < n; ++v) {
    mesh.positions.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
    if (normals) mesh.normals.push_back(glm::normalize(glm::vec3(coordinate(rng), coordinate(rng), 1.0f)));
    if (normals) mesh.tangents.emplace_back(glm::normalize(glm::vec3(1.0f, coordinate(rng), coordinate(rng))), v % 3 ? 1.0f : -1.0f);
    const int count = 1 + static_cast<int>(v % b);
    std::vector<int> order(b);
    for (std::size_t i = 0; i < b; ++i) order[i] = static_cast<int>(i);
    if (v % 3 == 1) std::shuffle(order.begin(), order.end(), rng);  // non-zero weights not only in the first slots
    std::vector<float> w(b, 0.0f);
    float sum = 0.0f;
    const auto slot = [&](int c) { return static_cast<std::size_t>(order[static_cast<std::size_t>(c)]); };
    if (count >= 3 && (v % 7 == 3 || v % 7 == 4)) {
      // Two equal weights a little below a quantum's half and a third one: rounding leaves one quantum
      // to give away, and the two equal residues tie (unorm8: 50.4, 50.4, 154.2 of 255; unorm16: 13107.4,
      // 13107.4, 39320.2 of 65535): the earlier slot gets it.
      const bool eight = v % 7 == 3;
      w[slot(0)] = w[slot(1)] = eight ? 50.4f : 13107.4f;
      w[slot(2)] = eight ? 154.2f : 39320.2f;
      sum = 2 * w[slot(0)] + w[slot(2)];
    } else {
      for (int c = 0; c < count; ++c) {
        w[slot(c)] = v % 5 == 2 ? 1.0f : weight(rng);  // every fifth vertex: equal weights, ties when quantised
        sum += w[slot(c)];
      }
    }
    for (std::size_t i = 0; i < b; ++i) {
      mesh.weights.push_back(w[i] / sum);
      mesh.joints.push_back(static_cast<std::uint16_t>(joint(rng)));
    }
  }
  return mesh;
}

// Random morph targets for `mesh`: every other target sparse (a tenth of
// the vertices), offsets of every magnitude a half holds, some exactly half
// way between two halves (ties to even), normal and tangent offsets where
// the mesh has them, one target of normal offsets alone.
MorphTargets RandomMorph(const SkinnedMesh& mesh, int targets, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> offset(-0.3f, 0.3f);
  std::uniform_int_distribution<int> exponent(-26, 15);
  MorphTargets m;
  const std::size_t n = mesh.vertex_count();
  for (int t = 0; t < targets; ++t) {
    m.positions.emplace_back(n, glm::vec3(0.0f));
    if (mesh.has_normals()) m.normals.emplace_back(n, glm::vec3(0.0f));
    if (mesh.has_tangents()) m.tangents.emplace_back(n, glm::vec3(0.0f));
    for (std::size_t v = 0; v < n; ++v) {
      if (t % 2 == 1 && v % 10 != static_cast<std::size_t>(t)) continue;
      if (t != 2) {
        glm::vec3 d(offset(rng), std::ldexp(offset(rng), exponent(rng)), offset(rng));
        if (v % 13 == 0) d.z = 1.0f + 1.0f / 2048.0f;  // halfway between two halves: ties to even
        m.positions[static_cast<std::size_t>(t)][v] = d;
      }
      if (mesh.has_normals()) m.normals[static_cast<std::size_t>(t)][v] = glm::vec3(offset(rng), 0.0f, offset(rng));
      if (mesh.has_tangents()) m.tangents[static_cast<std::size_t>(t)][v] = glm::vec3(0.0f, offset(rng), 0.0f);
    }
    m.weights.push_back(0.5);
  }
  m.where = "random morph targets";
  return m;
}

// Target after target, 3 floats a vertex, as PackMorphTargets takes them.
std::vector<float> Flat(const std::vector<std::vector<glm::vec3>>& targets) {
  std::vector<float> out;
  for (const std::vector<glm::vec3>& target : targets)
    for (const glm::vec3& d : target) out.insert(out.end(), {d.x, d.y, d.z});
  return out;
}

void ExpectPackedLikeSkintune(const fk::Kernel& k, SkinnedMesh mesh) {
  const Variant v = VariantOf(k);
  const testing::MeshArrays a = testing::ArraysOf(mesh);
  fk::PackedInputs packed;
  std::string error;
  ASSERT_TRUE(fk::PackMesh(k, mesh.vertex_count(), mesh.influences, a.positions.data(),
                           a.normals.empty() ? nullptr : a.normals.data(),
                           a.tangents.empty() ? nullptr : a.tangents.data(), a.joints.data(), a.weights.data(),
                           &packed, &error))
      << error;
  if (k.morph != fk::Morph::kNone) {
    mesh.morph = RandomMorph(mesh, k.morph_targets, static_cast<unsigned>(mesh.vertex_count()));
    const std::vector<float> positions = Flat(mesh.morph.positions), normals = Flat(mesh.morph.normals),
                             tangents = Flat(mesh.morph.tangents);
    ASSERT_TRUE(fk::PackMorphTargets(k, mesh.vertex_count(), k.morph_targets, positions.data(),
                                     normals.empty() ? nullptr : normals.data(),
                                     tangents.empty() ? nullptr : tangents.data(), &packed, &error))
        << error;
  }
  const PackedMesh want = Pack(mesh, v);
  ASSERT_EQ(want.launches.size(), 1u);
  testing::ExpectInputsOf(packed, want.launches[0]);
}

TEST(EmbedHeader, PackMeshIsByteIdenticalToTheSkintunePackerForEveryKernel) {
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    SCOPED_TRACE(Context(k));
    // 1001 vertices: not a multiple of any slot stride or work-group size.
    ExpectPackedLikeSkintune(k, RandomMesh(1001, k.influences, k.normals, 7u + static_cast<unsigned>(i)));
  }
}

TEST(EmbedHeader, PackMeshPadsAMeshWithFewerSlotsThanTheKernelLikeThePacker) {
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    if (k.influences < 2) continue;
    SCOPED_TRACE(Context(k));
    ExpectPackedLikeSkintune(k, RandomMesh(300, k.influences - 1, k.normals, 100u + static_cast<unsigned>(i)));
    ExpectPackedLikeSkintune(k, RandomMesh(5, 1, k.normals, 200u + static_cast<unsigned>(i)));
  }
}

// A dual-quaternion kernel's palette: rigid matrices as the packer's dual
// quaternions, identities after them, and a matrix that scales refused.
TEST(EmbedHeader, PackPaletteIsThePackersPaletteFilledUpWithIdentities) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> value(-3.0f, 3.0f);
  std::vector<glm::mat4> general(kJoints), rigid(kJoints);
  for (std::size_t j = 0; j < general.size(); ++j) {
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) general[j][c][r] = value(rng);
    const glm::vec3 axis = glm::normalize(glm::vec3(value(rng), value(rng), value(rng)) + glm::vec3(0, 0, 0.01f));
    rigid[j] = glm::rotate(glm::mat4(1.0f), value(rng), axis);
    rigid[j][3] = glm::vec4(value(rng), value(rng), value(rng), 1.0f);
  }
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    const Variant v = VariantOf(k);
    SCOPED_TRACE(Context(k));
    const bool dq = k.palette == fk::PaletteFormat::kDualquat;
    std::vector<glm::mat4>& matrices = dq ? rigid : general;
    if (dq) {
      std::vector<glm::mat4> scaled = rigid;
      scaled[7] = glm::scale(scaled[7], glm::vec3(1.0f, 1.5f, 1.0f));
      EXPECT_TRUE(fk::PackPalette(k, &scaled[0][0][0], kJoints).empty()) << "a scaled joint as a dual quaternion";
    }
    for (const int joints : {kJoints, 50, 1, 0}) {
      std::vector<glm::mat4> full(matrices.begin(), matrices.begin() + joints);
      full.resize(kJoints, glm::mat4(1.0f));
      const std::vector<std::uint8_t> want = PackPalette(full, v);
      const std::vector<float> got = fk::PackPalette(k, &matrices[0][0][0], joints);
      ASSERT_EQ(got.size() * sizeof(float), want.size()) << joints;
      EXPECT_EQ(std::memcmp(got.data(), want.data(), want.size()), 0) << joints;
    }
    EXPECT_TRUE(fk::PackPalette(k, &matrices[0][0][0], kJoints + 1).empty());
    EXPECT_TRUE(fk::PackPalette(k, &matrices[0][0][0], -1).empty());
    EXPECT_TRUE(fk::PackPalette(k, nullptr, 3).empty());
  }
}

TEST(EmbedHeader, UnpackPositionsReadsTheOutputLikeTheUnpacker) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> value(-10.0f, 10.0f);
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    SCOPED_TRACE(Context(k));
    SkinnedMesh mesh = RandomMesh(97, k.influences, k.normals, 5);
    if (k.morph != fk::Morph::kNone) mesh.morph = RandomMorph(mesh, k.morph_targets, 5);
    const PackedMesh packed = Pack(mesh, VariantOf(k));
    std::vector<float> output(mesh.vertex_count() * fk::OutputStrideBytes(k) / sizeof(float));
    for (float& f : output) f = value(rng);
    std::vector<std::uint8_t> bytes(output.size() * sizeof(float));
    std::memcpy(bytes.data(), output.data(), bytes.size());
    const std::vector<glm::vec3> want = Unpack(packed, bytes);
    std::vector<float> got(3 * mesh.vertex_count(), -1.0f);
    fk::UnpackPositions(k, output.data(), mesh.vertex_count(), got.data());
    for (std::size_t v = 0; v < want.size(); ++v) {
      EXPECT_EQ(got[3 * v], want[v].x) << v;
      EXPECT_EQ(got[3 * v + 1], want[v].y) << v;
      EXPECT_EQ(got[3 * v + 2], want[v].z) << v;
    }
  }
}

// ------------------------------------------------------------------ PackMesh errors

const fk::Kernel& KernelWith(const std::string& key_part) {
  for (int i = 0; i < fk::kKernelCount; ++i) {
    if (std::string(fk::kKernels[i].variant).find(key_part) != std::string::npos) return fk::kKernels[i];
  }
  throw Error("no fixture kernel with " + key_part);
}

// PackMesh's error for one bad input, the output cleared.
std::string PackError(const fk::Kernel& k, std::size_t n, int influences, const float* positions, const float* normals,
                      const std::uint32_t* joints, const float* weights) {
  fk::PackedInputs out;
  out.records.assign(8, 1);
  out.positions.assign(8, 1);
  std::string error;
  const bool ok = fk::PackMesh(k, n, influences, positions, normals, joints, weights, &out, &error);
  EXPECT_FALSE(ok);
  EXPECT_TRUE(out.records.empty() && out.positions.empty() && out.indices.empty() && out.weights.empty() &&
              out.normals.empty());
  EXPECT_EQ(fk::PackMesh(k, n, influences, positions, normals, joints, weights, &out, nullptr), false);
  return error;
}

TEST(EmbedHeader, PackMeshRefusesMoreInfluencesThanTheKernelHas) {
  const fk::Kernel& k = KernelWith("opencl.b2.");
  const std::vector<float> p(9, 0.0f), n(9, 0.0f), w(9, 1.0f / 3.0f);
  const std::vector<std::uint32_t> j(9, 0);
  EXPECT_EQ(PackError(k, 3, 3, p.data(), n.data(), j.data(), w.data()),
            std::string("PackMesh ") + k.variant + ": influences 3 outside 1..2 (the kernel's B)");
  EXPECT_NE(PackError(k, 3, 0, p.data(), n.data(), j.data(), w.data()).find("influences 0 outside 1..2"),
            std::string::npos);
}

TEST(EmbedHeader, PackMeshRefusesAJointTheIndexFormatCannotHold) {
  const std::vector<float> p(6, 0.0f), n(6, 0.0f), w(2, 1.0f);
  const fk::Kernel& u8 = KernelWith("opencl.b1.padded.aos.float3.u8");
  EXPECT_NE(PackError(u8, 2, 1, p.data(), n.data(), std::vector<std::uint32_t>{3, 256}.data(), w.data())
                .find("vertex 1 slot 0: joint 256 does not fit u8 indices (at most 255)"),
            std::string::npos);
  const fk::Kernel& u16 = KernelWith(".u16.");
  EXPECT_NE(PackError(u16, 2, 1, p.data(), n.data(), std::vector<std::uint32_t>{65536, 0}.data(), w.data())
                .find("vertex 0 slot 0: joint 65536 does not fit u16 indices (at most 65535)"),
            std::string::npos);
  const fk::Kernel& i32 = KernelWith(".i32.");
  EXPECT_NE(PackError(i32, 2, 1, p.data(), n.data(), std::vector<std::uint32_t>{0, 0x80000000u}.data(), w.data())
                .find("joint 2147483648 does not fit i32 indices"),
            std::string::npos);
}

TEST(EmbedHeader, PackMeshRefusesAJointBeyondTheKernelsPalette) {
  const fk::Kernel& k = KernelWith(".u16.");
  const std::vector<float> p(6, 0.0f), n(6, 0.0f), w(2 * static_cast<std::size_t>(k.influences), 0.5f);
  std::vector<std::uint32_t> j(2 * static_cast<std::size_t>(k.influences), 76);  // 76 < 77: fine
  fk::PackedInputs out;
  EXPECT_TRUE(fk::PackMesh(k, 2, k.influences, p.data(), n.data(), j.data(), w.data(), &out, nullptr));
  j.back() = 77;
  EXPECT_NE(PackError(k, 2, k.influences, p.data(), n.data(), j.data(), w.data())
                .find("joint 77 out of range (the kernel has 77 joints)"),
            std::string::npos);
}

TEST(EmbedHeader, PackMeshRefusesMissingNormalsOnlyWhenTheKernelSkinsThem) {
  const std::vector<float> p(3, 0.0f), w = {1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  const std::vector<std::uint32_t> j(8, 0);
  const fk::Kernel& with = KernelWith("opencl.b2.padded.soa-split.float4.u16.unorm16.mat4.local.point.v2c.wg128.");
  EXPECT_NE(PackError(with, 1, 1, p.data(), nullptr, j.data(), w.data()).find("normals is null"), std::string::npos);
  const fk::Kernel& without = KernelWith("opencl.b8.");
  fk::PackedInputs out;
  std::string error;
  EXPECT_TRUE(fk::PackMesh(without, 1, 1, p.data(), nullptr, j.data(), w.data(), &out, &error)) << error;
  EXPECT_TRUE(out.normals.empty());
}

TEST(EmbedHeader, PackMeshRefusesMissingTangentsWhenTheKernelSkinsThem) {
  const std::vector<float> p(3, 0.0f), n = {0.0f, 0.0f, 1.0f}, t = {1.0f, 0.0f, 0.0f, -1.0f};
  const std::vector<float> w = {1.0f, 0.0f, 0.0f, 0.0f};
  const std::vector<std::uint32_t> j(4, 0);
  const fk::Kernel& with = KernelWith("glsl-compute.b4.padded.aos.float4.u16.unorm8.mat4.global.matrix.v2s.wg64.tangents");
  fk::PackedInputs out;
  std::string error;
  EXPECT_FALSE(fk::PackMesh(with, 1, 1, p.data(), n.data(), j.data(), w.data(), &out, &error));
  EXPECT_NE(error.find("tangents is null"), std::string::npos) << error;
  EXPECT_TRUE(fk::PackMesh(with, 1, 1, p.data(), n.data(), t.data(), j.data(), w.data(), &out, &error)) << error;
  ASSERT_FALSE(out.records.empty());
  float w_out = 0.0f;  // the handedness, the record's last float of the tangent
  std::memcpy(&w_out, out.records.data() + out.records.size() - 4, 4);
  EXPECT_EQ(w_out, -1.0f);
}

TEST(EmbedHeader, PackMeshRefusesNullPointersAndAnEmptyMesh) {
  const fk::Kernel& k = KernelWith("opencl.b1.");
  const float p[3] = {}, w[1] = {1.0f};
  const std::uint32_t j[1] = {0};
  EXPECT_NE(PackError(k, 1, 1, nullptr, nullptr, j, w).find("positions is null"), std::string::npos);
  EXPECT_NE(PackError(k, 1, 1, p, nullptr, nullptr, w).find("joints is null"), std::string::npos);
  EXPECT_NE(PackError(k, 1, 1, p, nullptr, j, nullptr).find("weights is null"), std::string::npos);
  EXPECT_NE(PackError(k, 0, 1, p, nullptr, j, w).find("no vertices"), std::string::npos);
  std::string error;
  EXPECT_FALSE(fk::PackMesh(k, 1, 1, p, nullptr, j, w, nullptr, &error));
  EXPECT_NE(error.find("out is null"), std::string::npos) << error;
}

// The contract's weights: finite, non-negative, not all zero per vertex. A
// negative weight was left out of the sum ([-0.1, 0.6, 0.5] packed to
// [0, 139, 116]) and an all-zero vertex packed to zeros that do not sum to M.
TEST(EmbedHeader, PackMeshRefusesANegativeOrNonFiniteWeightAndAVertexOfZeroWeights) {
  const float p[6] = {};
  const std::uint32_t j[6] = {};
  for (const char* key : {".unorm8.", ".unorm16.", ".f32."}) {
    const fk::Kernel& k = KernelWith(key);
    if (k.influences < 3) continue;
    SCOPED_TRACE(k.variant);
    const float negative[6] = {0.2f, 0.3f, 0.5f, -0.1f, 0.6f, 0.5f};
    EXPECT_NE(PackError(k, 2, 3, p, p, j, negative).find(": vertex 1 slot 0: weight -0.1 is negative"), std::string::npos);
    const float nan[6] = {0.2f, std::nanf(""), 0.8f, 1.0f, 0.0f, 0.0f};
    EXPECT_NE(PackError(k, 2, 3, p, p, j, nan).find(": vertex 0 slot 1: weight nan is not finite"), std::string::npos);
    const float inf[6] = {1.0f, 0.0f, 0.0f, 0.0f, 0.0f, HUGE_VALF};
    EXPECT_NE(PackError(k, 2, 3, p, p, j, inf).find(": vertex 1 slot 2: weight inf is not finite"), std::string::npos);
    const float zero[6] = {0.5f, 0.5f, 0.0f, 0.0f, 0.0f, 0.0f};
    EXPECT_NE(PackError(k, 2, 3, p, p, j, zero).find(": vertex 1: all weights are zero"), std::string::npos);
  }
}

// docs/VARIANTS.md's quantisation rule, written from its text alone (not from
// the header's or the packer's code): every step one double operation, the
// missing quanta to the largest remainders by a stable sort.
std::vector<std::uint32_t> DocumentedQuantisation(const float* w, int b, std::uint32_t m) {
  double s = 0.0;
  for (int i = 0; i < b; ++i) s = s + static_cast<double>(w[i]);
  std::vector<std::uint32_t> q(static_cast<std::size_t>(b));
  std::vector<double> r(static_cast<std::size_t>(b));
  std::uint64_t total = 0;
  for (int i = 0; i < b; ++i) {
    const double t = (static_cast<double>(w[i]) / s) * static_cast<double>(m);
    q[i] = static_cast<std::uint32_t>(std::floor(t));
    r[i] = t - std::floor(t);
    total += q[i];
  }
  std::vector<int> nonzero;
  for (int i = 0; i < b; ++i)
    if (w[i] != 0.0f) nonzero.push_back(i);
  std::stable_sort(nonzero.begin(), nonzero.end(), [&](int x, int y) { return r[x] > r[y]; });
  const std::uint64_t missing = m - total;
  EXPECT_LE(missing, nonzero.size());
  for (std::uint64_t d = 0; d < missing && d < nonzero.size(); ++d) ++q[nonzero[d]];
  return q;
}

// The rule's words, from "In IEEE 754" to "A zero weight stays 0.", with
// comment markers and line breaks reduced to single spaces.
std::string RuleWords(const std::string& text, const std::string& where) {
  std::string flat;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    std::size_t at = line.find_first_not_of(" \t");
    if (at != std::string::npos && line.compare(at, 2, "//") == 0) at = line.find_first_not_of(" \t", at + 2);
    if (at != std::string::npos) flat += line.substr(at) + " ";
  }
  const std::size_t begin = flat.find("In IEEE 754");
  const std::string end_words = "A zero weight stays 0.";
  const std::size_t end = flat.find(end_words, begin);
  EXPECT_NE(begin, std::string::npos) << where << " does not state the rule";
  EXPECT_NE(end, std::string::npos) << where << " does not state the rule to its end";
  if (begin == std::string::npos || end == std::string::npos) return "";
  std::string words;
  for (const char c : flat.substr(begin, end + end_words.size() - begin))
    if (c != ' ' || (!words.empty() && words.back() != ' ')) words += c;
  return words;
}

// VARIANTS.md says its rule is copied word for word into the header's
// QuantiseVertex and the sidecar's weights.rule: one rule, three places.
TEST(EmbedHeader, TheQuantisationRuleReadsTheSameInTheDocsTheHeaderAndTheSidecar) {
  auto read = [](const std::string& file) {
    std::ifstream in(std::string(SKINTUNE_SOURCE_DIR) + "/" + file);
    EXPECT_TRUE(in) << file;
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string docs = RuleWords(read("docs/VARIANTS.md"), "docs/VARIANTS.md");
  ASSERT_FALSE(docs.empty());
  EXPECT_EQ(RuleWords(read("templates/embedded_support.h"), "templates/embedded_support.h"), docs);
  const Variant v = ParseVariantKey("opencl.b4.padded.soa.float4.u16.unorm16");
  const std::string sidecar = SidecarJson(Emit(v), v).at("weights").at("rule").get<std::string>();
  EXPECT_EQ(RuleWords(sidecar, "the sidecar's weights.rule"), docs);
}

TEST(EmbedHeader, AFloat64ReimplementationOfTheDocumentedRuleIsBitIdenticalToPackMeshAndPack) {
  std::mt19937 rng(2026);
  std::uniform_real_distribution<float> any(0.0f, 1.0f);
  std::uniform_int_distribution<int> kind(0, 5), slots(1, 8), quanta(0, 255);
  std::size_t differ_header = 0, differ_packer = 0, vertices = 0;
  for (const std::uint32_t m : {255u, 65535u}) {
    // A million vertices through the header's rule, B = 1..8 (the header's limit).
    for (int v = 0; v < 500000; ++v) {
      const int b = slots(rng);
      float w[8] = {};
      const int k = kind(rng);
      for (int i = 0; i < b; ++i) {
        if (k == 0) w[i] = 1.0f;                                   // all equal: every remainder ties
        if (k == 1) w[i] = static_cast<float>(quanta(rng)) / 255;  // multiples of 1/255, some zero
        if (k == 2) w[i] = any(rng) < 0.3f ? 0.0f : any(rng);      // zeros among them
        if (k == 3) w[i] = any(rng) * 1e-30f;                      // tiny, unnormalised
        if (k >= 4) w[i] = any(rng);
      }
      if (std::all_of(w, w + b, [](float x) { return x == 0.0f; })) w[b - 1] = 1.0f;
      std::uint32_t header[8] = {};
      fk::detail::QuantiseVertex(w, b, m, header);
      const std::vector<std::uint32_t> want = DocumentedQuantisation(w, b, m);
      differ_header += !std::equal(want.begin(), want.end(), header);
      ++vertices;
    }
    // skintune's packer on a mesh of normalised weights (QuantisedMesh gives q / M as float).
    for (int b = 1; b <= 4; ++b) {
      SkinnedMesh mesh = RandomMesh(20000, b, false, 300u + m + static_cast<unsigned>(b));
      Variant variant = ParseVariantKey("opencl.b" + std::to_string(b));
      variant.weight = m == 255u ? WeightFormat::kUnorm8 : WeightFormat::kUnorm16;
      const SkinnedMesh quantised = QuantisedMesh(mesh, variant);
      for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
        const std::vector<std::uint32_t> want = DocumentedQuantisation(&mesh.weights[v * b], b, m);
        for (int i = 0; i < b; ++i)
          differ_packer += std::lround(static_cast<double>(quantised.weights[v * b + i]) * m) != want[i];
      }
    }
  }
  EXPECT_EQ(vertices, 1000000u);
  EXPECT_EQ(differ_header, 0u);
  EXPECT_EQ(differ_packer, 0u);
}

// ------------------------------------------------------------------ FindKernel

int IndexOf(const fk::Kernel* k) { return k == nullptr ? -1 : static_cast<int>(k - fk::kKernels); }

// The fixture's index of the winner (lang, B, bucket) of the database.
int EntryIndex(const std::string& lang, int influences, const std::string& bucket) {
  const std::vector<WinnersEntry>& entries = Fixture();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (skintune::internal::Name(entries[i].lang) == lang && entries[i].influences == influences &&
        entries[i].vertex_bucket == bucket)
      return static_cast<int>(i);
  }
  return -2;
}

// docs/VARIANTS.md "Dual quaternions", steps 1 to 4, written from the text
// alone: the bytes of one joint's dual quaternion. `branch` receives which
// case of step 1 ran (0: T > 0, 1 to 3: the largest diagonal element).
std::array<float, 8> DocumentedDualQuaternion(const glm::mat4& m, int* branch) {
  const auto a = [&](int r, int c) { return static_cast<double>(m[c][r]); };
  const double tx = m[3][0], ty = m[3][1], tz = m[3][2];
  double x, y, z, w;
  const double t = (a(0, 0) + a(1, 1)) + a(2, 2);
  if (t > 0) {
    const double s = std::sqrt(t + 1) * 2;
    w = 0.25 * s, x = (a(2, 1) - a(1, 2)) / s, y = (a(0, 2) - a(2, 0)) / s, z = (a(1, 0) - a(0, 1)) / s;
    *branch = 0;
  } else if (a(0, 0) > a(1, 1) && a(0, 0) > a(2, 2)) {
    const double s = std::sqrt(((1 + a(0, 0)) - a(1, 1)) - a(2, 2)) * 2;
    w = (a(2, 1) - a(1, 2)) / s, x = 0.25 * s, y = (a(0, 1) + a(1, 0)) / s, z = (a(0, 2) + a(2, 0)) / s;
    *branch = 1;
  } else if (a(1, 1) > a(2, 2)) {
    const double s = std::sqrt(((1 + a(1, 1)) - a(0, 0)) - a(2, 2)) * 2;
    w = (a(0, 2) - a(2, 0)) / s, x = (a(0, 1) + a(1, 0)) / s, y = 0.25 * s, z = (a(1, 2) + a(2, 1)) / s;
    *branch = 2;
  } else {
    const double s = std::sqrt(((1 + a(2, 2)) - a(0, 0)) - a(1, 1)) * 2;
    w = (a(1, 0) - a(0, 1)) / s, x = (a(0, 2) + a(2, 0)) / s, y = (a(1, 2) + a(2, 1)) / s, z = 0.25 * s;
    *branch = 3;
  }
  const double l = std::sqrt(((x * x + y * y) + z * z) + w * w);
  x /= l, y /= l, z /= l, w /= l;
  const double d[4] = {0.5 * ((w * tx + ty * z) - tz * y), 0.5 * ((w * ty + tz * x) - tx * z),
                       0.5 * ((w * tz + tx * y) - ty * x), -0.5 * ((tx * x + ty * y) + tz * z)};
  return {static_cast<float>(x + 0.0),    static_cast<float>(y + 0.0),    static_cast<float>(z + 0.0),
          static_cast<float>(w + 0.0),    static_cast<float>(d[0] + 0.0), static_cast<float>(d[1] + 0.0),
          static_cast<float>(d[2] + 0.0), static_cast<float>(d[3] + 0.0)};
}

// The outside contract for the dualquat palette: a program written from the
// docs packs the same bytes as skintune's packer and the header, in every case.
TEST(EmbedHeader, AReimplementationOfTheDocumentedDualQuaternionRuleIsBitIdenticalToPackPalette) {
  std::mt19937 rng(2027);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> shift(-100.0, 100.0);
  std::vector<glm::mat4> palette;
  for (int j = 0; j < 20000; ++j) {
    glm::dquat q = glm::normalize(glm::dquat(normal(rng), normal(rng), normal(rng), normal(rng)));
    if (j % 4 == 1) q = glm::normalize(glm::dquat(1e-3 * normal(rng), normal(rng), 0.2 * normal(rng), 0.1));  // near pi
    glm::mat4 m(glm::mat3(glm::mat3_cast(q)));
    m[3] = glm::vec4(static_cast<float>(shift(rng)), static_cast<float>(shift(rng)), static_cast<float>(shift(rng)),
                     1.0f);
    if (j % 97 == 0) m = glm::mat4(1.0f);
    float unused[8];
    if (fk::DualQuaternionOf(&m[0][0], unused)) palette.push_back(m);
  }
  ASSERT_GT(palette.size(), 19000u);
  Variant v;
  v.palette = PaletteFormat::kDualQuaternion;
  v.blend = Blend::kDualQuaternion;
  const std::vector<std::uint8_t> packed = PackPalette(palette, v);
  std::array<std::size_t, 4> branches{};
  std::size_t differ = 0;
  for (std::size_t j = 0; j < palette.size(); ++j) {
    int branch = 0;
    const std::array<float, 8> want = DocumentedDualQuaternion(palette[j], &branch);
    ++branches[static_cast<std::size_t>(branch)];
    differ += std::memcmp(want.data(), packed.data() + 32 * j, 32) != 0 ? 1 : 0;
  }
  EXPECT_EQ(differ, 0u) << "of " << palette.size();
  for (std::size_t b = 0; b < 4; ++b) EXPECT_GT(branches[b], 100u) << "step 1's case " << b << " barely tried";
}

TEST(EmbedHeader, FindKernelTakesTheSmallestInfluenceCountThatHoldsTheMesh) {
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 1, 10, kJoints)), EntryIndex("opencl", 1, "25k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 2, 100000, kJoints)), EntryIndex("opencl", 2, "100k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 3, 100000, kJoints)), EntryIndex("opencl", 4, "100k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 5, 100000, kJoints)), EntryIndex("opencl", 8, "400k"));
  EXPECT_EQ(fk::FindKernel("opencl", 9, 100000, kJoints), nullptr);
  EXPECT_EQ(IndexOf(fk::FindKernel("cuda", 1, 10, kJoints)), EntryIndex("cuda", 2, "25k"));
}

TEST(EmbedHeader, FindKernelTakesTheNearestVertexBucketAndTheLargerOnATie) {
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 4, 150000, kJoints)), EntryIndex("opencl", 4, "100k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 4, 49999, kJoints)), EntryIndex("opencl", 4, "100k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 4, 2000000, kJoints)), EntryIndex("opencl", 4, "1600k"));
  // 400k is one bucket from both 100k and 1600k: the larger wins.
  EXPECT_EQ(IndexOf(fk::FindKernel("opencl", 4, 400000, kJoints)), EntryIndex("opencl", 4, "1600k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("cuda", 3, 400000, kJoints)), EntryIndex("cuda", 3, "1600k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("cuda", 3, 199999, kJoints)), EntryIndex("cuda", 3, "100k"));
}

TEST(EmbedHeader, FindKernelNeedsAKernelSpecialisedForAtLeastTheJointCount) {
  EXPECT_EQ(IndexOf(fk::FindKernel("glsl-vertex", 2, 1000, kJoints)), EntryIndex("glsl-vertex", 2, "25k"));
  EXPECT_EQ(IndexOf(fk::FindKernel("glsl-vertex", 2, 1000, 1)), EntryIndex("glsl-vertex", 2, "25k"));
  EXPECT_EQ(fk::FindKernel("glsl-vertex", 2, 1000, kJoints + 1), nullptr);
}

// A dual-quaternion winner serves FindDualQuaternionKernel only, never the linear FindKernel.
TEST(EmbedHeader, DualQuaternionKernelsAreFoundOnlyWhenAskedFor) {
  const fk::Kernel* dq = fk::FindDualQuaternionKernel("cuda", 2, 100000, 40);
  ASSERT_NE(dq, nullptr);
  EXPECT_EQ(dq->palette, fk::PaletteFormat::kDualquat);
  for (int b = 1; b <= 8; ++b) {
    const fk::Kernel* linear = fk::FindKernel("cuda", b, 100000, 40);
    if (linear) {
      EXPECT_NE(linear->palette, fk::PaletteFormat::kDualquat) << b;
    }
  }
  EXPECT_EQ(fk::FindDualQuaternionKernel("opencl", 2, 100000, 40), nullptr);
}

// Morph kernels only where asked for, and only for the target count they
// were specialised for; the other finders never return one.
TEST(EmbedHeader, MorphKernelsAreFoundOnlyForTheirTargetCount) {
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    if (k.morph == fk::Morph::kNone) continue;
    SCOPED_TRACE(Context(k));
    const fk::Kernel* found = fk::FindMorphKernel(k.lang, k.influences, k.vertices, kJoints, kFixtureMorphTargets);
    ASSERT_NE(found, nullptr);
    EXPECT_NE(found->morph, fk::Morph::kNone);
    EXPECT_EQ(found->morph_targets, kFixtureMorphTargets);
    EXPECT_EQ(fk::FindMorphKernel(k.lang, k.influences, k.vertices, kJoints, kFixtureMorphTargets + 1), nullptr);
    EXPECT_EQ(fk::FindMorphKernel(k.lang, k.influences, k.vertices, kJoints, 0), nullptr);
  }
  for (const char* lang : {"opencl", "cuda", "glsl-compute", "glsl-vertex"})
    for (int b = 1; b <= 8; ++b) {
      const fk::Kernel* plain = fk::FindKernel(lang, b, 100000, kJoints);
      if (plain != nullptr) {
        EXPECT_EQ(plain->morph, fk::Morph::kNone) << plain->variant;
      }
    }
}

// Packed-normal kernels only where asked for, by their format; the other
// finders never return one. Their outputs are one word a vertex, which
// UnpackNormals / UnpackTangents decode by the rule the packer runs.
TEST(EmbedHeader, PackedNormalKernelsAreFoundOnlyForTheirFormatAndDecodeByTheRule) {
  int packed = 0;
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    SCOPED_TRACE(Context(k));
    EXPECT_EQ(static_cast<int>(k.normal_format), static_cast<int>(ParseVariantKey(k.variant).normal_format));
    if (k.normal_format == fk::NormalFormat::kF32) continue;
    ++packed;
    const fk::Kernel* found = fk::FindPackedNormalsKernel(k.lang, k.influences, k.vertices, kJoints, k.normal_format);
    ASSERT_NE(found, nullptr);
    EXPECT_EQ(found->normal_format, k.normal_format);
    EXPECT_EQ(fk::NormalStrideBytes(k), 4u);
    EXPECT_EQ(fk::TangentStrideBytes(k), 4u);
    const fk::Kernel* plain = fk::FindKernel(k.lang, k.influences, k.vertices, kJoints);
    if (plain != nullptr) {
      EXPECT_EQ(plain->normal_format, fk::NormalFormat::kF32) << plain->variant;
    }
  }
  EXPECT_EQ(packed, 2) << "the fixture's oct16 and snorm8 winners";
  const fk::Kernel* oct = fk::FindPackedNormalsKernel("opencl", 4, 100000, kJoints, fk::NormalFormat::kOct16);
  ASSERT_NE(oct, nullptr);
  const NormalFormat format = NormalFormat::kOct16;
  const std::vector<glm::vec3> normals = {{0, 0, 1}, glm::normalize(glm::vec3(0.3f, -0.8f, -0.2f)), {-1, 0, 0}};
  std::vector<std::uint32_t> words;
  for (const glm::vec3& n : normals) words.push_back(PackedNormalWord(format, n));
  std::vector<float> xyz(3 * normals.size());
  fk::UnpackNormals(*oct, words.data(), normals.size(), xyz.data());
  for (std::size_t v = 0; v < normals.size(); ++v) {
    EXPECT_EQ(glm::vec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]), UnpackedNormal(format, words[v]));
    EXPECT_LT(glm::length(glm::vec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]) - normals[v]), NormalFormatBound(format));
  }
  const std::uint32_t tangent = PackedTangentWord(format, {0.6f, 0.8f, 0.0f, -1.0f});
  float t[4];
  fk::UnpackTangents(*oct, &tangent, 1, t);
  EXPECT_EQ(t[3], -1.0f);
  EXPECT_EQ(fk::FindPackedNormalsKernel("opencl", 4, 100000, kJoints, fk::NormalFormat::kF32),
            fk::FindKernel("opencl", 4, 100000, kJoints));
}

// The header's float-to-half rule (detail::HalfBits, plain C++17, which
// skintune's packer calls too) gives the bits of the compiler's own
// conversion (_Float16) for every float class: normals, subnormals of the
// half, ties, overflow.
TEST(EmbedHeader, HalfBitsIsTheIeeeConversionToBinary16) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<std::uint32_t> bits;
  std::size_t checked = 0;
  const auto check = [&](float f) {
    if (!std::isfinite(f)) return;
    ASSERT_EQ(fk::detail::HalfBits(f), std::bit_cast<std::uint16_t>(static_cast<_Float16>(f))) << f;
    ASSERT_EQ(HalfBits(f), fk::detail::HalfBits(f)) << f;
    ++checked;
  };
  for (int i = 0; i < 200000; ++i) check(std::bit_cast<float>(bits(rng)));
  for (int e = -30; e <= 17; ++e)
    for (int m = 0; m < 2048; ++m) {
      const float f = std::ldexp(1.0f + static_cast<float>(m) / 2048.0f, e);  // every tie of this binade
      check(f);
      check(-f);
      check(std::nextafter(f, 0.0f));
      check(std::nextafter(f, 1e30f));
    }
  check(65504.0f);
  check(65519.99f);
  check(65520.0f);
  check(0.0f);
  check(-0.0f);
  EXPECT_GT(checked, 300000u);
}

// PackMorphTargets names what it refuses.
TEST(EmbedHeader, PackMorphTargetsRefusesWhatDoesNotFitNamingIt) {
  const fk::Kernel* morph = nullptr;
  const fk::Kernel* plain = nullptr;
  for (int i = 0; i < fk::kKernelCount; ++i) {
    const fk::Kernel& k = fk::kKernels[i];
    if (k.morph == fk::Morph::kDenseHalf || k.morph == fk::Morph::kSparseHalf) morph = &k;
    if (k.morph == fk::Morph::kNone) plain = &k;
  }
  ASSERT_NE(morph, nullptr);
  ASSERT_NE(plain, nullptr);
  fk::PackedInputs out;
  std::string error;
  std::vector<float> offsets(static_cast<std::size_t>(kFixtureMorphTargets) * 10 * 3, 0.0f);
  EXPECT_FALSE(fk::PackMorphTargets(*plain, 10, kFixtureMorphTargets, offsets.data(), nullptr, nullptr, &out, &error));
  EXPECT_NE(error.find("the kernel applies no morph targets"), std::string::npos) << error;
  EXPECT_FALSE(fk::PackMorphTargets(*morph, 10, 3, offsets.data(), nullptr, nullptr, &out, &error));
  EXPECT_NE(error.find("3 morph targets, the kernel is specialised for 4"), std::string::npos) << error;
  offsets[(2 * 10 + 7) * 3 + 1] = 70000.0f;
  EXPECT_FALSE(fk::PackMorphTargets(*morph, 10, kFixtureMorphTargets, offsets.data(), nullptr, nullptr, &out, &error));
  EXPECT_NE(error.find("target 2 vertex 7: position offset component 70000"), std::string::npos) << error;
  EXPECT_NE(error.find("rounds to infinity as a half"), std::string::npos) << error;
  offsets[(2 * 10 + 7) * 3 + 1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(fk::PackMorphTargets(*morph, 10, kFixtureMorphTargets, offsets.data(), nullptr, nullptr, &out, &error));
  EXPECT_NE(error.find("is not finite"), std::string::npos) << error;
}

TEST(EmbedHeader, FindKernelReturnsNullForAnUnknownLanguageOrBadArguments) {
  EXPECT_EQ(fk::FindKernel("metal", 1, 1000, kJoints), nullptr);
  EXPECT_EQ(fk::FindKernel("", 1, 1000, kJoints), nullptr);
  EXPECT_EQ(fk::FindKernel(nullptr, 1, 1000, kJoints), nullptr);
  EXPECT_EQ(fk::FindKernel("opencl", 0, 1000, kJoints), nullptr);
  EXPECT_EQ(fk::FindKernel("opencl", 1, 1000, 0), nullptr);
  EXPECT_NE(fk::FindKernel("glsl-compute", 1, 1000, kJoints), nullptr);
}

// ------------------------------------------------------------------ C++17, two units

TEST(EmbedHeader, SecondTranslationUnitSeesTheSameKernelTable) {
  EXPECT_EQ(SecondUnitKernelTable(), fk::kKernels);
  EXPECT_EQ(SecondUnitFindKernel("cuda", 3, 400000, kJoints), fk::FindKernel("cuda", 3, 400000, kJoints));
  EXPECT_NE(SecondUnitFindKernel("cuda", 3, 400000, kJoints), nullptr);
}

fs::path Scratch() { return skintune::internal::testing::ScratchDir("skintune_embed_test"); }

// Runs a shell command; returns its exit code, its output in *log.
int Shell(const std::string& command, const fs::path& log_file, std::string* log) {
  const int status = std::system((command + " > '" + log_file.string() + "' 2>&1").c_str());
  std::ifstream in(log_file);
  std::ostringstream text;
  text << in.rdbuf();
  *log = text.str();
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

const std::string kStrict17 =
    "-std=c++17 -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion -Werror";

TEST(EmbedHeader, CompilesAsCxx17WithWarningsAsErrorsAndLinksTwoUnits) {
  const fs::path dir = Scratch();
  const std::string here = std::string(SKINTUNE_SOURCE_DIR) + "/tests/tools/emit";
  std::string log;
  const std::string compile = std::string("'") + SKINTUNE_CXX_COMPILER + "' " + kStrict17 + " -I'" +
                              SKINTUNE_EMBED_DIR + "' -I'" + here + "' '" + here + "/embed_header_main17.cpp' '" +
                              here + "/embed_header_second_tu.cpp' -o '" + (dir / "two_units").string() + "'";
  ASSERT_EQ(Shell(compile, dir / "compile.log", &log), 0) << compile << "\n" << log;
  EXPECT_EQ(Shell("'" + (dir / "two_units").string() + "'", dir / "run.log", &log), 0) << log;
  fs::remove_all(dir);
}

// `dir`/main.cpp compiled as strict C++17 and run: both must succeed (exit 0).
void CompileAndRunMain(const fs::path& dir) {
  std::string log;
  const std::string compile = std::string("'") + SKINTUNE_CXX_COMPILER + "' " + kStrict17 + " '" +
                              (dir / "main.cpp").string() + "' -o '" + (dir / "main").string() + "'";
  ASSERT_EQ(Shell(compile, dir / "compile.log", &log), 0) << log;
  EXPECT_EQ(Shell("'" + (dir / "main").string() + "'", dir / "run.log", &log), 0) << log;
}

TEST(EmbedHeader, TheTemplateAloneCompilesAsCxx17WithAnEmptyTable) {
  const fs::path dir = Scratch();
  std::ofstream(dir / "main.cpp") << "#include \"" << SKINTUNE_SOURCE_DIR << "/templates/embedded_support.h\"\n"
                                  << "int main() {\n"
                                  << "  static_assert(skintune_kernels::kKernelCount == 0);\n"
                                  << "  return skintune_kernels::FindKernel(\"opencl\", 1, 1, 1) == nullptr ? 0 : 1;\n"
                                  << "}\n";
  CompileAndRunMain(dir);
  fs::remove_all(dir);
}

// ------------------------------------------------------------------ EmbedHeader itself

EmbeddedKernel Embedded(const std::string& key, const std::string& bucket, int joints) {
  EmbeddedKernel k;
  k.variant = ParseVariantKey(key);
  k.entry.device_id = "opencl:P/D/1";
  k.entry.backend = "opencl";
  k.entry.platform = "P";
  k.entry.device_name = "D";
  k.entry.driver_version = "1";
  k.entry.lang = k.variant.lang;
  k.entry.influences = k.variant.influences;
  k.entry.vertex_bucket = bucket;
  k.entry.vertices = NominalVertices(bucket);
  k.entry.dataset = "d";
  k.entry.variant = k.variant;
  k.source = Emit(k.variant, 0, joints);
  return k;
}

TEST(EmbedHeader, FindKernelSkipsKernelsWhoseIndexFormatCannotAddressTheJoints) {
  // skintune emit never embeds such a kernel (it skips it with a warning), so
  // the header is made here: a u8 b1 kernel and an i32 b2 kernel, both for 300 joints.
  EmbedHeaderOptions options;
  options.name_space = "index_test::kernels";
  const std::string header =
      EmbedHeader({Embedded("opencl.b1.u8", "25k", 300), Embedded("opencl.b2.i32", "25k", 300)}, options);
  const fs::path dir = Scratch();
  std::ofstream(dir / "kernels.h") << header;
  std::ofstream(dir / "main.cpp") << R"(#include "kernels.h"
namespace k = index_test::kernels;
int main() {
  if (k::FindKernel("opencl", 1, 1000, 256) != &k::kKernels[0]) return 1;  // u8 addresses 256 joints
  if (k::FindKernel("opencl", 1, 1000, 257) != &k::kKernels[1]) return 2;  // but not 257
  if (k::FindKernel("opencl", 1, 1000, 301) != nullptr) return 3;          // specialised for 300
  return 0;
}
)";
  CompileAndRunMain(dir);
  fs::remove_all(dir);
}

// A vulkan kernel carries its SPIR-V (what vkCreateShaderModule takes), the
// others none; the header still compiles alone as strict C++17.
TEST(EmbedHeader, AVulkanKernelCarriesItsSpirvWords) {
  EmbedHeaderOptions options;
  options.name_space = "spirv_test::kernels";
  const std::string header =
      EmbedHeader({Embedded("vulkan.b2.image.wg64", "25k", 20), Embedded("opencl.b2", "25k", 20)}, options);
  EXPECT_NE(header.find("inline constexpr std::uint32_t kSpirv0[] = {\n    0x07230203u,"), std::string::npos);
  const fs::path dir = Scratch();
  std::ofstream(dir / "kernels.h") << header;
  std::ofstream(dir / "main.cpp") << R"(#include "kernels.h"
namespace k = spirv_test::kernels;
int main() {
  const k::Kernel& vulkan = k::kKernels[0];
  if (vulkan.spirv_words < 5 || vulkan.spirv[0] != 0x07230203u) return 1;
  if (k::kKernels[1].spirv != nullptr || k::kKernels[1].spirv_words != 0) return 2;
  return 0;
}
)";
  CompileAndRunMain(dir);
}

TEST(EmbedHeader, EmbedHeaderPutsTheNamespaceAndOneSourcePerDistinctKernel) {
  EmbedHeaderOptions options;
  options.name_space = "game::gpu";
  const std::string header = EmbedHeader({Embedded("cuda.b2", "25k", 10), Embedded("cuda.b2", "100k", 10),
                                          Embedded("cuda.b3", "25k", 10)},
                                         options);
  EXPECT_NE(header.find("\nnamespace game::gpu {\n"), std::string::npos);
  EXPECT_NE(header.find("}  // namespace game::gpu\n"), std::string::npos);
  EXPECT_EQ(header.find("namespace skintune_kernels"), std::string::npos);
  EXPECT_EQ(header.find("skintune_kernels::"), std::string::npos);
  EXPECT_NE(header.find("inline constexpr int kKernelCount = 3;"), std::string::npos);
  std::size_t sources = 0;
  for (std::size_t at = header.find("inline constexpr char kSource"); at != std::string::npos;
       at = header.find("inline constexpr char kSource", at + 1))
    ++sources;
  EXPECT_EQ(sources, 2u);
  EXPECT_EQ(header.find("skintune:kernel-table-begin"), std::string::npos);
}

TEST(EmbedHeader, EmbedHeaderRefusesNoKernelsABucketedKernelAnUnspecialisedOneAndABadNamespace) {
  const auto error = [](const std::vector<EmbeddedKernel>& kernels, const std::string& name_space) {
    EmbedHeaderOptions options;
    options.name_space = name_space;
    try {
      EmbedHeader(kernels, options);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error({}, "a"), "embed header: no kernels");
  EmbeddedKernel bucketed = Embedded("opencl.b2", "25k", 10);
  bucketed.variant.mixed = MixedCounts::kBucketed;
  EXPECT_NE(error({bucketed}, "a").find("is not padded"), std::string::npos);
  EmbeddedKernel unspecialised = Embedded("opencl.b2", "25k", 10);
  unspecialised.source = Emit(unspecialised.variant);
  EXPECT_NE(error({unspecialised}, "a").find("not specialised for a joint count"), std::string::npos);
  EXPECT_NE(error({Embedded("opencl.b2", "25k", 10)}, "a b").find("'a b' is not a C++ namespace name"),
            std::string::npos);
  EXPECT_EQ(error({Embedded("opencl.b2", "25k", 10)}, "a::b"), "");
}

TEST(EmbedHeader, NamespaceNamesAreIdentifiersJoinedByColonsAndNoKeywords) {
  for (const char* good : {"a", "skintune_kernels", "game::gpu::kernels", "_x", "K9"}) {
    EXPECT_TRUE(IsCppNamespaceName(good)) << good;
  }
  for (const char* bad : {"", "9a", "a::", "::a", "a:::b", "a b", "a-b", "class", "a::int", "a__b", "_X", "std",
                          "é"}) {
    EXPECT_FALSE(IsCppNamespaceName(bad)) << bad;
  }
}

TEST(EmbedHeader, EscapingKeepsEveryByteAndFormsNoTrigraph) {
  EXPECT_EQ(CppEscaped("a\"b\\c\n\t\r"), "a\\\"b\\\\c\\n\\t\\r");
  EXPECT_EQ(CppEscaped("?\?=?\?/"), "?\\?=?\\?/");  // "??=??/"
  EXPECT_EQ(CppEscaped("???"), "?\\?\\?");
  EXPECT_EQ(CppEscaped(std::string("\x01\x7f\xc3\xa9" "7", 5)), "\\001\\177\\303\\2517");
  EXPECT_EQ(CppEscaped("plain text 123"), "plain text 123");
}

}  // namespace
}  // namespace skintune::internal
