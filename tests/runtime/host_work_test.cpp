// The Skinner's host work (runtime/host_work.h): the read-back's scan and
// copy give exactly what their serial forms give.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "generator/packer.h"
#include "runtime/host_work.h"

namespace skintune::internal {
namespace {

// Vertices [begin, end) of a stride-12 or stride-16 buffer into a float3
// array at every alignment of the array, streaming or not: exactly the
// float3s, and nothing outside [3 begin, 3 end) written.
TEST(HostWork, CopyFloat3WritesExactlyTheRangeAtEveryAlignmentAndStride) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-100.0f, 100.0f);
  for (const std::size_t stride : {12u, 16u}) {
    const std::size_t vertices = 1000;
    std::vector<std::uint8_t> packed(vertices * stride);
    std::vector<float> truth(vertices * 3);
    for (std::size_t v = 0; v < vertices; ++v)
      for (int c = 0; c < 3; ++c) {
        truth[v * 3 + c] = u(rng);
        std::memcpy(packed.data() + v * stride + c * 4, &truth[v * 3 + c], 4);
      }
    if (stride == 16)
      for (std::size_t v = 0; v < vertices; ++v) std::memcpy(packed.data() + v * 16 + 12, &truth[0], 4);
    for (const bool streaming : {false, true})
      for (std::size_t shift = 0; shift < 4; ++shift)
        for (const auto& [begin, end] : std::vector<std::pair<std::size_t, std::size_t>>{
                 {0, 1000}, {0, 3}, {1, 2}, {5, 9}, {3, 997}, {17, 18}, {0, 0}, {999, 1000}}) {
          std::vector<float> storage(vertices * 3 + 8, -7.0f);
          float* out = storage.data() + shift;  // 4-byte steps through a 16-byte line
          CopyFloat3(packed.data(), stride, out, begin, end, streaming);
          for (std::size_t i = 0; i < storage.size(); ++i) {
            const std::ptrdiff_t at = static_cast<std::ptrdiff_t>(i) - static_cast<std::ptrdiff_t>(shift);
            const bool inside = at >= static_cast<std::ptrdiff_t>(begin * 3) && at < static_cast<std::ptrdiff_t>(end * 3);
            ASSERT_EQ(storage[i], inside ? truth[static_cast<std::size_t>(at)] : -7.0f)
                << "stride " << stride << (streaming ? " streaming" : "") << ", shift " << shift << ", [" << begin
                << ", " << end << ") at " << at;
          }
        }
  }
}

TEST(HostWork, AllFiniteFindsAnInfinityOrNaNAnywhere) {
  std::vector<float> words(5000, 1.5f);
  const auto bytes = [&] { return std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(words.data()), words.size() * 4); };
  EXPECT_TRUE(AllFinite(bytes()));
  for (const std::size_t at : {0u, 1023u, 1024u, 4999u}) {
    for (const float bad : {std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                            std::numeric_limits<float>::quiet_NaN()}) {
      words[at] = bad;
      EXPECT_FALSE(AllFinite(bytes())) << at;
      words[at] = std::numeric_limits<float>::max();
      EXPECT_TRUE(AllFinite(bytes())) << at;
    }
  }
}

// The one-pass copy and scan: every vertex of a finite range copied as
// CopyFloat3 copies it (true); a NaN or infinity anywhere (x, y, z, or
// float4's w) gives false, and no vertex from its 512-vertex block on is
// written, so the bad word never reaches the array.
TEST(HostWork, CopyFloat3FiniteCopiesAFiniteRangeAndStopsBeforeANonFiniteBlock) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-100.0f, 100.0f);
  const std::size_t vertices = 3000;
  for (const std::size_t stride : {12u, 16u}) {
    std::vector<float> words(vertices * stride / 4);
    for (float& w : words) w = u(rng);
    const auto* packed = reinterpret_cast<const std::uint8_t*>(words.data());
    for (const bool streaming : {false, true})
      for (const auto& [begin, end] : std::vector<std::pair<std::size_t, std::size_t>>{{0, 3000}, {7, 2001}, {513, 514}, {5, 5}}) {
        std::vector<float> expected(vertices * 3, -7.0f), out(vertices * 3, -7.0f);
        CopyFloat3(packed, stride, expected.data(), begin, end, false);
        EXPECT_TRUE(CopyFloat3Finite(packed, stride, out.data(), begin, end, streaming));
        ASSERT_EQ(out, expected) << "stride " << stride << ", [" << begin << ", " << end << ")";
      }
    for (const std::size_t bad_vertex : {std::size_t{0}, std::size_t{511}, std::size_t{1700}, vertices - 1})
      for (std::size_t word = 0; word < stride / 4; ++word) {
        std::vector<float> with = words;
        with[bad_vertex * stride / 4 + word] =
            word % 2 ? std::numeric_limits<float>::quiet_NaN() : -std::numeric_limits<float>::infinity();
        std::vector<float> out(vertices * 3, -7.0f);
        EXPECT_FALSE(CopyFloat3Finite(reinterpret_cast<const std::uint8_t*>(with.data()), stride, out.data(), 0,
                                      vertices, true))
            << "stride " << stride << ", vertex " << bad_vertex << " word " << word;
        const std::size_t block = bad_vertex / 512 * 512;  // blocks of 512 from `begin` (0)
        std::vector<float> before(vertices * 3, -7.0f);     // the blocks before it, copied
        CopyFloat3(reinterpret_cast<const std::uint8_t*>(with.data()), stride, before.data(), 0, block, false);
        ASSERT_EQ(out, before) << "stride " << stride << ", vertex " << bad_vertex << " word " << word;
      }
  }
}

// The read-back's overflow bound: 4 x (largest weight sum + B) x largest
// |position| (at least 1), whatever vertex holds each; and the one-pass
// threshold at a 1024th of float32's largest.
TEST(HostWork, TheOutputBoundIsFourTermsOfWeightSumAndPositionAndItsThreshold) {
  SkinnedMesh mesh;
  mesh.influences = 2;
  mesh.joint_count = 3;
  mesh.positions = {{0.5f, -0.25f, 0.0f}, {3.0f, -5.0f, 2.0f}, {0.0f, 0.0f, 0.0f}};
  mesh.joints = {0, 1, 1, 2, 0, 0};
  mesh.weights = {0.5f, 0.5f, 1.0f, 0.0f, 0.75f, 0.5f};  // the last vertex's sum, 1.25, is the largest
  EXPECT_DOUBLE_EQ(OutputBound(mesh), 4.0 * (1.25 + 2.0) * 5.0);
  mesh.positions = {{0.5f, -0.25f, 0.0f}, {0.1f, 0.2f, 0.3f}, {0.0f, 0.0f, 0.0f}};
  EXPECT_DOUBLE_EQ(OutputBound(mesh), 4.0 * (1.25 + 2.0) * 1.0) << "the translation column: |position| at least 1";
  const double bound = 65.0, limit = static_cast<double>(std::numeric_limits<float>::max()) / 1024.0;
  EXPECT_TRUE(CannotOverflow(bound, 1.0f));
  EXPECT_TRUE(CannotOverflow(bound, static_cast<float>(limit / bound * 0.999)));
  EXPECT_FALSE(CannotOverflow(bound, static_cast<float>(limit / bound * 1.001)));
  EXPECT_FALSE(CannotOverflow(bound, 3e38f));
  EXPECT_FALSE(CannotOverflow(bound, std::numeric_limits<float>::max()));
}

// Every index exactly once, in chunks on the pool and as one chunk on the caller.
// The read-back's chunk for at most N chunks: a multiple of the one asked
// for, at least it, and N of them cover every byte count, including those
// not a multiple of N (bytes / N rounded down gave N + 1 chunks there).
TEST(HostWork, ChunkCoveringIsAWholeMultipleAndAtMostMaxChunksCoverTheBytes) {
  EXPECT_EQ(ChunkCovering(100, 1000, 8), 1000u);  // fewer bytes than one chunk
  EXPECT_EQ(ChunkCovering(8000, 1000, 8), 1000u);
  EXPECT_EQ(ChunkCovering(8001, 1000, 8), 2000u);
  for (std::size_t max_chunks : {1u, 8u, 16u})
    for (std::size_t unit : {12u, 786432u})
      for (std::size_t bytes : std::initializer_list<std::size_t>{unit, 16 * unit + 1, 19200000, 19200012, 100 * unit + 7}) {
        const std::size_t chunk = ChunkCovering(bytes, unit, max_chunks);
        EXPECT_EQ(chunk % unit, 0u) << bytes << " " << unit;
        EXPECT_GE(chunk, unit);
        EXPECT_LE((bytes + chunk - 1) / chunk, max_chunks) << bytes << " " << unit << " " << max_chunks;
        if (chunk > unit) {
          EXPECT_GT((bytes + chunk - unit - 1) / (chunk - unit), max_chunks) << "not the smallest";
        }
      }
}

// The palette packed on the pool is PackPaletteInto's, byte for byte, in
// both palette formats and at sizes below, at and above a run: the same
// first non-finite matrix (wherever it falls among the runs, the earliest
// of two in different runs) and the same largest |element|.
TEST(HostWork, PackingOnThePoolGivesTheOnePassBytesFirstBadMatrixAndMagnitude) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-50.0f, 50.0f);
  for (const PaletteFormat format : {PaletteFormat::kMat3x4, PaletteFormat::kMat4}) {
    Variant variant;
    variant.palette = format;
    const std::size_t row = PaletteMatrixBytes(variant);
    for (const std::size_t matrices : {std::size_t{77}, kPaletteGrain * 2, std::size_t{64 * 77}, std::size_t{5003}}) {
      std::vector<float> in(matrices * 16);
      for (float& f : in) f = u(rng);
      in[16 * (matrices - 2) + 5] = 97.5f;  // the largest, in the last run
      const auto check = [&](const std::string& what) {
        std::vector<std::uint8_t> one(matrices * row, 0xcd), pooled(matrices * row, 0xab);
        float one_largest = -1.0f, pooled_largest = -2.0f;
        const std::size_t one_bad = PackPaletteInto(in.data(), matrices, variant, one.data(), PackIsa::kAuto, &one_largest);
        const std::size_t pooled_bad = PackPaletteOnPool(in.data(), matrices, variant, pooled.data(), &pooled_largest);
        ASSERT_EQ(pooled_bad, one_bad) << what;
        if (one_bad == matrices) {
          EXPECT_EQ(pooled, one) << what;
          EXPECT_EQ(pooled_largest, one_largest) << what;
        }
      };
      check(std::to_string(matrices) + " finite matrices");
      for (const std::size_t bad : {std::size_t{0}, matrices / 2, matrices - 1}) {
        const float kept = in[16 * bad + 3];
        in[16 * bad + 3] = std::numeric_limits<float>::quiet_NaN();
        check("a NaN in matrix " + std::to_string(bad) + " of " + std::to_string(matrices));
        if (bad > 0) {
          const float first = in[7];
          in[7] = std::numeric_limits<float>::infinity();  // an earlier one, in the first run
          check("infinity in matrix 0 and a NaN in matrix " + std::to_string(bad));
          in[7] = first;
        }
        in[16 * bad + 3] = kept;
      }
    }
  }
}

// The palette's threads (each its own run, the caller any run left) under
// the frame loop's conditions: thousands of packings back to back, on 1 to 8
// threads in turn, a packing after the helpers have gone to sleep, and two
// callers at once (the second packs alone); every result PackPaletteInto's.
TEST(HostWork, PackingOnThePoolStaysExactBackToBackAfterASleepAndFromTwoThreads) {
  Variant variant;
  variant.palette = PaletteFormat::kMat3x4;
  constexpr std::size_t kMatrices = 64 * 77;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  std::vector<std::vector<float>> poses(3, std::vector<float>(kMatrices * 16));
  std::vector<std::vector<std::uint8_t>> expected;
  for (auto& pose : poses) {
    for (float& f : pose) f = u(rng);
    expected.emplace_back(kMatrices * 48);
    PackPaletteInto(pose.data(), kMatrices, variant, expected.back().data());
  }
  const auto pack_and_check = [&](std::size_t pose, std::vector<std::uint8_t>& out) {
    float largest = 0.0f;
    EXPECT_EQ(PackPaletteOnPool(poses[pose].data(), kMatrices, variant, out.data(), &largest), kMatrices);
    return out == expected[pose];
  };
  std::vector<std::uint8_t> out(kMatrices * 48);
  int wrong = 0;
  for (int f = 0; f < 2000; ++f) wrong += !pack_and_check(static_cast<std::size_t>(f) % 3, out);
  EXPECT_EQ(wrong, 0);
  // At most n threads (SkinnerOptions::palette_threads), in any order of n.
  for (const unsigned n : {1u, 2u, 8u, 3u, 0u, 5u, 1u, 4u})
    for (std::size_t pose = 0; pose < 3; ++pose) {
      float largest = 0.0f;
      std::fill(out.begin(), out.end(), std::uint8_t{0xee});
      EXPECT_EQ(PackPaletteOnPool(poses[pose].data(), kMatrices, variant, out.data(), &largest, n), kMatrices);
      EXPECT_TRUE(out == expected[pose]) << n << " threads, pose " << pose;
    }
  std::this_thread::sleep_for(std::chrono::milliseconds(5));  // past the helpers' polling: asleep
  EXPECT_TRUE(pack_and_check(1, out));
  std::atomic<int> wrong_elsewhere{0};
  std::thread other([&] {
    std::vector<std::uint8_t> mine(kMatrices * 48);
    for (int f = 0; f < 300; ++f) wrong_elsewhere += !pack_and_check(static_cast<std::size_t>(f + 1) % 3, mine);
  });
  for (int f = 0; f < 300; ++f) wrong += !pack_and_check(static_cast<std::size_t>(f) % 3, out);
  other.join();
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(wrong_elsewhere.load(), 0);
}

TEST(HostWork, ForChunksVisitsEveryIndexOnce) {
  for (const std::size_t grain : {std::size_t{4096}, std::size_t{1} << 20}) {
    std::vector<std::atomic<int>> hits(100003);
    ForChunks(hits.size(), grain, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) ++hits[i];
    });
    for (std::size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i].load(), 1) << i;
  }
}

TEST(HostWork, StreamingOnlyForWritesLargerThanMostOfTheLastLevelCache) {
  EXPECT_FALSE(StreamingWrite(0));
  EXPECT_FALSE(StreamingWrite(64 << 10));
  EXPECT_TRUE(StreamingWrite(std::size_t{1} << 40));
}

}  // namespace
}  // namespace skintune::internal
