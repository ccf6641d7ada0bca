#include "runtime/submit_thread.h"

#include "base/thread_pool.h"
#include "runtime/host_work.h"

#include <chrono>
#include <utility>

namespace skintune::internal {

namespace {

// How long the thread polls for the next operation (and WaitFor for its
// operation) before sleeping: longer than a frame's gap between SetPalette's
// upload and Skin's launch (kFramePoll, runtime/host_work.h).
constexpr auto kPoll = kFramePoll;

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
    const auto work = [&] { return queued_.load(std::memory_order_acquire) > taken; };
    if (!work() && awaiting_.load(std::memory_order_acquire)) {
      // Nothing queued, the caller waits: poll its condition, then block in its wait.
      if (!PollFor(kPoll, [&] { return work() || CheckAwait(false); }) && !work()) CheckAwait(true);
      continue;
    }
    if (!PollFor(kPoll, [&] { return work() || awaiting_.load(std::memory_order_acquire); })) {
      std::unique_lock<std::mutex> lock(mutex_);
      sleeping_ = true;
      work_.wait(lock, [this] { return !queue_.empty() || stop_ || awaiting_.load(std::memory_order_relaxed); });
      sleeping_ = false;
      if (queue_.empty() && stop_) return;  // nothing left
    }
    if (!work()) continue;  // woken for an Await
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
      if (failed && !error_) error_ = std::move(failed);
      finished_.store(taken, std::memory_order_release);
    }
    done_.notify_all();
    CheckAwait(false);
  }
}

bool SubmitThread::CheckAwait(bool blocking) {
  if (!awaiting_.load(std::memory_order_acquire)) return false;
  std::exception_ptr failed;
  bool resolved = true;
  {
    bool errors = false;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      errors = error_ != nullptr;  // an operation before it failed: the caller hears that instead
    }
    if (!errors) {
      try {
        if (blocking) (*await_wait_)();
        else resolved = (*await_done_)();
      } catch (...) {
        failed = std::current_exception();
      }
    }
  }
  if (!resolved) return false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    await_error_ = std::move(failed);
    awaiting_.store(false, std::memory_order_relaxed);
    awaited_.store(true, std::memory_order_release);
  }
  done_.notify_all();
  return true;
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
  if (!PollFor(kPoll, [&] { return finished_.load(std::memory_order_acquire) >= number; })) {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return finished_.load(std::memory_order_acquire) >= number; });
  }
  Rethrow();
}

void SubmitThread::Await(const std::function<bool()>& done, const std::function<void()>& wait) {
  bool wake = false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    await_done_ = &done;
    await_wait_ = &wait;
    awaited_.store(false, std::memory_order_relaxed);
    awaiting_.store(true, std::memory_order_release);
    wake = sleeping_;
  }
  if (wake) work_.notify_one();
  if (!PollFor(kPoll, [&] { return awaited_.load(std::memory_order_acquire); })) {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return awaited_.load(std::memory_order_acquire); });
  }
  std::exception_ptr failed;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    failed = std::exchange(await_error_, nullptr);
  }
  Rethrow();  // an operation's error first
  if (failed) std::rethrow_exception(failed);
}

void SubmitThread::DrainQuietly() noexcept {
  try {
    Drain();
  } catch (...) {
  }
}

}  // namespace skintune::internal
