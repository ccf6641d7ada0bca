// Fuzz target for the measurement cache readers: MeasurementCache (`skintune
// tune` resuming from DIR/cache.jsonl) and ReadMeasurementLines (`skintune db
// replay`). Every measurement either reader accepts has possible figures.
#include <cstddef>
#include <cstdint>
#include <string>

#include "tests/fuzz/fuzz_support.h"
#include "tuner/measurement.h"
#include "tuner/replay.h"

namespace {

void CheckPossible(const skintune::Measurement& m) {
  if (!skintune::ImpossibleFigures(m).empty())
    skintune::fuzz::Die("cache_fuzz", "accepted an impossible measurement: " + skintune::ImpossibleFigures(m));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = skintune::fuzz::ScratchFile("cache_fuzz", "cache.jsonl");
  skintune::fuzz::WriteBytes("cache_fuzz", path, data, size);
  try {
    for (const skintune::Measurement& m : skintune::ReadMeasurementLines(path)) CheckPossible(m);
  } catch (const skintune::Error& e) {
    skintune::fuzz::ExpectNamed("cache_fuzz", e, path);
  }
  try {
    skintune::MeasurementCache cache(path);  // may cut off a torn last line: the file is ours
    for (const skintune::Measurement& m : cache.all()) {
      CheckPossible(m);
      if (cache.Find(m.CacheKey()) == nullptr) skintune::fuzz::Die("cache_fuzz", "a measurement it holds is not found");
    }
  } catch (const skintune::Error& e) {
    skintune::fuzz::ExpectNamed("cache_fuzz", e, path);
  }
  return 0;
}
