// The submit thread (runtime/submit_thread.h): operations run in order, off
// the caller's thread; WaitFor returns once an operation (and every one
// before it) has run; a failure is thrown once, by the next wait, and the
// operations queued after it are skipped until then; the destructor runs
// what is queued.
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
  std::vector<int> ran;  // written by the thread only, read after a wait
  std::atomic<bool> go{false};
  std::thread::id where;
  const std::uint64_t first = submit.Push([&] {
    where = std::this_thread::get_id();
    while (!go) std::this_thread::yield();  // held until the caller has queued the rest
    ran.push_back(1);
  });
  std::uint64_t last = 0;
  for (int i = 2; i <= 100; ++i) last = submit.Push([&ran, i] { ran.push_back(i); });
  EXPECT_EQ(first, 1u);
  EXPECT_EQ(last, 100u);
  go = true;
  submit.WaitFor(50);
  EXPECT_GE(ran.size(), 50u);
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

}  // namespace
}  // namespace skintune::internal
