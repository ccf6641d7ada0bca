// What the fuzz targets of skintune's readers share (tests/fuzz/*_fuzz.cpp).
//
// Every reader of untrusted input promises: for any bytes it returns, or
// throws skintune::internal::Error whose message starts with the name it was given for
// the input ("<file>: <element>: what"). Anything else (another exception, a
// crash, a sanitizer report, a hang, runaway memory, an anonymous message) is
// a bug: Die() aborts, which libFuzzer and the corpus replay both report.
#pragma once

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

#include "base/error.h"

namespace skintune::internal::fuzz {

[[noreturn]] inline void Die(const char* target, const std::string& what) {
  std::fprintf(stderr, "%s: %s\n", target, what.c_str());
  std::abort();
}

// An Error from reading `name` must name it first.
inline void ExpectNamed(const char* target, const Error& e, const std::string& name) {
  if (std::string_view(e.what()).substr(0, name.size() + 1) != name + ":")
    Die(target, "error message without the input's name '" + name + "': " + std::string(e.what()));
}

inline std::filesystem::path& Folder() {
  static std::filesystem::path folder;
  return folder;
}

inline void RemoveFolder() {
  std::error_code ec;
  std::filesystem::remove_all(Folder(), ec);
}

// <temp>/skintune_<target>_<pid>/<file>, the folder created on first use and
// removed at exit: for readers that take a path.
inline std::string ScratchFile(const char* target, const std::string& file) {
  if (Folder().empty()) {
    std::error_code ec;
    std::filesystem::path folder = std::filesystem::temp_directory_path(ec);
    if (ec) folder = "/tmp";
    folder /= std::string("skintune_") + target + "_" + std::to_string(::getpid());
    std::filesystem::create_directories(folder, ec);
    if (ec) Die(target, "cannot create " + folder.string() + ": " + ec.message());
    Folder() = folder;
    std::atexit(RemoveFolder);
  }
  return (Folder() / file).string();
}

inline void WriteBytes(const char* target, const std::string& path, const std::uint8_t* data, std::size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (size > 0) out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) Die(target, "cannot write " + path);
}

}  // namespace skintune::internal::fuzz
