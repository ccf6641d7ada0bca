// skintune: the one error type of the offline (reference/generator/tuner) code.
//
// Inside skintune, bad input is reported by throwing skintune::internal::Error whose
// message is complete and user-facing: it names the file (when there is one)
// and the offending element, e.g.
//   "CesiumMan.gltf: accessors[7] (JOINTS_0 of meshes[0].primitives[0]): component type FLOAT is not allowed (expected UNSIGNED_BYTE or UNSIGNED_SHORT)"
// The command-line tool prints it as one line on stderr and exits non-zero.
// The runtime's public API (runtime/) turns these into error values.
#pragma once

#include <iterator>
#include <stdexcept>
#include <string>
#include <string_view>

namespace skintune::internal {

// "A", "A or B", "A, B or C": `name(item)` of each item of `items`, for the
// messages that list what was expected.
template <typename Items, typename Name>
std::string OneOf(const Items& items, Name&& name) {
  std::string out;
  const std::size_t n = std::size(items);
  std::size_t i = 0;
  for (const auto& item : items) {
    if (i > 0) out += i + 1 == n ? " or " : ", ";
    out += name(item);
    ++i;
  }
  return out;
}

// `text` as an error message quotes it: whole up to `max` characters, else
// its start, "..." and how long it was, so a 100 KB bad string in an input
// gives a line a terminal can show.
inline std::string Excerpt(std::string_view text, std::size_t max = 120) {
  if (text.size() <= max) return std::string(text);
  return std::string(text.substr(0, max)) + "... (" + std::to_string(text.size()) + " characters)";
}

// An error message as it is shown (a public Status, a command's stderr):
// a run of more than 4096 characters without white space (longer than any
// path) keeps its first 120 (Excerpt), and the whole is cut at 16384. An
// input's bad string is quoted whole by the reader that finds it; a 100 KB
// one must not become a 100 KB message.
inline std::string Bounded(std::string_view message) {
  constexpr std::size_t kLongestRun = 4096, kLongest = 16384;
  std::string out;
  for (std::size_t i = 0; i < message.size();) {
    std::size_t end = i;
    while (end < message.size() && static_cast<unsigned char>(message[end]) > ' ') ++end;
    if (end == i) {
      out += message[i++];
      continue;
    }
    const std::string_view run = message.substr(i, end - i);
    out += run.size() > kLongestRun ? Excerpt(run) : std::string(run);
    i = end;
  }
  return Excerpt(out, kLongest);
}

// Bounded, on one line: control characters (a newline in a config's string,
// a build log's lines) become spaces. What the command prints after "skintune: error: ".
inline std::string OneLine(std::string_view message) {
  std::string out = Bounded(message);
  for (char& c : out)
    if (static_cast<unsigned char>(c) < ' ') c = ' ';
  return out;
}

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// A setting that cannot work (a config's impossible stop rule): the command
// exits 2, as for a bad command line, rather than 1 for bad data.
class UsageError : public Error {
 public:
  using Error::Error;
};

}  // namespace skintune::internal
