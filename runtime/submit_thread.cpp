#include "runtime/submit_thread.h"

#include "runtime/host_work.h"

#include <chrono>
#include <utility>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace skintune::internal {

namespace {

// How long the thread polls for the next operation (and WaitFor for its
// operation) before sleeping: longer than a frame's gap between SetPalette's
// upload and Skin's launch (kFramePoll, runtime/host_work.h).
constexpr auto kPoll = kFramePoll;

void Pause() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}

// Polls `until_true` for kPoll, the clock read every 64 polls; true when it held.
template <typename Condition>
bool Poll(Condition until_true) {
  const auto until = std::chrono::steady_clock::now() + kPoll;
  for (int n = 1;; ++n) {
    if (until_true()) return true;
    Pause();
    if (n % 64 == 0 && std::chrono::steady_clock::now() >= until) return until_true();
  }
}

}  // namespace

SubmitThread::SubmitThread() : thread_([this] { Loop(); }) {}

SubmitThread::~SubmitThread() {
  DrainQuietly();
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  work_.notify_one();
  thread_.join();
}

std::uint64_t SubmitThread::Push(std::function<void()> op) {
  bool wake = false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(std::move(op));
    queued_.store(pushed_ + 1, std::memory_order_release);
    wake = sleeping_;
  }
  if (wake) work_.notify_one();
  return ++pushed_;
}

void SubmitThread::Loop() {
  std::uint64_t taken = 0;
  for (;;) {
    if (!Poll([&] { return queued_.load(std::memory_order_acquire) > taken; })) {
      std::unique_lock<std::mutex> lock(mutex_);
      sleeping_ = true;
      work_.wait(lock, [this] { return !queue_.empty() || stop_; });
      sleeping_ = false;
      if (queue_.empty()) return;  // stop_, and nothing left
    }
    std::function<void()> op;
    bool skip = false;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      op = std::move(queue_.front());
      queue_.pop_front();
      ++taken;
      skip = error_ != nullptr || taken <= skip_through_;
    }
    std::exception_ptr failed;
    if (!skip) {
      try {
        op();
      } catch (...) {
        failed = std::current_exception();
      }
    }
    op = nullptr;  // what it captured goes before the caller hears it ran
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (failed && !error_) error_ = failed;
      finished_.store(taken, std::memory_order_release);
    }
    done_.notify_all();
  }
}

void SubmitThread::Rethrow() {
  std::exception_ptr error;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    error = std::exchange(error_, nullptr);
    if (error) skip_through_ = pushed_;  // queued before the caller knew: skipped too
  }
  if (error) std::rethrow_exception(error);
}

void SubmitThread::WaitFor(std::uint64_t number) {
  // The frame loop waits for operations a few frames old, mostly done: poll
  // briefly, then sleep until the thread says one finished.
  if (!Poll([&] { return finished_.load(std::memory_order_acquire) >= number; })) {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return finished_.load(std::memory_order_acquire) >= number; });
  }
  Rethrow();
}

void SubmitThread::DrainQuietly() noexcept {
  try {
    Drain();
  } catch (...) {
  }
}

}  // namespace skintune::internal
