// skintune command-line tool: what the long-running commands (tune, paper)
// share: progress on stderr, the output directory, the worker executable,
// --lang names.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <filesystem>
#include <string>

#include "generator/variant.h"

namespace skintune::internal::tools {

// Progress on stderr: a bar with ETA on a terminal, plain lines prefixed with
// "skintune: <command>: " otherwise.
class Progress {
 public:
  Progress(bool terminal, std::string command);

  // `total` 0: a set-up step (shown on a terminal only, where it is overwritten).
  void Update(std::size_t done, std::size_t total, const std::string& what);
  // A step without a count (always shown).
  void Note(const std::string& what);
  // Keeps the last progress line (success), or clears it (an error follows).
  void Finish(bool keep);

 private:
  using Clock = std::chrono::steady_clock;
  void Show(std::string line);
  bool terminal_;
  std::string command_;
  bool shown_ = false;
  Clock::time_point start_;
  Clock::time_point first_measured_;
  Clock::time_point last_time_ = Clock::now();
  std::size_t last_done_ = 0;
  std::size_t measured_ = 0;
};

// The output directory of a run (tune, paper): `dir`, created when missing;
// Error naming it when it is a file or cannot be created. A run that fails
// before it recorded a measurement (a config with no valid variant, no
// device) leaves no trace: unless Keep() was called, the destructor removes
// the folders it created while they hold nothing but an empty cache.jsonl.
class OutputDirectory {
 public:
  explicit OutputDirectory(const std::string& dir);
  ~OutputDirectory();
  OutputDirectory(const OutputDirectory&) = delete;
  OutputDirectory& operator=(const OutputDirectory&) = delete;

  const std::filesystem::path& path() const { return path_; }
  void Keep() { kept_ = true; }

 private:
  std::filesystem::path path_;
  std::filesystem::path created_;  // the outermost folder created here, or empty
  bool kept_ = false;
};
// The running skintune binary (started again as `skintune tune-worker`).
std::string SelfExecutable();
// --lang NAME; Error naming the accepted names.
Lang LangFromName(const std::string& name);

// The decimal whole number `text` if it is one from 0 to `max` (digits only:
// no sign, no exponent, no overflow), else nothing. CLI11's own conversion to
// an unsigned type wraps "-3" and saturates 18446744073709551616, so numeric
// limits on the command line go through this (WholeNumberOption).
std::optional<std::uint64_t> ParseWholeNumber(const std::string& text, std::uint64_t max);

}  // namespace skintune::internal::tools
