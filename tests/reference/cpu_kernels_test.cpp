// The CPU kernel family (reference/cpu_kernels.h) on its own: streaming and
// plain stores write the same bytes and nothing outside the range, whatever
// the range's alignment; the table's keys and names; the schedule
// candidates and the choice among them; bad keys and palettes. Every kernel
// against the float64 gold through the cpu device: tests/runtime/cpu_runner_test.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <set>
#include <thread>

#include "reference/cpu_kernels.h"
#include "reference/error.h"
#include "reference/skinning.h"
#include "reference/synthetic.h"
#include "reference/thread_pool.h"

namespace skintune {
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
  const std::string isa = CpuKernelIsa();
  EXPECT_TRUE(isa == "avx512" || isa == "avx2" || isa == "baseline") << isa;
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
  std::vector<std::size_t> calls(3, 0);
  const std::size_t best = FastestCandidate(3, [&](std::size_t i) { return times[i][calls[i]++]; });
  EXPECT_EQ(best, 1u);
  EXPECT_EQ(calls, (std::vector<std::size_t>{4, 4, 4}));  // one untimed call and three samples each
}

}  // namespace
}  // namespace skintune
