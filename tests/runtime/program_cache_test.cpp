// The on-disk program cache (runtime/program_cache.h): what it loads back and
// what it treats as absent (then the program is rebuilt and the file
// rewritten). A payload altered so that its old FNV-1a checksum still
// matched was once loaded, and PoCL crashed on it at every start (2026-11);
// the cache now checks SHA-256.
#include "runtime/program_cache.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "generator/emit.h"
#include "base/input_file.h"
#include "tests/common/scratch_dir.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

// Two 8-byte blocks with the same FNV-1a 64 from its offset basis
// (0x069d3b25617ef03a), found with a distinguished-point rho search over
// 8-byte blocks (about 4e9 evaluations): any two payloads that start with
// them and continue alike have the same FNV-1a 64.
const std::vector<std::uint8_t> kBlockA = {0x2e, 0xc7, 0xd7, 0xaa, 0xab, 0x52, 0x51, 0x5f};
const std::vector<std::uint8_t> kBlockB = {0xc4, 0xa3, 0x2e, 0xc5, 0xa0, 0x4e, 0x78, 0xc7};

std::vector<std::uint8_t> Payload(const std::vector<std::uint8_t>& block) {
  std::vector<std::uint8_t> payload = block;
  const std::string rest = "\x7f" "ELF... the rest of a program binary";
  payload.insert(payload.end(), rest.begin(), rest.end());
  return payload;
}

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

const std::string kKey = ProgramKey("opencl", "opencl:Portable Computing Language/cpu/5.0", "0123456789abcdef", "-cl-std=CL1.2");

TEST(ProgramCache, TheTestsPayloadsCollideUnderFnv1a) {
  const std::vector<std::uint8_t> a = Payload(kBlockA), b = Payload(kBlockB);
  ASSERT_NE(a, b);
  EXPECT_EQ(SourceHash(std::string(a.begin(), a.end())), SourceHash(std::string(b.begin(), b.end())));
}

TEST(ProgramCache, StoredPayloadLoadsBackWithTheKeyAndASha256InTheHeader) {
  const fs::path dir = testing::ScratchDir("skintune_program_cache");
  const ProgramCache cache(dir.string());
  const std::vector<std::uint8_t> payload = Payload(kBlockA);
  cache.Store("opencl", kKey, payload);
  EXPECT_EQ(cache.Load("opencl", kKey), payload);
  const std::string file = ReadAll(cache.PathOf("opencl", kKey));
  const std::string header = "skintune-program-cache 2\nbackend opencl\\ndevice opencl:Portable Computing Language/cpu/5.0"
                             "\\nsource 0123456789abcdef\\noptions -cl-std=CL1.2\n" +
                             std::to_string(payload.size()) + " sha256:";
  ASSERT_EQ(file.rfind(header, 0), 0u) << file.substr(0, 200);
  const std::size_t hex = header.size();
  EXPECT_EQ(file.find('\n', hex), hex + 64);
  EXPECT_EQ(cache.Load("opencl", kKey + "x"), std::nullopt);  // another key: absent
}

TEST(ProgramCache, AlteredPayloadWhoseFnvChecksumStillMatchesIsRebuilt) {
  const fs::path dir = testing::ScratchDir("skintune_program_cache");
  const ProgramCache cache(dir.string());
  const std::vector<std::uint8_t> original = Payload(kBlockA);
  cache.Store("opencl", kKey, original);
  const std::string path = cache.PathOf("opencl", kKey);
  std::string file = ReadAll(path);
  const std::size_t at = file.size() - original.size();
  ASSERT_EQ(file.substr(at), std::string(original.begin(), original.end()));
  file.replace(at, kBlockB.size(), std::string(kBlockB.begin(), kBlockB.end()));
  std::ofstream(path, std::ios::binary | std::ios::trunc) << file;

  EXPECT_EQ(cache.Load("opencl", kKey), std::nullopt) << "the altered payload was loaded";
  // What a runner does next: rebuild, store over it, and load that.
  cache.Store("opencl", kKey, original);
  EXPECT_EQ(cache.Load("opencl", kKey), original);
}

TEST(ProgramCache, VersionOneFilesAreAbsent) {
  const fs::path dir = testing::ScratchDir("skintune_program_cache");
  const ProgramCache cache(dir.string());
  const std::vector<std::uint8_t> payload = Payload(kBlockA);
  cache.Store("opencl", kKey, payload);
  const std::string path = cache.PathOf("opencl", kKey);
  // The same payload as version 1 wrote it: FNV-1a 64 as its checksum.
  std::string escaped;
  for (char c : kKey) escaped += c == '\n' ? std::string("\\n") : std::string(1, c);
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      << "skintune-program-cache 1\n" << escaped << "\n" << payload.size() << " "
      << SourceHash(std::string(payload.begin(), payload.end())) << "\n"
      << std::string(payload.begin(), payload.end());
  EXPECT_EQ(cache.Load("opencl", kKey), std::nullopt);
}

// A FIFO in place of a cache file blocked the open forever (skin_animation
// hung on GL, OpenCL and Vulkan); a folder, an oversized file or one that
// cannot be read is as absent as a damaged one. The alarm fails the test
// (SIGALRM) instead of letting it hang.
TEST(ProgramCache, AFifoAFolderOrAnOversizedFileInPlaceOfAnEntryIsAbsentWithoutBlocking) {
  const fs::path dir = testing::ScratchDir("skintune_program_cache");
  const ProgramCache cache(dir.string());
  const std::string path = cache.PathOf("opencl", kKey);
  ::alarm(30);
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  EXPECT_EQ(cache.Load("opencl", kKey), std::nullopt);
  fs::remove(path);
  fs::create_directories(path);
  EXPECT_EQ(cache.Load("opencl", kKey), std::nullopt);
  fs::remove(path);
  std::ofstream(path, std::ios::binary) << "skintune-program-cache 2\n";
  fs::resize_file(path, kProgramCacheInput.bytes + 1);  // sparse
  EXPECT_EQ(cache.Load("opencl", kKey), std::nullopt);
  ::alarm(0);
  cache.Store("opencl", kKey, Payload(kBlockA));  // replaced by an entry: loads
  EXPECT_EQ(cache.Load("opencl", kKey), Payload(kBlockA));
}

// What Load does with a file's bytes, without the file.
TEST(ProgramCache, DecodeTakesExactlyWhatEncodeWritesForItsKey) {
  const std::vector<std::uint8_t> payload = Payload(kBlockA);
  const std::string file = EncodeProgramCacheFile(kKey, payload);
  EXPECT_EQ(DecodeProgramCacheFile(file, kKey), payload);
  EXPECT_EQ(DecodeProgramCacheFile(file, kKey + "x"), std::nullopt);
  EXPECT_EQ(DecodeProgramCacheFile(file + "x", kKey), std::nullopt);                     // trailing bytes
  EXPECT_EQ(DecodeProgramCacheFile(file.substr(0, file.size() - 1), kKey), std::nullopt);  // truncated
  EXPECT_EQ(EncodeProgramCacheFile(kKey, {}), "");
  // The size line only as written: no padding, sign or leading zero, nothing after the hash.
  const std::string size = std::to_string(payload.size());
  const std::size_t at = file.find("\n" + size + " sha256:") + 1;
  ASSERT_NE(at, 0u);
  for (const char* edit : {" ", "+", "0"})
    EXPECT_EQ(DecodeProgramCacheFile(file.substr(0, at) + edit + file.substr(at), kKey), std::nullopt) << edit;
  const std::size_t end = file.find('\n', at);
  for (const char* edit : {" ", "\t", " x"})
    EXPECT_EQ(DecodeProgramCacheFile(file.substr(0, end) + edit + file.substr(end), kKey), std::nullopt) << edit;
  EXPECT_EQ(DecodeProgramCacheFile(file.substr(0, at + size.size()) + "  " + file.substr(at + size.size() + 1), kKey),
            std::nullopt);
}

}  // namespace
}  // namespace skintune::internal
