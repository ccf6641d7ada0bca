#include "generator/covering.h"

#include <array>
#include <set>

namespace skintune {

namespace {

// The six paired axes, as small integer codes per variant.
constexpr int kAxes = 6;
constexpr std::array<int, kAxes> kSizes = {3, 3, 3, 2, 4, 2};  // layout, index, weight, palette, storage, blend
constexpr std::array<const char*, kAxes> kAxisNames = {"layout", "index", "weight", "palette", "storage", "blend"};

using Row = std::array<int, kAxes>;

Variant FromRow(Lang lang, const Row& r) {
  Variant v;
  v.lang = lang;
  v.layout = static_cast<Layout>(r[0]);
  v.index = static_cast<IndexFormat>(r[1]);
  v.weight = static_cast<WeightFormat>(r[2]);
  v.palette = static_cast<PaletteFormat>(r[3]);
  v.storage = static_cast<PaletteStorage>(r[4]);
  v.blend = static_cast<Blend>(r[5]);
  if (lang == Lang::kGlslVertex) v.wg_size = 0;
  return v;
}

std::string ValueName(int axis, int value) {
  switch (axis) {
    case 0: return Name(static_cast<Layout>(value));
    case 1: return Name(static_cast<IndexFormat>(value));
    case 2: return Name(static_cast<WeightFormat>(value));
    case 3: return Name(static_cast<PaletteFormat>(value));
    case 4: return Name(static_cast<PaletteStorage>(value));
    default: return Name(static_cast<Blend>(value));
  }
}

// A pair key: (axis a, value x, axis b, value y) with a < b.
using Pair = std::array<int, 4>;

std::set<Pair> PairsOf(const Row& r) {
  std::set<Pair> pairs;
  for (int a = 0; a < kAxes; ++a)
    for (int b = a + 1; b < kAxes; ++b) pairs.insert({a, r[a], b, r[b]});
  return pairs;
}

std::vector<Row> AllRows() {
  std::vector<Row> rows;
  Row r{};
  for (r[0] = 0; r[0] < kSizes[0]; ++r[0]) for (r[1] = 0; r[1] < kSizes[1]; ++r[1])
  for (r[2] = 0; r[2] < kSizes[2]; ++r[2]) for (r[3] = 0; r[3] < kSizes[3]; ++r[3])
  for (r[4] = 0; r[4] < kSizes[4]; ++r[4]) for (r[5] = 0; r[5] < kSizes[5]; ++r[5]) rows.push_back(r);
  return rows;
}

// Fills the other axes round-robin (row number i), keeping the variant valid.
Variant Complete(Variant v, std::size_t i, const DeviceLimits& device, const ProblemShape& shape,
                 const std::vector<int>& wgs) {
  static constexpr int kVpi[] = {1, 2, 4, 8};
  v.influences = std::max(shape.max_influences, static_cast<int>(i % 8) + 1);
  v.mixed = i % 2 ? MixedCounts::kBucketed : MixedCounts::kPadded;
  v.position = (i / 2) % 2 ? PositionFormat::kFloat3 : PositionFormat::kFloat4;
  v.normals = shape.has_normals && (i / 3) % 2 == 1;
  if (v.lang != Lang::kGlslVertex) {
    v.vertices_per_item = kVpi[i % 4];
    v.assignment = v.vertices_per_item > 1 && (i / 4) % 2 ? Assignment::kStrided : Assignment::kContiguous;
    v.wg_size = wgs.empty() ? 128 : wgs[i % wgs.size()];
    for (std::size_t k = 0; k < wgs.size() && !CheckVariant(v, device, shape).empty(); ++k)
      v.wg_size = wgs[(i + k + 1) % wgs.size()];
  }
  return v;
}

}  // namespace

CoveringSet BuildCoveringSet(Lang lang, const DeviceLimits& device, const ProblemShape& shape,
                             const std::vector<int>& wg_sizes) {
  // Rows whose variant (with a valid completion) can run.
  std::vector<Row> candidates;
  for (const Row& r : AllRows()) {
    if (CheckVariant(Complete(FromRow(lang, r), 0, device, shape, wg_sizes), device, shape).empty())
      candidates.push_back(r);
  }
  std::set<Pair> wanted;
  for (const Row& r : AllRows())
    for (const Pair& p : PairsOf(r)) wanted.insert(p);
  std::set<Pair> coverable;
  for (const Row& r : candidates)
    for (const Pair& p : PairsOf(r)) coverable.insert(p);

  CoveringSet result;
  for (const Pair& p : wanted) {
    if (!coverable.count(p)) {
      result.uncoverable.push_back(std::string(kAxisNames[p[0]]) + "=" + ValueName(p[0], p[1]) + " & " +
                                   kAxisNames[p[2]] + "=" + ValueName(p[2], p[3]));
    }
  }
  // Greedy: take the candidate covering the most still-uncovered pairs.
  std::set<Pair> missing = coverable;
  std::vector<Row> chosen;
  while (!missing.empty()) {
    std::size_t best = 0, best_gain = 0;
    for (std::size_t c = 0; c < candidates.size(); ++c) {
      std::size_t gain = 0;
      for (const Pair& p : PairsOf(candidates[c])) gain += missing.count(p);
      if (gain > best_gain) best_gain = gain, best = c;
    }
    for (const Pair& p : PairsOf(candidates[best])) missing.erase(p);
    chosen.push_back(candidates[best]);
  }
  // At least 8 rows so that every influence count 1..8 and every other
  // rotated value appears (extra rows repeat the first rows' pairs).
  for (std::size_t i = 0; chosen.size() < 8 && i < candidates.size(); ++i) chosen.push_back(candidates[i]);
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    Variant v = Complete(FromRow(lang, chosen[i]), i, device, shape, wg_sizes);
    if (CheckVariant(v, device, shape).empty()) result.variants.push_back(v);
  }
  return result;
}

}  // namespace skintune
