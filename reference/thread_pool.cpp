#include "reference/thread_pool.h"

#include <algorithm>

namespace skintune::internal {

ThreadPool::ThreadPool(unsigned threads) {
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

void ThreadPool::RunChunks() {
  std::unique_lock lock(mutex_);
  while (next_chunk_ < chunks_) {
    const std::size_t chunk = next_chunk_++;
    const auto* body = body_;
    lock.unlock();
    const std::size_t begin = chunk * grain_;
    (*body)(begin, std::min(count_, begin + grain_));
    lock.lock();
    if (++finished_chunks_ == chunks_) done_.notify_all();
  }
}

void ThreadPool::WorkerLoop() {
  std::size_t seen = 0;
  for (;;) {
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
  std::unique_lock lock(mutex_);
  done_.wait(lock, [&] { return finished_chunks_ == chunks_; });
  body_ = nullptr;
}

}  // namespace skintune::internal
