// Fuzz target for the program-cache reader (ProgramCache::Load, every
// backend's start: runtime/program_cache.h). A file that fails any check is
// absent (the program is rebuilt), never an error: for any bytes in place of
// an entry, Load returns a payload or nothing, the payload only when the
// bytes are exactly what Store writes for the key (its SHA-256 included),
// and Load and DecodeProgramCacheFile agree.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "runtime/program_cache.h"
#include "tests/fuzz/fuzz_support.h"

using namespace skintune::internal;  // the reader under test and fuzz_support.h's helpers

namespace {

const std::string kKey = ProgramKey("opencl", "opencl:Portable Computing Language/cpu/3.1", "0123456789abcdef",
                                    "-cl-std=CL1.2\nsecond line");

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const std::optional<std::vector<std::uint8_t>> decoded = DecodeProgramCacheFile(bytes, kKey);
  if (decoded && EncodeProgramCacheFile(kKey, *decoded) != bytes)
    fuzz::Die("program_cache_fuzz", "took bytes that are not what Store writes for the key");
  const std::string folder = fuzz::ScratchFile("program_cache_fuzz", "cache");
  const ProgramCache cache(folder);
  static const bool made = [&] {
    cache.Store("opencl", kKey, {1});  // creates the folder
    return true;
  }();
  (void)made;
  fuzz::WriteBytes("program_cache_fuzz", cache.PathOf("opencl", kKey), data, size);
  if (cache.Load("opencl", kKey) != decoded) fuzz::Die("program_cache_fuzz", "Load and Decode disagree");
  return 0;
}
