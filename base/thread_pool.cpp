#include "base/thread_pool.h"

#include <algorithm>

namespace skintune::internal {

ThreadPool::ThreadPool(unsigned threads, std::chrono::microseconds spin) : spin_(spin) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  for (unsigned i = 1; i < threads; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ThreadPool::~ThreadPool() {
  stop_.store(true);
  {
    std::lock_guard lock(mutex_);  // a worker between its check of stop_ and its wait holds it
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void ThreadPool::RunChunks(std::uint64_t generation) {
  std::uint64_t c = claim_.load(std::memory_order_acquire);
  while (Generation(c) == generation && Next(c) < Chunks(c)) {
    if (!claim_.compare_exchange_weak(c, c + 1, std::memory_order_acq_rel, std::memory_order_acquire)) continue;
    const std::size_t begin = static_cast<std::size_t>(Next(c)) * grain_;
    (*body_)(begin, std::min(count_, begin + grain_));
    // The last chunk wakes the caller if it sleeps (seq_cst with its flag: Dekker).
    if (finished_.fetch_add(1) + 1 == Chunks(c) && caller_sleeps_.load()) {
      { std::lock_guard lock(mutex_); }
      done_.notify_all();
    }
    c = claim_.load(std::memory_order_acquire);
  }
}

void ThreadPool::WorkerLoop() {
  std::uint64_t seen = 0;  // the last generation this worker looked at
  for (;;) {
    const auto fresh = [&] { return stop_.load() || Generation(claim_.load()) != seen; };
    if (!PollFor(spin_, fresh)) {
      std::unique_lock lock(mutex_);
      sleepers_.fetch_add(1);  // before the check (seq_cst with the caller's store of claim_: Dekker)
      wake_.wait(lock, fresh);
      sleepers_.fetch_sub(1);
    }
    if (stop_.load()) return;
    seen = Generation(claim_.load());
    RunChunks(seen);
  }
}

void ThreadPool::ParallelFor(std::size_t count, std::size_t grain,
                             const std::function<void(std::size_t, std::size_t)>& body) {
  if (count == 0) return;
  grain = std::max<std::size_t>(grain, 1);
  if ((count + grain - 1) / grain > kChunkMask) grain = (count + kChunkMask - 1) / kChunkMask;
  const std::uint64_t chunks = (count + grain - 1) / grain;
  body_ = &body;
  count_ = count;
  grain_ = grain;
  finished_.store(0);
  generation_ = (generation_ + 1) & 0xffff;
  if (generation_ == 0) generation_ = 1;  // 0 is the pool's state before its first loop
  claim_.store((generation_ << (2 * kChunkBits)) | (chunks << kChunkBits));  // seq_cst: see sleepers_
  if (sleepers_.load() > 0) {
    { std::lock_guard lock(mutex_); }
    wake_.notify_all();
  }
  RunChunks(generation_);
  const auto done = [&] { return finished_.load() == chunks; };
  if (!PollFor(spin_, done)) {
    std::unique_lock lock(mutex_);
    caller_sleeps_.store(true);
    done_.wait(lock, done);
    caller_sleeps_.store(false);
  }
  body_ = nullptr;
}

void ThreadPool::Ready() {
  if (workers_.empty()) return;
  // One chunk per thread, each held until every thread holds one: a thread
  // cannot claim a second chunk while in its first, so each chunk is a
  // different thread's.
  const std::size_t threads = size();
  std::atomic<std::size_t> arrived{0};
  ParallelFor(threads, 1, [&](std::size_t, std::size_t) {
    arrived.fetch_add(1);
    while (arrived.load() < threads) CpuPause();
  });
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
