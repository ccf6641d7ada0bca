#include "generator/covering.h"

#include <algorithm>
#include <array>
#include <iterator>
#include <set>

#include "generator/axes.h"

namespace skintune::internal {

namespace {

// The paired axes (Covering::kPaired in generator/axes.h), in table order;
// a row holds one value index per paired axis.
constexpr std::size_t kPairedCount = static_cast<std::size_t>(
    std::count_if(std::begin(kAxes), std::end(kAxes), [](const Axis& a) { return a.covering == Covering::kPaired; }));
constexpr std::array<std::size_t, kPairedCount> kPaired = [] {
  std::array<std::size_t, kPairedCount> paired{};
  std::size_t n = 0;
  for (std::size_t i = 0; i < kAxisCount; ++i)
    if (kAxes[i].covering == Covering::kPaired) paired[n++] = i;
  return paired;
}();

using Row = std::array<int, kPairedCount>;

const Axis& PairedAxis(std::size_t k) { return kAxes[kPaired[k]]; }

Variant FromRow(Lang lang, const Row& r) {
  Variant v;
  v.lang = lang;
  for (std::size_t k = 0; k < kPairedCount; ++k) PairedAxis(k).Set(v, PairedAxis(k).values[r[k]].code);
  return CollapseWorkGroups(v);
}

std::string ValueName(std::size_t k, int value) { return PairedAxis(k).values[value].name; }

// A pair key: (axis a, value x, axis b, value y) with a < b.
using Pair = std::array<int, 4>;

std::set<Pair> PairsOf(const Row& r) {
  std::set<Pair> pairs;
  for (std::size_t a = 0; a < kPairedCount; ++a)
    for (std::size_t b = a + 1; b < kPairedCount; ++b)
      pairs.insert({static_cast<int>(a), r[a], static_cast<int>(b), r[b]});
  return pairs;
}

// Every row, the last paired axis fastest.
std::vector<Row> AllRows() {
  std::vector<Row> rows;
  Row r{};
  for (;;) {
    rows.push_back(r);
    std::size_t k = kPairedCount;
    do {
      if (k == 0) return rows;
      --k;
      r[k] = (r[k] + 1) % static_cast<int>(PairedAxis(k).values.size());
    } while (r[k] == 0);
  }
}

// Fills the rotated axes round-robin (row number i), keeping the variant valid.
Variant Complete(Variant v, std::size_t i, const DeviceLimits& device, const ProblemShape& shape,
                 const std::vector<int>& wgs) {
  constexpr std::size_t kWg = AxisIndex<&Variant::wg_size>();
  for (std::size_t a = 0; a < kAxisCount; ++a) {
    const Axis& axis = kAxes[a];
    if (axis.covering != Covering::kRotated || (axis.without_work_groups && !HasWorkGroups(v.lang))) continue;
    std::vector<int> codes;
    for (const AxisValueSpec& value : axis.values) codes.push_back(value.code);
    if (a == kWg) codes = wgs.empty() ? std::vector<int>{128} : wgs;  // the caller's sizes
    axis.Set(v, codes[(i / static_cast<std::size_t>(axis.covering_step)) % codes.size()]);
  }
  // What the problem and the other axes allow.
  v.influences = std::max(shape.max_influences, v.influences);
  if (!shape.has_normals) v.normals = Normals::kNone;
  if (!shape.has_tangents && v.normals == Normals::kTangents) v.normals = Normals::kNormals;
  if (v.normals == Normals::kTangents) v.position = PositionFormat::kFloat4;  // tangents are float4
  if (v.normals == Normals::kNone) v.normal_format = NormalFormat::kF32;     // nothing to pack
  // Morph targets: a mesh without them has no morph variants, one that they move none without them.
  if (shape.morph_targets == 0) v.morph = Morph::kNone;
  if (shape.morph_moves && v.morph == Morph::kNone) {
    constexpr Morph kSkinning[] = {Morph::kDense, Morph::kSparse, Morph::kDenseHalf, Morph::kSparseHalf};
    v.morph = kSkinning[i % std::size(kSkinning)];
  }
  // Animation: a scene the host animates has host only, one animated on the device every other value.
  if (!shape.animated) v.animation = Animation::kHost;
  if (shape.animated && v.animation == Animation::kHost) v.animation = Animation::kSampled;
  if (v.animation != Animation::kHost && v.palette == PaletteFormat::kDualQuaternion) v.animation = Animation::kHost;
  if (v.vertices_per_item == 1) v.assignment = Assignment::kContiguous;
  if (HasWorkGroups(v.lang)) {
    for (std::size_t k = 0; k < wgs.size() && !CheckVariant(v, device, shape).empty(); ++k)
      v.wg_size = wgs[(i + k + 1) % wgs.size()];
  }
  return v;
}

// Whether a row's paired values belong together whatever the device: it
// breaks none of the constraints that hold by construction (blend dq with
// the dualquat palette and only with it, dq only on a rigid mesh). Pairs no
// such row holds are not wanted (nor reported uncoverable).
bool Coherent(const Row& r, const DeviceLimits& device, const ProblemShape& shape) {
  for (const Violation& v : CheckVariant(FromRow(Lang::kOpenCl, r), device, shape))
    if (v.constraint == Constraint::kBlendPalette || v.constraint == Constraint::kJointsNotRigid) return false;
  return true;
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
    if (Coherent(r, device, shape))
      for (const Pair& p : PairsOf(r)) wanted.insert(p);
  std::set<Pair> coverable;
  for (const Row& r : candidates)
    for (const Pair& p : PairsOf(r)) coverable.insert(p);

  CoveringSet result;
  for (const Pair& p : wanted) {
    if (!coverable.count(p)) {
      const auto a = static_cast<std::size_t>(p[0]), b = static_cast<std::size_t>(p[2]);
      result.uncoverable.push_back(std::string(PairedAxis(a).name) + "=" + ValueName(a, p[1]) + " & " +
                                   PairedAxis(b).name + "=" + ValueName(b, p[3]));
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

}  // namespace skintune::internal
