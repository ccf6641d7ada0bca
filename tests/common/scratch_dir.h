// A fresh, empty folder for the running test: <tmp>/<prefix>_<pid>_<test name>
// ('/' in the name as '_'), emptied first if an earlier run left it. Kept for
// inspection when a test of the program failed; removed when the program ends
// with every test passed (the pid in the name made every run leave its folders
// behind: thousands in the temporary directory after a day of test runs).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

namespace skintune::internal::testing {

namespace scratch_internal {

class MadeDirs {
 public:
  void Add(const std::filesystem::path& dir) {
    std::lock_guard<std::mutex> lock(mutex_);
    dirs_.push_back(dir);
  }
  // After main: UnitTest, made before the first folder, outlives this.
  ~MadeDirs() {
    if (::testing::UnitTest::GetInstance()->Failed()) return;
    for (const std::filesystem::path& dir : dirs_) {
      std::error_code ignored;  // never throw from here
      std::filesystem::remove_all(dir, ignored);
    }
  }

 private:
  std::mutex mutex_;
  std::vector<std::filesystem::path> dirs_;
};

inline MadeDirs& Made() {
  static MadeDirs made;
  return made;
}

}  // namespace scratch_internal

inline std::filesystem::path ScratchDir(const std::string& prefix) {
  // A parameterised test's name holds a '/' ("Name/param"): one folder, not a
  // folder in a folder that only the inner one of would be removed.
  std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
  std::replace(name.begin(), name.end(), '/', '_');
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(::getpid()) + "_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  scratch_internal::Made().Add(dir);
  return dir;
}

}  // namespace skintune::internal::testing
