// The CPU kernel family (cpu_kernels/cpu_kernels.h) on its own: streaming and
// plain stores write the same bytes and nothing outside the range, whatever
// the range's alignment; every loop path (the first and last vertex of a
// range, ranges split off 4- and 64-vertex boundaries, positions ending at an
// unreadable page, each stream layout, normals on and off, 3 and 4 output
// floats) against the float64 gold; every dual-quaternion kernel (B, index
// and weight formats) against the float64 dual-quaternion gold on rigid
// random palettes, some joints' quaternions negated; the table's keys and
// names; the schedule candidates and the choice among them; bad keys and
// palettes. Every linear-blend kernel against the float64 gold through the
// cpu device: tests/runtime/cpu_runner_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <sys/mman.h>
#include <unistd.h>

#include <glm/gtc/quaternion.hpp>

#include "cpu_kernels/cpu_kernels.h"
#include "base/error.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "base/thread_pool.h"
#include "templates/embedded_support.h"

namespace skintune::internal {
namespace {

constexpr std::uint32_t kPoison = 0x7fc00000u;  // a quiet NaN, as the runner's poisoned outputs

struct Streams {
  std::vector<float> positions, normals;
  std::vector<std::uint8_t> joints;   // u8 slots: [slot * n + v]
  std::vector<std::uint16_t> weights;  // unorm16 slots
  CpuPalette palette;
};

Streams MakeStreams(const SkinnedAsset& asset) {
  const SkinnedMesh& m = asset.mesh;
  const std::size_t n = m.vertex_count(), b = static_cast<std::size_t>(m.influences);
  Streams s;
  s.positions.assign(&m.positions[0].x, &m.positions[0].x + 3 * n);
  s.normals.assign(&m.normals[0].x, &m.normals[0].x + 3 * n);
  s.joints.resize(b * n);
  s.weights.resize(b * n);
  for (std::size_t v = 0; v < n; ++v)
    for (std::size_t i = 0; i < b; ++i) {
      s.joints[i * n + v] = static_cast<std::uint8_t>(m.joints[v * b + i]);
      s.weights[i * n + v] = static_cast<std::uint16_t>(std::lround(m.weights[v * b + i] * 65535.0f));
    }
  std::vector<std::uint8_t> rows;
  for (const glm::mat4& j : asset.PaletteAt(-1, 0.0))
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) {
        std::uint8_t bytes[4];
        std::memcpy(bytes, &j[c][r], 4);
        rows.insert(rows.end(), bytes, bytes + 4);
      }
  LoadCpuPalette(rows, 3, s.palette);
  return s;
}

// Outputs of `floats` per vertex, 64-byte aligned, poisoned.
struct Output {
  explicit Output(std::size_t words) : data(static_cast<float*>(std::aligned_alloc(64, (words * 4 + 63) / 64 * 64))) {
    for (std::size_t k = 0; k < words; ++k) std::memcpy(data + k, &kPoison, 4);
  }
  ~Output() { std::free(data); }
  float* data;
  bool Poisoned(std::size_t k) const {
    std::uint32_t w;
    std::memcpy(&w, data + k, 4);
    return w == kPoison;
  }
};

TEST(CpuKernels, StreamingAndPlainStoresWriteTheSameBytesAndOnlyTheRange) {
  const SkinnedAsset asset = GenerateDataset(ParseDatasetKey("1000-b3-normals"));
  const std::size_t n = asset.mesh.vertex_count();
  const Streams in = MakeStreams(asset);
  const CpuKernelFn kernel = FindCpuKernel({3, CpuIndex::kU8, CpuWeight::kUnorm16, 3, false});
  for (const int floats : {3, 4}) {
    // Ranges starting and ending on and off 4-vertex (16-byte) boundaries.
    for (const auto& [begin, end] : {std::pair<std::size_t, std::size_t>{0, n}, {1, n - 1}, {3, 7}, {5, 6}, {8, 40}}) {
      SCOPED_TRACE(std::to_string(floats) + " floats, vertices " + std::to_string(begin) + ".." + std::to_string(end));
      Output plain(floats * n), streamed(floats * n), plain_n(floats * n), streamed_n(floats * n);
      for (const bool stream : {false, true}) {
        CpuStreams s;
        s.positions = reinterpret_cast<const std::uint8_t*>(in.positions.data());
        s.position_stride = 12;
        s.normals = reinterpret_cast<const std::uint8_t*>(in.normals.data());
        s.normal_stride = 12;
        s.indices = in.joints.data();
        s.index_stride = 1;
        s.index_slot = n;
        s.weights = reinterpret_cast<const std::uint8_t*>(in.weights.data());
        s.weight_stride = 2;
        s.weight_slot = 2 * n;
        s.out_positions = (stream ? streamed : plain).data;
        s.out_normals = (stream ? streamed_n : plain_n).data;
        s.output_floats = floats;
        s.stream_stores = stream;
        kernel(s, in.palette, begin, end);
      }
      EXPECT_EQ(std::memcmp(plain.data, streamed.data, 4 * floats * n), 0);
      EXPECT_EQ(std::memcmp(plain_n.data, streamed_n.data, 4 * floats * n), 0);
      for (std::size_t k = 0; k < floats * n; ++k) {
        const bool inside = k >= floats * begin && k < floats * end;
        ASSERT_EQ(streamed.Poisoned(k), !inside) << "word " << k;
        ASSERT_EQ(streamed_n.Poisoned(k), !inside) << "word " << k;
      }
      if (floats == 4)
        for (std::size_t v = begin; v < end; ++v) {
          EXPECT_EQ(streamed.data[4 * v + 3], 1.0f);
          EXPECT_EQ(streamed_n.data[4 * v + 3], 0.0f);
        }
    }
  }
}

// Bytes placed so that the last one is followed by an unreadable page: a
// kernel reading past the end of its stream faults instead of passing.
class BeforeGuardPage {
 public:
  explicit BeforeGuardPage(std::span<const std::uint8_t> bytes) {
    const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
    span_ = (bytes.size() + page - 1) / page * page + page;
    void* m = mmap(nullptr, span_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (m == MAP_FAILED) throw std::runtime_error("mmap failed");
    base_ = static_cast<std::uint8_t*>(m);
    if (mprotect(base_ + span_ - page, page, PROT_NONE) != 0) throw std::runtime_error("mprotect failed");
    data_ = base_ + span_ - page - bytes.size();
    std::memcpy(data_, bytes.data(), bytes.size());
  }
  ~BeforeGuardPage() { munmap(base_, span_); }
  BeforeGuardPage(const BeforeGuardPage&) = delete;
  BeforeGuardPage& operator=(const BeforeGuardPage&) = delete;
  const std::uint8_t* data() const { return data_; }

 private:
  std::uint8_t* base_ = nullptr;
  std::uint8_t* data_ = nullptr;
  std::size_t span_ = 0;
};

template <typename T>
void Put(std::vector<std::uint8_t>& bytes, std::size_t at, T value) {
  std::memcpy(bytes.data() + at, &value, sizeof value);
}

TEST(CpuKernels, EveryLoopPathMatchesTheGoldAtRangeEdgesInEveryLayout) {
  // 301 vertices: ranges end off 4- and 64-vertex boundaries, and the
  // unorm16 weights are decoded in blocks of 64 vertices across them.
  SkinnedAsset asset = GenerateDataset(ParseDatasetKey("301-b3-normals"));
  SkinnedMesh& mesh = asset.mesh;
  const std::size_t n = mesh.vertex_count(), b = static_cast<std::size_t>(mesh.influences);
  // The gold of the weights the kernels read: unorm16 as stored (f32 reads them exactly too).
  for (float& w : mesh.weights) w = static_cast<float>(std::lround(w * 65535.0f)) / 65535.0f;
  const std::vector<glm::mat4> palette = asset.PaletteAt(-1, 0.0);
  const GoldResult gold = SkinGold(mesh, palette, true);
  // Split points of the kernel calls over [0, n): a single vertex, the first
  // and last vertex of a 64-vertex block, one vertex before and after it.
  const std::vector<std::size_t> cuts = {0, 1, 2, 5, 63, 64, 65, 67, 128, 200, 299, 300, 301};

  enum class Layout { kSoaSplit, kSoa, kAos };
  for (const Layout layout : {Layout::kSoaSplit, Layout::kSoa, Layout::kAos})
    for (const CpuWeight weight : {CpuWeight::kF32, CpuWeight::kUnorm16})
      for (const int rows : {3, 4})
        for (const bool point : {false, true})
          for (const bool normals : {false, true})
            for (const int floats : {3, 4}) {
              SCOPED_TRACE("layout " + std::to_string(static_cast<int>(layout)) + ", " +
                           CpuKernelName({3, CpuIndex::kU8, weight, rows, point}) + (normals ? ", normals" : "") +
                           ", " + std::to_string(floats) + " output floats");
              // u8 joints; weights as `weight`; positions and normals 12-byte
              // float3 runs (soa, soa-split) or inside records (aos).
              const std::size_t wb = weight == CpuWeight::kF32 ? 4 : 2;
              const std::size_t record = layout == Layout::kAos ? 24 + b + b * wb + 1 : 0;
              std::vector<std::uint8_t> pos(layout == Layout::kAos ? record * n : 12 * n), nrm(12 * n),
                  idx(b * n), wgt(wb * b * n);
              CpuStreams s;
              for (std::size_t v = 0; v < n; ++v)
                for (std::size_t i = 0; i < b; ++i) {
                  const std::size_t slot_at = layout == Layout::kSoaSplit ? i * n + v : v * b + i;
                  const float w = mesh.weights[v * b + i];
                  const auto j = static_cast<std::uint8_t>(mesh.joints[v * b + i]);
                  if (layout == Layout::kAos) {
                    Put(pos, v * record + 24 + i, j);
                    if (wb == 4) Put(pos, v * record + 24 + b + 4 * i, w);
                    else Put(pos, v * record + 24 + b + 2 * i, static_cast<std::uint16_t>(std::lround(w * 65535.0f)));
                  } else {
                    idx[slot_at] = j;
                    if (wb == 4) Put(wgt, 4 * slot_at, w);
                    else Put(wgt, 2 * slot_at, static_cast<std::uint16_t>(std::lround(w * 65535.0f)));
                  }
                }
              for (std::size_t v = 0; v < n; ++v) {
                const std::size_t at = layout == Layout::kAos ? v * record : 12 * v;
                for (int c = 0; c < 3; ++c) {
                  Put(pos, at + 4 * c, mesh.positions[v][c]);
                  Put(layout == Layout::kAos ? pos : nrm, (layout == Layout::kAos ? at + 12 : 12 * v) + 4 * c,
                      mesh.normals[v][c]);
                }
              }
              // Each stream ends where an unreadable page starts.
              const BeforeGuardPage g_pos(pos), g_nrm(nrm), g_idx(idx), g_wgt(wgt);
              if (layout == Layout::kAos) {
                s.positions = g_pos.data();
                s.normals = g_pos.data() + 12;
                s.indices = g_pos.data() + 24;
                s.weights = g_pos.data() + 24 + b;
                s.position_stride = s.normal_stride = s.index_stride = s.weight_stride = record;
                s.index_slot = 1;
                s.weight_slot = wb;
              } else {
                s.positions = g_pos.data();
                s.normals = g_nrm.data();
                s.position_stride = s.normal_stride = 12;
                s.indices = g_idx.data();
                s.weights = g_wgt.data();
                const bool split = layout == Layout::kSoaSplit;
                s.index_stride = split ? 1 : b;
                s.index_slot = split ? n : 1;
                s.weight_stride = split ? wb : b * wb;
                s.weight_slot = split ? n * wb : wb;
              }
              // The palette in the kernels' form, 3 or 4 rows per joint.
              std::vector<std::uint8_t> packed;
              for (const glm::mat4& m : palette)
                for (int r = 0; r < rows; ++r)
                  for (int c = 0; c < 4; ++c) {
                    packed.resize(packed.size() + 4);
                    std::memcpy(packed.data() + packed.size() - 4, &m[c][r], 4);
                  }
              CpuPalette cpu_palette;
              LoadCpuPalette(packed, rows, cpu_palette);

              Output out(floats * (n + 4)), out_n(floats * (n + 4));  // 4 guard vertices after the mesh
              s.out_positions = out.data;
              s.out_normals = normals ? out_n.data : nullptr;
              s.output_floats = floats;
              const CpuKernelFn kernel = FindCpuKernel({3, CpuIndex::kU8, weight, rows, point});
              for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
                s.stream_stores = c % 2 == 1;  // both store paths, alternating by range
                kernel(s, cpu_palette, cuts[c], cuts[c + 1]);
              }
              std::vector<glm::vec3> got(n), got_n(n);
              for (std::size_t v = 0; v < n; ++v) {
                got[v] = {out.data[floats * v], out.data[floats * v + 1], out.data[floats * v + 2]};
                got_n[v] = {out_n.data[floats * v], out_n.data[floats * v + 1], out_n.data[floats * v + 2]};
                if (floats == 4) {
                  ASSERT_EQ(out.data[4 * v + 3], 1.0f) << "vertex " << v;
                  if (normals) {
                    ASSERT_EQ(out_n.data[4 * v + 3], 0.0f) << "vertex " << v;
                  }
                }
              }
              for (std::size_t k = floats * n; k < floats * (n + 4); ++k) {
                ASSERT_TRUE(out.Poisoned(k)) << "guard word " << k;
                ASSERT_TRUE(out_n.Poisoned(k)) << "guard word " << k;
              }
              const GoldComparison p = CompareToGold(gold.positions, got);
              EXPECT_EQ(p.non_finite, 0u);
              EXPECT_LT(p.max_relative, 1e-5) << "worst vertex " << p.worst_vertex;
              if (normals) {
                const GoldComparison q = CompareToGold(gold.normals, got_n);
                EXPECT_EQ(q.non_finite, 0u);
                EXPECT_LT(q.max_absolute, 1e-5) << "worst vertex " << q.worst_vertex;
              } else {
                for (std::size_t k = 0; k < floats * n; ++k) ASSERT_TRUE(out_n.Poisoned(k)) << "normal word " << k;
              }
              if (HasFailure()) return;  // one failing path says enough
            }
}

// A rigid palette of `joints` random rotations and translations of up to 0.3
// a coordinate, as the float matrices the gold skins with: the rotations
// uniform over all rotations, or (`near`) within about 0.3 rad of one.
std::vector<glm::mat4> RigidPalette(std::mt19937& rng, int joints, bool near) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<float> shift(-0.3f, 0.3f);
  const auto random_quaternion = [&] { return glm::dquat(normal(rng), normal(rng), normal(rng), normal(rng)); };
  const glm::dquat base = glm::normalize(random_quaternion());
  std::vector<glm::mat4> palette;
  for (int j = 0; j < joints; ++j) {
    const glm::dquat q = glm::normalize(near ? base + 0.08 * random_quaternion() : random_quaternion());
    glm::mat4 m(glm::mat3(glm::mat3_cast(q)));
    m[3] = glm::vec4(shift(rng), shift(rng), shift(rng), 1.0f);
    palette.push_back(m);
  }
  return palette;
}

// `palette` as the kernels read it, 2 float4 rows a joint (the packer's
// conversion, DualQuaternionOf), each odd joint's given as (-q, -d) when
// `negate_odd`: the same rigid map from the other side of the sphere of
// quaternions, which a blend that ignored the side would cancel.
std::vector<std::uint8_t> DualQuaternionRows(std::span<const glm::mat4> palette, bool negate_odd) {
  std::vector<std::uint8_t> rows(palette.size() * 32);
  for (std::size_t j = 0; j < palette.size(); ++j) {
    float dq[8];
    if (!skintune_kernels::DualQuaternionOf(&palette[j][0][0], dq)) throw std::runtime_error("joint is not rigid");
    if (negate_odd && j % 2 == 1)
      for (float& x : dq) x = -x;
    std::memcpy(rows.data() + 32 * j, dq, sizeof dq);
  }
  return rows;
}

// `n` random vertices with `b` influences on `joints` joints: positions 2 to
// 3 from the origin (each skinned one stays far from it, so that the
// relative error is the error of the map, not of a cancellation), unit
// normals and tangents of both handednesses, every weight non-zero and the
// largest first (the first influence is the side every other quaternion is
// taken to, in the kernels as in the gold).
SkinnedMesh RandomMesh(std::mt19937& rng, int b, int joints, std::size_t n) {
  std::normal_distribution<float> normal;
  std::uniform_real_distribution<float> radius(2.0f, 3.0f), weight(0.05f, 1.0f);
  std::uniform_int_distribution<int> joint(0, joints - 1);
  const auto direction = [&] { return glm::normalize(glm::vec3(normal(rng), normal(rng), normal(rng))); };
  SkinnedMesh mesh;
  mesh.name = "random rigid";
  mesh.influences = b;
  mesh.joint_count = joints;
  for (std::size_t v = 0; v < n; ++v) {
    mesh.positions.push_back(radius(rng) * direction());
    mesh.normals.push_back(direction());
    mesh.tangents.emplace_back(direction(), v % 2 ? -1.0f : 1.0f);
    std::vector<float> w(static_cast<std::size_t>(b));
    float sum = 0.0f;
    for (float& x : w) sum += x = weight(rng);
    std::sort(w.begin(), w.end(), std::greater<>());
    for (const float x : w) {
      mesh.joints.push_back(static_cast<std::uint16_t>(joint(rng)));
      mesh.weights.push_back(x / sum);
    }
  }
  return mesh;
}

// `mesh` with its weights as `format` stores them: unorm weights quantised
// to raw / scale by the largest remainder (each vertex's raw values sum to
// the scale exactly), as the kernels decode them.
SkinnedMesh StoredWeights(SkinnedMesh mesh, CpuWeight format) {
  if (format == CpuWeight::kF32) return mesh;
  const int scale = format == CpuWeight::kUnorm8 ? 255 : 65535;
  const auto b = static_cast<std::size_t>(mesh.influences);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    float* w = &mesh.weights[v * b];
    std::vector<int> raw(b);
    std::vector<std::size_t> order(b);
    int left = scale;
    for (std::size_t i = 0; i < b; ++i) {
      raw[i] = static_cast<int>(std::floor(static_cast<double>(w[i]) * scale));
      left -= raw[i];
      order[i] = i;
    }
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
      return static_cast<double>(w[x]) * scale - raw[x] > static_cast<double>(w[y]) * scale - raw[y];
    });
    for (std::size_t k = 0; left > 0; ++k, --left) ++raw[order[k % b]];
    for (std::size_t i = 0; i < b; ++i) w[i] = static_cast<float>(raw[i]) * (1.0f / static_cast<float>(scale));
  }
  return mesh;
}

enum class StreamLayout { kSoaSplit, kSoa, kAos };

// `mesh`'s vertices in `layout` with `index` and `weight` formats (unorm
// weights stored as raw = round(weight x scale): StoredWeights's values
// exactly), normals and tangents included, and the streams that read them.
struct MeshStreams {
  std::vector<std::uint8_t> positions, normals, tangents, indices, weights;  // aos: records in positions
  CpuStreams s;
};
MeshStreams StreamsOf(const SkinnedMesh& mesh, StreamLayout layout, CpuIndex index, CpuWeight weight) {
  const std::size_t n = mesh.vertex_count(), b = static_cast<std::size_t>(mesh.influences);
  const std::size_t ib = index == CpuIndex::kU32 ? 4 : index == CpuIndex::kU16 ? 2 : 1;
  const std::size_t wb = weight == CpuWeight::kF32 ? 4 : weight == CpuWeight::kUnorm16 ? 2 : 1;
  const bool aos = layout == StreamLayout::kAos;
  // aos: position, normal, tangent, indices, weights and a byte of padding a record.
  const std::size_t record = 40 + b * (ib + wb) + 1;
  MeshStreams m;
  m.positions.resize(aos ? record * n : 12 * n);
  m.normals.resize(12 * n);
  m.tangents.resize(16 * n);
  m.indices.resize(ib * b * n);
  m.weights.resize(wb * b * n);
  const auto put_index = [&](std::vector<std::uint8_t>& to, std::size_t at, std::uint16_t j) {
    if (ib == 4) Put(to, at, std::uint32_t{j});
    else if (ib == 2) Put(to, at, j);
    else Put(to, at, static_cast<std::uint8_t>(j));
  };
  const auto put_weight = [&](std::vector<std::uint8_t>& to, std::size_t at, float w) {
    if (wb == 4) Put(to, at, w);
    else if (wb == 2) Put(to, at, static_cast<std::uint16_t>(std::lround(w * 65535.0f)));
    else Put(to, at, static_cast<std::uint8_t>(std::lround(w * 255.0f)));
  };
  for (std::size_t v = 0; v < n; ++v) {
    const std::size_t at = aos ? v * record : 0;
    for (int c = 0; c < 3; ++c) {
      Put(m.positions, aos ? at + 4 * c : 12 * v + 4 * c, mesh.positions[v][c]);
      Put(aos ? m.positions : m.normals, aos ? at + 12 + 4 * c : 12 * v + 4 * c, mesh.normals[v][c]);
    }
    for (int c = 0; c < 4; ++c)
      Put(aos ? m.positions : m.tangents, aos ? at + 24 + 4 * c : 16 * v + 4 * c, mesh.tangents[v][c]);
    for (std::size_t i = 0; i < b; ++i) {
      const std::uint16_t j = mesh.joints[v * b + i];
      const float w = mesh.weights[v * b + i];
      if (aos) {
        put_index(m.positions, at + 40 + ib * i, j);
        put_weight(m.positions, at + 40 + ib * b + wb * i, w);
      } else {
        const std::size_t slot_at = layout == StreamLayout::kSoaSplit ? i * n + v : v * b + i;
        put_index(m.indices, ib * slot_at, j);
        put_weight(m.weights, wb * slot_at, w);
      }
    }
  }
  CpuStreams& s = m.s;
  if (aos) {
    s.positions = m.positions.data();
    s.normals = m.positions.data() + 12;
    s.tangents = m.positions.data() + 24;
    s.indices = m.positions.data() + 40;
    s.weights = m.positions.data() + 40 + ib * b;
    s.position_stride = s.normal_stride = s.tangent_stride = s.index_stride = s.weight_stride = record;
    s.index_slot = ib;
    s.weight_slot = wb;
  } else {
    const bool split = layout == StreamLayout::kSoaSplit;
    s.positions = m.positions.data();
    s.normals = m.normals.data();
    s.tangents = m.tangents.data();
    s.position_stride = s.normal_stride = 12;
    s.tangent_stride = 16;
    s.indices = m.indices.data();
    s.weights = m.weights.data();
    s.index_stride = split ? ib : b * ib;
    s.index_slot = split ? n * ib : ib;
    s.weight_stride = split ? wb : b * wb;
    s.weight_slot = split ? n * wb : wb;
  }
  return m;
}

// `kernel` over `s`'s n vertices in calls split at the first and last vertex
// of a 64-vertex block and off the 4-vertex stores, streaming and plain
// stores in turn, `floats` output floats, with normals and tangents or not;
// its outputs against `gold`.
void ExpectKernelMatchesGold(CpuKernelFn kernel, CpuStreams s, const CpuPalette& palette, std::size_t n, int floats,
                             bool normals, const GoldResult& gold) {
  const std::vector<std::size_t> cuts = {0, 1, 2, 5, 63, 64, 65, 67, 128, n - 1, n};
  Output out(floats * n), out_n(floats * n), out_t(4 * n);
  s.out_positions = out.data;
  s.out_normals = normals ? out_n.data : nullptr;
  s.out_tangents = normals ? out_t.data : nullptr;
  s.output_floats = floats;
  for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
    s.stream_stores = c % 2 == 1;
    kernel(s, palette, cuts[c], cuts[c + 1]);
  }
  std::vector<glm::vec3> got(n), got_n(n);
  std::vector<glm::vec4> got_t(n);
  for (std::size_t v = 0; v < n; ++v) {
    got[v] = {out.data[floats * v], out.data[floats * v + 1], out.data[floats * v + 2]};
    got_n[v] = {out_n.data[floats * v], out_n.data[floats * v + 1], out_n.data[floats * v + 2]};
    got_t[v] = {out_t.data[4 * v], out_t.data[4 * v + 1], out_t.data[4 * v + 2], out_t.data[4 * v + 3]};
    if (floats == 4) {
      ASSERT_EQ(out.data[4 * v + 3], 1.0f) << "vertex " << v;
    }
    if (floats == 4 && normals) {
      ASSERT_EQ(out_n.data[4 * v + 3], 0.0f) << "vertex " << v;
    }
  }
  const GoldComparison p = CompareToGold(gold.positions, got);
  EXPECT_EQ(p.non_finite, 0u);
  EXPECT_LT(p.max_relative, 1e-5) << "positions, worst vertex " << p.worst_vertex;
  if (normals) {
    const GoldComparison q = CompareToGold(gold.normals, got_n);
    EXPECT_EQ(q.non_finite, 0u);
    EXPECT_LT(q.max_relative, 1e-5) << "normals, worst vertex " << q.worst_vertex;
    const GoldComparison t = CompareTangentsToGold(gold.tangents, got_t);
    EXPECT_EQ(t.non_finite, 0u);
    EXPECT_EQ(t.wrong_handedness, 0u) << "first at vertex " << t.worst_vertex;
    EXPECT_LT(t.max_relative, 1e-5) << "tangents, worst vertex " << t.worst_vertex;
  } else {
    for (std::size_t k = 0; k < floats * n; ++k) ASSERT_TRUE(out_n.Poisoned(k)) << "normal word " << k;
    for (std::size_t k = 0; k < 4 * n; ++k) ASSERT_TRUE(out_t.Poisoned(k)) << "tangent word " << k;
  }
}

TEST(CpuKernels, EveryDualQuaternionKernelMatchesTheDualQuaternionGoldOnRigidPalettes) {
  // The kernels' form of a 2-row palette: each joint's real part, then its dual part, as packed.
  {
    std::vector<std::uint8_t> packed(64);
    for (std::size_t k = 0; k < 16; ++k) Put(packed, 4 * k, static_cast<float>(k + 1));
    CpuPalette p;
    LoadCpuPalette(packed, 2, p);
    ASSERT_EQ(p.joints.size(), 2u);
    for (std::size_t j = 0; j < 2; ++j)
      for (std::size_t k = 0; k < 16; ++k)
        ASSERT_EQ(p.joints[j].f[k], k < 8 ? static_cast<float>(8 * j + k + 1) : 0.0f)
            << "joint " << j << " float " << k;
  }

  std::mt19937 rng(20261201);
  constexpr int kJoints = 12;
  constexpr std::size_t kVertices = 150;
  struct PaletteCase {
    const char* name;
    bool near, negate_odd;
  };
  const PaletteCase palette_cases[] = {
      {"random rotations", false, false},
      {"random rotations, odd joints negated", false, true},
      {"rotations near one another, odd joints negated", true, true},
  };
  std::size_t kernel_count = 0;
  for (int b = 1; b <= kCpuMaxInfluences; ++b) {
    const SkinnedMesh mesh = RandomMesh(rng, b, kJoints, kVertices);
    for (const PaletteCase& pc : palette_cases) {
      const std::vector<glm::mat4> palette = RigidPalette(rng, kJoints, pc.near);
      CpuPalette cpu_palette;
      LoadCpuPalette(DualQuaternionRows(palette, pc.negate_odd), 2, cpu_palette);
      for (const CpuWeight weight : {CpuWeight::kF32, CpuWeight::kUnorm16, CpuWeight::kUnorm8}) {
        const SkinnedMesh stored = StoredWeights(mesh, weight);
        const GoldResult gold = SkinGoldDualQuaternion(stored, palette, true, true);
        for (const CpuIndex index : {CpuIndex::kU32, CpuIndex::kU16, CpuIndex::kU8}) {
          const CpuKernelKey key{b, index, weight, 2, false, true};
          ++kernel_count;
          // The layout and output floats turn with the kernel; normals and tangents off and on.
          const auto layout = static_cast<StreamLayout>(kernel_count % 3);
          const int floats = kernel_count / 3 % 2 ? 4 : 3;
          const MeshStreams streams = StreamsOf(stored, layout, index, weight);
          for (const bool normals : {false, true}) {
            SCOPED_TRACE(CpuKernelName(key) + ", " + pc.name + ", layout " + std::to_string(static_cast<int>(layout)) +
                         ", " + std::to_string(floats) + " output floats" + (normals ? ", normals and tangents" : ""));
            ExpectKernelMatchesGold(FindCpuKernel(key), streams.s, cpu_palette, kVertices, floats, normals, gold);
            if (HasFailure()) return;  // one failing kernel says enough
          }
        }
      }
    }
  }
  EXPECT_EQ(kernel_count, 8u * 3 * 3 * std::size(palette_cases));
}

TEST(CpuKernels, OneKernelPerKeyWithDistinctNames) {
  const std::vector<CpuKernelKey> keys = AllCpuKernelKeys();
  // Linear blending (matrix, point) with mat4 and mat3x4 palettes, dual
  // quaternions with their own 2-row palette only: 5 forms per (B, index, weight).
  EXPECT_EQ(keys.size(), 8u * 3 * 3 * 5);
  std::set<std::string> names;
  std::set<CpuKernelFn> kernels;
  std::set<std::tuple<int, int, int, int, bool, bool>> linear, dual_quaternion;
  for (const CpuKernelKey& k : keys) {
    names.insert(CpuKernelName(k));
    kernels.insert(FindCpuKernel(k));
    const auto key = std::make_tuple(k.influences, static_cast<int>(k.index), static_cast<int>(k.weight),
                                     k.palette_rows, k.point_blend, k.dual_quaternion);
    if (k.dual_quaternion) {
      EXPECT_EQ(k.palette_rows, 2) << CpuKernelName(k);
      EXPECT_FALSE(k.point_blend) << CpuKernelName(k);
      dual_quaternion.insert(key);
    } else {
      EXPECT_TRUE(k.palette_rows == 3 || k.palette_rows == 4) << CpuKernelName(k);
      linear.insert(key);
    }
  }
  EXPECT_EQ(names.size(), keys.size());
  EXPECT_EQ(kernels.size(), keys.size());
  EXPECT_EQ(linear.size(), 8u * 3 * 3 * 2 * 2);  // every linear key as before dual quaternions
  EXPECT_EQ(dual_quaternion.size(), 8u * 3 * 3);
  // Every linear key, built by hand, still resolves to its own kernel, and the key lists it.
  for (int b = 1; b <= 8; ++b)
    for (const CpuIndex index : {CpuIndex::kU32, CpuIndex::kU16, CpuIndex::kU8})
      for (const CpuWeight weight : {CpuWeight::kF32, CpuWeight::kUnorm16, CpuWeight::kUnorm8})
        for (const int rows : {4, 3})
          for (const bool point : {false, true}) {
            const CpuKernelKey k{b, index, weight, rows, point};
            EXPECT_TRUE(linear.contains(std::make_tuple(b, static_cast<int>(index), static_cast<int>(weight), rows,
                                                        point, false)))
                << CpuKernelName(k);
            EXPECT_TRUE(kernels.contains(FindCpuKernel(k))) << CpuKernelName(k);
          }
  EXPECT_EQ(CpuKernelName({4, CpuIndex::kU8, CpuWeight::kUnorm16, 3, true}), "b4.u8.unorm16.mat3x4.point");
  EXPECT_EQ(CpuKernelName({4, CpuIndex::kU16, CpuWeight::kF32, 4, false}), "b4.u16.f32.mat4.matrix");
  EXPECT_EQ(CpuKernelName({4, CpuIndex::kU8, CpuWeight::kUnorm16, 2, false, true}), "b4.u8.unorm16.dualquat.dq");
  EXPECT_NE(FindCpuKernel({4, CpuIndex::kU8, CpuWeight::kUnorm16, 2, false, true}),
            FindCpuKernel({4, CpuIndex::kU8, CpuWeight::kUnorm16, 3, false}));
  // The table chosen is one this build holds (SKINTUNE_CPU_ISAS), the first of them
  // (fastest first) that this CPU runs: baseline runs on every CPU.
  const std::string isa = CpuKernelIsa();
  const std::vector<std::string> built = CpuKernelIsasBuilt();
  ASSERT_FALSE(built.empty());
  EXPECT_NE(std::find(built.begin(), built.end(), isa), built.end()) << isa;
  if (built.back() == "baseline") {
    EXPECT_NE(isa, "none");
  }
}

TEST(CpuKernels, BadKeysAndPalettesAreErrorsNamingTheProblem) {
  const auto expect_error = [](auto f, const std::string& part) {
    try {
      f();
      ADD_FAILURE() << "no error (expected '" << part << "')";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_error([] { FindCpuKernel({0, CpuIndex::kU16, CpuWeight::kF32, 4, false}); }, "0 influences (expected 1..8)");
  expect_error([] { FindCpuKernel({9, CpuIndex::kU16, CpuWeight::kF32, 4, false}); }, "9 influences");
  expect_error([] { FindCpuKernel({4, CpuIndex::kU16, CpuWeight::kF32, 5, false}); },
               "5 palette rows (expected 4, 3 or 2)");
  expect_error([] { FindCpuKernel({4, CpuIndex::kU16, CpuWeight::kF32, 1, false, true}); }, "1 palette rows");
  // A dual-quaternion palette only with dual-quaternion blending, and that blending with no other palette.
  expect_error([] { FindCpuKernel({4, CpuIndex::kU16, CpuWeight::kF32, 2, false}); },
               "2 palette rows (a unit dual quaternion) are read by dual-quaternion blending only, not matrix");
  expect_error([] { FindCpuKernel({4, CpuIndex::kU16, CpuWeight::kF32, 2, true}); }, "only, not point blending");
  expect_error([] { FindCpuKernel({4, CpuIndex::kU16, CpuWeight::kF32, 4, false, true}); },
               "dual-quaternion blending reads 2 palette rows a joint (a unit dual quaternion), not 4");
  expect_error([] { FindCpuKernel({4, CpuIndex::kU16, CpuWeight::kF32, 2, true, true}); },
               "dual-quaternion and point blending together");
  CpuPalette p;
  expect_error([&] { LoadCpuPalette(std::vector<std::uint8_t>(40), 3, p); }, "40 bytes is not a whole number");
  expect_error([&] { LoadCpuPalette(std::vector<std::uint8_t>(40), 2, p); }, "40 bytes is not a whole number of 2-row");
  expect_error([&] { LoadCpuPalette(std::vector<std::uint8_t>(64), 5, p); }, "5 rows per joint (expected 4, 3 or 2)");
  expect_error([&] { LoadCpuPalette(std::vector<std::uint8_t>(64), 1, p); }, "1 rows per joint");
  ThreadPool pool(1);
  expect_error([&] { RunCpuKernel(FindCpuKernel({}), CpuStreams{}, p, 10, pool, 0); }, "chunk of 0 vertices");
  expect_error([] { FastestCandidate(0, [](std::size_t) { return 1.0; }); }, "no candidates");
}

TEST(CpuSchedules, CandidatesCoverThreadCountsAndChunksUpToTheMesh) {
  const std::vector<CpuSchedule> big = CpuScheduleCandidates(1600000, 4);
  std::set<unsigned> threads;
  for (const CpuSchedule& s : big) {
    threads.insert(s.threads);
    EXPECT_GT(s.chunk, 0u);
    EXPECT_EQ(s.chunk % 64, 0u) << Describe(s);
  }
  EXPECT_EQ(threads, (std::set<unsigned>{1, 2, 4}));
  EXPECT_EQ(big.size(), 3u * 4);  // 4k, 16k, 64k and one chunk per thread, for each count
  for (const CpuSchedule& s : CpuScheduleCandidates(1000, 2)) EXPECT_LE(s.chunk, 1024u) << Describe(s);
  EXPECT_FALSE(CpuScheduleCandidates(1, 0).empty());
  EXPECT_EQ(CpuScheduleCandidates(1, 0).back().threads, std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(Describe(CpuSchedule{2, 16384}), "2 threads x 16384-vertex chunks");
}

// FastestCandidate over candidates whose calls return `times[i]` in turn:
// the one chosen, each one's count of calls, and the order of the calls.
struct Choice {
  std::size_t best = 0;
  std::vector<std::size_t> calls, order;
};
Choice ChooseAmong(const std::vector<std::vector<double>>& times,
                   const std::function<std::size_t(std::size_t)>& warm_group = nullptr) {
  Choice c;
  c.calls.assign(times.size(), 0);
  c.best = FastestCandidate(
      times.size(),
      [&](std::size_t i) {
        c.order.push_back(i);
        return times[i][c.calls[i]++];
      },
      3, warm_group);
  return c;
}

TEST(CpuSchedules, TheCandidateWithTheQuickestSampleWins) {
  // Candidate 1 is fastest by median; candidate 2 has the quickest sample,
  // its others hit (as a neighbour's thread that preempts one of a frame's
  // threads doubles it), and wins. Every first sample is within
  // kFastestCandidateCut of the quickest: all go on.
  const Choice c = ChooseAmong({{5, 2.5, 5, 5}, {100, 2, 50, 2}, {9, 1, 9, 9}});
  EXPECT_EQ(c.best, 2u);
  EXPECT_EQ(c.calls, (std::vector<std::size_t>{4, 4, 4}));  // one untimed call and three samples each
  // In rounds, candidate after candidate: a slow spell of the host's falls on all alike.
  EXPECT_EQ(c.order, (std::vector<std::size_t>{0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2}));
}

TEST(CpuSchedules, ACandidateFarBehindAfterOneRoundIsTimedNoFurther) {
  // Candidate 0's first sample is 4x the quickest (1), candidate 2's exactly
  // 3x: 0 drops out after the first round (its later 0.1s are never
  // taken), 2 goes on, and 2 wins by its quickest sample.
  const Choice c = ChooseAmong({{9, 4, 0.1, 0.1}, {9, 1, 2, 2}, {9, 3, 0.5, 1}});
  EXPECT_EQ(c.best, 2u);
  EXPECT_EQ(c.calls, (std::vector<std::size_t>{2, 4, 4}));
  EXPECT_EQ(c.order, (std::vector<std::size_t>{0, 1, 2, 0, 1, 2, 1, 2, 1, 2}));
}

TEST(CpuSchedules, WarmGroupsTakeOneUntimedCallEach) {
  // Candidates 0 and 1 share a group (say, a pool of 4 threads), 2 is alone:
  // one untimed call for 0 and one for 2; 1's first call is timed.
  const Choice c = ChooseAmong({{9, 3, 3, 3}, {2, 2, 2}, {9, 4, 4, 4}}, [](std::size_t i) { return i < 2 ? 4u : 8u; });
  EXPECT_EQ(c.best, 1u);
  EXPECT_EQ(c.calls, (std::vector<std::size_t>{4, 3, 4}));
  EXPECT_EQ(c.order, (std::vector<std::size_t>{0, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2}));
}

}  // namespace
}  // namespace skintune::internal
