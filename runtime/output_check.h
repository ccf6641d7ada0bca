// skintune (internal): the output checks every kernel runner shares
// (OpenClRunner, CudaRunner, GlRunner), and their log excerpt helper.
//
// A tuner keeps the fastest variant, so a kernel that is fast because it is
// wrong must never win. Two checks make a wrong kernel fail instead:
// - POISON: before every run each output buffer is filled with kPoisonWord
//   (0x7fc00000, a quiet NaN) in every 32-bit word, so a vertex the kernel
//   never writes reads back as NaN and fails the comparison with the gold
//   instead of passing on stale data from an earlier run; the runners also
//   count such vertices (RunResult::poisoned_vertices).
// - GUARD: each output buffer is followed by kGuardBytes of kGuardWord; a
//   guard word changed after the run means the kernel (or a transform
//   feedback capture) wrote past the end of its output, which the runner
//   reports as an error ("<API> guard: ...") instead of a result.
// Each runner formats its own errors (stage prefix, what wrote): this file
// only fills, checks and counts.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace skintune::internal {

inline constexpr std::size_t kGuardBytes = 4096;
inline constexpr std::uint32_t kPoisonWord = 0x7fc00000u;  // quiet NaN
inline constexpr std::uint32_t kGuardWord = 0xa5c3e1f0u;

// The first `lines` lines of `text` (a build or JIT log), each on its own
// line indented by two spaces, then "... (N more lines)" when there are more.
std::string FirstLines(const std::string& text, int lines);

// The initial contents of an output buffer: `out_bytes` of kPoisonWord
// followed by kGuardBytes of kGuardWord (out_bytes + kGuardBytes in all).
std::vector<std::uint8_t> PoisonedOutput(std::size_t out_bytes);

struct OutputCheck {
  bool guard_ok = true;
  std::size_t changed_guard_words = 0;             // when !guard_ok
  std::size_t first_changed_offset = kGuardBytes;  // bytes after the output's end, when !guard_ok
  std::size_t poisoned_vertices = 0;               // when guard_ok: vertices with a word still poisoned
};

// Checks an output read back as out_bytes + kGuardBytes bytes. When a guard
// word changed, returns guard_ok = false and leaves `bytes` as it is.
// Otherwise trims `bytes` to out_bytes and counts the vertices (`stride`
// bytes each, `vertex_count` of them) that hold kPoisonWord in any word.
OutputCheck CheckGuardAndCountPoisoned(std::vector<std::uint8_t>& bytes, std::size_t out_bytes, std::size_t stride,
                                       std::size_t vertex_count);

// "wrote past the end of its <out_bytes>-byte output (<K> guard words
// changed, the first at +<X> bytes)": the tail of a runner's guard error.
std::string GuardFailure(const OutputCheck& check, std::size_t out_bytes);

}  // namespace skintune::internal
