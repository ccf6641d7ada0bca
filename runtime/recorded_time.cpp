#include "runtime/recorded_time.h"

#include <cmath>
#include <cstdio>

namespace skintune::internal {

namespace {

// %.17g: a value shown in an error is the value read, not a rounding of it.
std::string Text(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", value);
  return text;
}

bool Positive(double value) { return std::isfinite(value) && value > 0.0; }

std::string NotPositive(const char* name, double value, const char* what) {
  return std::string("'") + name + "' is " + Text(value) + ": " + what + " must be a positive, finite number";
}

}  // namespace

std::string ImpossibleTime(const RecordedTime& t) {
  if (!Positive(t.median_ms)) return NotPositive("median_ms", t.median_ms, "a time");
  if (t.min_ms.has_value() != t.max_ms.has_value()) return "'min_ms' and 'max_ms' must be recorded together";
  if (t.min_ms) {
    if (!Positive(*t.min_ms)) return NotPositive("min_ms", *t.min_ms, "a time");
    if (!Positive(*t.max_ms)) return NotPositive("max_ms", *t.max_ms, "a time");
    if (!(*t.min_ms <= t.median_ms && t.median_ms <= *t.max_ms)) {
      return "'min_ms' " + Text(*t.min_ms) + ", 'median_ms' " + Text(t.median_ms) + ", 'max_ms' " + Text(*t.max_ms) +
             ": must be in order (min <= median <= max)";
    }
  }
  if (t.bytes_per_frame && !Positive(*t.bytes_per_frame))
    return NotPositive("bytes_per_frame", *t.bytes_per_frame, "a frame's bytes");
  if (t.gbps) {
    if (!Positive(*t.gbps)) return NotPositive("gbps", *t.gbps, "a bandwidth");
    if (t.bytes_per_frame) {
      const double expected = *t.bytes_per_frame / t.median_ms / 1e6;
      if (!std::isfinite(expected))  // 1e308 bytes in 0.001 ms: the check below would pass inf against inf
        return "'bytes_per_frame' " + Text(*t.bytes_per_frame) + " / 'median_ms' " + Text(t.median_ms) +
               " overflows: not a bandwidth";
      if (!(std::fabs(*t.gbps - expected) <= kGbpsTolerance * expected)) {
        return "'gbps' is " + Text(*t.gbps) + " but 'bytes_per_frame' / 'median_ms' is " + Text(expected) +
               " GB/s: they must agree";
      }
    }
  }
  return "";
}

std::string NotFiniteNonNegative(const char* name, double value) {
  if (std::isfinite(value) && value >= 0.0) return "";
  return std::string("'") + name + "' is " + Text(value) + ": must be a finite number >= 0";
}

}  // namespace skintune::internal
