#include "runtime/host_work.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <thread>

#include <unistd.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif

#include "generator/packer.h"
#include "reference/thread_pool.h"

namespace skintune::internal {

namespace {

// Up to 16 threads (the GPU machines' hosts have 16; more would only contend
// for their memory); idle workers poll for 20 us after a loop before
// sleeping: long enough to catch the copy that follows a scan, short enough
// not to hold cores the driver's threads want (a 100 us spin after every
// parallel palette packing made a SetPalette + Skin + Finish frame 10 us
// slower on the H200 machine).
constexpr unsigned kMaxHostThreads = 16;
constexpr auto kHostSpin = std::chrono::microseconds(20);

ThreadPool& HostPool() {
  static ThreadPool pool(std::clamp(std::thread::hardware_concurrency(), 1u, kMaxHostThreads), kHostSpin);
  return pool;
}

// The palette's pool: 4 threads pack 236 KB in 3-4 us where one takes 7-15
// (skintune_bench_upload palette/pinned-wc/poses:2/spinning:<n>, H200
// machine); more would spin on cores the driver's threads want. Its 3 workers
// poll for kFramePoll after each packing, as the submit thread does: with
// 20 us they were asleep by the next SetPalette of a frame loop that waits
// for its frames, and the wake-up cost the frame ~9 us (docs/PERFORMANCE.md,
// session 31).
constexpr unsigned kPaletteThreads = 4;

ThreadPool& PalettePool() {
  static ThreadPool pool(std::clamp(std::thread::hardware_concurrency(), 1u, kPaletteThreads), kFramePoll);
  return pool;
}

}  // namespace

void ForChunks(std::size_t count, std::size_t grain, const std::function<void(std::size_t, std::size_t)>& body) {
  static std::mutex busy;
  if (count <= std::max<std::size_t>(grain, 1)) {  // the pool only for more than one chunk
    if (count > 0) body(0, count);
    return;
  }
  ForChunksOn(HostPool(), busy, count, grain, body);
}

std::size_t PackPaletteOnPool(const float* column_major, std::size_t matrices, const Variant& variant,
                              std::uint8_t* out, float* largest_magnitude) {
  static std::mutex busy;
  ThreadPool& pool = PalettePool();
  const std::size_t runs = std::min<std::size_t>(pool.size(), matrices / kPaletteGrain);
  if (runs < 2) return PackPaletteInto(column_major, matrices, variant, out, PackIsa::kAuto, largest_magnitude);
  // Runs of whole multiples of 16 matrices (the packer's four-matrix stores
  // then start on the same boundaries as in one pass).
  const std::size_t grain = ((matrices + runs - 1) / runs + 15) / 16 * 16;
  const std::size_t bytes = PaletteMatrixBytes(variant);
  std::size_t first_bad[kPaletteThreads];
  float largest[kPaletteThreads];
  ForChunksOn(pool, busy, matrices, grain, [&](std::size_t begin, std::size_t end) {
    const std::size_t run = begin / grain;
    first_bad[run] = begin + PackPaletteInto(column_major + 16 * begin, end - begin, variant, out + bytes * begin,
                                             PackIsa::kAuto, &largest[run]);
  });
  std::size_t bad = matrices;
  float magnitude = 0.0f;
  for (std::size_t run = 0; run * grain < matrices; ++run) {
    const std::size_t end = std::min(matrices, (run + 1) * grain);
    if (first_bad[run] < end) bad = std::min(bad, first_bad[run]);
    magnitude = std::max(magnitude, largest[run]);
  }
  if (largest_magnitude) *largest_magnitude = magnitude;
  return bad;
}

bool StreamingWrite(std::size_t bytes) {
  static const std::size_t threshold = [] {
    long cache = 0;
#if defined(_SC_LEVEL3_CACHE_SIZE)
    cache = sysconf(_SC_LEVEL3_CACHE_SIZE);
    if (cache <= 0) cache = sysconf(_SC_LEVEL2_CACHE_SIZE);
#endif
    if (cache <= 0) cache = 32L << 20;  // not told: a typical server's
    return static_cast<std::size_t>(cache) / 4 * 3;
  }();
  return bytes >= threshold;
}

bool AllFinite(std::span<const std::uint8_t> bytes) {
  constexpr std::size_t kBlock = 1024;
  std::uint32_t words[kBlock];
  for (std::size_t at = 0; at < bytes.size() / 4; at += kBlock) {
    const std::size_t n = std::min(kBlock, bytes.size() / 4 - at);
    std::memcpy(words, bytes.data() + at * 4, n * 4);
    std::uint32_t special = 0;
    for (std::size_t i = 0; i < n; ++i) special |= ((words[i] & 0x7f800000u) == 0x7f800000u) ? 1u : 0u;
    if (special) return false;
  }
  return true;
}

void CopyFloat3(const std::uint8_t* packed, std::size_t stride, float* out, std::size_t begin, std::size_t end,
                bool streaming) {
  std::size_t v = begin;
  const auto scalar_until = [&](std::size_t until) {
    if (stride == 3 * sizeof(float)) {
      std::memcpy(out + 3 * v, packed + v * stride, (until - v) * stride);
      v = until;
    }
    for (; v < until; ++v) std::memcpy(out + 3 * v, packed + v * stride, 3 * sizeof(float));
  };
#if defined(__SSE2__)
  if (streaming && (reinterpret_cast<std::uintptr_t>(out) % sizeof(float)) == 0 && (stride == 12 || stride == 16)) {
    // The first vertex whose float3 starts on a 16-byte boundary (one of the
    // next four: 12 v mod 16 cycles through 0, 12, 8, 4), then four vertices
    // (48 bytes, three aligned 16-byte stores) at a time.
    std::size_t aligned = v;
    while (aligned < end && reinterpret_cast<std::uintptr_t>(out + 3 * aligned) % 16 != 0) ++aligned;
    if (aligned + 4 <= end && reinterpret_cast<std::uintptr_t>(out + 3 * aligned) % 16 == 0) {
      scalar_until(aligned);
      const std::size_t groups_end = aligned + (end - aligned) / 4 * 4;
      for (; v < groups_end; v += 4) {
        float* o = out + 3 * v;
        const std::uint8_t* in = packed + v * stride;
        if (stride == 16) {
          const __m128 a = _mm_loadu_ps(reinterpret_cast<const float*>(in));
          const __m128 b = _mm_loadu_ps(reinterpret_cast<const float*>(in + 16));
          const __m128 c = _mm_loadu_ps(reinterpret_cast<const float*>(in + 32));
          const __m128 d = _mm_loadu_ps(reinterpret_cast<const float*>(in + 48));
          const __m128 zx = _mm_shuffle_ps(a, b, _MM_SHUFFLE(0, 0, 2, 2));   // z0 z0 x1 x1
          const __m128 o0 = _mm_shuffle_ps(a, zx, _MM_SHUFFLE(2, 0, 1, 0));  // x0 y0 z0 x1
          const __m128 o1 = _mm_shuffle_ps(b, c, _MM_SHUFFLE(1, 0, 2, 1));   // y1 z1 x2 y2
          const __m128 zx2 = _mm_shuffle_ps(c, d, _MM_SHUFFLE(0, 0, 2, 2));  // z2 z2 x3 x3
          const __m128 o2 = _mm_shuffle_ps(zx2, d, _MM_SHUFFLE(2, 1, 2, 0)); // z2 x3 y3 z3
          _mm_stream_ps(o, o0);
          _mm_stream_ps(o + 4, o1);
          _mm_stream_ps(o + 8, o2);
        } else {
          for (int i = 0; i < 3; ++i)
            _mm_stream_si128(reinterpret_cast<__m128i*>(o) + i,
                             _mm_loadu_si128(reinterpret_cast<const __m128i*>(in) + i));
        }
      }
      _mm_sfence();
    }
  }
#else
  (void)streaming;
#endif
  scalar_until(end);
}

std::size_t ChunkCovering(std::size_t bytes, std::size_t chunk_bytes, std::size_t max_chunks) {
  const std::size_t at_least = (bytes + max_chunks - 1) / max_chunks;  // so that max_chunks of them cover `bytes`
  return std::max(chunk_bytes, (at_least + chunk_bytes - 1) / chunk_bytes * chunk_bytes);
}

bool CopyFloat3Finite(const std::uint8_t* packed, std::size_t stride, float* out, std::size_t begin, std::size_t end,
                      bool streaming) {
  constexpr std::size_t kBlock = 512;  // vertices: 6-8 KB of `packed`, well inside a core's L1
  for (std::size_t at = begin; at < end; at += kBlock) {
    const std::size_t until = std::min(end, at + kBlock);
    if (!AllFinite({packed + at * stride, (until - at) * stride})) return false;
    CopyFloat3(packed, stride, out, at, until, streaming);
  }
  return true;
}

double OutputBound(const SkinnedMesh& mesh) {
  double weight_sum = 0.0, position = 1.0;
  const std::size_t b = static_cast<std::size_t>(mesh.influences);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    double sum = 0.0;
    for (std::size_t i = 0; i < b; ++i) sum += std::fabs(static_cast<double>(mesh.weights[v * b + i]));
    weight_sum = std::max(weight_sum, sum);
    for (int c = 0; c < 3; ++c) position = std::max(position, std::fabs(static_cast<double>(mesh.positions[v][c])));
  }
  return 4.0 * (weight_sum + static_cast<double>(b)) * position;
}

bool CannotOverflow(double output_bound, float magnitude) {
  return output_bound * static_cast<double>(magnitude) <= static_cast<double>(std::numeric_limits<float>::max()) / 1024.0;
}

}  // namespace skintune::internal
