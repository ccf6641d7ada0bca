// skintune: a persistent pool of worker threads for data-parallel loops.
// Starting threads per frame would cost more than skinning a small mesh.
#pragma once

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
  explicit ThreadPool(unsigned threads = 0);
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

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  const std::function<void(std::size_t, std::size_t)>* body_ = nullptr;
  std::size_t count_ = 0, grain_ = 1, next_chunk_ = 0, chunks_ = 0, finished_chunks_ = 0;
  std::size_t generation_ = 0;
  bool stop_ = false;
};

}  // namespace skintune::internal
