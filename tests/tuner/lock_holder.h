// Tests of the tuner's locks (tuner/host_lock.h): another process (a worker)
// that takes a lock with hold() and keeps it for 300 ms; constructed once it
// holds it. Join() checks that it ended well.
#pragma once

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <thread>

namespace skintune::internal::testing {

class LockHolder {
 public:
  explicit LockHolder(const std::function<void()>& hold) {
    if (::pipe(ready_) != 0) ADD_FAILURE() << "no pipe";
    pid_ = ::fork();
    if (pid_ == 0) {
      hold();
      const char byte = 1;
      if (::write(ready_[1], &byte, 1) != 1) ::_exit(2);
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
      ::_exit(0);  // the lock goes with the process
    }
    char byte = 0;
    if (pid_ < 0 || ::read(ready_[0], &byte, 1) != 1) ADD_FAILURE() << "the holder did not start";
  }
  void Join() {
    int status = 0;
    ASSERT_EQ(::waitpid(pid_, &status, 0), pid_);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    ::close(ready_[0]);
    ::close(ready_[1]);
  }

 private:
  int ready_[2] = {-1, -1};
  pid_t pid_ = -1;
};

}  // namespace skintune::internal::testing
