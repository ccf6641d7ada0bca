// skintune: keyframed animation clips (glTF 2.0 animation semantics).
//
// Interpolation follows the glTF 2.0 specification, Appendix C:
//   STEP:        the value of the key at or before t.
//   LINEAR:      lerp for translation/scale, shortest-path slerp for rotation.
//   CUBICSPLINE: Hermite spline through the key values, with the stored
//                tangents scaled by the key interval (t[k+1] - t[k]).
// Rotations are normalised after every interpolation. Outside the keyed range
// the first/last key value is held.
#include "model/animation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include <glm/gtc/quaternion.hpp>

#include "base/error.h"

namespace skintune::internal {

const char* ChannelPathName(ChannelPath path) {
  switch (path) {
    case ChannelPath::kTranslation: return "translation";
    case ChannelPath::kRotation: return "rotation";
    case ChannelPath::kScale: return "scale";
    case ChannelPath::kWeights: return "weights";
  }
  return "?";
}

namespace {

std::size_t ValuesPerKey(const Channel& c) { return c.interpolation == Interpolation::kCubicSpline ? 3 : 1; }

std::string Seconds(float t) {
  std::ostringstream s;
  s.precision(7);
  s << t << " s";
  return s.str();
}

bool Finite(const glm::dvec4& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && std::isfinite(v.w);
}

// The key value (not a tangent) of key k.
glm::dvec4 KeyValue(const Channel& c, std::size_t k) {
  return c.values[k * ValuesPerKey(c) + (c.interpolation == Interpolation::kCubicSpline ? 1 : 0)];
}

// glTF stores quaternions as (x, y, z, w); glm::dquat's constructor takes (w, x, y, z).
glm::dquat ToQuat(const glm::dvec4& xyzw) { return glm::dquat(xyzw.w, xyzw.x, xyzw.y, xyzw.z); }

glm::dvec4 NormalizeQuat(const glm::dvec4& xyzw) {
  double length = std::sqrt(glm::dot(xyzw, xyzw));
  return length > 0.0 ? xyzw / length : xyzw;
}

// Shortest-path spherical interpolation of two (x, y, z, w) quaternions.
glm::dvec4 Slerp(const glm::dvec4& a, glm::dvec4 b, double u) {
  double cos_theta = glm::dot(a, b);
  if (cos_theta < 0.0) {  // q and -q are the same rotation: take the short way
    b = -b;
    cos_theta = -cos_theta;
  }
  if (cos_theta > 1.0 - 1e-9) return NormalizeQuat(a + u * (b - a));  // nearly equal
  double theta = std::acos(std::min(cos_theta, 1.0));
  double sin_theta = std::sin(theta);
  glm::dvec4 r = (std::sin((1.0 - u) * theta) / sin_theta) * a + (std::sin(u * theta) / sin_theta) * b;
  return NormalizeQuat(r);
}

glm::dvec4 Hermite(const Channel& c, std::size_t k, double u, double interval) {
  const glm::dvec4& p0 = c.values[3 * k + 1];
  const glm::dvec4 m0 = interval * c.values[3 * k + 2];  // out-tangent of key k
  const glm::dvec4& p1 = c.values[3 * (k + 1) + 1];
  const glm::dvec4 m1 = interval * c.values[3 * (k + 1)];  // in-tangent of key k+1
  double u2 = u * u, u3 = u2 * u;
  return (2.0 * u3 - 3.0 * u2 + 1.0) * p0 + (u3 - 2.0 * u2 + u) * m0 + (-2.0 * u3 + 3.0 * u2) * p1 +
         (u3 - u2) * m1;
}

// The channel's value at time t (quaternions not yet normalised for STEP).
glm::dvec4 Evaluate(const Channel& c, double t) {
  const std::size_t n = c.times.size();
  if (n == 1 || t <= c.times.front()) return KeyValue(c, 0);
  if (t >= c.times.back()) return KeyValue(c, n - 1);
  // k: the last key with times[k] <= t; t < times[k + 1].
  std::size_t k = static_cast<std::size_t>(
      std::upper_bound(c.times.begin(), c.times.end(), t,
                       [](double x, float key) { return x < static_cast<double>(key); }) -
      c.times.begin() - 1);
  const double t0 = c.times[k], t1 = c.times[k + 1];
  const double interval = t1 - t0;
  const double u = (t - t0) / interval;
  switch (c.interpolation) {
    case Interpolation::kStep: return KeyValue(c, k);
    case Interpolation::kLinear:
      if (c.path == ChannelPath::kRotation) return Slerp(KeyValue(c, k), KeyValue(c, k + 1), u);
      return KeyValue(c, k) + u * (KeyValue(c, k + 1) - KeyValue(c, k));
    case Interpolation::kCubicSpline: return Hermite(c, k, u, interval);
  }
  return KeyValue(c, k);
}

void ValidateChannel(const Channel& c, std::size_t index, int node_count, const std::string& context) {
  const std::string where = context + ": channels[" + std::to_string(index) + "] (node " +
                            std::to_string(c.node) + " " + ChannelPathName(c.path) + ")";
  if (c.node < 0 || c.node >= node_count) {
    throw Error(where + ": node " + std::to_string(c.node) + " out of range (" + std::to_string(node_count) +
                " nodes)");
  }
  if (c.times.empty()) throw Error(where + ": no keys");
  for (std::size_t k = 0; k < c.times.size(); ++k) {
    if (!std::isfinite(c.times[k])) {
      throw Error(where + ": time of key " + std::to_string(k) + " is not finite");
    }
    if (k > 0 && !(c.times[k] > c.times[k - 1])) {
      throw Error(where + ": times not strictly increasing: key " + std::to_string(k) + " at " +
                  Seconds(c.times[k]) + " follows key " + std::to_string(k - 1) + " at " +
                  Seconds(c.times[k - 1]));
    }
  }
  const std::size_t expected = c.times.size() * ValuesPerKey(c);
  if (c.values.size() != expected) {
    throw Error(where + ": " + std::to_string(c.values.size()) + " values for " +
                std::to_string(c.times.size()) + " keys (expected " + std::to_string(expected) + ")");
  }
  for (std::size_t i = 0; i < c.values.size(); ++i) {
    if (!Finite(c.values[i])) throw Error(where + ": value " + std::to_string(i) + " is not finite");
  }
  if (c.path == ChannelPath::kRotation) {
    for (std::size_t k = 0; k < c.times.size(); ++k) {
      glm::dvec4 q = KeyValue(c, k);
      if (glm::dot(q, q) == 0.0) {
        throw Error(where + ": rotation of key " + std::to_string(k) + " is the zero quaternion");
      }
    }
  }
}

}  // namespace

void AnimationClip::Validate(int node_count, const std::string& context) const {
  for (std::size_t i = 0; i < channels.size(); ++i) ValidateChannel(channels[i], i, node_count, context);
}

void AnimationClip::Sample(double t, Pose& pose) const {
  for (const Channel& c : channels) {
    if (c.path == ChannelPath::kWeights) continue;  // SampleMorphWeights
    if (c.node < 0 || static_cast<std::size_t>(c.node) >= pose.size() || c.times.empty() ||
        c.values.size() != c.times.size() * ValuesPerKey(c)) {
      throw Error("animation '" + name + "': channel on node " + std::to_string(c.node) +
                  " cannot be sampled (clip not validated against this skeleton)");
    }
    const glm::dvec4 v = Evaluate(c, t);
    Transform& target = pose[static_cast<std::size_t>(c.node)];
    switch (c.path) {
      case ChannelPath::kTranslation: target.translation = glm::dvec3(v); break;
      case ChannelPath::kScale: target.scale = glm::dvec3(v); break;
      case ChannelPath::kRotation: target.rotation = ToQuat(NormalizeQuat(v)); break;
      case ChannelPath::kWeights: break;
    }
  }
}

void AnimationClip::SampleMorphWeights(double t, std::vector<double>& weights) const {
  for (const Channel& c : channels) {
    if (c.path != ChannelPath::kWeights || c.times.empty() || c.values.size() != c.times.size() * ValuesPerKey(c))
      continue;
    const glm::dvec4 v = Evaluate(c, t);
    for (int k = 0; k < 4; ++k) {
      const std::size_t target = static_cast<std::size_t>(c.first_target + k);
      if (target < weights.size()) weights[target] = v[k];
    }
  }
}

void AnimationClip::UpdateRange() {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  for (const Channel& c : channels) {
    if (c.times.empty()) continue;
    lo = std::min(lo, static_cast<double>(c.times.front()));
    hi = std::max(hi, static_cast<double>(c.times.back()));
  }
  if (lo > hi) lo = hi = 0.0;  // no keys at all
  start = lo;
  end = hi;
}

}  // namespace skintune::internal
