// A thread that makes a Device's driver calls for the caller (DeviceOptions::
// submit_thread): the Runner hands it a frame's palette upload and launches
// and returns, so the caller packs the next palette while the driver queues
// this frame's work (on the H100 machine's host, 2026-11, the packing and the
// frame's driver calls each took less than the kernel, together more).
//
// Operations run in the order pushed. The thread polls for work for a while
// after each one (a frame's next operation is microseconds away; waking a
// sleeping thread costs more than that), then sleeps; it polls an atomic
// counter with the CPU's pause hint, so a core it shares with the caller's
// thread (hyperthreads) keeps most of its issue slots. An operation that
// throws is recorded and every one pushed before the caller collects the
// error is skipped: the next WaitFor or Drain rethrows it, once.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace skintune::internal {

class SubmitThread {
 public:
  SubmitThread();
  ~SubmitThread();  // runs what is queued, then joins (errors dropped)
  SubmitThread(const SubmitThread&) = delete;
  SubmitThread& operator=(const SubmitThread&) = delete;

  // Queues `op`; returns its number (1, 2, ...), for WaitFor.
  std::uint64_t Push(std::function<void()> op);
  // Blocks until operation `number` (and every one before it) has run;
  // rethrows the first error of an operation run since the last rethrow.
  void WaitFor(std::uint64_t number);
  // WaitFor the last operation pushed.
  void Drain() { WaitFor(pushed_); }
  // Blocks until the thread has seen `done` return true, so that the caller
  // waits outside the driver while the thread makes the frame's calls (the
  // palette ring's fence: Runner::PaletteStaging). The thread calls
  // `done` (which must not block) after each operation and while it polls
  // for work; once it has polled for as long as it polls for work, it calls
  // `wait` (which blocks until `done` would hold) after the operations
  // queued. An error of either is thrown here (an operation's earlier error
  // first, as WaitFor throws it); unlike an operation's, it skips none of the
  // operations queued. One Await at a time (the caller's thread).
  void Await(const std::function<bool()>& done, const std::function<void()>& wait);
  // Drain without rethrowing (destructors).
  void DrainQuietly() noexcept;

 private:
  void Loop();
  void Rethrow();
  // The thread's side of Await: calls the awaited `done` (or, when
  // `blocking`, `wait`) if an Await is pending; true when it resolved it.
  bool CheckAwait(bool blocking);

  std::mutex mutex_;
  std::condition_variable work_, done_;
  std::deque<std::function<void()>> queue_;  // under mutex_
  std::uint64_t pushed_ = 0;                 // the caller's thread only
  // Polled without the lock (a poll that took the lock would hold up the
  // caller's Push), written under it.
  std::atomic<std::uint64_t> queued_{0};     // operations pushed
  std::atomic<std::uint64_t> finished_{0};   // operations run (or skipped)
  std::exception_ptr error_;                 // under mutex_: the first failure not yet rethrown
  std::uint64_t skip_through_ = 0;           // under mutex_: operations pushed before the caller heard of a failure
  bool sleeping_ = false, stop_ = false;     // under mutex_
  // Await: the caller's functions (set under mutex_, then `awaiting_`), and
  // whether the thread resolved them (set under mutex_).
  const std::function<bool()>* await_done_ = nullptr;
  const std::function<void()>* await_wait_ = nullptr;
  std::atomic<bool> awaiting_{false};
  std::atomic<bool> awaited_{false};
  std::exception_ptr await_error_;  // under mutex_: what `done` or `wait` threw
  std::thread thread_;                       // last: started once the rest is initialised
};

}  // namespace skintune::internal
