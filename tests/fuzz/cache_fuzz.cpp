// Fuzz target for the measurement cache readers: MeasurementCache (`skintune
// tune` resuming from DIR/cache.jsonl) and ReadMeasurementLines (`skintune db
// replay`). Every measurement either reader accepts has possible figures.
#include <cstddef>
#include <cstdint>
#include <string>

#include "tests/fuzz/fuzz_support.h"
#include "tuner/measurement.h"
#include "tuner/replay.h"

using namespace skintune::internal;  // the readers under test and fuzz_support.h's helpers

namespace {

void CheckPossible(const Measurement& m) {
  if (!ImpossibleFigures(m).empty())
    fuzz::Die("cache_fuzz", "accepted an impossible measurement: " + ImpossibleFigures(m));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::ScratchFile("cache_fuzz", "cache.jsonl");
  fuzz::WriteBytes("cache_fuzz", path, data, size);
  try {
    for (const Measurement& m : ReadMeasurementLines(path)) CheckPossible(m);
  } catch (const Error& e) {
    fuzz::ExpectNamed("cache_fuzz", e, path);
  }
  try {
    MeasurementCache cache(path);  // may cut off a torn last line: the file is ours
    for (const Measurement& m : cache.all()) {
      CheckPossible(m);
      if (cache.Find(m.CacheKey()) == nullptr) fuzz::Die("cache_fuzz", "a measurement it holds is not found");
    }
  } catch (const Error& e) {
    fuzz::ExpectNamed("cache_fuzz", e, path);
  }
  return 0;
}
