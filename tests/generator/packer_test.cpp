// Pack / PackPalette / Unpack / QuantisedMesh against docs/VARIANTS.md. The
// buffers are decoded by a reader written here from the document (byte
// offsets, little-endian words, slot-major soa-split, aos record alignment),
// not through the packer's own helpers.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "generator/packer.h"
#include "base/error.h"
#include "model/gltf_import.h"

namespace skintune::internal {
namespace {

// ---------------------------------------------------------------- test-side reader

std::size_t Up(std::size_t x, std::size_t m) { return (x + m - 1) / m * m; }

std::uint32_t ReadUint(const std::vector<std::uint8_t>& b, std::size_t at, std::size_t bytes) {
  EXPECT_LE(at + bytes, b.size());
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < bytes && at + i < b.size(); ++i) v |= std::uint32_t{b[at + i]} << (8 * i);
  return v;
}
float ReadFloat(const std::vector<std::uint8_t>& b, std::size_t at) { return std::bit_cast<float>(ReadUint(b, at, 4)); }

// Format sizes from the document (float4 16, float3 12; i32/f32 4, u16/unorm16 2, u8/unorm8 1).
std::size_t PosBytes(const Variant& v) { return v.position == PositionFormat::kFloat4 ? 16 : 12; }
std::size_t IdxBytes(const Variant& v) { return v.index == IndexFormat::kU8 ? 1 : v.index == IndexFormat::kU16 ? 2 : 4; }
std::size_t WgtBytes(const Variant& v) {
  return v.weight == WeightFormat::kUnorm8 ? 1 : v.weight == WeightFormat::kUnorm16 ? 2 : 4;
}
std::uint32_t UnormMax(const Variant& v) { return (1u << (8 * WgtBytes(v))) - 1; }

// The aos record as a C struct: fields at their natural alignment.
struct Record { std::size_t indices, weights, normal, tangent, size; };
Record ExpectedRecord(const Variant& v, int b) {
  const std::size_t align = v.position == PositionFormat::kFloat4 ? 16 : 4;
  Record r{};
  r.indices = PosBytes(v);
  r.weights = Up(r.indices + b * IdxBytes(v), WgtBytes(v));
  std::size_t end = r.weights + b * WgtBytes(v);
  if (SkinsNormals(v)) end = (r.normal = Up(end, align)) + PosBytes(v);
  if (SkinsTangents(v)) end = (r.tangent = Up(end, align)) + 16;  // 4 floats
  r.size = Up(end, align);
  return r;
}

struct Decoded {
  float position[4] = {};
  float normal[4] = {};
  float tangent[4] = {};
  std::vector<std::uint32_t> joints, weights;  // weights: stored word (float bits / unorm integer)
};

const std::vector<std::uint8_t>& Buffer(const Launch& l, const std::string& name) {
  for (const PackedBuffer& b : l.inputs) if (b.name == name) return b.bytes;
  ADD_FAILURE() << "no buffer " << name;
  static const std::vector<std::uint8_t> kNone;
  return kNone;
}

void ReadVector(const std::vector<std::uint8_t>& b, std::size_t at, const Variant& v, float* out) {
  for (int c = 0; c < (v.position == PositionFormat::kFloat4 ? 4 : 3); ++c) out[c] = ReadFloat(b, at + 4 * c);
}

// Vertex p of launch l.
Decoded Read(const Variant& v, const Launch& l, std::size_t p) {
  Decoded d;
  const auto b = static_cast<std::size_t>(l.influences);
  if (v.layout == Layout::kAos) {
    const Record r = ExpectedRecord(v, l.influences);
    const auto& rec = Buffer(l, "records");
    const std::size_t base = p * r.size;
    ReadVector(rec, base, v, d.position);
    for (std::size_t i = 0; i < b; ++i) {
      d.joints.push_back(ReadUint(rec, base + r.indices + i * IdxBytes(v), IdxBytes(v)));
      d.weights.push_back(ReadUint(rec, base + r.weights + i * WgtBytes(v), WgtBytes(v)));
    }
    if (SkinsNormals(v)) ReadVector(rec, base + r.normal, v, d.normal);
    for (int c = 0; c < 4 && SkinsTangents(v); ++c) d.tangent[c] = ReadFloat(rec, base + r.tangent + 4 * c);
    return d;
  }
  ReadVector(Buffer(l, "positions"), p * PosBytes(v), v, d.position);
  if (SkinsNormals(v)) ReadVector(Buffer(l, "normals"), p * PosBytes(v), v, d.normal);
  for (int c = 0; c < 4 && SkinsTangents(v); ++c) d.tangent[c] = ReadFloat(Buffer(l, "tangents"), p * 16 + 4 * c);
  for (std::size_t i = 0; i < b; ++i) {
    const std::size_t e = v.layout == Layout::kSoa ? p * b + i : i * l.slot_stride + p;
    d.joints.push_back(ReadUint(Buffer(l, "indices"), e * IdxBytes(v), IdxBytes(v)));
    d.weights.push_back(ReadUint(Buffer(l, "weights"), e * WgtBytes(v), WgtBytes(v)));
  }
  return d;
}

// ---------------------------------------------------------------- meshes

// Random mesh: every vertex uses 1..influences bones in random slots (zero
// slots in between, joint 0), weights >= 0.05 normalised to 1.
SkinnedMesh RandomMesh(std::size_t n, int influences, int joints, bool normals, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coord(-2.0f, 2.0f), weight(0.05f, 1.0f);
  SkinnedMesh m;
  m.name = "random";
  m.influences = influences;
  m.joint_count = joints;
  for (std::size_t v = 0; v < n; ++v) {
    m.positions.emplace_back(coord(rng), coord(rng), coord(rng));
    if (normals) m.normals.push_back(glm::normalize(glm::vec3(coord(rng), coord(rng), 1.0f)));
    if (normals) m.tangents.emplace_back(glm::normalize(glm::vec3(1.0f, coord(rng), coord(rng))), v % 3 ? 1.0f : -1.0f);
    std::vector<double> w(influences, 0.0);  // 1..influences of them non-zero, anywhere
    std::fill_n(w.begin(), 1 + rng() % influences, 1.0);
    std::shuffle(w.begin(), w.end(), rng);
    for (double& x : w) x *= weight(rng);
    const double sum = std::accumulate(w.begin(), w.end(), 0.0);
    for (int i = 0; i < influences; ++i) {
      m.weights.push_back(static_cast<float>(w[i] / sum));
      m.joints.push_back(w[i] > 0 ? static_cast<std::uint16_t>(rng() % joints) : 0);
    }
  }
  return m;
}

SkinnedMesh OneVertex(std::vector<float> weights) {
  SkinnedMesh m;
  m.name = "one";
  m.influences = static_cast<int>(weights.size());
  m.joint_count = 8;
  m.positions = {glm::vec3(1, 2, 3)};
  m.weights = weights;
  for (std::size_t i = 0; i < weights.size(); ++i) m.joints.push_back(static_cast<std::uint16_t>(i));
  return m;
}

// The words a kernel should find for slot i of vertex v (QuantisedMesh's weights).
std::uint32_t ExpectedWord(const Variant& v, float quantised) {
  if (v.weight == WeightFormat::kF32) return std::bit_cast<std::uint32_t>(quantised);
  return static_cast<std::uint32_t>(std::lround(quantised * UnormMax(v)));
}

// Every vertex of every launch decodes to the mesh (padded: slots in place,
// zeros beyond the mesh's; bucketed: the non-zero slots, compacted).
void ExpectDecodesToQuantisedMesh(const SkinnedMesh& mesh, const Variant& v, const PackedMesh& packed) {
  const SkinnedMesh q = QuantisedMesh(mesh, v);
  ASSERT_EQ(packed.order.size(), mesh.vertex_count());
  std::uint32_t next = 0;
  for (const Launch& l : packed.launches) {
    ASSERT_EQ(l.first, next) << v.Key();
    next += l.count;
    for (std::size_t p = 0; p < l.count; ++p) {
      const std::uint32_t mv = packed.order[l.first + p];
      const Decoded d = Read(v, l, p);
      const bool w = v.position == PositionFormat::kFloat4;
      ASSERT_EQ(glm::vec4(d.position[0], d.position[1], d.position[2], w ? d.position[3] : 1.0f),
                glm::vec4(mesh.positions[mv], 1.0f)) << v.Key();
      if (SkinsNormals(v)) {
        ASSERT_EQ(glm::vec4(d.normal[0], d.normal[1], d.normal[2], w ? d.normal[3] : 0.0f),
                  glm::vec4(mesh.normals[mv], 0.0f)) << v.Key();
      }
      if (SkinsTangents(v)) {
        ASSERT_EQ(glm::vec4(d.tangent[0], d.tangent[1], d.tangent[2], d.tangent[3]), mesh.tangents[mv]) << v.Key();
      }
      std::vector<std::uint32_t> joints, words;
      for (int i = 0; i < mesh.influences; ++i) {
        const std::size_t s = mv * mesh.influences + i;
        if (v.mixed == MixedCounts::kBucketed && mesh.weights[s] == 0.0f) continue;
        joints.push_back(mesh.joints[s]);
        words.push_back(ExpectedWord(v, q.weights[s]));
      }
      joints.resize(l.influences, 0);
      words.resize(l.influences, 0);
      ASSERT_EQ(d.joints, joints) << v.Key() << " vertex " << mv;
      ASSERT_EQ(d.weights, words) << v.Key() << " vertex " << mv;
    }
  }
  EXPECT_EQ(next, mesh.vertex_count());
}

std::vector<Variant> AllFormatVariants() {
  std::vector<Variant> out;
  for (auto mixed : {MixedCounts::kPadded, MixedCounts::kBucketed})
    for (auto layout : {Layout::kAos, Layout::kSoa, Layout::kSoaSplit})
      for (auto position : {PositionFormat::kFloat4, PositionFormat::kFloat3})
        for (auto index : {IndexFormat::kI32, IndexFormat::kU16, IndexFormat::kU8})
          for (auto weight : {WeightFormat::kF32, WeightFormat::kUnorm16, WeightFormat::kUnorm8})
            for (Normals normals : {Normals::kNone, Normals::kNormals, Normals::kTangents}) {
              if (normals == Normals::kTangents && position != PositionFormat::kFloat4) continue;  // tangents_format
              Variant v;
              v.mixed = mixed, v.layout = layout, v.position = position, v.index = index;
              v.weight = weight, v.normals = normals;
              out.push_back(v);
            }
  return out;
}

// ---------------------------------------------------------------- tests

TEST(Packer, EveryLayoutPositionIndexWeightCombinationDecodesToTheQuantisedMesh) {
  const SkinnedMesh mesh = RandomMesh(70, 4, 40, true, 7);
  for (const Variant& v : AllFormatVariants()) {
    const PackedMesh packed = Pack(mesh, v);
    EXPECT_EQ(packed.output_stride_bytes, PosBytes(v));
    std::vector<std::string> names;
    for (const PackedBuffer& b : packed.launches.at(0).inputs) {
      names.push_back(b.name);
      EXPECT_EQ(b.bytes.size() % 4, 0u) << v.Key() << " " << b.name;
    }
    std::vector<std::string> expected{"positions", "indices", "weights", "normals", "tangents"};
    expected.resize(3 + (SkinsNormals(v) ? 1 : 0) + (SkinsTangents(v) ? 1 : 0));
    EXPECT_EQ(names, v.layout == Layout::kAos ? std::vector<std::string>{"records"} : expected) << v.Key();
    ExpectDecodesToQuantisedMesh(mesh, v, packed);
  }
}

TEST(Packer, PaddedFillsSlotsBeyondTheMeshWithZeroAndAcceptsExtraZeroSlots) {
  const SkinnedMesh b2 = RandomMesh(50, 2, 10, false, 3);
  Variant v;
  v.influences = 6;
  for (auto layout : {Layout::kAos, Layout::kSoa, Layout::kSoaSplit}) {
    v.layout = layout;
    ExpectDecodesToQuantisedMesh(b2, v, Pack(b2, v));
  }
  const SkinnedMesh b4 = OneVertex({0.6f, 0.4f, 0.0f, 0.0f});  // slots 2, 3 zero: fits b2
  v.influences = 2;
  const PackedMesh packed = Pack(b4, v);
  EXPECT_EQ(Read(v, packed.launches[0], 0).joints, (std::vector<std::uint32_t>{0, 1}));
}

TEST(Packer, UnormWeightsSumToExactlyTheMaximumAndStayWithinAQuantum) {
  const SkinnedMesh mesh = RandomMesh(500, 8, 77, false, 11);
  for (auto weight : {WeightFormat::kUnorm16, WeightFormat::kUnorm8}) {
    Variant v;
    v.influences = 8;
    v.weight = weight;
    const PackedMesh packed = Pack(mesh, v);
    const double max = UnormMax(v);
    for (std::size_t p = 0; p < mesh.vertex_count(); ++p) {
      const Decoded d = Read(v, packed.launches[0], p);
      std::uint32_t sum = 0;
      int beyond_half = 0;
      for (int i = 0; i < 8; ++i) {
        const double exact = mesh.weights[p * 8 + i] * max;
        const double error = std::abs(d.weights[i] - exact);
        sum += d.weights[i];
        EXPECT_LT(error, 1.0 + 1e-3) << "vertex " << p << " slot " << i;
        beyond_half += error > 0.5 + 1e-3 ? 1 : 0;
        if (mesh.weights[p * 8 + i] == 0.0f) { EXPECT_EQ(d.weights[i], 0u); }
      }
      EXPECT_EQ(sum, UnormMax(v)) << "vertex " << p;
      // Only the corrected slots leave half a quantum: at most B/2 of them.
      EXPECT_LE(beyond_half, 4) << "vertex " << p;
    }
  }
}

TEST(Packer, UnormQuantisationHandlesTiesThirdsAndExactGltfWeights) {
  Variant v;
  v.weight = WeightFormat::kUnorm8;
  auto words = [&v](std::vector<float> w) {
    v.influences = static_cast<int>(w.size());
    return Read(v, Pack(OneVertex(w), v).launches[0], 0).weights;
  };
  // Ties: the earlier slot keeps the quantum.
  EXPECT_EQ(words({0.5f, 0.5f}), (std::vector<std::uint32_t>{128, 127}));
  EXPECT_EQ(words({0.25f, 0.25f, 0.25f, 0.25f}), (std::vector<std::uint32_t>{64, 64, 64, 63}));
  EXPECT_EQ(words({1 / 3.0f, 1 / 3.0f, 1 / 3.0f}), (std::vector<std::uint32_t>{85, 85, 85}));
  EXPECT_EQ(words({200 / 255.0f, 50 / 255.0f, 5 / 255.0f}), (std::vector<std::uint32_t>{200, 50, 5}));
  EXPECT_EQ(words({0.999f, 0.0f, 0.001f})[1], 0u);  // zero stays zero
  const SkinnedMesh q = QuantisedMesh(OneVertex({0.5f, 0.5f}), v);
  EXPECT_FLOAT_EQ(q.weights[0] + q.weights[1], 1.0f);
  EXPECT_EQ(q.weights[0], 128 / 255.0f);
  v.weight = WeightFormat::kF32;
  EXPECT_EQ(QuantisedMesh(OneVertex({0.3f, 0.7f}), v).weights, (std::vector<float>{0.3f, 0.7f}));
}

// docs/VARIANTS.md, the kernel contract, item 1, written here from the
// document: floor, then the missing quanta to the largest remainders, ties to
// the earlier slot. The packer computes it as round-then-adjust; on random
// weights (with ties and zeros) both must give the same integers.
std::vector<std::uint32_t> DocumentedQuantisation(const std::vector<float>& w, std::uint32_t max) {
  double sum = 0.0;
  for (float x : w) sum += x > 0.0f ? x : 0.0;
  std::vector<double> t(w.size());
  std::vector<std::uint32_t> q(w.size());
  std::uint32_t total = 0;
  for (std::size_t i = 0; i < w.size(); ++i) {
    t[i] = w[i] > 0.0f ? w[i] / sum * max : 0.0;
    q[i] = static_cast<std::uint32_t>(std::floor(t[i]));
    total += q[i];
  }
  for (; total < max; ++total) {
    std::size_t best = w.size();
    for (std::size_t i = 0; i < w.size(); ++i)
      if (w[i] > 0.0f && (best == w.size() || t[i] - std::floor(t[i]) > t[best] - std::floor(t[best]))) best = i;
    ++q[best];
    t[best] = std::floor(t[best]);  // one quantum per slot: its remainder is spent
  }
  return q;
}

TEST(Packer, QuantisationIsTheFloorAndLargestRemainderRule) {
  Variant v;
  auto words = [&v](std::vector<float> w) {
    v.influences = static_cast<int>(w.size());
    return Read(v, Pack(OneVertex(w), v).launches[0], 0).weights;
  };
  using W = std::vector<std::uint32_t>;
  // The worked examples of docs/VARIANTS.md.
  v.weight = WeightFormat::kUnorm8;
  EXPECT_EQ(words({0.5f, 0.5f}), (W{128, 127}));
  EXPECT_EQ(words({0.25f, 0.25f, 0.25f, 0.25f}), (W{64, 64, 64, 63}));
  EXPECT_EQ(words({0.625f, 0.25f, 0.125f}), (W{159, 64, 32}));
  EXPECT_EQ(words({0.6f, 0.4f, 0.0f}), (W{153, 102, 0}));
  v.weight = WeightFormat::kUnorm16;
  EXPECT_EQ(words({0.5f, 0.5f}), (W{32768, 32767}));
  EXPECT_EQ(words({0.25f, 0.25f, 0.25f, 0.25f}), (W{16384, 16384, 16384, 16383}));

  std::mt19937 random(14);
  std::uniform_int_distribution<int> count(1, 8), grid(0, 8);
  for (auto weight : {WeightFormat::kUnorm8, WeightFormat::kUnorm16}) {
    v.weight = weight;
    for (int trial = 0; trial < 2000; ++trial) {
      // Weights on a coarse grid (many ties), some zero, normalised.
      std::vector<float> w(static_cast<std::size_t>(count(random)));
      float sum = 0.0f;
      for (float& x : w) sum += (x = static_cast<float>(grid(random)));
      if (sum == 0.0f) w[0] = sum = 1.0f;
      for (float& x : w) x /= sum;
      ASSERT_EQ(words(w), DocumentedQuantisation(w, UnormMax(v))) << "trial " << trial;
    }
  }
}

TEST(Packer, HoldsWeightsExactlyOnlyForWeightsOnTheFormatsGrid) {
  EXPECT_TRUE(HoldsWeightsExactly(OneVertex({0.3f, 0.7f}), WeightFormat::kF32));
  EXPECT_FALSE(HoldsWeightsExactly(OneVertex({0.3f, 0.7f}), WeightFormat::kUnorm8));
  EXPECT_TRUE(HoldsWeightsExactly(OneVertex({200 / 255.0f, 50 / 255.0f, 5 / 255.0f}), WeightFormat::kUnorm8));
  // unorm8's grid is part of unorm16's (65535 = 255 x 257).
  EXPECT_TRUE(HoldsWeightsExactly(OneVertex({200 / 255.0f, 50 / 255.0f, 5 / 255.0f}), WeightFormat::kUnorm16));
  EXPECT_FALSE(HoldsWeightsExactly(OneVertex({0.5f, 0.5f}), WeightFormat::kUnorm8));  // 127.5 is not on the grid
  const SkinnedMesh gltf = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple-unorm8.gltf").asset.mesh;
  EXPECT_TRUE(HoldsWeightsExactly(gltf, WeightFormat::kUnorm8));
  const SkinnedMesh original = ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/RiggedSimple.gltf").asset.mesh;
  EXPECT_FALSE(HoldsWeightsExactly(original, WeightFormat::kUnorm8));
}

TEST(Packer, SoaSplitSlotArraysStartOn256ByteBoundaries) {
  for (std::size_t n : {1u, 63u, 64u, 65u, 200u, 300u}) {
    const SkinnedMesh mesh = RandomMesh(n, 3, 20, false, static_cast<unsigned>(n));
    for (const Variant& base : AllFormatVariants()) {
      if (base.layout != Layout::kSoaSplit || base.mixed != MixedCounts::kPadded || SkinsNormals(base)) continue;
      Variant v = base;
      v.influences = 3;
      const Launch l = Pack(mesh, v).launches.at(0);
      const std::size_t s = l.slot_stride;
      EXPECT_GE(s, n);
      EXPECT_EQ(s % 64, 0u);
      EXPECT_LT(s, n + 256) << v.Key();
      EXPECT_EQ(s * IdxBytes(v) % 256, 0u) << v.Key();
      EXPECT_EQ(s * WgtBytes(v) % 256, 0u) << v.Key();
      EXPECT_EQ(Buffer(l, "indices").size(), 3 * s * IdxBytes(v));
      EXPECT_EQ(Buffer(l, "weights").size(), 3 * s * WgtBytes(v));
      EXPECT_EQ(s, SoaSplitSlotStride(static_cast<std::uint32_t>(n), v));
      if (IdxBytes(v) == 4 && WgtBytes(v) == 4) { EXPECT_EQ(s, Up(n, 64)); }  // the documented S
    }
  }
}

TEST(Packer, AosRecordSizesRoundUpTo16ForFloat4And4ForFloat3) {
  struct Case { const char* key; std::size_t indices, weights, normal, size; };
  const Case cases[] = {
      {"b4.float4.u16.unorm8", 16, 24, 0, 32},           // 16 + 8 + 4 = 28 -> 32
      {"b1.float3.u8.unorm8", 12, 13, 0, 16},            // 12 + 1 + 1 = 14 -> 16
      {"b4.float3.i32.f32", 12, 28, 0, 44},              // 12 + 16 + 16
      {"b3.float3.u8.f32", 12, 16, 0, 28},               // weights aligned to 4
      {"b3.float3.u8.unorm16", 12, 16, 0, 24},           // weights aligned to 2
      {"b4.float4.i32.f32.normals", 16, 32, 48, 64},     // 16 + 16 + 16 + 16
      {"b4.float4.u16.unorm8.normals", 16, 24, 32, 48},  // normal on 16
      {"b2.float3.u16.unorm16.normals", 12, 16, 20, 32},
      {"b8.float4.u8.unorm8", 16, 24, 0, 32},
  };
  for (const Case& c : cases) {
    Variant v = ParseVariantKey(c.key);
    v.layout = Layout::kAos;
    const RecordLayout r = AosRecordLayout(v, v.influences);
    EXPECT_EQ(r.position, 0u) << c.key;
    EXPECT_EQ(r.indices, c.indices) << c.key;
    EXPECT_EQ(r.weights, c.weights) << c.key;
    EXPECT_EQ(r.normal, c.normal) << c.key;
    EXPECT_EQ(r.size, c.size) << c.key;
    EXPECT_EQ(ExpectedRecord(v, v.influences).size, c.size) << c.key;
    const SkinnedMesh mesh = RandomMesh(5, v.influences, 30, true, 5);
    EXPECT_EQ(Buffer(Pack(mesh, v).launches.at(0), "records").size(), 5 * c.size) << c.key;
  }
}

SkinnedMesh CesiumMan() {
  return ImportGltf(std::string(SKINTUNE_TEST_DATA_DIR) + "/CesiumMan.gltf").asset.mesh;
}

TEST(Packer, BucketedGroupsVerticesByCountAscendingInStableOrder) {
  const SkinnedMesh mesh = CesiumMan();
  Variant v = ParseVariantKey("bucketed.soa-split.u8.unorm8");
  v.influences = mesh.influences;
  const PackedMesh packed = Pack(mesh, v);
  std::vector<std::uint32_t> expected(mesh.vertex_count());
  std::iota(expected.begin(), expected.end(), 0u);
  std::stable_sort(expected.begin(), expected.end(),
                   [&mesh](std::uint32_t a, std::uint32_t b) { return mesh.InfluencesOf(a) < mesh.InfluencesOf(b); });
  EXPECT_EQ(packed.order, expected);
  const std::vector<std::size_t> histogram = InfluenceHistogram(mesh);
  std::vector<int> counts;
  for (std::size_t k = 1; k < histogram.size(); ++k)
    if (histogram[k] > 0) counts.push_back(static_cast<int>(k));
  ASSERT_EQ(packed.launches.size(), counts.size());
  ASSERT_GE(counts.size(), 2u) << "CesiumMan should mix per-vertex counts";
  for (std::size_t b = 0; b < counts.size(); ++b) {
    const Launch& l = packed.launches[b];
    EXPECT_EQ(l.influences, counts[b]);
    EXPECT_EQ(l.count, histogram[counts[b]]);
    for (std::uint32_t p = 0; p < l.count; ++p) EXPECT_EQ(mesh.InfluencesOf(packed.order[l.first + p]), counts[b]);
  }
  ExpectDecodesToQuantisedMesh(mesh, v, packed);
}

TEST(Packer, UnpackRestoresTheMeshOrder) {
  const SkinnedMesh mesh = CesiumMan();
  ASSERT_TRUE(mesh.has_normals());
  for (const char* key : {"bucketed.aos.float3.normals", "bucketed.soa.float4", "padded.soa-split.float3"}) {
    Variant v = ParseVariantKey(key);
    v.influences = mesh.influences;
    const PackedMesh packed = Pack(mesh, v);
    // An identity kernel: out_positions[first + v] = positions[v] (and normals).
    std::vector<std::uint8_t> out(packed.vertex_count * packed.output_stride_bytes);
    std::vector<std::uint8_t> out_normals(out.size());
    for (const Launch& l : packed.launches) {
      for (std::uint32_t p = 0; p < l.count; ++p) {
        const Decoded d = Read(v, l, p);
        std::uint8_t* at = out.data() + (l.first + p) * packed.output_stride_bytes;
        std::copy_n(reinterpret_cast<const std::uint8_t*>(d.position), packed.output_stride_bytes, at);
        at = out_normals.data() + (l.first + p) * packed.output_stride_bytes;
        std::copy_n(reinterpret_cast<const std::uint8_t*>(d.normal), packed.output_stride_bytes, at);
      }
    }
    EXPECT_EQ(Unpack(packed, out), mesh.positions) << key;
    if (SkinsNormals(v)) { EXPECT_EQ(Unpack(packed, out_normals), mesh.normals) << key; }
  }
}

TEST(Packer, PalettesAreFloat4RowsFourForMat4AndThreeForMat3x4) {
  std::vector<glm::mat4> palette(3);
  for (int j = 0; j < 3; ++j)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) palette[j][c][r] = static_cast<float>(100 * j + 10 * r + c);
  for (auto format : {PaletteFormat::kMat4, PaletteFormat::kMat3x4}) {
    Variant v;
    v.palette = format;
    const std::size_t rows = format == PaletteFormat::kMat4 ? 4 : 3;
    const std::vector<std::uint8_t> bytes = PackPalette(palette, v);
    ASSERT_EQ(bytes.size(), 3 * rows * 16);
    for (std::size_t j = 0; j < 3; ++j)
      for (std::size_t r = 0; r < rows; ++r)
        for (std::size_t c = 0; c < 4; ++c)
          EXPECT_EQ(ReadFloat(bytes, ((j * rows + r) * 4 + c) * 4), static_cast<float>(100 * j + 10 * r + c));
    const PackedMesh packed = Pack(RandomMesh(4, 2, 3, false, 1), v);
    EXPECT_EQ(packed.palette_joints, 3u);
    EXPECT_EQ(packed.palette, PackPalette(std::vector<glm::mat4>(3, glm::mat4(1.0f)), v));
  }
}

// The dualquat palette: per joint the unit quaternion of its rotation and
// the dual part 0.5 (t, 0) q, which give back the matrix; identity padding;
// a joint that scales, shears or mirrors refused by index, never rounded.
TEST(Packer, DualQuaternionPalettesHoldRigidJointsAndRefuseTheRest) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<glm::mat4> palette;
  for (int j = 0; j < 5; ++j) {
    const glm::vec3 axis = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 1e-3f));
    glm::mat4 m = glm::rotate(glm::mat4(1.0f), 3.0f * u(rng) + (j == 4 ? 3.1f : 0.0f), axis);  // j 4: near pi
    m[3] = glm::vec4(10.0f * u(rng), 10.0f * u(rng), 10.0f * u(rng), 1.0f);
    palette.push_back(m);
  }
  Variant v;
  v.palette = PaletteFormat::kDualQuaternion;
  v.blend = Blend::kDualQuaternion;
  EXPECT_EQ(PaletteMatrixBytes(v), 32u);
  const std::vector<std::uint8_t> bytes = PackPalette(palette, v);
  ASSERT_EQ(bytes.size(), palette.size() * 32);
  for (std::size_t j = 0; j < palette.size(); ++j) {
    float f[8];
    for (int i = 0; i < 8; ++i) f[i] = ReadFloat(bytes, (j * 8 + static_cast<std::size_t>(i)) * 4);
    const glm::dquat q(f[3], f[0], f[1], f[2]), d(f[7], f[4], f[5], f[6]);
    EXPECT_NEAR(glm::length(q), 1.0, 1e-6) << j;
    const glm::dmat3 r = glm::mat3_cast(q);
    const glm::dquat t = 2.0 * (d * glm::conjugate(q));
    for (int c = 0; c < 3; ++c)
      for (int row = 0; row < 3; ++row) EXPECT_NEAR(r[c][row], palette[j][c][row], 1e-6) << j;
    EXPECT_NEAR(t.x, palette[j][3][0], 1e-5) << j;
    EXPECT_NEAR(t.y, palette[j][3][1], 1e-5) << j;
    EXPECT_NEAR(t.z, palette[j][3][2], 1e-5) << j;
  }
  const PackedMesh packed = Pack(RandomMesh(4, 2, 3, false, 1), v);
  EXPECT_EQ(packed.palette, PackPalette(std::vector<glm::mat4>(3, glm::mat4(1.0f)), v));
  for (const glm::mat4& bad : {glm::scale(palette[2], glm::vec3(1.0f, 1.0f, 1.001f)),
                               glm::scale(palette[2], glm::vec3(-1.0f, 1.0f, 1.0f))}) {
    std::vector<glm::mat4> scaled = palette;
    scaled[2] = bad;
    std::vector<std::uint8_t> out(scaled.size() * 32);
    EXPECT_EQ(PackPaletteInto(&scaled.front()[0][0], scaled.size(), v, out.data()), 2u);
    try {
      PackPalette(scaled, v);
      ADD_FAILURE() << "a scaled or mirrored joint packed as a dual quaternion";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("palette entry 2 is not a rigid transform"), std::string::npos) << e.what();
    }
  }
}

// Every code path of PackPaletteInto (the AVX-512 one where this CPU has
// it, else skipped and said so) against the element-by-element definition:
// the transposed rows, nothing written past the last matrix, and the first
// matrix with a NaN or infinite element, wherever it sits in the matrix.
TEST(Packer, EveryPackPathWritesTheRowsAndFindsTheFirstNonFiniteMatrix) {
  constexpr std::size_t kMatrices = 37;
  std::vector<float> matrices(16 * kMatrices);
  for (std::size_t i = 0; i < matrices.size(); ++i) matrices[i] = static_cast<float>(i % 251) * 0.5f - 60.0f;
  const float specials[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity()};
  for (PackIsa isa : {PackIsa::kBaseline, PackIsa::kAvx512, PackIsa::kAuto}) {
    if (!PackIsaAvailable(isa)) {
      std::cout << "[   INFO   ] pack path " << static_cast<int>(isa) << " skipped: this CPU (or build) lacks it\n";
      continue;
    }
    for (auto format : {PaletteFormat::kMat4, PaletteFormat::kMat3x4}) {
      Variant v;
      v.palette = format;
      const std::size_t rows = format == PaletteFormat::kMat4 ? 4 : 3;
      std::vector<std::uint8_t> out(kMatrices * rows * 16 + 64, 0xAB);  // a guard after the rows
      EXPECT_EQ(PackPaletteInto(matrices.data(), kMatrices, v, out.data(), isa), kMatrices);
      for (std::size_t j = 0; j < kMatrices; ++j)
        for (std::size_t r = 0; r < rows; ++r)
          for (std::size_t c = 0; c < 4; ++c)
            ASSERT_EQ(ReadFloat(out, ((j * rows + r) * 4 + c) * 4), matrices[16 * j + 4 * c + r])
                << "isa " << static_cast<int>(isa) << " matrix " << j << " row " << r << " column " << c;
      for (std::size_t b = kMatrices * rows * 16; b < out.size(); ++b) ASSERT_EQ(out[b], 0xAB) << "byte " << b;
      // The largest magnitude, wherever it sits (each element of a group of
      // four, of the tail, and of row 4, which mat3x4 does not store), and
      // negative or positive.
      for (std::size_t at : {std::size_t{0}, std::size_t{16 * 5 + 7}, std::size_t{16 * 34 + 15}, 16 * kMatrices - 1,
                             std::size_t{16 * 9 + 3}})
        for (float sign : {1.0f, -1.0f}) {
          std::vector<float> with = matrices;
          with[at] = sign * 1e30f;
          float largest = -1.0f;
          EXPECT_EQ(PackPaletteInto(with.data(), kMatrices, v, out.data(), isa, &largest), kMatrices);
          EXPECT_EQ(largest, 1e30f) << "isa " << static_cast<int>(isa) << " element " << at;
        }
      float largest = -1.0f;
      PackPaletteInto(matrices.data(), kMatrices, v, out.data(), isa, &largest);
      float expected = 0.0f;
      for (float m : matrices) expected = std::max(expected, std::fabs(m));
      EXPECT_EQ(largest, expected);
      EXPECT_EQ(PackPaletteInto(matrices.data(), 0, v, out.data(), isa, &largest), 0u);
      EXPECT_EQ(largest, 0.0f) << "no matrices";
      // A special element in each position of a few matrices: the first such matrix is reported.
      // (AVX-512 packs three rows four matrices at a time: each position in a group, and the tail.)
      for (std::size_t bad : {std::size_t{0}, std::size_t{2}, std::size_t{17}, std::size_t{35}, kMatrices - 1})
        for (std::size_t e = 0; e < 16; ++e) {
          std::vector<float> with = matrices;
          with[16 * bad + e] = specials[e % 3];
          if (bad + 5 < kMatrices) with[16 * (bad + 5)] = specials[(e + 1) % 3];  // a later one does not count
          if (bad + 1 < kMatrices) with[16 * (bad + 1) + 15 - e] = specials[(e + 2) % 3];  // nor the next, in its group
          EXPECT_EQ(PackPaletteInto(with.data(), kMatrices, v, out.data(), isa), bad)
              << "isa " << static_cast<int>(isa) << " element " << e << " of matrix " << bad;
        }
    }
  }
}

// The message of the Error that f throws ("" and a failure when it throws none).
template <typename F>
std::string ErrorOf(F f) {
  try { f(); } catch (const Error& e) { return e.what(); }
  ADD_FAILURE() << "no Error thrown";
  return "";
}

// Pack throws Error whose message starts with "pack <key>: " and contains `text`.
void ExpectPackError(const SkinnedMesh& mesh, const Variant& v, const std::string& text) {
  const std::string message = ErrorOf([&] { Pack(mesh, v); });
  EXPECT_EQ(message.rfind("pack " + v.Key() + ": ", 0), 0u) << message;
  EXPECT_NE(message.find(text), std::string::npos) << message;
}

TEST(Packer, RejectsU8IndicesForMoreThan256Joints) {
  Variant v;
  v.index = IndexFormat::kU8;
  ExpectPackError(RandomMesh(10, 4, 300, false, 2), v, "300 joints do not fit u8");
  EXPECT_NO_THROW(Pack(RandomMesh(10, 4, 256, false, 2), v));
  v.index = IndexFormat::kU16;
  EXPECT_NO_THROW(Pack(RandomMesh(10, 4, 300, false, 2), v));
}

TEST(Packer, RejectsInfluencesBelowTheMeshCount) {
  const SkinnedMesh mesh = OneVertex({0.25f, 0.25f, 0.25f, 0.25f});
  Variant v;
  v.influences = 3;
  ExpectPackError(mesh, v, "influences 3 below the mesh's per-vertex count 4");
  v.mixed = MixedCounts::kBucketed;
  ExpectPackError(mesh, v, "influences 3 below the mesh's per-vertex count 4");
  // Two bones, but in slot 3: padded keeps slots in place, bucketed compacts.
  const SkinnedMesh late = OneVertex({0.5f, 0.0f, 0.0f, 0.5f});
  v.influences = 2;
  EXPECT_NO_THROW(Pack(late, v));
  v.mixed = MixedCounts::kPadded;
  ExpectPackError(late, v, "non-zero weight in slot 3");
}

TEST(Packer, RejectsNormalsOnAMeshWithoutNormalsAndInvalidMeshes) {
  Variant v;
  v.normals = Normals::kNormals;
  ExpectPackError(RandomMesh(10, 2, 5, false, 4), v, "normals");
  v.normals = Normals::kTangents;
  SkinnedMesh no_tangents = RandomMesh(10, 2, 5, true, 4);
  no_tangents.tangents.clear();
  ExpectPackError(no_tangents, v, "tangents requested");
  v.position = PositionFormat::kFloat3;
  ExpectPackError(RandomMesh(10, 2, 5, true, 4), v, "float4 position format");
  SkinnedMesh bad = RandomMesh(10, 2, 5, false, 4);
  bad.joints[3] = 9;
  ExpectPackError(bad, Variant{}, "out of range");
}

TEST(Packer, UnpackRejectsOutputOfTheWrongSize) {
  Variant v;
  v.position = PositionFormat::kFloat3;
  const PackedMesh packed = Pack(RandomMesh(10, 2, 5, false, 4), v);
  const std::string message = ErrorOf([&] { Unpack(packed, std::vector<std::uint8_t>(10 * 16)); });
  EXPECT_NE(message.find("unpack " + v.Key() + ": positions output has 160 bytes, expected 10 vertices x 12 bytes = 120"),
            std::string::npos) << message;
  EXPECT_EQ(Unpack(packed, std::vector<std::uint8_t>(120)).size(), 10u);
}

}  // namespace
}  // namespace skintune::internal
