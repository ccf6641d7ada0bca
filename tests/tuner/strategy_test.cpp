#include "tuner/strategy.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "generator/axes.h"
#include "generator/space.h"
#include "base/error.h"
#include "tests/tuner/synthetic_model.h"

namespace skintune::internal {
namespace {

// Every point (constraints ignored) of the OpenCL space at B = 4 without normals, palettes from
// the host: a full product, so every axis value is a neighbour of every point. (Forms animated on
// the device have a start of their own: AnimatedSpace below.)
std::vector<Variant> ProductSpace() {
  TuningSpace space = TuningSpace::Full();
  space.langs = {Lang::kOpenCl};
  space.influences = {4};
  space.normals = {Normals::kNone};
  space.morphs = {Morph::kNone};
  space.normal_formats = {NormalFormat::kF32};
  space.animations = {Animation::kHost};
  std::vector<Variant> out;
  space.ForEach([&](const Variant& v) { out.push_back(v); });
  return out;
}

// Separable: a sum of one term per axis, minimal (exactly 1.0) at bucketed, soa-split, float3, u8,
// unorm8, mat3x4, local, point, v4s, wg64.
double SeparableCost(const Variant& v) {
  double t = 1.0;
  t += v.mixed == MixedCounts::kBucketed ? 0.0 : 0.05;
  t += v.layout == Layout::kSoaSplit ? 0.0 : v.layout == Layout::kSoa ? 0.2 : 0.5;
  t += v.position == PositionFormat::kFloat3 ? 0.0 : 0.1;
  t += 0.07 * static_cast<int>(2 - static_cast<int>(v.index));
  t += 0.09 * static_cast<int>(2 - static_cast<int>(v.weight));
  t += v.palette == PaletteFormat::kMat3x4 ? 0.0 : 0.03;
  t += v.storage == PaletteStorage::kLocal ? 0.0 : v.storage == PaletteStorage::kImage ? 0.01 : 0.2;
  t += v.blend == Blend::kPoint ? 0.0 : 0.02;
  t += v.vertices_per_item == 4 ? 0.0 : 0.04 * std::abs(v.vertices_per_item - 4);
  t += v.assignment == Assignment::kStrided ? 0.0 : 0.06;
  t += 0.001 * std::abs(v.wg_size - 64);
  return t;
}

struct Counted {
  std::map<std::string, int> calls;
  std::function<std::optional<double>(const Variant&)> model;
  Evaluator evaluator() {
    return [this](const Variant& v) {
      ++calls[v.Key()];
      return model(v);
    };
  }
};

std::optional<Variant> TrueOptimum(const std::vector<Variant>& candidates,
                                   const std::function<std::optional<double>(const Variant&)>& model) {
  std::optional<Variant> best;
  double best_ms = 0.0;
  for (const Variant& v : candidates) {
    const std::optional<double> t = model(v);
    if (t && (!best || *t < best_ms)) {
      best = v;
      best_ms = *t;
    }
  }
  return best;
}

TEST(Strategy, ExhaustiveFindsTheOptimumEvaluatingEveryDistinctCandidateOnce) {
  std::vector<Variant> candidates = testing::SyntheticCandidates();
  candidates.resize(3000);
  candidates.push_back(candidates[5]);  // a duplicate costs nothing
  Counted counted{{}, testing::SyntheticEvaluate};
  const SearchResult r = Search(candidates, counted.evaluator(), {"exhaustive", 0, 1});
  ASSERT_TRUE(r.best);
  EXPECT_EQ(*r.best, *TrueOptimum(candidates, testing::SyntheticEvaluate));
  EXPECT_EQ(r.best_ms, *testing::SyntheticEvaluate(*r.best));
  EXPECT_EQ(r.evaluations, 3000u);
  EXPECT_EQ(counted.calls.size(), 3000u);
  for (const auto& [key, n] : counted.calls) EXPECT_EQ(n, 1) << key;
}

// Two candidates differing in one axis only are two points: for every value of
// every axis of the table, so a coordinate the search forgets fails here.
TEST(Strategy, CoordinatesTellApartVariantsDifferingInAnyOneAxis) {
  for (const Axis& axis : kAxes) {
    for (const AxisValueSpec& value : axis.values) {
      Variant other;
      axis.Set(other, value.code);
      if (other == Variant{}) continue;
      for (const char* name : {"exhaustive", "coordinate"}) {
        const SearchResult r = Search({Variant{}, other}, [&](const Variant& v) { return v == other ? 1.0 : 2.0; },
                                      {name, 0, 1});
        EXPECT_EQ(r.evaluations, 2u) << name << " " << other.Key();
        EXPECT_EQ(r.best, other) << name << " " << other.Key();
      }
    }
  }
}

TEST(Strategy, ExhaustiveWithABudgetEvaluatesTheFirstCandidatesInOrder) {
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  Counted counted{{}, testing::SyntheticEvaluate};
  const SearchResult r = Search(candidates, counted.evaluator(), {"exhaustive", 100, 1});
  EXPECT_EQ(r.evaluations, 100u);
  for (std::size_t i = 0; i < 100; ++i) EXPECT_EQ(counted.calls.count(candidates[i].Key()), 1u);
  EXPECT_EQ(*r.best, *TrueOptimum({candidates.begin(), candidates.begin() + 100}, testing::SyntheticEvaluate));
}

TEST(Strategy, RandomRespectsTheBudgetAndIsDeterministicPerSeed) {
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  Counted a{{}, testing::SyntheticEvaluate};
  Counted b{{}, testing::SyntheticEvaluate};
  Counted c{{}, testing::SyntheticEvaluate};
  const SearchResult ra = Search(candidates, a.evaluator(), {"random", 250, 7});
  const SearchResult rb = Search(candidates, b.evaluator(), {"random", 250, 7});
  Search(candidates, c.evaluator(), {"random", 250, 8});
  EXPECT_EQ(ra.evaluations, 250u);
  EXPECT_EQ(a.calls.size(), 250u);  // distinct variants
  for (const auto& [key, n] : a.calls) EXPECT_EQ(n, 1) << key;
  EXPECT_EQ(a.calls, b.calls);
  EXPECT_EQ(*ra.best, *rb.best);
  EXPECT_EQ(ra.best_ms, rb.best_ms);
  EXPECT_NE(a.calls, c.calls);
}

TEST(Strategy, RandomSequenceIsFixedAcrossPlatforms) {
  // The PRNG is skintune's own (SplitMix64), not a standard distribution, so
  // the sample is the same with every compiler and standard library: pinned.
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  std::vector<std::string> order;
  const Evaluator record = [&](const Variant& v) -> std::optional<double> {
    order.push_back(v.Key());
    return 1.0;
  };
  Search(candidates, record, {"random", 3, 1});
  EXPECT_EQ(order, (std::vector<std::string>{
                       "opencl.b4.padded.soa.float3.u16.f32.mat4.local.matrix.v2s.wg64.nonormals",
                       "opencl.b4.bucketed.soa-split.float4.i32.unorm8.mat4.constant.point.v8c.wg128.nonormals",
                       "opencl.b4.padded.aos.float3.u8.unorm8.mat4.global.matrix.v8s.wg128.nonormals"}));
}

TEST(Strategy, RandomWithABudgetAboveTheCandidatesEvaluatesEachOnce) {
  std::vector<Variant> candidates = testing::SyntheticCandidates();
  candidates.resize(40);
  Counted counted{{}, testing::SyntheticEvaluate};
  const SearchResult r = Search(candidates, counted.evaluator(), {"random", 1000, 3});
  EXPECT_EQ(r.evaluations, 40u);
  EXPECT_EQ(*r.best, *TrueOptimum(candidates, testing::SyntheticEvaluate));
}

TEST(Strategy, BadOptionsThrow) {
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  EXPECT_THROW(Search(candidates, testing::SyntheticEvaluate, {"random", 0, 1}), Error);
  try {
    Search(candidates, testing::SyntheticEvaluate, {"annealing", 10, 1});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("annealing"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(Search({}, testing::SyntheticEvaluate, {"coordinate", 10, 1}).best);
}

TEST(Strategy, CoordinateFindsTheOptimumOfASeparableCostWithFarFewerEvaluations) {
  const std::vector<Variant> candidates = ProductSpace();
  ASSERT_GT(candidates.size(), 50000u);
  const std::function<std::optional<double>(const Variant&)> model = [](const Variant& v) {
    return std::optional<double>(SeparableCost(v));
  };
  Counted counted{{}, model};
  const SearchResult r = Search(candidates, counted.evaluator(), {"coordinate", 0, 1});
  ASSERT_TRUE(r.best);
  const Variant optimum = *TrueOptimum(candidates, model);
  EXPECT_EQ(*r.best, optimum) << r.best->Key() << " vs " << optimum.Key();
  EXPECT_LT(r.evaluations, candidates.size() / 500) << r.evaluations << " of " << candidates.size();
  for (const auto& [key, n] : counted.calls) EXPECT_EQ(n, 1) << key;
}

TEST(Strategy, CoordinateRestartsWhileTheBudgetLastsAndIsDeterministic) {
  const std::vector<Variant> candidates = testing::SyntheticCandidates();
  Counted a{{}, testing::SyntheticEvaluate};
  Counted b{{}, testing::SyntheticEvaluate};
  const SearchResult ra = Search(candidates, a.evaluator(), {"coordinate", 2000, 5});
  const SearchResult rb = Search(candidates, b.evaluator(), {"coordinate", 2000, 5});
  EXPECT_EQ(ra.evaluations, 2000u);  // the first descent ends long before: restarts used the rest
  EXPECT_EQ(a.calls.size(), 2000u);
  EXPECT_EQ(a.calls, b.calls);
  EXPECT_EQ(*ra.best, *rb.best);
}

TEST(Strategy, FailedVariantsNeverWin) {
  // The fastest variants of the model fail; no strategy may return them.
  std::vector<Variant> candidates = testing::SyntheticCandidates();
  std::vector<Variant> sorted = candidates;
  std::sort(sorted.begin(), sorted.end(), [](const Variant& x, const Variant& y) {
    return testing::SyntheticTimeMs(x) < testing::SyntheticTimeMs(y);
  });
  std::map<std::string, bool> failing;
  for (std::size_t i = 0; i < 50; ++i) failing[sorted[i].Key()] = true;
  const Evaluator evaluate = [&](const Variant& v) -> std::optional<double> {
    if (failing.count(v.Key())) return std::nullopt;
    return testing::SyntheticEvaluate(v);
  };
  for (const char* name : {"exhaustive", "random", "coordinate"}) {
    const SearchResult r = Search(candidates, evaluate, {name, name == std::string("exhaustive") ? 0u : 5000u, 2});
    ASSERT_TRUE(r.best) << name;
    EXPECT_FALSE(failing.count(r.best->Key())) << name << " returned failed " << r.best->Key();
    EXPECT_TRUE(evaluate(*r.best)) << name;
  }
  // Nothing ok: no best, whatever the strategy.
  const Evaluator all_fail = [](const Variant&) -> std::optional<double> { return std::nullopt; };
  for (const char* name : {"exhaustive", "random", "coordinate"}) {
    const SearchResult r = Search(candidates, all_fail, {name, 300, 1});
    EXPECT_FALSE(r.best) << name;
    EXPECT_EQ(r.evaluations, 300u) << name;
  }
}

TEST(Strategy, CoordinateLeavesAFailedStartingPoint) {
  const std::vector<Variant> candidates = ProductSpace();
  // The default start (soa, float4, u16, f32, mat3x4, global, matrix, v1c, wg128, padded) fails.
  Variant start;
  start.influences = 4;
  const Evaluator evaluate = [&](const Variant& v) -> std::optional<double> {
    if (v == start) return std::nullopt;
    return SeparableCost(v);
  };
  const SearchResult r = Search(candidates, evaluate, {"coordinate", 0, 1});
  ASSERT_TRUE(r.best);
  EXPECT_NE(*r.best, start);
  EXPECT_DOUBLE_EQ(r.best_ms, 1.0);  // the separable optimum (every term 0)
}

// Like SeparableCost but the index and weight formats interact, as GLSL on the
// H100 at 6400k-b4 did: u8 indices or unorm8 weights alone cost more than the
// default u16 + f32, both together cost least (and i32 / unorm16 cost more
// still). A descent moving one axis at a time stays on f32 weights.
double CoupledFormatsCost(const Variant& v) {
  const bool u8 = v.index == IndexFormat::kU8, unorm8 = v.weight == WeightFormat::kUnorm8;
  double t = SeparableCost(v) - 0.07 * static_cast<int>(2 - static_cast<int>(v.index)) -
             0.09 * static_cast<int>(2 - static_cast<int>(v.weight));
  if (u8 && unorm8) return t;
  if (u8 || unorm8) return t + 0.4;
  return t + 0.2 + (v.index == IndexFormat::kI32 ? 0.05 : 0.0) + (v.weight == WeightFormat::kUnorm16 ? 0.05 : 0.0);
}

TEST(Strategy, CoordinateMovesCoupledFormatsTogetherInsteadOfStoppingOnF32Weights) {
  const std::vector<Variant> candidates = ProductSpace();
  const std::function<std::optional<double>(const Variant&)> model = [](const Variant& v) {
    return std::optional<double>(CoupledFormatsCost(v));
  };
  const Variant optimum = *TrueOptimum(candidates, model);
  ASSERT_EQ(optimum.weight, WeightFormat::kUnorm8);
  ASSERT_EQ(optimum.index, IndexFormat::kU8);
  // One descent (budget 0): the model's optimum, not a point on f32 weights.
  const SearchResult r = Search(candidates, model, {"coordinate", 0, 1});
  ASSERT_TRUE(r.best);
  EXPECT_EQ(*r.best, optimum) << r.best->Key() << " vs " << optimum.Key();
  EXPECT_LT(r.evaluations, candidates.size() / 500) << r.evaluations << " of " << candidates.size();
}

// The animated-crowds space in small: palette kernels' forms (baked240) and
// forms that make their palette in the skin launch (fused120, fused240: storage
// local only, as the animation_fused constraint says), or `animations`.
std::vector<Variant> AnimatedSpace(std::vector<Animation> animations = {Animation::kBaked240, Animation::kFused120,
                                                                        Animation::kFused240}) {
  TuningSpace space = TuningSpace::Full();
  space.langs = {Lang::kCuda};
  space.influences = {4};
  space.mixed = {MixedCounts::kPadded};
  space.layouts = {Layout::kSoa, Layout::kSoaSplit};
  space.positions = {PositionFormat::kFloat4};
  space.indices = {IndexFormat::kU16};
  space.weights = {WeightFormat::kF32, WeightFormat::kUnorm16};
  space.palettes = {PaletteFormat::kMat3x4};
  space.storages = {PaletteStorage::kGlobal, PaletteStorage::kLocal};
  space.blends = {Blend::kMatrix};
  space.vertices_per_item = {1, 8};
  space.assignments = {Assignment::kContiguous, Assignment::kStrided};
  space.wg_sizes = {64, 256};
  space.normals = {Normals::kNone};
  space.morphs = {Morph::kNone};
  space.normal_formats = {NormalFormat::kF32};
  space.animations = std::move(animations);
  std::vector<Variant> out;
  space.ForEach([&](const Variant& v) {
    if (FusesPalette(v.animation) && v.storage != PaletteStorage::kLocal) return;
    out.push_back(v);
  });
  return out;
}

// As the H200 measured the 64 x 25k crowd (2026-11-30, CUDA, us): a palette
// kernel's form about 23 in any shape, best in global storage, one vertex an
// item; a fused form 18.2 in groups of 256, 8 vertices an item, strided, and
// slower than 23 in every shape one move away from that (33 with one vertex
// an item, 66 in groups of 64).
std::optional<double> AnimatedCrowdCost(const Variant& v) {
  const double formats = (v.layout == Layout::kSoa ? 0.0 : 0.3) + (v.weight == WeightFormat::kF32 ? 0.2 : 0.0);
  if (!FusesPalette(v.animation))
    return 23.0 + formats + (v.storage == PaletteStorage::kLocal ? 3.5 : 0.0) + (v.vertices_per_item == 8 ? 40.0 : 0.0) +
           (v.wg_size == 64 ? 0.2 : 0.0);
  const double rate = v.animation == Animation::kFused240 ? 0.0 : 0.1;
  double t = 18.2 + formats + rate;
  if (v.vertices_per_item == 1) t += 15.0;
  if (v.assignment == Assignment::kContiguous) t += 6.0;
  if (v.wg_size == 64) t += 40.0;
  return t;
}

TEST(Strategy, CoordinateStartsAtTheFusedShapeWhereItIsFasterThanTheDefault) {
  const std::vector<Variant> candidates = AnimatedSpace();
  const Variant optimum = *TrueOptimum(candidates, AnimatedCrowdCost);
  ASSERT_EQ(optimum, InFusedShape([] {
              Variant v;
              v.lang = Lang::kCuda;
              v.influences = 4;
              v.weight = WeightFormat::kUnorm16;
              v.animation = Animation::kFused240;
              return v;
            }()));
  // The animated-crowds config's budget: the fused shape is evaluated second
  // and the descent goes on from it.
  Counted counted;
  counted.model = AnimatedCrowdCost;
  const SearchResult r = Search(candidates, counted.evaluator(), {"coordinate", 12, 1, 0.05});
  ASSERT_TRUE(r.best);
  EXPECT_EQ(*r.best, optimum) << r.best->Key();
  EXPECT_LE(r.evaluations, 12u);
  // Where a fused form fails its checks (a cross-fading crowd, whose blends
  // palette records cannot make within the budget), the descent starts from
  // the default as before: the fused start costs one evaluation.
  const Evaluator without_fused = [](const Variant& v) -> std::optional<double> {
    if (FusesPalette(v.animation)) return std::nullopt;
    return AnimatedCrowdCost(v);
  };
  const SearchResult plain = Search(candidates, without_fused, {"coordinate", 12, 1, 0.05});
  ASSERT_TRUE(plain.best);
  EXPECT_FALSE(FusesPalette(plain.best->animation));
  EXPECT_EQ(plain.best->storage, PaletteStorage::kGlobal);
  EXPECT_EQ(plain.best->vertices_per_item, 1);
  EXPECT_LT(plain.best_ms, 23.0 * 1.05);  // moves within the margin are not taken
}

// A cross-fading crowd: palette records (baked240, fused240) are over the
// budget, so they measure nothing; hybrid records made in the skin launch are
// the fastest form in the fused shape, local records with a palette kernel
// about 20% slower in any shape. The fused start takes the hybrid records, so
// the first descent starts where they win, within the config's budget.
TEST(Strategy, CoordinateStartsACrossFadingCrowdAtTheFusedRecordsThatCanServeIt) {
  const std::vector<Variant> candidates = AnimatedSpace(
      {Animation::kBaked240, Animation::kLocal240, Animation::kFused240, Animation::kFusedLocal240, Animation::kFusedHybrid240});
  const Evaluator cross_fading = [](const Variant& v) -> std::optional<double> {
    if (!BakesLocally(v.animation)) return std::nullopt;  // palette records: over the budget
    Variant shape = v;  // the cost of the same shape with palette records, fused or not
    shape.animation = FusesPalette(v.animation) ? Animation::kFused240 : Animation::kBaked240;
    const std::optional<double> t = AnimatedCrowdCost(shape);
    if (!FusesPalette(v.animation)) return *t * 1.2;
    return *t + (BakesHybrid(v.animation) ? 1.0 : 2.0);  // the walk: hybrid records walk a third of the crowd
  };
  const Variant optimum = *TrueOptimum(candidates, cross_fading);
  ASSERT_EQ(optimum.animation, Animation::kFusedHybrid240) << optimum.Key();
  ASSERT_EQ(optimum, InFusedShape(optimum)) << optimum.Key();
  Counted counted;
  counted.model = cross_fading;
  const SearchResult r = Search(candidates, counted.evaluator(), {"coordinate", 12, 1, 0.05});
  ASSERT_TRUE(r.best);
  EXPECT_EQ(*r.best, optimum) << r.best->Key();
  EXPECT_LE(r.evaluations, 12u);
}

TEST(Strategy, CoordinateWithFivePercentOfAWideSpaceLandsWithinFivePercentOfTheOptimum) {
  // The shape of the recorded landscapes' space (tests/data/tuning/exhaustive-1600k-b4.json):
  // 3 layouts x float4/float3 x u16/u8 x f32/unorm8 x 4 storages x 5 vertex assignments, mat3x4, wg 256.
  TuningSpace space = TuningSpace::Full();
  space.langs = {Lang::kGlslCompute};
  space.influences = {4};
  space.normals = {Normals::kNone};
  space.morphs = {Morph::kNone};
  space.normal_formats = {NormalFormat::kF32};
  space.mixed = {MixedCounts::kPadded};
  space.positions = {PositionFormat::kFloat4, PositionFormat::kFloat3};
  space.indices = {IndexFormat::kU16, IndexFormat::kU8};
  space.weights = {WeightFormat::kF32, WeightFormat::kUnorm8};
  space.palettes = {PaletteFormat::kMat3x4};
  space.storages = {PaletteStorage::kConstant, PaletteStorage::kLocal, PaletteStorage::kGlobal, PaletteStorage::kImage};
  space.blends = {Blend::kMatrix};
  space.vertices_per_item = {1, 2, 4};
  space.assignments = {Assignment::kContiguous, Assignment::kStrided};
  space.wg_sizes = {256};
  std::vector<Variant> candidates;
  space.ForEach([&](const Variant& v) { candidates.push_back(v); });
  ASSERT_GE(candidates.size(), 400u);
  const std::function<std::optional<double>(const Variant&)> model = [](const Variant& v) {
    return std::optional<double>(CoupledFormatsCost(v));
  };
  const double optimum_ms = *model(*TrueOptimum(candidates, model));
  const std::size_t budget = (candidates.size() * 5 + 99) / 100;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    const SearchResult r = Search(candidates, model, {"coordinate", budget, seed});
    ASSERT_TRUE(r.best) << seed;
    EXPECT_LE(r.evaluations, budget);
    EXPECT_LE(r.best_ms, 1.05 * optimum_ms) << "seed " << seed << ": " << r.best->Key();
  }
}

// The look-ahead (what the tuner compiles in parallel) announces, for every
// strategy and budget, only variants not evaluated yet, never more than the
// budget has left, and every evaluated variant before its evaluation; and
// the search is the same with it as without.
TEST(Strategy, LookAheadAnnouncesWhatIsEvaluatedNextWithinTheBudgetAndChangesNothing) {
  std::vector<Variant> candidates = testing::SyntheticCandidates();
  candidates.resize(600);
  const struct {
    const char* name;
    std::size_t budget;
  } cases[] = {{"exhaustive", 0}, {"exhaustive", 40}, {"random", 30}, {"coordinate", 0}, {"coordinate", 25}, {"coordinate", 60}};
  for (const auto& c : cases) {
    SCOPED_TRACE(std::string(c.name) + " budget " + std::to_string(c.budget));
    const StrategyOptions options{c.name, c.budget, 3};
    const SearchResult plain = Search(candidates, testing::SyntheticEvaluate, options);

    std::vector<std::string> evaluated;
    std::map<std::string, std::size_t> announced_at;  // key -> evaluations done when first announced
    std::size_t announced = 0, unannounced = 0;
    const Evaluator evaluate = [&](const Variant& v) {
      if (!announced_at.count(v.Key())) ++unannounced;
      evaluated.push_back(v.Key());
      return testing::SyntheticEvaluate(v);
    };
    const LookAhead ahead = [&](const std::vector<Variant>& next) {
      ASSERT_FALSE(next.empty());
      if (c.budget != 0) {
        EXPECT_LE(evaluated.size() + next.size(), c.budget);
      }
      for (const Variant& v : next) {
        EXPECT_EQ(std::find(evaluated.begin(), evaluated.end(), v.Key()), evaluated.end()) << v.Key();
        announced_at.emplace(v.Key(), evaluated.size());
        ++announced;
      }
    };
    const SearchResult looked = Search(candidates, evaluate, options, ahead);
    ASSERT_TRUE(plain.best && looked.best);
    EXPECT_EQ(looked.best->Key(), plain.best->Key());
    EXPECT_EQ(looked.evaluations, plain.evaluations);
    EXPECT_GT(announced, 0u);
    EXPECT_EQ(unannounced, 0u);
  }
}

// A coordinate descent announces its start together with every single-axis
// move from it (the first sweep, while it does not move), so that one batch
// is compiled where the axes one at a time built one kernel after another.
TEST(Strategy, ADescentAnnouncesItsStartWithItsFirstSweepInOneBatch) {
  std::vector<Variant> candidates = testing::SyntheticCandidates();
  candidates.resize(600);
  std::vector<std::vector<std::string>> batches;
  std::vector<std::string> evaluated;
  const Evaluator evaluate = [&](const Variant& v) {
    evaluated.push_back(v.Key());
    return testing::SyntheticEvaluate(v);
  };
  const LookAhead ahead = [&](const std::vector<Variant>& next) {
    std::vector<std::string>& batch = batches.emplace_back();
    for (const Variant& v : next) batch.push_back(v.Key());
  };
  (void)Search(candidates, evaluate, {"coordinate", 0, 3}, ahead);
  ASSERT_FALSE(batches.empty());
  ASSERT_FALSE(evaluated.empty());
  const std::vector<std::string>& first = batches.front();
  EXPECT_EQ(first.front(), evaluated.front()) << "the start leads the first batch";
  // Every variant one axis from the start is in it.
  const auto start = AxisCodes(ParseVariantKey(evaluated.front()));
  std::size_t neighbours = 0;
  for (const Variant& v : candidates) {
    const auto codes = AxisCodes(v);
    std::size_t differ = 0;
    for (std::size_t a = 0; a < codes.size(); ++a) differ += codes[a] != start[a] ? 1 : 0;
    if (differ != 1) continue;
    ++neighbours;
    EXPECT_NE(std::find(first.begin(), first.end(), v.Key()), first.end()) << v.Key();
  }
  EXPECT_GT(neighbours, 2u);
}

}  // namespace
}  // namespace skintune::internal
