#include "tuner/strategy.h"

#include <algorithm>
#include <array>
#include <limits>
#include <unordered_map>
#include <utility>

#include "generator/axes.h"
#include "base/error.h"

namespace skintune::internal {

namespace {

// SplitMix64 (Steele, Lea, Flood 2014): a tiny PRNG whose output depends only
// on the seed, so a search is the same on every compiler and platform (the
// standard library's distributions are implementation-defined).
class Prng {
 public:
  explicit Prng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, n), n > 0, without modulo bias (rejection).
  std::size_t Below(std::size_t n) {
    const std::uint64_t bound = static_cast<std::uint64_t>(n);
    const std::uint64_t limit = std::numeric_limits<std::uint64_t>::max() - std::numeric_limits<std::uint64_t>::max() % bound;
    std::uint64_t x = Next();
    while (x >= limit) x = Next();
    return static_cast<std::size_t>(x % bound);
  }

 private:
  std::uint64_t state_;
};

// Every axis of a Variant (generator/axes.h), as small integers (coordinate
// descent moves along one of them at a time).
using Coords = std::array<int, kAxisCount>;

Coords CoordsOf(const Variant& v) { return AxisCodes(v); }

struct CoordsHash {
  std::size_t operator()(const Coords& c) const {
    std::uint64_t h = 1469598103934665603ull;  // FNV-1a over the values
    for (int x : c) {
      h ^= static_cast<std::uint32_t>(x);
      h *= 1099511628211ull;
    }
    return static_cast<std::size_t>(h);
  }
};

// The distinct candidates (first occurrence kept, in order) and the memoised
// evaluator: each distinct variant costs one evaluation, once.
class Session {
 public:
  Session(const std::vector<Variant>& candidates, const Evaluator& evaluate, std::size_t budget,
          const LookAhead& ahead)
      : evaluate_(evaluate), ahead_(ahead), budget_(budget) {
    for (const Variant& v : candidates) {
      const Coords c = CoordsOf(v);
      if (index_.emplace(c, variants_.size()).second) {
        variants_.push_back(v);
        coords_.push_back(c);
      }
    }
    results_.assign(variants_.size(), std::nullopt);
    evaluated_.assign(variants_.size(), false);
  }

  std::size_t size() const { return variants_.size(); }
  const Variant& variant(std::size_t i) const { return variants_[i]; }
  const Coords& coords(std::size_t i) const { return coords_[i]; }
  // The candidate at `c`, if there is one.
  std::optional<std::size_t> Find(const Coords& c) const {
    const auto it = index_.find(c);
    if (it == index_.end()) return std::nullopt;
    return it->second;
  }
  bool evaluated(std::size_t i) const { return evaluated_[i]; }
  // Budget 0 means no limit.
  bool exhausted() const { return budget_ != 0 && evaluations_ >= budget_; }
  std::size_t budget() const { return budget_; }

  // The time of candidate i: recorded, or evaluated now when the budget allows.
  // nullopt for a failed variant or when the budget is spent.
  std::optional<double> Evaluate(std::size_t i) {
    if (evaluated_[i]) return results_[i];
    if (exhausted()) return std::nullopt;
    evaluated_[i] = true;
    ++evaluations_;
    results_[i] = evaluate_(variants_[i]);
    if (results_[i] && (!best_ || *results_[i] < best_ms_)) {
      best_ = i;
      best_ms_ = *results_[i];
    }
    return results_[i];
  }

  // Announces the candidates among `next` that Evaluate would still run, in
  // order, as many as the budget has left (LookAhead).
  void Ahead(const std::vector<std::size_t>& next) const {
    if (!ahead_) return;
    std::vector<Variant> out;
    for (std::size_t i : next) {
      if (budget_ != 0 && evaluations_ + out.size() >= budget_) break;
      if (!evaluated_[i]) out.push_back(variants_[i]);
    }
    if (!out.empty()) ahead_(out);
  }

  SearchResult Result() const {
    SearchResult r;
    if (best_) {
      r.best = variants_[*best_];
      r.best_ms = best_ms_;
    }
    r.evaluations = evaluations_;
    return r;
  }

 private:
  const Evaluator& evaluate_;
  const LookAhead& ahead_;
  std::size_t budget_;
  std::vector<Variant> variants_;
  std::vector<Coords> coords_;
  std::unordered_map<Coords, std::size_t, CoordsHash> index_;
  std::vector<std::optional<double>> results_;
  std::vector<bool> evaluated_;
  std::size_t evaluations_ = 0;
  std::optional<std::size_t> best_;
  double best_ms_ = 0.0;
};

SearchResult Exhaustive(Session& s) {
  std::vector<std::size_t> all(s.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  s.Ahead(all);
  for (std::size_t i = 0; i < s.size() && !s.exhausted(); ++i) s.Evaluate(i);
  return s.Result();
}

SearchResult Random(Session& s, std::uint64_t seed) {
  // Partial Fisher-Yates: the first `budget` positions of a seeded shuffle.
  std::vector<std::size_t> order(s.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  Prng prng(seed);
  const std::size_t n = s.budget() == 0 ? order.size() : std::min(s.budget(), order.size());
  for (std::size_t i = 0; i < n; ++i) std::swap(order[i], order[i + prng.Below(order.size() - i)]);
  order.resize(n);
  s.Ahead(order);
  for (std::size_t i : order) s.Evaluate(i);
  return s.Result();
}

// The axes whose values interact most: the formats of the per-vertex data,
// which decide how the inputs pack into words and loads (a narrow index
// format pays off with a narrow weight format, and may cost alone: GLSL on
// the H100 at 6400k-b4). Coordinate descent also tries moves along two of
// them at once, and its first restart starts from their narrowest values.
constexpr std::array<std::size_t, 3> kCoupledAxes = {AxisIndex<&Variant::position>(), AxisIndex<&Variant::index>(),
                                                     AxisIndex<&Variant::weight>()};

// The candidate closest (fewest differing axes) to a sensible default: the
// Variant{} defaults (soa, float4, u16 indices, f32 weights, mat3x4 in global
// memory, matrix blend, one vertex per item, 128 items per group) in the first
// candidate's language, influence count and normals (those are set by the
// problem, not tuned). Ties go to the earlier candidate.
std::size_t ClosestTo(const Session& s, const Coords& target) {
  std::size_t best = 0;
  std::size_t best_distance = kAxisCount + 1;
  for (std::size_t i = 0; i < s.size(); ++i) {
    std::size_t distance = 0;
    for (std::size_t a = 0; a < kAxisCount; ++a) distance += s.coords(i)[a] != target[a] ? 1 : 0;
    if (distance < best_distance) {
      best = i;
      best_distance = distance;
      if (distance == 0) break;
    }
  }
  return best;
}

// The Variant{} defaults in the first candidate's language, influence count and normals.
Variant DefaultVariant(const Session& s) {
  Variant d;
  d.lang = s.variant(0).lang;
  d.influences = s.variant(0).influences;
  d.normals = s.variant(0).normals;
  return d;
}

Coords DefaultCoords(const Session& s) { return CoordsOf(CollapseWorkGroups(DefaultVariant(s))); }

std::size_t DefaultStart(const Session& s) { return ClosestTo(s, DefaultCoords(s)); }

// Where the space holds forms that make their palette in the skin launch
// (FusesPalette), the candidate closest to the default in the shape a fused
// form takes where nothing chose one (InFusedShape: storage local, 8 vertices
// an item, strided, groups of 256), at the highest rate among them. A fused
// form wins only in that shape, three axes from the default start, and is
// slower than the forms with a palette kernel in any shape one move from it:
// `skintune tune --config animated-crowds` on an H200 (2026-11-30) never
// reached it, and named for CUDA's 64 x 25k crowd a palette kernel's form at
// 23.2 us where fused240 in that shape took 18.2. At the highest rate, hybrid
// records come first, then local ones, then palette records: the first serve
// a crowd that cross-fades (over which palette records are over any budget,
// so the start would measure nothing) and one that does not at the palette
// records' cost.
std::optional<std::size_t> FusedStart(const Session& s) {
  const auto rank = [](Animation a) {
    return std::pair{BakeRateOf(a), BakesHybrid(a) ? 2 : BakesLocally(a) ? 1 : 0};
  };
  std::optional<Animation> fused;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Animation a = s.variant(i).animation;
    if (FusesPalette(a) && (!fused || rank(a) > rank(*fused))) fused = a;
  }
  if (!fused) return std::nullopt;
  Variant d = DefaultVariant(s);
  d.animation = *fused;
  return ClosestTo(s, CoordsOf(CollapseWorkGroups(InFusedShape(d))));
}

// The default with each coupled axis at its narrowest value among the
// candidates (the formats' codes grow as they narrow: float4 -> float3,
// i32 -> u16 -> u8, f32 -> unorm16 -> unorm8).
std::size_t NarrowStart(const Session& s, const std::array<std::vector<int>, kAxisCount>& axis_values) {
  Coords target = DefaultCoords(s);
  for (std::size_t a : kCoupledAxes)
    if (!axis_values[a].empty()) target[a] = axis_values[a].back();
  return ClosestTo(s, target);
}

// The values each axis takes among the candidates (in increasing order).
std::array<std::vector<int>, kAxisCount> AxisValues(const Session& s) {
  std::array<std::vector<int>, kAxisCount> axis_values;
  for (std::size_t a = 0; a < kAxisCount; ++a) {
    std::vector<int>& values = axis_values[a];
    for (std::size_t i = 0; i < s.size(); ++i) {
      const int x = s.coords(i)[a];
      if (std::find(values.begin(), values.end(), x) == values.end()) values.push_back(x);
    }
    std::sort(values.begin(), values.end());
  }
  return axis_values;
}

// Coordinate descent's descents over one session: each from a start, in
// sweeps over the axes until a full sweep moves nowhere.
class Descent {
 public:
  Descent(Session& s, const std::array<std::vector<int>, kAxisCount>& axis_values, double margin)
      : s_(s), axis_values_(axis_values), margin_(margin) {}

  // One descent from `start`. In each sweep, when no single move along a
  // coupled axis won, the moves along two coupled axes at once come right
  // after the last of them (a descent stuck on f32 weights because u8
  // indices or unorm8 weights alone are slower takes both at once there).
  void From(std::size_t start) {
    current_ = start;
    announced_.reset();
    AnnounceSweep(true);  // the start with its first sweep: one batch
    current_ms_ = s_.Evaluate(current_);
    while (!s_.exhausted() && Sweep()) {
    }
  }

 private:
  // One sweep over the axes; whether it moved.
  bool Sweep() {
    AnnounceSweep(false);
    const std::size_t last_coupled = *std::max_element(kCoupledAxes.begin(), kCoupledAxes.end());
    bool moved = false;
    bool coupled_moved = false;
    for (std::size_t a = 0; a < kAxisCount && !s_.exhausted(); ++a) {
      const bool m = TryMoves(Line(current_, a));
      moved = moved || m;
      if (std::find(kCoupledAxes.begin(), kCoupledAxes.end(), a) != kCoupledAxes.end()) coupled_moved = coupled_moved || m;
      if (a != last_coupled || coupled_moved) continue;
      for (std::size_t p = 0; p < kCoupledAxes.size() && !s_.exhausted(); ++p)
        for (std::size_t q = p + 1; q < kCoupledAxes.size() && !s_.exhausted(); ++q)
          moved = TryMoves(PairLine(current_, kCoupledAxes[p], kCoupledAxes[q])) || moved;
    }
    return moved;
  }

  // Evaluates `moves` and goes to the fastest when it beats the current
  // point by more than the margin; a later move replaces an earlier one only
  // by beating it by as much, so moves within noise of each other are
  // decided by their order, the same in every run.
  bool TryMoves(const std::vector<std::size_t>& moves) {
    std::size_t best = current_;
    std::optional<double> best_ms = current_ms_;
    s_.Ahead(moves);
    for (std::size_t j : moves) {
      const std::optional<double> t = s_.Evaluate(j);
      if (t && (!best_ms || *t < *best_ms * (1.0 - margin_))) {
        best = j;
        best_ms = t;
      }
    }
    if (best == current_) return false;
    current_ = best;
    current_ms_ = best_ms;
    return true;
  }

  // The other candidates that differ from candidate i on axis a only.
  std::vector<std::size_t> Line(std::size_t i, std::size_t a) const {
    std::vector<std::size_t> out;
    Coords c = s_.coords(i);
    for (int x : axis_values_[a]) {
      if (x == s_.coords(i)[a]) continue;
      c[a] = x;
      if (const std::optional<std::size_t> j = s_.Find(c)) out.push_back(*j);
    }
    return out;
  }

  // Announces (LookAhead) every single-axis move from the current point,
  // axis after axis, what a sweep from it evaluates while it does not move,
  // and the point itself first when `with_it`; once a point. One batch
  // compiled in parallel, where the axes one at a time (most of them one
  // move from a point) built their kernels one after another on the
  // search's path.
  void AnnounceSweep(bool with_it) {
    if (announced_ == current_) return;
    announced_ = current_;
    std::vector<std::size_t> next;
    if (with_it) next.push_back(current_);
    for (std::size_t a = 0; a < kAxisCount; ++a) {
      const std::vector<std::size_t> line = Line(current_, a);
      next.insert(next.end(), line.begin(), line.end());
    }
    s_.Ahead(next);
  }

  // Moves from candidate i along two coupled axes at once (both changed).
  std::vector<std::size_t> PairLine(std::size_t i, std::size_t a, std::size_t b) const {
    std::vector<std::size_t> out;
    Coords c = s_.coords(i);
    for (int x : axis_values_[a]) {
      if (x == s_.coords(i)[a]) continue;
      for (int y : axis_values_[b]) {
        if (y == s_.coords(i)[b]) continue;
        c[a] = x;
        c[b] = y;
        if (const std::optional<std::size_t> j = s_.Find(c)) out.push_back(*j);
      }
    }
    return out;
  }

  Session& s_;
  const std::array<std::vector<int>, kAxisCount>& axis_values_;
  double margin_;
  std::size_t current_ = 0;
  std::optional<double> current_ms_;
  std::optional<std::size_t> announced_;  // the point whose sweep was announced last
};

SearchResult Coordinate(Session& s, std::uint64_t seed, bool restarts, double margin) {
  const std::array<std::vector<int>, kAxisCount> axis_values = AxisValues(s);
  Descent descent(s, axis_values, margin);
  // The first descent starts from the default, or from the fused start
  // where that is faster by more than the margin.
  std::size_t start = DefaultStart(s);
  if (const std::optional<std::size_t> fused = FusedStart(s); fused && *fused != start) {
    s.Ahead({start, *fused});
    const std::optional<double> a = s.Evaluate(start);
    const std::optional<double> b = s.Evaluate(*fused);
    if (b && (!a || *b < *a * (1.0 - margin))) start = *fused;
  }
  descent.From(start);
  if (!restarts) return s.Result();
  // The first restart starts from the fewest bytes: the candidate closest to
  // the default with the narrowest formats of the coupled axes.
  if (!s.exhausted()) {
    const std::size_t narrow = NarrowStart(s, axis_values);
    if (!s.evaluated(narrow)) descent.From(narrow);
  }
  // Then restarts from random candidates not evaluated yet, while the budget lasts.
  std::vector<std::size_t> order(s.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  Prng prng(seed);
  for (std::size_t i = 0; i < order.size() && !s.exhausted(); ++i) {
    std::swap(order[i], order[i + prng.Below(order.size() - i)]);
    if (!s.evaluated(order[i])) descent.From(order[i]);
  }
  return s.Result();
}

}  // namespace

std::vector<Variant> Neighbours(const std::vector<Variant>& candidates, const Variant& of) {
  const Coords centre = CoordsOf(of);
  std::vector<Variant> out;
  std::unordered_map<Coords, bool, CoordsHash> seen;
  for (const Variant& v : candidates) {
    const Coords c = CoordsOf(v);
    std::size_t differing = 0;
    for (std::size_t a = 0; a < kAxisCount; ++a) differing += c[a] != centre[a] ? 1 : 0;
    if (differing == 1 && seen.emplace(c, true).second) out.push_back(v);
  }
  return out;
}

SearchResult Search(const std::vector<Variant>& candidates, const Evaluator& evaluate,
                    const StrategyOptions& options, const LookAhead& ahead) {
  const std::string& name = options.name;
  if (name != "exhaustive" && name != "random" && name != "coordinate") {
    throw Error("strategy '" + name + "': unknown (expected exhaustive, random or coordinate)");
  }
  if (name == "random" && options.budget == 0) {
    throw Error("strategy 'random': a budget (number of evaluations, > 0) is required");
  }
  if (!evaluate) throw Error("strategy '" + name + "': no evaluator");
  Session session(candidates, evaluate, options.budget, ahead);
  if (session.size() == 0) return {};
  if (name == "exhaustive") return Exhaustive(session);
  if (name == "random") return Random(session, options.seed);
  // Without a budget, coordinate descent stops at its first local optimum.
  return Coordinate(session, options.seed, options.budget != 0, options.margin);
}

}  // namespace skintune::internal
