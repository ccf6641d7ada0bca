// Reading a file from outside: kind and size first (base/input_file.h).
#include "base/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "base/error.h"
#include "base/memory_limit.h"

namespace skintune::internal {
namespace {

// An open descriptor, closed when it goes.
struct Descriptor {
  int fd = -1;
  ~Descriptor() {
    if (fd >= 0) ::close(fd);
  }
};

const char* KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "is a directory, not a file";
  if (S_ISFIFO(mode)) return "is a FIFO (named pipe), not a regular file";
  if (S_ISCHR(mode)) return "is a character device, not a regular file";
  if (S_ISBLK(mode)) return "is a block device, not a regular file";
  if (S_ISSOCK(mode)) return "is a socket, not a regular file";
  return "is not a regular file";
}

// Opens `path` without blocking (a FIFO's open would wait for a writer) and
// checks the descriptor: a regular file of at most cap.bytes. Returns its size.
std::uint64_t OpenChecked(const std::string& path, const InputCap& cap, Descriptor& file) {
  file.fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (file.fd < 0) throw Error(path + ": cannot open file (" + std::strerror(errno) + ")");
  struct stat info {};
  if (::fstat(file.fd, &info) != 0) throw Error(path + ": cannot open file (" + std::strerror(errno) + ")");
  if (!S_ISREG(info.st_mode)) throw Error(path + ": " + KindOf(info.st_mode));
  const auto size = static_cast<std::uint64_t>(info.st_size);
  if (size > cap.bytes)
    throw Error(path + ": is " + FormatBytes(size) + ", more than the " + FormatBytes(cap.bytes) + " " + cap.what +
                " may have");
  return size;
}

// The checked file read whole into a `Bytes` (std::string or a byte vector).
// A file that grew since fstat is read up to its checked size; /proc files
// report 0 and are read the same way (then nothing is read).
template <typename Bytes>
Bytes ReadChecked(const std::string& path, const InputCap& cap) {
  Descriptor file;
  const std::uint64_t size = OpenChecked(path, cap, file);
  Bytes bytes(static_cast<std::size_t>(size), '\0');
  std::size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::read(file.fd, bytes.data() + got, bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(path + ": cannot read file (" + std::strerror(errno) + ")");
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  bytes.resize(got);
  return bytes;
}

}  // namespace

std::uint64_t CheckInputFile(const std::string& path, const InputCap& cap) {
  Descriptor file;
  return OpenChecked(path, cap, file);
}

std::string ReadInputFile(const std::string& path, const InputCap& cap) {
  return ReadChecked<std::string>(path, cap);
}

std::vector<unsigned char> ReadInputBytes(const std::string& path, const InputCap& cap) {
  return ReadChecked<std::vector<unsigned char>>(path, cap);
}

nlohmann::json ParseJson(const std::string& text, const std::string& name) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, and out_of_range for 1e400
    throw Error(name + ": not valid JSON (" + Excerpt(e.what()) + ")");
  }
}

nlohmann::json ReadJsonFile(const std::string& path) { return ParseJson(ReadInputFile(path, kJsonInput), path); }

}  // namespace skintune::internal
