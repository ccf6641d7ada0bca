// The CPU kernel family (cpu_kernels/cpu_kernels.h) on its own: streaming and
// plain stores write the same bytes and nothing outside the range, whatever
// the range's alignment; every loop path (the first and last vertex of a
// range, ranges split off 4- and 64-vertex boundaries, positions ending at an
// unreadable page, each stream layout, normals on and off, 3 and 4 output
// floats) against the float64 gold; the table's keys and names; the schedule
// candidates and the choice among them; bad keys and palettes. Every kernel
// against the float64 gold through the cpu device: tests/runtime/cpu_runner_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <sys/mman.h>
#include <unistd.h>

#include "cpu_kernels/cpu_kernels.h"
#include "base/error.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "base/thread_pool.h"

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

TEST(CpuKernels, OneKernelPerKeyWithDistinctNames) {
  const std::vector<CpuKernelKey> keys = AllCpuKernelKeys();
  EXPECT_EQ(keys.size(), 8u * 3 * 3 * 2 * 2);
  std::set<std::string> names;
  std::set<CpuKernelFn> kernels;
  for (const CpuKernelKey& k : keys) {
    names.insert(CpuKernelName(k));
    kernels.insert(FindCpuKernel(k));
  }
  EXPECT_EQ(names.size(), keys.size());
  EXPECT_EQ(kernels.size(), keys.size());
  EXPECT_EQ(CpuKernelName({4, CpuIndex::kU8, CpuWeight::kUnorm16, 3, true}), "b4.u8.unorm16.mat3x4.point");
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
  expect_error([] { FindCpuKernel({4, CpuIndex::kU16, CpuWeight::kF32, 2, false}); }, "2 palette rows");
  CpuPalette p;
  expect_error([&] { LoadCpuPalette(std::vector<std::uint8_t>(40), 3, p); }, "40 bytes is not a whole number");
  expect_error([&] { LoadCpuPalette(std::vector<std::uint8_t>(64), 5, p); }, "5 rows per joint");
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

TEST(CpuSchedules, TheFastestCandidateByMedianWins) {
  // Candidate 1 is fastest by median although its first (untimed) call and
  // one sample are slow; candidate 2 has the fastest single sample.
  std::vector<std::vector<double>> times = {{5, 5, 5, 5}, {100, 2, 50, 2}, {9, 1, 9, 9}};
  std::vector<std::size_t> calls(3, 0), order;
  const std::size_t best = FastestCandidate(3, [&](std::size_t i) {
    order.push_back(i);
    return times[i][calls[i]++];
  });
  EXPECT_EQ(best, 1u);
  EXPECT_EQ(calls, (std::vector<std::size_t>{4, 4, 4}));  // one untimed call and three samples each
  // In rounds, candidate after candidate: a slow spell of the host's falls on all alike.
  EXPECT_EQ(order, (std::vector<std::size_t>{0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2}));
}

}  // namespace
}  // namespace skintune::internal
