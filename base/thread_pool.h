// skintune: a persistent pool of worker threads for data-parallel loops.
// Starting threads per frame would cost more than skinning a small mesh.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace skintune::internal {

// The CPU's hint for a spin-wait loop (x86's pause, which leaves a sibling
// hardware thread most of the core; elsewhere a yield).
inline void CpuPause() {
#if defined(__SSE2__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}

// Polls `ready` until it holds or `limit` has passed, pausing between polls
// and reading the clock every 64; whether it held. A zero limit checks once.
// The threads that serve a frame loop wait so for their next piece of work
// (ThreadPool's workers, the runtime's submit thread and palette crew):
// waking a sleeping thread costs more than the work.
template <typename Ready>
bool PollFor(std::chrono::microseconds limit, Ready&& ready) {
  if (limit.count() <= 0) return ready();
  const auto until = std::chrono::steady_clock::now() + limit;
  for (;;) {
    for (int i = 0; i < 64; ++i) {
      if (ready()) return true;
      CpuPause();
    }
    if (std::chrono::steady_clock::now() >= until) return ready();
  }
}

class ThreadPool {
 public:
  // threads = 0: std::thread::hardware_concurrency(). The calling thread
  // takes part in every loop, so `threads - 1` workers are started.
  //
  // spin: how long an idle worker (and a caller waiting for the last chunk)
  // keeps polling before it sleeps on a condition variable. Zero for loops
  // of milliseconds far apart (the float64 gold: a sleeping worker costs
  // nothing); some microseconds for loops that follow each other closely
  // (the runtime's read-back: its scan, then its copy; the cpu device's
  // kernels, one loop per instance of a crowd), where waking a sleeping
  // thread takes about as long as the work.
  explicit ThreadPool(unsigned threads = 0, std::chrono::microseconds spin = std::chrono::microseconds(0));
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  unsigned size() const { return static_cast<unsigned>(workers_.size()) + 1; }

  // Wakes every worker and returns once all of them run: a loop started
  // within `spin` of it starts on every thread at once, paying no sleeping
  // thread's wake-up (tens of microseconds, and unsteady: a futex wake and a
  // scheduler's decision per worker). The cpu device's kernel time starts
  // after it, as a GPU's starts after its launch reached the device.
  void Ready();

  // Calls body(begin, end) over [0, count) in chunks of `grain` (the last may
  // be shorter), spread over all threads; returns when every chunk is done.
  // Not reentrant: one loop at a time per pool.
  void ParallelFor(std::size_t count, std::size_t grain,
                   const std::function<void(std::size_t, std::size_t)>& body);

 private:
  // The loop's chunks are claimed without a lock: claim_ holds the loop's
  // generation (16 bits), its chunk count (24 bits) and the next chunk (24
  // bits), so a thread claims a chunk only of the loop it was woken for, and
  // one compare-and-swap hands it out. A thread that holds a claim reads
  // body_, count_ and grain_, which stay until every chunk is finished. The
  // mutex and the condition variables are only for threads that sleep.
  static constexpr int kChunkBits = 24;
  static constexpr std::uint64_t kChunkMask = (std::uint64_t{1} << kChunkBits) - 1;
  static std::uint64_t Generation(std::uint64_t c) { return c >> (2 * kChunkBits); }
  static std::uint64_t Chunks(std::uint64_t c) { return (c >> kChunkBits) & kChunkMask; }
  static std::uint64_t Next(std::uint64_t c) { return c & kChunkMask; }

  void WorkerLoop();
  // Runs chunks of loop `generation` while some are left unclaimed.
  void RunChunks(std::uint64_t generation);

  std::vector<std::thread> workers_;
  std::chrono::microseconds spin_;
  const std::function<void(std::size_t, std::size_t)>* body_ = nullptr;
  std::size_t count_ = 0, grain_ = 1;
  std::uint64_t generation_ = 0;  // the caller's count of loops
  std::atomic<std::uint64_t> claim_{0};
  std::atomic<std::uint64_t> finished_{0};  // chunks of the current loop done
  std::atomic<int> sleepers_{0};            // workers asleep on wake_ (or about to be)
  std::atomic<bool> caller_sleeps_{false};  // the caller asleep on done_ (or about to be)
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
};

// body(begin, end) over [0, count) in chunks of `grain` on `pool` when count >
// grain and no other loop holds `busy` (ParallelFor is not reentrant: a
// second caller, or a nested loop, runs on its own thread); otherwise on the
// calling thread, chunk by chunk in order.
void ForChunksOn(ThreadPool& pool, std::mutex& busy, std::size_t count, std::size_t grain,
                 const std::function<void(std::size_t, std::size_t)>& body);

// ForChunksOn a process-wide pool of hardware_concurrency() sleeping threads:
// the float64 gold and its comparisons, which the tuner runs on meshes of
// millions of vertices (6.4M: ~0.5 s for one gold on one thread).
void ParallelChunks(std::size_t count, std::size_t grain, const std::function<void(std::size_t, std::size_t)>& body);

}  // namespace skintune::internal
