// skintune: the host lock between the tuner's workers (tuner/host_lock.h).
#include "tuner/host_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "base/error.h"

namespace skintune::internal::tuner_internal {

namespace {
int lock_fd = -1;  // the worker's lock file, or -1 (no lock)
}  // namespace

void UseHostLock(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) throw Error("host lock '" + path + "': cannot open it (" + std::strerror(errno) + ")");
  if (lock_fd >= 0) ::close(lock_fd);
  lock_fd = fd;
}

HostLock::HostLock(Mode mode) {
  if (mode == Mode::kNone || lock_fd < 0) return;
  const int operation = mode == Mode::kShared ? LOCK_SH : LOCK_EX;
  while (::flock(lock_fd, operation) != 0) {
    if (errno != EINTR) return;  // a lock that cannot be taken costs only the measurement's quiet
  }
  held_ = true;
}

void HostLock::Release() {
  if (!held_) return;
  ::flock(lock_fd, LOCK_UN);
  held_ = false;
}

HostLock::Mode HostWorkMode(bool cpu_device) { return cpu_device ? HostLock::Mode::kNone : HostLock::Mode::kShared; }
HostLock::Mode TimedMode(bool cpu_device) { return cpu_device ? HostLock::Mode::kExclusive : HostLock::Mode::kNone; }

HostLockFile::HostLockFile() {
  std::error_code error;
  const std::filesystem::path dir = std::filesystem::temp_directory_path(error);
  if (error) return;
  std::string name = (dir / "skintune-host-XXXXXX").string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) return;
  ::close(fd);
  path_ = name;
}

HostLockFile::~HostLockFile() {
  if (!path_.empty()) ::unlink(path_.c_str());
}

}  // namespace skintune::internal::tuner_internal
