// skintune (internal): the runner driver (runtime/runner.h) on the host CPU,
// running the fast path's kernels (cpu_kernels/cpu_kernels.h) as the cpu
// language. Its DeviceApi (cpu_runner.cpp):
//
// - Build: the kernel text is a parameter block (templates/skin.cpu): its
//   #define lines select the kernel of the table (B, index and weight
//   formats, palette rows, blend); any other line that is not a comment or
//   #line fails with Error("CPU build: ..."). The copy (templates/copy.cpu)
//   is an all-thread memcpy.
// - Buffers are 64-byte-aligned host memory; palettes are reordered per
//   frame into the kernels' column blocks (LoadCpuPalette).
// - Launches run on a thread pool in chunks; instanced launches loop over
//   the instances.
// - Schedule: threads, chunk size and streaming stores are chosen per
//   variant and frame shape (each launch's vertices and instances) by
//   measurement on the first timed (or live) frames: every candidate
//   (CpuScheduleCandidates x streaming on/off) runs the variant's own frame,
//   timed as the use times it (cold for the kernel time), in rounds; the
//   fastest median wins (ScheduleOf says which). The copy
//   runs on every thread, one chunk per thread.
// - Times: the host's steady clock around each launch (verify, and the
//   kernel time: each frame's buffers first evicted from every cache with
//   clflushopt and the pool's threads woken, then the clock) or each burst
//   (time).
// Errors name the stage: "CPU setup", "build", "launch" or "guard".
#pragma once

#include <optional>
#include <string>

#include "cpu_kernels/cpu_kernels.h"
#include "runtime/runner.h"

namespace skintune::internal {

// What the cpu device chose for a variant.
struct CpuChoice {
  CpuSchedule schedule;
  bool stream_stores = true;
};
// "2 threads x 16384-vertex chunks, streaming stores"
std::string Describe(const CpuChoice& choice);

class CpuRunner final : public Runner {
 public:
  // `threads`: the most threads a schedule may use (0: every logical CPU).
  explicit CpuRunner(unsigned threads = 0);
  // The choice made for the variant `key` on the frame shape it ran last, if any.
  std::optional<CpuChoice> ScheduleOf(const std::string& key) const;
};

}  // namespace skintune::internal
