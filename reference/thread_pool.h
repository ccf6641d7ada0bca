// skintune: a persistent pool of worker threads for data-parallel loops.
// Starting threads per frame would cost more than skinning a small mesh.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace skintune::internal {

class ThreadPool {
 public:
  // threads = 0: std::thread::hardware_concurrency(). The calling thread
  // takes part in every loop, so `threads - 1` workers are started.
  //
  // spin: how long an idle worker (and a caller waiting for the last chunk)
  // keeps polling before it sleeps on a condition variable. Zero for loops
  // of milliseconds (the cpu device's kernels: a sleeping worker costs
  // nothing); some microseconds for loops that follow each other closely
  // (the runtime's read-back: its scan, then its copy), where waking a
  // sleeping thread takes about as long as the work.
  explicit ThreadPool(unsigned threads = 0, std::chrono::microseconds spin = std::chrono::microseconds(0));
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  unsigned size() const { return static_cast<unsigned>(workers_.size()) + 1; }

  // Calls body(begin, end) over [0, count) in chunks of `grain` (the last may
  // be shorter), spread over all threads; returns when every chunk is done.
  // Not reentrant: one loop at a time per pool.
  void ParallelFor(std::size_t count, std::size_t grain,
                   const std::function<void(std::size_t, std::size_t)>& body);

 private:
  void WorkerLoop();
  void RunChunks();
  // Polls `ready` for up to spin_; whether it came true.
  template <typename Ready>
  bool Spin(Ready&& ready) const;

  std::vector<std::thread> workers_;
  std::chrono::microseconds spin_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  const std::function<void(std::size_t, std::size_t)>* body_ = nullptr;
  std::size_t count_ = 0, grain_ = 1, next_chunk_ = 0, chunks_ = 0;
  // Written under mutex_; read without it by spinning threads.
  std::atomic<std::size_t> finished_chunks_{0};
  std::atomic<std::size_t> generation_{0};
  std::atomic<bool> stop_{false};
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
