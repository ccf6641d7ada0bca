// skintune (internal): compiled kernels cached on disk, so that a second
// start compiles nothing.
//
// Each backend builds a program from source once, then stores what it can
// load back without compiling (OpenCL: the program binary; CUDA: the PTX from
// NVRTC; GL: glGetProgramBinary's blob with its format). The key is a text
// naming everything the compiled result depends on: the backend, the device
// id (which includes the driver version), the source hash and the build
// options; the file is "<dir>/<backend>-<FNV-1a 64 of the key, 16 hex>.bin".
//
// File layout (all text lines but the payload):
//   "skintune-program-cache 2\n"
//   the key, newlines escaped as "\n", then "\n"
//   "<payload bytes> sha256:<SHA-256 of the payload, 64 hex>\n"
//   the payload
// A file that does not follow this exactly (truncated, another key with the
// same file name, a flipped bit, an altered payload, a version 1 file with
// its FNV-1a checksum) is treated as absent: the program is rebuilt from
// source and the file rewritten. SHA-256 (OpenSSL's libcrypto) because a
// driver handed a corrupt binary may crash the process (PoCL does, in
// clCreateProgramWithBinary): a payload altered so that a 64-bit
// non-cryptographic checksum still matches is easy to make, one that keeps
// its SHA-256 is not. (It is a checksum, not a signature: whoever may write
// the cache directory may also rewrite the header.) Writes are atomic (a temporary file in the
// same directory, then rename), so a reader never sees half a file, and
// concurrent writers of the same key leave one complete file. A cache that
// cannot be written (read-only, full disk) only costs a rebuild next start:
// storing never fails the caller.
//
// The counters are per ProgramCache (one per Device): programs compiled from
// source, loaded from disk, and reused in memory by the runners.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace skintune::internal {

// Atomic: an API with ConcurrentBuilds (device_api.h) counts from several threads.
struct ProgramCacheCounters {
  std::atomic<int> builds = 0;
  std::atomic<int> disk_hits = 0;
  std::atomic<int> memory_hits = 0;
};

class ProgramCache {
 public:
  // `dir`: the cache directory; "" = DefaultDir(); "-" = no disk cache (the
  // counters still count).
  explicit ProgramCache(const std::string& dir);

  // $SKINTUNE_CACHE_DIR, else $XDG_CACHE_HOME/skintune, else
  // $HOME/.cache/skintune, else "" (no disk cache).
  static std::string DefaultDir();

  const std::string& dir() const { return dir_; }  // "" when there is no disk cache
  bool enabled() const { return !dir_.empty(); }

  // The stored payload for `key`, or nothing (absent, unreadable or corrupt).
  std::optional<std::vector<std::uint8_t>> Load(const std::string& backend, const std::string& key) const;
  // Stores `payload` for `key` atomically; failures are ignored (see above).
  void Store(const std::string& backend, const std::string& key, const std::vector<std::uint8_t>& payload) const;
  // Where `key` is stored.
  std::string PathOf(const std::string& backend, const std::string& key) const;

  ProgramCacheCounters& counters() { return counters_; }
  const ProgramCacheCounters& counters() const { return counters_; }

 private:
  std::string dir_;
  ProgramCacheCounters counters_;
};

// A cache file's bytes for `key` (the layout above); "" when there is
// nothing to store (an empty payload, libcrypto failing).
std::string EncodeProgramCacheFile(const std::string& key, const std::vector<std::uint8_t>& payload);
// The payload a cache file's `bytes` hold for `key`, or nothing when they do
// not follow the layout exactly (Load reads the file, at most
// kProgramCacheInput, base/input_file.h, then this).
std::optional<std::vector<std::uint8_t>> DecodeProgramCacheFile(std::string_view bytes, const std::string& key);

// The key text of a program: one line per field, in this order.
std::string ProgramKey(const std::string& backend, const std::string& device_id, const std::string& source_hash,
                       const std::string& options);

}  // namespace skintune::internal
