// A program that skins and exits at once must not crash on any backend, even
// on a machine's first run (empty program and PoCL caches): the Skinner's
// destructor waits for the work it queued, so no driver thread is still
// compiling or launching while exit() destroys the drivers' globals.
// skin_and_exit (beside this test) is that program; it makes the race certain
// (see its header), so one run per backend fails without the wait.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "tests/tools/run_command.h"

namespace skintune::internal {
namespace {

// A new empty directory, removed with its contents at the end.
struct ScratchDir {
  ScratchDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "skintune-exit-XXXXXX").string();
    if (::mkdtemp(pattern.data())) path = pattern;
  }
  ~ScratchDir() {
    std::error_code ignored;
    if (!path.empty()) std::filesystem::remove_all(path, ignored);
  }
  std::string path;
};

struct ChildExit {
  int code = -1;  // exit code, or 128 + signal
  std::string err;
};

// skin_and_exit on `backend`, with its program cache and POCL_CACHE_DIR both empty.
ChildExit RunSkinAndExit(const std::string& backend) {
  ScratchDir program_cache, pocl_cache, logs;
  const std::string err_path = logs.path + "/err";
  const pid_t pid = ::fork();
  if (pid == 0) {
    const std::string exe = SKINTUNE_BINARY_DIR "/bin/skin_and_exit";
    ::setenv("POCL_CACHE_DIR", pocl_cache.path.c_str(), 1);
    if (!std::freopen(err_path.c_str(), "w", stderr)) std::_Exit(127);
    ::execl(exe.c_str(), exe.c_str(), backend.c_str(), program_cache.path.c_str(), static_cast<char*>(nullptr));
    std::_Exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ChildExit out;
  out.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  out.err = testing::ReadAll(err_path);
  return out;
}

class SkinAndExit : public ::testing::TestWithParam<const char*> {};

TEST_P(SkinAndExit, AProgramThatExitsRightAfterSkinDoesNotCrash) {
  const ChildExit child = RunSkinAndExit(GetParam());
  if (child.code == 3) GTEST_SKIP() << child.err;
  EXPECT_EQ(child.code, 0) << "skin_and_exit " << GetParam() << " (128 + signal when it crashed): " << child.err;
}

INSTANTIATE_TEST_SUITE_P(EveryBackend, SkinAndExit, ::testing::Values("opencl", "gl", "vulkan", "cuda", "cpu"),
                         [](const ::testing::TestParamInfo<const char*>& param) { return std::string(param.param); });

}  // namespace
}  // namespace skintune::internal
