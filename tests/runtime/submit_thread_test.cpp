// The submit thread (runtime/submit_thread.h): operations run in order, off
// the caller's thread; WaitFor returns once an operation (and every one
// before it) has run; a failure is thrown once, by the next wait, and the
// operations queued after it are skipped until then; the destructor runs
// what is queued. Await: the caller's condition is checked on the thread,
// after the operations queued before it and without blocking, and only once
// the thread has polled as long as it polls for work by a blocking wait.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "runtime/submit_thread.h"

namespace skintune::internal {
namespace {

TEST(SubmitThread, RunsInOrderOffTheCallersThreadAndWaitsForANumber) {
  SubmitThread submit;
  std::vector<int> ran;  // written by the thread only, read after Drain
  std::atomic<int> count{0};  // read while the thread still runs
  std::atomic<bool> go{false};
  std::thread::id where;
  const std::uint64_t first = submit.Push([&] {
    where = std::this_thread::get_id();
    while (!go) std::this_thread::yield();  // held until the caller has queued the rest
    ran.push_back(1);
    ++count;
  });
  std::uint64_t last = 0;
  for (int i = 2; i <= 100; ++i) last = submit.Push([&ran, &count, i] {
    ran.push_back(i);
    ++count;
  });
  EXPECT_EQ(first, 1u);
  EXPECT_EQ(last, 100u);
  go = true;
  submit.WaitFor(50);
  EXPECT_GE(count, 50);
  submit.Drain();
  ASSERT_EQ(ran.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(ran[static_cast<std::size_t>(i)], i + 1);
  EXPECT_NE(where, std::this_thread::get_id());
}

TEST(SubmitThread, AFailureIsThrownOnceByTheNextWaitAndWhatFollowedItIsSkipped) {
  SubmitThread submit;
  std::atomic<int> ran{0};
  submit.Push([&] { ++ran; });
  const std::uint64_t failing = submit.Push([] { throw std::runtime_error("the driver said no"); });
  submit.Push([&] { ran += 10; });  // queued behind the failure: skipped
  try {
    submit.WaitFor(failing);
    submit.Drain();
    ADD_FAILURE() << "no error thrown";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "the driver said no");
  }
  submit.Drain();  // collected: nothing more to throw
  EXPECT_EQ(ran, 1);
  submit.Push([&] { ran += 100; });  // after the error was collected, operations run again
  submit.Drain();
  EXPECT_EQ(ran, 101);
}

TEST(SubmitThread, SleepsWhenIdleAndWakesForTheNextOperation) {
  SubmitThread submit;
  submit.Push([] {});
  submit.Drain();
  std::this_thread::sleep_for(std::chrono::milliseconds(5));  // past the polling: asleep
  std::atomic<bool> ran{false};
  submit.Drain();  // nothing queued: returns at once
  submit.WaitFor(submit.Push([&] { ran = true; }));
  EXPECT_TRUE(ran);
}

TEST(SubmitThread, TheDestructorRunsWhatIsQueued) {
  std::atomic<int> ran{0};
  {
    SubmitThread submit;
    for (int i = 0; i < 20; ++i) submit.Push([&] {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
      ++ran;
    });
    submit.Push([] { throw std::runtime_error("dropped by the destructor"); });
  }
  EXPECT_EQ(ran, 20);
}

TEST(SubmitThread, AwaitChecksItsConditionOnTheThreadBetweenOperations) {
  SubmitThread submit;
  std::atomic<int> ran{0};
  std::atomic<bool> go{false};
  submit.Push([&] {
    while (!go) std::this_thread::yield();
    ++ran;
  });
  for (int i = 0; i < 9; ++i) submit.Push([&] { ++ran; });
  std::atomic<int> checks{0}, waits{0};
  std::atomic<bool> elsewhere{true};
  const std::thread::id caller = std::this_thread::get_id();
  std::thread release([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    go = true;
  });
  submit.Await(
      [&] {
        if (std::this_thread::get_id() == caller) elsewhere = false;
        ++checks;
        return ran >= 5;  // true once the thread has run five of the operations queued before
      },
      [&] { ++waits; });
  release.join();
  EXPECT_GE(ran, 5);
  EXPECT_GE(checks, 1);
  EXPECT_EQ(waits, 0);  // resolved by the check, well within the polling
  EXPECT_TRUE(elsewhere);
  submit.Drain();
  EXPECT_EQ(ran, 10);
}

TEST(SubmitThread, AwaitWaitsByTheBlockingCallAfterPollingAndWakesASleepingThread) {
  SubmitThread submit;
  submit.Push([] {});
  submit.Drain();
  std::this_thread::sleep_for(std::chrono::milliseconds(5));  // past the polling: asleep
  std::atomic<bool> signalled{false};
  std::atomic<int> waits{0};
  std::thread signal([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // longer than the polling
    signalled = true;
  });
  submit.Await([&] { return signalled.load(); },
               [&] {
                 ++waits;
                 while (!signalled) std::this_thread::sleep_for(std::chrono::microseconds(50));
               });
  signal.join();
  EXPECT_TRUE(signalled);
  EXPECT_EQ(waits, 1);
  std::atomic<bool> ran{false};
  submit.WaitFor(submit.Push([&] { ran = true; }));  // the thread goes on with its operations
  EXPECT_TRUE(ran);
}

TEST(SubmitThread, AwaitThrowsItsConditionsErrorOrAnEarlierOperationsOnce) {
  SubmitThread submit;
  EXPECT_THROW(submit.Await([]() -> bool { throw std::runtime_error("query failed"); }, [] {}), std::runtime_error);
  submit.Drain();  // collected once
  std::atomic<int> checks{0};
  submit.Push([] { throw std::runtime_error("upload failed"); });
  try {
    submit.Await(
        [&] {
          ++checks;
          return true;
        },
        [] {});
    ADD_FAILURE() << "no error thrown";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "upload failed");  // the operation's, not checked past it
  }
  EXPECT_EQ(checks, 0);
  submit.Await(
      [&] {
        ++checks;
        return true;
      },
      [] {});
  EXPECT_EQ(checks, 1);
}

}  // namespace
}  // namespace skintune::internal
