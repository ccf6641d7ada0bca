#include "runtime/program_cache.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <openssl/evp.h>

#include "generator/emit.h"
#include "base/error.h"
#include "base/input_file.h"

namespace skintune::internal {

namespace {

// Version 2: the payload's checksum is SHA-256 (version 1 had FNV-1a 64, for
// which an altered payload with the same checksum is easy to make; a driver
// that loads such a binary may crash on every start). A version 1 file is
// treated as absent: rebuilt and overwritten.
constexpr const char* kMagic = "skintune-program-cache 2";

std::string Escaped(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

// "sha256:" and 64 lowercase hex digits; "" when libcrypto fails (then
// nothing is stored, and nothing loads).
std::string PayloadHash(const std::vector<std::uint8_t>& payload) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  if (EVP_Digest(payload.data(), payload.size(), digest, &size, EVP_sha256(), nullptr) != 1 || size != 32) return "";
  static const char kHex[] = "0123456789abcdef";
  std::string text = "sha256:";
  for (unsigned int i = 0; i < size; ++i) {
    text += kHex[digest[i] >> 4];
    text += kHex[digest[i] & 15];
  }
  return text;
}

std::string Env(const char* name) {
  const char* value = std::getenv(name);
  return value ? value : "";
}

}  // namespace

std::string ProgramKey(const std::string& backend, const std::string& device_id, const std::string& source_hash,
                       const std::string& options) {
  return "backend " + backend + "\ndevice " + device_id + "\nsource " + source_hash + "\noptions " + options;
}

ProgramCache::ProgramCache(const std::string& dir) : dir_(dir.empty() ? DefaultDir() : dir == "-" ? "" : dir) {}

std::string ProgramCache::DefaultDir() {
  if (const std::string dir = Env("SKINTUNE_CACHE_DIR"); !dir.empty()) return dir;
  if (const std::string xdg = Env("XDG_CACHE_HOME"); !xdg.empty()) return xdg + "/skintune";
  if (const std::string home = Env("HOME"); !home.empty()) return home + "/.cache/skintune";
  return "";
}

std::string ProgramCache::PathOf(const std::string& backend, const std::string& key) const {
  return dir_ + "/" + backend + "-" + SourceHash(key) + ".bin";
}

std::optional<std::vector<std::uint8_t>> DecodeProgramCacheFile(std::string_view bytes, const std::string& key) {
  std::string_view rest = bytes;
  auto line = [&rest]() -> std::optional<std::string_view> {
    const std::size_t end = rest.find('\n');
    if (end == std::string_view::npos) return std::nullopt;
    const std::string_view out = rest.substr(0, end);
    rest.remove_prefix(end + 1);
    return out;
  };
  const std::optional<std::string_view> magic = line(), stored_key = line(), sizes = line();
  if (!magic || *magic != kMagic || !stored_key || *stored_key != Escaped(key) || !sizes) return std::nullopt;
  std::istringstream fields{std::string(*sizes)};
  std::size_t size = 0;
  std::string hash;
  if (!(fields >> size >> hash) || size == 0 || size != rest.size()) return std::nullopt;  // truncated or trailing bytes
  // The line exactly as Store writes it: a stream also reads " 280", "+280", "0280" and ignores what follows the hash.
  if (*sizes != std::to_string(size) + ' ' + hash) return std::nullopt;
  std::vector<std::uint8_t> payload(rest.begin(), rest.end());
  const std::string actual = PayloadHash(payload);
  if (actual.empty() || actual != hash) return std::nullopt;
  return payload;
}

std::string EncodeProgramCacheFile(const std::string& key, const std::vector<std::uint8_t>& payload) {
  const std::string hash = PayloadHash(payload);
  if (payload.empty() || hash.empty()) return "";
  std::string out = std::string(kMagic) + '\n' + Escaped(key) + '\n' + std::to_string(payload.size()) + ' ' + hash + '\n';
  out.append(payload.begin(), payload.end());
  return out;
}

std::optional<std::vector<std::uint8_t>> ProgramCache::Load(const std::string& backend, const std::string& key) const {
  if (!enabled()) return std::nullopt;
  std::string bytes;
  try {
    bytes = ReadInputFile(PathOf(backend, key), kProgramCacheInput);  // a FIFO or a folder in its place: absent
  } catch (const Error&) {
    return std::nullopt;
  }
  return DecodeProgramCacheFile(bytes, key);
}

void ProgramCache::Store(const std::string& backend, const std::string& key,
                         const std::vector<std::uint8_t>& payload) const {
  if (!enabled()) return;
  const std::string file = EncodeProgramCacheFile(key, payload);
  if (file.empty()) return;
  static std::atomic<unsigned> counter{0};
  std::error_code error;
  std::filesystem::create_directories(dir_, error);
  const std::string path = PathOf(backend, key);
  const std::string temporary =
      path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) return;
    out.write(file.data(), static_cast<std::streamsize>(file.size()));
    out.flush();
    if (!out) {
      out.close();
      std::filesystem::remove(temporary, error);
      return;
    }
  }
  std::filesystem::rename(temporary, path, error);
  if (error) std::filesystem::remove(temporary, error);
}

}  // namespace skintune::internal
