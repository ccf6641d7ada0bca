#include "runtime/host_work.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <thread>
#include <vector>

#include <unistd.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif

#include "generator/packer.h"
#include "base/thread_pool.h"

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

// Threads that each run the same lane of every loop: Run(body) calls
// body(lane) once for each lane, lane 0 on the caller and lane l on helper l
// when that helper takes it in time; the caller takes every lane still free
// once its own is done, so a helper asleep or descheduled costs the loop
// nothing but its share of the speed-up. Helpers poll for the next loop for
// `poll`, then sleep. One Run at a time.
//
// Why not the ThreadPool, whose chunks go to whichever thread claims them: on
// the GPU machine's host (16 cores) the palette's 4 runs packed in 3.1-3.4 us
// by threads that keep their run, in 9.9-10.3 us when the runs changed hands
// every frame, and 10.5-11.3 us on the ThreadPool, no better than one thread
// (skintune_bench_upload palette/pinned-wc/poses:2/{spinning:4,
// spinning:4/claims,runtime}, H100 machine, 2026-11-27): a run's input
// lines are in the cache of the core that packed it last.
class LaneCrew {
 public:
  LaneCrew(unsigned lanes, std::chrono::microseconds poll) : lanes_(std::clamp(lanes, 1u, kMaxLanes)), poll_(poll) {
    for (unsigned l = 0; l < lanes_; ++l) claimed_[l].store(0, std::memory_order_relaxed);
    for (unsigned l = 1; l < lanes_; ++l) helpers_.emplace_back([this, l] { Helper(l); });
  }
  ~LaneCrew() {
    stop_.store(true);
    { const std::lock_guard<std::mutex> lock(mutex_); }
    wake_.notify_all();
    for (std::thread& t : helpers_) t.join();
  }
  LaneCrew(const LaneCrew&) = delete;
  LaneCrew& operator=(const LaneCrew&) = delete;

  unsigned lanes() const { return lanes_; }

  // Lanes [0, count) (count clamped to [1, lanes()]); the helpers of the
  // others go back to sleep without polling.
  void Run(unsigned count, const std::function<void(unsigned)>& body) {
    count = std::clamp(count, 1u, lanes_);
    body_ = &body;
    done_.store(0, std::memory_order_relaxed);
    const std::uint64_t generation = ++loops_;
    loop_.store(generation << 8 | count);  // seq_cst: publishes body_; see asleep_
    // Woken only when a helper of this loop sleeps: the helpers of lanes it
    // leaves out sleep for good, and waking them every loop would cost each
    // SetPalette a system call.
    bool wake = false;
    for (unsigned l = 1; l < count && !wake; ++l) wake = asleep_[l].load();
    if (wake) {
      { const std::lock_guard<std::mutex> lock(mutex_); }
      wake_.notify_all();
    }
    for (unsigned l = 0; l < count; ++l)  // its own lane first, then any a helper has not taken
      if (Take(l, generation)) {
        body(l);
        done_.fetch_add(1, std::memory_order_acq_rel);
      }
    while (done_.load(std::memory_order_acquire) != count) CpuPause();  // lanes running on helpers
    body_ = nullptr;
  }

 private:
  static constexpr unsigned kMaxLanes = 16;
  // Lane l of loop `generation`, unless someone took it (each lane's last
  // loop is its claim).
  bool Take(unsigned l, std::uint64_t generation) {
    std::uint64_t last = claimed_[l].load(std::memory_order_acquire);
    while (last < generation)
      if (claimed_[l].compare_exchange_weak(last, generation, std::memory_order_acq_rel)) return true;
    return false;
  }
  void Helper(unsigned lane) {
    std::uint64_t seen = 0;
    bool idle = true;  // not in the last loop: sleep at once, without polling
    for (;;) {
      const auto fresh = [&] { return stop_.load() || loop_.load() != seen; };
      if (!PollFor(idle ? std::chrono::microseconds(0) : poll_, fresh)) {
        std::unique_lock<std::mutex> lock(mutex_);
        asleep_[lane].store(true);  // before the check (seq_cst with Run's store of loop_: Dekker)
        wake_.wait(lock, fresh);
        asleep_[lane].store(false);
      }
      if (stop_.load()) return;
      // A loop's number and lane count in one word: a helper that reads it
      // late, after the next loop began, takes nothing (every lane of that
      // loop was taken before it ended).
      seen = loop_.load();
      idle = lane >= (seen & 0xff);
      if (!idle && Take(lane, seen >> 8)) {
        (*body_)(lane);
        done_.fetch_add(1, std::memory_order_acq_rel);
      }
    }
  }

  const unsigned lanes_;
  const std::chrono::microseconds poll_;
  const std::function<void(unsigned)>* body_ = nullptr;
  std::uint64_t loops_ = 0;              // the caller's count of loops
  std::atomic<std::uint64_t> loop_{0};   // the current loop: its number << 8 | its lane count
  std::atomic<std::uint64_t> claimed_[kMaxLanes];  // each lane: the last loop that took it
  std::atomic<unsigned> done_{0};
  std::atomic<bool> asleep_[kMaxLanes] = {};  // each helper's: asleep on wake_ (or about to be)
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<std::thread> helpers_;
};

// The palette's crew: half the host's cores, at least 2 (where there are 2)
// and at most kMaxPaletteLanes. 4 threads pack 236 KB in 3-4 us where one
// takes 7-15 (above); inside the frame loop 8 packed it in 6.5-7 us where 4
// took 7.3-10.2, and the CUDA frame with the submit thread went from 0.92-0.94
// to 0.96-0.97 of Skin-only (H100 machine, 2026-11-27); the other half
// of the cores stays for the driver's threads and the application. The
// helpers poll for kFramePoll after each packing, as the submit thread does:
// with 20 us they were asleep by the next SetPalette of a frame loop that
// waits for its frames, and the wake-up cost the frame ~9 us (H100 machine,
// 2026-11-27).
unsigned PaletteLanes() {
  const unsigned cores = std::max(std::thread::hardware_concurrency(), 1u);
  return std::min(cores, std::clamp(cores / 2, 2u, kMaxPaletteLanes));
}

LaneCrew& PaletteCrew() {
  static LaneCrew crew(PaletteLanes(), kFramePoll);
  return crew;
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
                              std::uint8_t* out, float* largest_magnitude, unsigned max_threads) {
  static std::mutex busy;  // one Run at a time: a second caller packs alone
  if (max_threads == 1 || matrices < 2 * kPaletteGrain)  // the crew not even started
    return PackPaletteInto(column_major, matrices, variant, out, PackIsa::kAuto, largest_magnitude);
  LaneCrew& crew = PaletteCrew();
  const unsigned threads = max_threads == 0 ? crew.lanes() : std::min(crew.lanes(), max_threads);
  const std::size_t runs = std::min<std::size_t>(threads, matrices / kPaletteGrain);
  std::unique_lock<std::mutex> lock(busy, std::defer_lock);
  if (runs < 2 || !lock.try_lock())
    return PackPaletteInto(column_major, matrices, variant, out, PackIsa::kAuto, largest_magnitude);
  // Runs of whole multiples of 16 matrices (the packer's four-matrix stores
  // then start on the same boundaries as in one pass).
  const std::size_t grain = ((matrices + runs - 1) / runs + 15) / 16 * 16;
  const std::size_t bytes = PaletteMatrixBytes(variant);
  std::size_t first_bad[kMaxPaletteLanes];
  float largest[kMaxPaletteLanes];
  crew.Run(static_cast<unsigned>(runs), [&](unsigned lane) {
    const std::size_t run = lane, begin = run * grain;
    if (begin >= matrices) return;
    const std::size_t end = std::min(matrices, begin + grain);
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
