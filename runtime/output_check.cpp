#include "runtime/output_check.h"

#include <algorithm>
#include <cstring>
#include <sstream>

namespace skintune::internal {

namespace {

std::uint32_t WordAt(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  std::uint32_t word = 0;
  std::memcpy(&word, bytes.data() + at, 4);
  return word;
}

}  // namespace

std::string FirstLines(const std::string& text, int lines) {
  std::istringstream in(text);
  std::string line, out;
  int count = 0, total = 0;
  while (std::getline(in, line)) {
    if (count < lines) {
      out += "\n  " + line;
      ++count;
    }
    ++total;
  }
  if (total > count) out += "\n  ... (" + std::to_string(total - count) + " more lines)";
  return out;
}

// Written a block at a time: the copy-bandwidth probe poisons outputs of
// hundreds of MB.
std::vector<std::uint8_t> PoisonedOutput(std::size_t out_bytes) {
  std::vector<std::uint8_t> bytes(out_bytes + kGuardBytes);
  const auto fill = [&](std::size_t from, std::size_t to, std::uint32_t word) {
    constexpr std::size_t kBlockWords = 1024;
    std::uint32_t block[kBlockWords];
    std::fill_n(block, kBlockWords, word);
    for (std::size_t at = from; at + 4 <= to; at += sizeof block)
      std::memcpy(bytes.data() + at, block, std::min(sizeof block, (to - at) / 4 * 4));
  };
  const std::size_t poisoned = out_bytes / 4 * 4;
  fill(0, poisoned, kPoisonWord);
  fill(poisoned, bytes.size(), kGuardWord);
  return bytes;
}

OutputCheck CheckGuardAndCountPoisoned(std::vector<std::uint8_t>& bytes, std::size_t out_bytes, std::size_t stride,
                                       std::size_t vertex_count) {
  OutputCheck check;
  for (std::size_t w = 0; w < kGuardBytes / 4; ++w) {
    if (WordAt(bytes, out_bytes + w * 4) != kGuardWord) {
      check.first_changed_offset = std::min(check.first_changed_offset, w * 4);
      ++check.changed_guard_words;
    }
  }
  if (check.changed_guard_words > 0) {
    check.guard_ok = false;
    return check;
  }
  bytes.resize(out_bytes);
  for (std::size_t v = 0; v < vertex_count; ++v) {
    for (std::size_t w = 0; w < stride / 4; ++w) {
      if (WordAt(bytes, v * stride + w * 4) == kPoisonWord) {
        ++check.poisoned_vertices;
        break;
      }
    }
  }
  return check;
}

std::string GuardFailure(const OutputCheck& check, std::size_t out_bytes) {
  return "wrote past the end of its " + std::to_string(out_bytes) + "-byte output (" +
         std::to_string(check.changed_guard_words) + " guard words changed, the first at +" +
         std::to_string(check.first_changed_offset) + " bytes)";
}

}  // namespace skintune::internal
