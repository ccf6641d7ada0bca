// Runs the built `skintune` binary with arguments, capturing exit code,
// stdout and stderr (through temporary files, no shell quoting games).
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/common/scratch_dir.h"

namespace skintune::internal::testing {

struct CommandResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

inline std::string ReadAll(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// `address_space_bytes` > 0: the child's RLIMIT_AS, so that a command that
// would allocate without bound fails fast instead of exhausting the machine.
// `timeout_s` > 0: the child is killed by SIGALRM after that long (exit code
// 128 + 14), so a command that would block (reading a FIFO) fails the test.
inline CommandResult RunSkintune(const std::vector<std::string>& args, std::uint64_t address_space_bytes = 0,
                                 unsigned timeout_s = 0) {
  namespace fs = std::filesystem;
  static int counter = 0;
  const fs::path dir = fs::temp_directory_path() / ("skintune_cli_" + std::to_string(::getpid()));
  if (counter == 0) scratch_internal::Made().Add(dir);  // removed at exit when every test passed
  fs::create_directories(dir);
  const fs::path out = dir / ("out" + std::to_string(counter));
  const fs::path err = dir / ("err" + std::to_string(counter++));
  const pid_t pid = ::fork();
  if (pid == 0) {
    const std::string exe = std::string(SKINTUNE_BINARY_DIR) + "/bin/skintune";
    std::vector<char*> argv{const_cast<char*>(exe.c_str())};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    if (!std::freopen(out.c_str(), "w", stdout) || !std::freopen(err.c_str(), "w", stderr)) std::_Exit(127);
    if (address_space_bytes > 0) {
      const rlimit limit{address_space_bytes, address_space_bytes};
      if (::setrlimit(RLIMIT_AS, &limit) != 0) std::_Exit(126);
    }
    if (timeout_s > 0) ::alarm(timeout_s);  // kept across execv
    ::execv(exe.c_str(), argv.data());
    std::_Exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  CommandResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = ReadAll(out);
  r.err = ReadAll(err);
  return r;
}

// Writes `text` to `path` as it is; returns the path, for a command's argument.
inline std::string Write(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

inline int CountLines(const std::string& text) {
  int lines = 0;
  for (char c : text) lines += c == '\n';
  return lines;
}

}  // namespace skintune::internal::testing
