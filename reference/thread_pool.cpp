#include "reference/thread_pool.h"

#include <algorithm>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace skintune::internal {

ThreadPool::ThreadPool(unsigned threads, std::chrono::microseconds spin) : spin_(spin) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  for (unsigned i = 1; i < threads; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

template <typename Ready>
bool ThreadPool::Spin(Ready&& ready) const {
  if (spin_.count() <= 0) return ready();
  const auto until = std::chrono::steady_clock::now() + spin_;
  for (;;) {
    for (int i = 0; i < 64; ++i) {
      if (ready()) return true;
#if defined(__SSE2__)
      _mm_pause();
#endif
    }
    if (std::chrono::steady_clock::now() >= until) return ready();
  }
}

void ThreadPool::RunChunks() {
  std::unique_lock lock(mutex_);
  while (next_chunk_ < chunks_) {
    const std::size_t chunk = next_chunk_++;
    const auto* body = body_;
    lock.unlock();
    const std::size_t begin = chunk * grain_;
    (*body)(begin, std::min(count_, begin + grain_));
    lock.lock();
    if (finished_chunks_.fetch_add(1) + 1 == chunks_) done_.notify_all();
  }
}

void ThreadPool::WorkerLoop() {
  std::size_t seen = 0;
  for (;;) {
    Spin([&] { return stop_.load(std::memory_order_acquire) || generation_.load(std::memory_order_acquire) != seen; });
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
    }
    RunChunks();
  }
}

void ThreadPool::ParallelFor(std::size_t count, std::size_t grain,
                             const std::function<void(std::size_t, std::size_t)>& body) {
  if (count == 0) return;
  grain = std::max<std::size_t>(grain, 1);
  {
    std::lock_guard lock(mutex_);
    body_ = &body;
    count_ = count;
    grain_ = grain;
    chunks_ = (count + grain - 1) / grain;
    next_chunk_ = 0;
    finished_chunks_ = 0;
    ++generation_;
  }
  wake_.notify_all();
  RunChunks();
  const std::size_t chunks = chunks_;  // RunChunks returned: no chunk is left to take, so chunks_ stays
  Spin([&] { return finished_chunks_.load(std::memory_order_acquire) == chunks; });
  std::unique_lock lock(mutex_);
  done_.wait(lock, [&] { return finished_chunks_ == chunks_; });
  body_ = nullptr;
}

void ForChunksOn(ThreadPool& pool, std::mutex& busy, std::size_t count, std::size_t grain,
                 const std::function<void(std::size_t, std::size_t)>& body) {
  grain = std::max<std::size_t>(grain, 1);
  std::unique_lock<std::mutex> lock(busy, std::defer_lock);
  if (count <= grain || pool.size() < 2 || !lock.try_lock()) {
    for (std::size_t begin = 0; begin < count; begin += grain) body(begin, std::min(count, begin + grain));
    return;
  }
  pool.ParallelFor(count, grain, body);
}

void ParallelChunks(std::size_t count, std::size_t grain, const std::function<void(std::size_t, std::size_t)>& body) {
  if (count <= grain) {  // no pool for small meshes
    if (count > 0) body(0, count);
    return;
  }
  static std::mutex busy;
  static ThreadPool pool;
  ForChunksOn(pool, busy, count, grain, body);
}

}  // namespace skintune::internal
