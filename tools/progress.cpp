#include "tools/progress.h"

#include <sys/ioctl.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "base/error.h"
#include "runtime/backend_table.h"

namespace skintune::internal::tools {

namespace {

std::string Duration(double seconds) {
  const long s = static_cast<long>(seconds + 0.5);
  char text[32];
  if (s >= 3600) {
    std::snprintf(text, sizeof text, "%ldh%02ldm", s / 3600, (s / 60) % 60);
  } else if (s >= 60) {
    std::snprintf(text, sizeof text, "%ldm%02lds", s / 60, s % 60);
  } else {
    std::snprintf(text, sizeof text, "%lds", s);
  }
  return text;
}

}  // namespace

Progress::Progress(bool terminal, std::string command)
    : terminal_(terminal), command_(std::move(command)), start_(Clock::now()) {}

void Progress::Update(std::size_t done, std::size_t total, const std::string& what) {
  const bool cached = what.ends_with("(cached)");
  if (done > last_done_ && !cached) {
    if (measured_ == 0) first_measured_ = last_time_;
    ++measured_;
  }
  last_done_ = done;
  last_time_ = Clock::now();
  if (!terminal_) {
    // Set-up steps (total 0) only on a terminal, where they are overwritten:
    // a run that fails before measuring says so in one line.
    if (total > 0) std::cerr << "skintune: " << command_ << ": [" << done << "/" << total << "] " << what << "\n";
    return;
  }
  std::string line;
  if (total > 0) {
    const int bar = 24;
    const int filled = static_cast<int>(bar * done / total);
    line = "[" + std::string(filled, '#') + std::string(bar - filled, '.') + "] " + std::to_string(done) + "/" +
           std::to_string(total);
    std::string eta = "ETA --";
    if (measured_ > 0 && done < total) {
      const double elapsed = std::chrono::duration<double>(last_time_ - first_measured_).count();
      eta = "ETA " + Duration(elapsed / measured_ * static_cast<double>(total - done));
    } else if (done >= total) {
      eta = "took " + Duration(std::chrono::duration<double>(last_time_ - start_).count());
    }
    line += " " + eta + "  ";
  }
  Show(line + what);
}

void Progress::Note(const std::string& what) {
  if (!terminal_) {
    std::cerr << "skintune: " << command_ << ": " << what << "\n";
    return;
  }
  Show(what);
}

void Progress::Show(std::string line) {
  int width = 100;
  winsize size{};
  if (::ioctl(2, TIOCGWINSZ, &size) == 0 && size.ws_col > 20) width = size.ws_col;
  if (static_cast<int>(line.size()) > width - 1) line = line.substr(0, width - 4) + "...";
  std::cerr << "\r\033[K" << line << std::flush;
  shown_ = true;
}

void Progress::Finish(bool keep) {
  if (terminal_ && shown_) std::cerr << (keep ? "\n" : "\r\033[K") << std::flush;
  shown_ = false;
}

namespace {

// `path` absolute, without "." and ".." and without a trailing separator.
std::filesystem::path Normal(const std::filesystem::path& path) {
  std::error_code ec;
  return (std::filesystem::absolute(path, ec).lexically_normal() / "").parent_path();
}

}  // namespace

OutputDirectory::OutputDirectory(const std::string& dir) : path_(dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(path_, ec) && !fs::is_directory(path_, ec)) throw Error(dir + ": not a directory");
  for (fs::path p = Normal(path_); p.has_relative_path() && !fs::exists(p, ec); p = p.parent_path()) created_ = p;
  fs::create_directories(path_, ec);
  if (ec || !fs::is_directory(path_)) {
    throw Error(dir + ": cannot create the output directory (" + (ec ? ec.message() : "not a directory") + ")");
  }
}

OutputDirectory::~OutputDirectory() {
  namespace fs = std::filesystem;
  if (kept_ || created_.empty()) return;
  std::error_code ec;
  const fs::path cache = path_ / "cache.jsonl";
  if (fs::is_regular_file(cache, ec) && fs::file_size(cache, ec) == 0) fs::remove(cache, ec);
  // fs::remove takes empty folders only: anything a run left stays.
  for (fs::path p = Normal(path_); p.string().size() >= created_.string().size(); p = p.parent_path())
    if (!fs::remove(p, ec) || p == created_) break;
}

std::string SelfExecutable() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error("cannot find the skintune executable for the tune workers (/proc/self/exe: " + ec.message() + ")");
  return self.string();
}

Lang LangFromName(const std::string& name) {
  std::string names;
  for (const BackendEntry& b : Backends()) {
    for (const Lang l : b.languages) {
      if (name == Name(l)) return l;
      names += (names.empty() ? "" : ", ") + std::string(Name(l));
    }
  }
  throw Error("--lang '" + name + "': unknown language (expected one of " + names + ")");
}

std::optional<std::uint64_t> ParseWholeNumber(const std::string& text, std::uint64_t max) {
  if (text.empty() || text.size() > 20) return std::nullopt;
  std::uint64_t value = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return std::nullopt;
    const auto digit = static_cast<std::uint64_t>(c - '0');
    if (value > (max - digit) / 10) return std::nullopt;
    value = value * 10 + digit;
  }
  return value;
}

}  // namespace skintune::internal::tools
