// skintune (internal): the physics of a recorded time, checked wherever one
// is read, so that an impossible figure never ranks, wins or is drawn.
//
// A time that a file claims (a tuning measurement in the cache, a report or a
// worker's answer; a winners-database entry, read by the runtime or merged;
// a paper result's CPU timing) is possible when:
//   - the median is a positive, finite number of milliseconds;
//   - min and max, when recorded, are positive and finite, min <= median <= max;
//   - the bytes moved per frame, when recorded, are positive and finite;
//   - the GB/s, when recorded, are positive and finite and, with the bytes,
//     equal bytes / median within kGbpsTolerance (relative), which must
//     itself be finite (1e308 bytes over 0.001 ms is not).
// The rule lives here, once; each reader turns a violation into its own error
// naming the file and the element (docs/INPUTS.md lists the readers).
#pragma once

#include <optional>
#include <string>

namespace skintune::internal {

// Relative difference allowed between a recorded GB/s and bytes / median
// (the writers compute it from the very numbers they write: only rounding in
// a hand-edited or foreign file differs).
inline constexpr double kGbpsTolerance = 1e-3;

struct RecordedTime {
  double median_ms = 0.0;
  std::optional<double> min_ms;           // both or neither
  std::optional<double> max_ms;
  std::optional<double> bytes_per_frame;  // bytes read + written per frame
  std::optional<double> gbps;
};

// The first impossibility, naming the field as the files do
// ("'median_ms' is 0: a time must be a positive, finite number of ms"), or ""
// when the time is possible.
std::string ImpossibleTime(const RecordedTime& time);

// A finite number >= 0 (a fraction of the copy bandwidth, an error): "" or
// "'<name>' is <value>: must be a finite number >= 0".
std::string NotFiniteNonNegative(const char* name, double value);

}  // namespace skintune::internal
