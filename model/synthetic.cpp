// skintune: seeded synthetic skinned characters (see synthetic.h).
//
// Rig: a humanoid template of 77 bones, listed so that any prefix is a valid
// body (torso, arms, legs first; fingers and face last). Fewer bones: the
// first N of the template. More bones: 4-bone "tentacle" chains hung from the
// template bones in turn. Every bone is a segment head -> tail; its frame has
// +Y along the bone (glTF/Blender convention), so a child's local translation
// runs along its parent's bone.
//
// Determinism: splitmix64 streams seeded from spec.seed, double maths, no
// std:: distributions.
#include "model/synthetic.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "base/error.h"
#include "base/memory_limit.h"

namespace skintune::internal {
namespace {

using glm::dquat;
using glm::dvec3;

constexpr double kPi = 3.14159265358979323846;
constexpr int kTemplateBones = 77;
constexpr int kChainLength = 4;         // bones per extension chain (bones > 77)
constexpr double kChainBoneLength = 0.04;
constexpr double kRadiusPerLength = 0.18;  // tube radius / bone length
constexpr double kWeightEps = 1e-3;        // metres, in 1 / (d + eps)^2
// Nearest bones are searched among this many tree neighbours of the own bone
// (all bones for rigs of up to 129 bones, so exhaustive for the paper's 77).
constexpr std::size_t kCandidates = 128;
constexpr int kMaxBones = 65535;
constexpr int kMaxSyntheticMorphTargets = 64;
constexpr const char* kKeyHint =
    "expected <vertices>-b<influences>[-bones<N>][-random][-seed<S>][-rigid][-morph<T>][-normals|-tangents], e.g. "
    "100k-b2";

// ---------------------------------------------------------------- PRNG

class Rng {
 public:
  explicit Rng(std::uint64_t seed, std::uint64_t stream) : state_(seed ^ (stream * 0xD1B54A32D192ED03ull)) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double Range(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  std::uint32_t Below(std::uint32_t n) { return static_cast<std::uint32_t>(((Next() >> 32) * n) >> 32); }
  dvec3 UnitVector() {
    const double z = Range(-1.0, 1.0), a = Range(0.0, 2.0 * kPi);
    const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
    return {s * std::cos(a), s * std::sin(a), z};
  }

 private:
  std::uint64_t state_;
};

// ---------------------------------------------------------------- rig

struct Bone {
  std::string name;
  int parent = -1;
  dvec3 head{0.0};
  dvec3 dir{0.0, 1.0, 0.0};  // unit
  double length = 0.1;
  dvec3 tail() const { return head + dir * length; }
};

class RigBuilder {
 public:
  std::vector<Bone> bones;
  int Add(std::string name, int parent, dvec3 head, dvec3 dir, double length) {
    bones.push_back({std::move(name), parent, head, glm::normalize(dir), length});
    return static_cast<int>(bones.size()) - 1;
  }
  // A bone starting at its parent's tail.
  int Chain(std::string name, int parent, dvec3 dir, double length) {
    return Add(std::move(name), parent, bones[parent].tail(), dir, length);
  }
};

std::string Sided(const std::string& name, double side) { return name + (side > 0 ? "_l" : "_r"); }

// Character faces +Z, up is +Y, its left is +X. Returns the hand index.
int AddArm(RigBuilder& b, int chest, double side) {
  const dvec3 shoulder = b.bones[chest].tail() + dvec3(side * 0.02, -0.04, 0.0);
  int i = b.Add(Sided("clavicle", side), chest, shoulder, {side, 0.05, -0.1}, 0.16);
  i = b.Chain(Sided("upperarm", side), i, {side, -0.15, 0.0}, 0.15);
  i = b.Chain(Sided("upperarm_twist", side), i, {side, -0.15, 0.0}, 0.14);
  i = b.Chain(Sided("forearm", side), i, {side, -0.1, 0.05}, 0.13);
  i = b.Chain(Sided("forearm_twist", side), i, {side, -0.1, 0.05}, 0.12);
  return b.Chain(Sided("hand", side), i, {side, -0.05, 0.0}, 0.05);
}

void AddLeg(RigBuilder& b, int pelvis, double side) {
  const dvec3 hip = b.bones[pelvis].head + dvec3(side * 0.1, -0.04, 0.0);
  int i = b.Add(Sided("thigh", side), pelvis, hip, {side * 0.02, -1.0, 0.0}, 0.22);
  i = b.Chain(Sided("thigh_twist", side), i, {side * 0.02, -1.0, 0.0}, 0.21);
  i = b.Chain(Sided("shin", side), i, {0.0, -1.0, -0.03}, 0.21);
  i = b.Chain(Sided("shin_twist", side), i, {0.0, -1.0, -0.03}, 0.20);
  i = b.Chain(Sided("foot", side), i, {0.0, -0.6, 1.0}, 0.12);
  i = b.Chain(Sided("ball", side), i, {0.0, -0.1, 1.0}, 0.05);
  b.Chain(Sided("toe", side), i, {0.0, 0.0, 1.0}, 0.03);
}

// Metacarpal + 3 phalanges per finger, thumb first (20 bones).
void AddFingers(RigBuilder& b, int hand, double side) {
  static const char* const kNames[5] = {"thumb", "index", "middle", "ring", "pinky"};
  static const double kLengths[5][4] = {{0.04, 0.035, 0.025, 0.02}, {0.07, 0.042, 0.025, 0.02},
                                        {0.07, 0.045, 0.028, 0.021}, {0.068, 0.042, 0.026, 0.02},
                                        {0.065, 0.035, 0.02, 0.018}};
  const dvec3 wrist = b.bones[hand].tail();
  for (int f = 0; f < 5; ++f) {
    const double z = 0.03 - 0.02 * (f - 1);  // index forward (+Z), pinky back
    dvec3 head = wrist + dvec3(side * 0.005, -0.005, z);
    dvec3 dir{side, -0.05, 0.3 * z / 0.03};
    if (f == 0) {
      head = wrist + dvec3(-side * 0.01, -0.01, 0.035);
      dir = {side * 0.5, -0.3, 0.8};
    }
    int i = hand;
    for (int p = 0; p < 4; ++p) {
      const std::string name = Sided(std::string(kNames[f]) + "_0" + std::to_string(p + 1), side);
      i = p == 0 ? b.Add(name, hand, head, dir, kLengths[f][0]) : b.Chain(name, i, dir, kLengths[f][p]);
      dir += dvec3(0.0, -0.15, 0.0);  // slight curl
    }
  }
}

std::vector<Bone> HumanoidTemplate() {
  RigBuilder b;
  const int pelvis = b.Add("pelvis", -1, {0.0, 1.0, 0.0}, {0.0, 1.0, 0.0}, 0.10);
  int i = pelvis;
  for (int s = 1; s <= 4; ++s) i = b.Chain("spine_0" + std::to_string(s), i, {0.0, 1.0, -0.02 * s}, 0.10);
  const int chest = i;
  i = b.Chain("neck_01", i, {0.0, 1.0, 0.1}, 0.06);
  i = b.Chain("neck_02", i, {0.0, 1.0, 0.05}, 0.06);
  const int head = b.Chain("head", i, {0.0, 1.0, 0.05}, 0.20);
  const int hand_l = AddArm(b, chest, 1.0), hand_r = AddArm(b, chest, -1.0);
  AddLeg(b, pelvis, 1.0);
  AddLeg(b, pelvis, -1.0);
  AddFingers(b, hand_l, 1.0);
  AddFingers(b, hand_r, -1.0);
  const dvec3 skull = b.bones[head].head;
  b.Add("jaw", head, skull + dvec3(0.0, 0.03, 0.03), {0.0, -0.4, 1.0}, 0.09);
  b.Add("eye_l", head, skull + dvec3(0.032, 0.10, 0.07), {0.0, 0.0, 1.0}, 0.025);
  b.Add("eye_r", head, skull + dvec3(-0.032, 0.10, 0.07), {0.0, 0.0, 1.0}, 0.025);
  return std::move(b.bones);
}

std::vector<Bone> BuildRig(int count) {
  std::vector<Bone> bones = HumanoidTemplate();
  if (count <= kTemplateBones) {
    bones.resize(count);
    return bones;
  }
  Rng shape(0x5EED0F816ull, 0);  // the rig's shape does not depend on the seed
  dvec3 dir{0.0};
  for (int k = 0; k < count - kTemplateBones; ++k) {
    const int chain = k / kChainLength, link = k % kChainLength;
    Bone bone;
    bone.name = "chain_" + std::to_string(chain) + "_" + std::to_string(link);
    if (link == 0) dir = shape.UnitVector();
    bone.parent = link == 0 ? chain % kTemplateBones : static_cast<int>(bones.size()) - 1;
    bone.head = bones[bone.parent].tail();
    bone.dir = dir;
    bone.length = kChainBoneLength;
    bones.push_back(std::move(bone));
  }
  return bones;
}

// Rotation taking +Y to `dir` (unit).
dquat FromY(const dvec3& dir) {
  const dvec3 y{0.0, 1.0, 0.0};
  const double c = glm::dot(y, dir);
  if (c < -1.0 + 1e-12) return dquat(0.0, 0.0, 0.0, 1.0);  // 180 degrees about Z
  const dvec3 axis = glm::cross(y, dir);
  return glm::normalize(dquat(1.0 + c, axis.x, axis.y, axis.z));
}

// Model-space rest rotation of every bone: +Y along the bone, seeded twist.
std::vector<dquat> RestFrames(const std::vector<Bone>& bones, std::uint64_t seed) {
  Rng rng(seed, 1);
  std::vector<dquat> frames;
  frames.reserve(bones.size());
  for (const Bone& bone : bones) {
    const double twist = rng.Range(-0.15, 0.15);
    frames.push_back(FromY(bone.dir) * glm::angleAxis(twist, dvec3(0.0, 1.0, 0.0)));
  }
  return frames;
}

Skeleton MakeSkeleton(const std::vector<Bone>& bones, const std::vector<dquat>& frames) {
  Skeleton skeleton;
  std::vector<glm::dmat4> global(bones.size());
  for (std::size_t i = 0; i < bones.size(); ++i) {
    Node node;
    node.name = bones[i].name;
    node.parent = bones[i].parent;
    if (node.parent < 0) {
      node.rest.translation = bones[i].head;
      node.rest.rotation = frames[i];
    } else {
      const int p = node.parent;
      const dquat to_parent = glm::conjugate(frames[p]);
      node.rest.translation = to_parent * (bones[i].head - bones[p].head);
      node.rest.rotation = glm::normalize(to_parent * frames[i]);
    }
    const glm::dmat4 local =
        glm::translate(glm::dmat4(1.0), node.rest.translation) * glm::mat4_cast(node.rest.rotation);
    global[i] = node.parent < 0 ? local : global[node.parent] * local;
    skeleton.nodes.push_back(std::move(node));
    skeleton.joints.push_back(static_cast<int>(i));
    skeleton.inverse_bind.push_back(glm::inverse(global[i]));
  }
  return skeleton;
}

// ---------------------------------------------------------------- skin

// Vertices per bone, proportional to length; largest remainders get the rest.
std::vector<std::size_t> SplitVertices(const std::vector<Bone>& bones, std::size_t total) {
  double sum = 0.0;
  for (const Bone& b : bones) sum += b.length;
  std::vector<std::size_t> counts(bones.size());
  std::vector<std::pair<double, std::size_t>> fractions(bones.size());
  std::size_t given = 0;
  for (std::size_t i = 0; i < bones.size(); ++i) {
    const double exact = static_cast<double>(total) * bones[i].length / sum;
    counts[i] = std::min(total - given, static_cast<std::size_t>(std::floor(exact)));
    given += counts[i];
    fractions[i] = {exact - std::floor(exact), i};
  }
  std::stable_sort(fractions.begin(), fractions.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  for (std::size_t k = 0; given < total; k = (k + 1) % bones.size(), ++given) ++counts[fractions[k].second];
  return counts;
}

double Distance2(const Bone& s, const dvec3& p) {
  const dvec3 v = p - s.head;
  const double t = std::clamp(glm::dot(v, s.dir), 0.0, s.length);
  const dvec3 d = v - s.dir * t;
  return glm::dot(d, d);
}

// The first `count` bones in breadth-first order from each bone (itself excluded).
std::vector<std::vector<int>> Neighbourhoods(const std::vector<Bone>& bones, std::size_t count) {
  std::vector<std::vector<int>> adjacent(bones.size());
  for (std::size_t i = 1; i < bones.size(); ++i) {
    adjacent[i].push_back(bones[i].parent);
    adjacent[bones[i].parent].push_back(static_cast<int>(i));
  }
  std::vector<std::vector<int>> result(bones.size());
  std::vector<std::size_t> seen(bones.size(), bones.size());
  for (std::size_t s = 0; s < bones.size(); ++s) {
    std::vector<int> order{static_cast<int>(s)};
    seen[s] = s;
    for (std::size_t q = 0; q < order.size() && order.size() <= count; ++q) {
      for (int a : adjacent[order[q]]) {
        if (order.size() > count) break;
        if (seen[a] == s) continue;
        seen[a] = s;
        order.push_back(a);
      }
    }
    result[s].assign(order.begin() + 1, order.end());
  }
  return result;
}

// Keeps the `capacity` smallest distances seen, ascending (first seen wins ties).
void KeepNearest(double d2, int bone, int capacity, int& found, double* best_d2, int* best) {
  if (found == capacity && !(d2 < best_d2[capacity - 1])) return;
  int k = found < capacity ? found++ : capacity - 1;
  for (; k > 0 && d2 < best_d2[k - 1]; --k) {
    best_d2[k] = best_d2[k - 1];
    best[k] = best[k - 1];
  }
  best_d2[k] = d2;
  best[k] = bone;
}

class Weigher {
 public:
  Weigher(const std::vector<Bone>& bones, int influences, bool random, std::uint64_t seed)
      : bones_(bones), b_(influences), random_(random), rng_(seed, 3) {
    if (!random_) candidates_ = Neighbourhoods(bones, std::min(bones.size() - 1, kCandidates));
  }

  void Weigh(int own, const dvec3& p, std::uint16_t* joints, float* weights) {
    int j[kMaxInfluences] = {};
    double w[kMaxInfluences] = {};
    random_ ? RandomSlots(j, w) : NearestSlots(own, p, j, w);
    const double sum = std::accumulate(w, w + b_, 0.0);
    for (int k = 0; k < b_; ++k) {
      joints[k] = static_cast<std::uint16_t>(j[k]);
      weights[k] = static_cast<float>(w[k] / sum);
    }
  }

 private:
  // Own bone first, then the B-1 nearest of its neighbourhood, each weighing
  // 1/(d+eps)^2 with d never below the own bone's: slot 0 weighs most.
  void NearestSlots(int own, const dvec3& p, int* j, double* w) const {
    double d2[kMaxInfluences];
    int found = 0;
    if (b_ > 1) {
      for (int c : candidates_[own]) KeepNearest(Distance2(bones_[c], p), c, b_ - 1, found, d2, j + 1);
    }
    const double own_d = std::sqrt(Distance2(bones_[own], p));
    j[0] = own;
    for (int k = 0; k < b_; ++k) {
      const double d = k == 0 ? own_d : std::max(own_d, std::sqrt(d2[k - 1]));
      w[k] = 1.0 / ((d + kWeightEps) * (d + kWeightEps));
    }
  }

  // B distinct uniformly random bones, weights uniform in [0.05, 1), sorted.
  void RandomSlots(int* j, double* w) {
    const auto n = static_cast<std::uint32_t>(bones_.size());
    for (int k = 0; k < b_; ++k) {
      do {
        j[k] = static_cast<int>(rng_.Below(n));
      } while (std::find(j, j + k, j[k]) != j + k);
      w[k] = rng_.Range(0.05, 1.0);
    }
    for (int k = 1; k < b_; ++k) {  // insertion sort, descending weight
      for (int m = k; m > 0 && w[m] > w[m - 1]; --m) {
        std::swap(w[m], w[m - 1]);
        std::swap(j[m], j[m - 1]);
      }
    }
  }

  const std::vector<Bone>& bones_;
  int b_;
  bool random_;
  Rng rng_;
  std::vector<std::vector<int>> candidates_;
};

// A tube of `count` vertices around `bone`: rings along the bone, points
// around each ring (odd rings staggered half a step).
void EmitTube(const Bone& bone, const dquat& frame, std::size_t count, double radius, int index,
              Weigher& weigher, SkinnedMesh& mesh, bool normals, bool tangents) {
  if (count == 0) return;
  const double circumference = 2.0 * kPi * radius;
  const double spacing = std::sqrt(circumference * bone.length / static_cast<double>(count));
  const std::size_t around =
      std::min(count, std::max<std::size_t>(3, static_cast<std::size_t>(std::lround(circumference / spacing))));
  const std::size_t rings = (count + around - 1) / around;
  const dvec3 u = frame * dvec3(1.0, 0.0, 0.0), v = frame * dvec3(0.0, 0.0, 1.0);
  const auto b = static_cast<std::size_t>(mesh.influences);
  for (std::size_t n = 0; n < count; ++n) {
    const std::size_t ring = n / around, k = n % around;
    const double along = bone.length * (static_cast<double>(ring) + 0.5) / static_cast<double>(rings);
    const double angle = 2.0 * kPi * (static_cast<double>(k) + 0.5 * static_cast<double>(ring & 1)) /
                         static_cast<double>(around);
    const dvec3 out = u * std::cos(angle) + v * std::sin(angle);
    const dvec3 p = bone.head + bone.dir * along + out * radius;
    const std::size_t vertex = mesh.positions.size();
    mesh.positions.emplace_back(p);
    if (normals) mesh.normals.emplace_back(glm::normalize(glm::vec3(out)));
    if (tangents) mesh.tangents.emplace_back(glm::normalize(glm::vec3(bone.dir)), k % 2 == 0 ? 1.0f : -1.0f);
    weigher.Weigh(index, p, &mesh.joints[vertex * b], &mesh.weights[vertex * b]);
  }
}

SkinnedMesh BuildMesh(const DatasetSpec& spec, const std::vector<Bone>& bones, const std::vector<dquat>& frames) {
  SkinnedMesh mesh;
  mesh.name = spec.Key();
  mesh.influences = spec.influences;
  mesh.joint_count = spec.bones;
  const auto b = static_cast<std::size_t>(spec.influences);
  mesh.positions.reserve(spec.vertices);
  if (spec.normals) mesh.normals.reserve(spec.vertices);
  if (spec.tangents) mesh.tangents.reserve(spec.vertices);
  mesh.joints.assign(spec.vertices * b, 0);
  mesh.weights.assign(spec.vertices * b, 0.0f);
  Weigher weigher(bones, spec.influences, spec.random_bones, spec.seed);
  Rng rng(spec.seed, 2);
  const std::vector<std::size_t> counts = SplitVertices(bones, spec.vertices);
  for (std::size_t i = 0; i < bones.size(); ++i) {
    const double radius = kRadiusPerLength * bones[i].length * rng.Range(0.9, 1.1);
    EmitTube(bones[i], frames[i], counts[i], radius, static_cast<int>(i), weigher, mesh, spec.normals, spec.tangents);
  }
  return mesh;
}

// ---------------------------------------------------------------- animation

glm::dvec4 AsXyzw(const dquat& q) { return {q.x, q.y, q.z, q.w}; }

// The largest relative change of a joint's scale along one axis.
constexpr double kScaleAmplitude = 0.2;

AnimationClip BuildAnimation(const DatasetSpec& spec, const Skeleton& skeleton) {
  Rng rng(spec.seed, 4);
  AnimationClip clip;
  clip.name = "synthetic";
  std::vector<float> times;
  for (int k = 0; k < spec.frames; ++k) times.push_back(static_cast<float>(k) / 30.0f);
  for (std::size_t i = 0; i < skeleton.nodes.size(); ++i) {
    const dvec3 axis = rng.UnitVector();
    const double amplitude = rng.Range(5.0, 35.0) * kPi / 180.0;
    const double hz = rng.Range(0.3, 1.2), phase = rng.Range(0.0, 2.0 * kPi);
    Channel channel{static_cast<int>(i), ChannelPath::kRotation, Interpolation::kLinear, times, {}};
    for (float t : times) {
      const double angle = amplitude * std::sin(2.0 * kPi * hz * static_cast<double>(t) + phase);
      channel.values.push_back(AsXyzw(glm::normalize(skeleton.nodes[i].rest.rotation * glm::angleAxis(angle, axis))));
    }
    clip.channels.push_back(std::move(channel));
  }
  // Every joint also scales non-uniformly (each axis by up to +-kScaleAmplitude,
  // its own sinusoid), as rigs' squash-and-stretch and corrective joints do:
  // the palettes are then general affine maps (scale and, through the
  // hierarchy, shear), on which a normal turned by the blended matrix's plain
  // upper 3x3 leaves its surface and the normal matrix does not. A stream of
  // its own, so the rotations are those of the rig without it.
  Rng scales(spec.seed, 5);
  for (std::size_t i = 0; !spec.rigid && i < skeleton.nodes.size(); ++i) {
    dvec3 amplitude, hz, phase;
    for (int a = 0; a < 3; ++a) {
      amplitude[a] = scales.Range(0.25, 1.0) * kScaleAmplitude;
      hz[a] = scales.Range(0.3, 1.2);
      phase[a] = scales.Range(0.0, 2.0 * kPi);
    }
    Channel channel{static_cast<int>(i), ChannelPath::kScale, Interpolation::kLinear, times, {}};
    for (float ft : times) {
      const auto t = static_cast<double>(ft);
      dvec3 scale;
      for (int a = 0; a < 3; ++a) scale[a] = 1.0 + amplitude[a] * std::sin(2.0 * kPi * hz[a] * t + phase[a]);
      channel.values.emplace_back(skeleton.nodes[i].rest.scale * scale, 0.0);
    }
    clip.channels.push_back(std::move(channel));
  }
  Channel root{0, ChannelPath::kTranslation, Interpolation::kLinear, times, {}};
  const double sway = rng.Range(0.0, 2.0 * kPi), bob = rng.Range(0.0, 2.0 * kPi);
  for (float ft : times) {
    const auto t = static_cast<double>(ft);
    const dvec3 offset{0.03 * std::sin(kPi * t + sway), 0.02 * std::sin(2.0 * kPi * t + bob), 0.5 * t};
    root.values.emplace_back(skeleton.nodes[0].rest.translation + offset, 0.0);
  }
  clip.channels.push_back(std::move(root));
  clip.UpdateRange();
  return clip;
}

// ---------------------------------------------------------------- keys

// The morph targets of -morph<T> (synthetic.h): target 0 over every vertex,
// target k >= 1 over vertices [k-1, k) x n / (2T) (at least one), each in its
// own seeded direction with a seeded per-vertex wobble, up to 2% of the
// mesh's extent; normal and tangent offsets a tenth of a unit.
MorphTargets BuildMorphTargets(const DatasetSpec& spec, const SkinnedMesh& mesh) {
  MorphTargets m;
  if (spec.morph_targets == 0) return m;
  m.where = "synthetic morph targets";
  Rng rng(spec.seed, 6);
  const std::size_t n = mesh.vertex_count(), targets = static_cast<std::size_t>(spec.morph_targets);
  glm::dvec3 lo(mesh.positions[0]), hi(lo);
  for (const glm::vec3& p : mesh.positions) {
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  const double amplitude = 0.02 * glm::length(hi - lo) / 1.3;  // |direction + wobble| <= 1.3
  const std::size_t region = std::max<std::size_t>(n / (2 * targets), 1);
  for (std::size_t k = 0; k < targets; ++k) {
    const std::size_t first = k == 0 ? 0 : std::min((k - 1) * region, n - 1);
    const std::size_t last = k == 0 ? n : std::min(first + region, n);
    const dvec3 direction = rng.UnitVector();
    m.positions.emplace_back(n, glm::vec3(0.0f));
    if (mesh.has_normals()) m.normals.emplace_back(n, glm::vec3(0.0f));
    if (mesh.has_tangents()) m.tangents.emplace_back(n, glm::vec3(0.0f));
    for (std::size_t v = first; v < last; ++v) {
      m.positions[k][v] = glm::vec3(amplitude * (direction + 0.3 * rng.UnitVector()));
      if (mesh.has_normals()) m.normals[k][v] = glm::vec3(0.1 * rng.UnitVector());
      if (mesh.has_tangents()) m.tangents[k][v] = glm::vec3(0.1 * rng.UnitVector());
    }
    m.weights.push_back(targets > 1 && k + 1 == targets ? 0.0 : rng.Range(0.2, 1.0));
  }
  return m;
}

std::string Problem(const DatasetSpec& s) {
  if (s.vertices == 0) return "vertices must be at least 1 (got 0)";
  if (s.influences < 1 || s.influences > kMaxInfluences) {
    return "influences " + std::to_string(s.influences) + " outside 1.." + std::to_string(kMaxInfluences);
  }
  if (s.bones < 1 || s.bones > kMaxBones) {
    return "bones " + std::to_string(s.bones) + " outside 1.." + std::to_string(kMaxBones);
  }
  if (s.influences > s.bones) {
    return "influences " + std::to_string(s.influences) + " exceed bones " + std::to_string(s.bones) +
           " (each vertex needs distinct bones)";
  }
  if (s.frames < 1) return "frames must be at least 1 (got " + std::to_string(s.frames) + ")";
  if (s.morph_targets < 0 || s.morph_targets > kMaxSyntheticMorphTargets)
    return "morph targets " + std::to_string(s.morph_targets) + " outside 0.." + std::to_string(kMaxSyntheticMorphTargets);
  if (s.vertices > kMaxVertexCount) {
    return std::to_string(s.vertices) + " vertices exceed the 2^32 - 1 = " + std::to_string(kMaxVertexCount) +
           " a mesh may have (vertex indices and counts are 32-bit): at most 4294m";
  }
  return {};
}

[[noreturn]] void BadKey(const std::string& key, const std::string& what) {
  throw Error("dataset '" + key + "': " + what + " (" + kKeyHint + ")");
}

// Decimal digits only; false on empty, other characters, or a value above `max`.
bool ParseCount(std::string_view text, std::uint64_t max, std::uint64_t& value) {
  if (text.empty()) return false;
  value = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return false;
    const auto digit = static_cast<std::uint64_t>(c - '0');
    if (value > (max - digit) / 10) return false;
    value = value * 10 + digit;
  }
  return true;
}

std::uint64_t ParseField(const std::string& key, std::string_view token, std::string_view prefix,
                         std::uint64_t max, const char* what) {
  std::uint64_t value = 0;
  if (!ParseCount(token.substr(prefix.size()), max, value)) {
    BadKey(key, "'" + std::string(token) + "': " + what + " must be a decimal number up to " + std::to_string(max));
  }
  return value;
}

std::size_t ParseVertices(const std::string& key, std::string_view token) {
  std::uint64_t scale = 1;
  if (!token.empty() && (token.back() == 'k' || token.back() == 'm')) {
    scale = token.back() == 'k' ? 1000 : 1000000;
    token.remove_suffix(1);
  }
  std::uint64_t value = 0;
  if (!ParseCount(token, std::numeric_limits<std::size_t>::max() / scale, value)) {
    BadKey(key, "vertex count '" + std::string(token) + (scale == 1 ? "" : scale == 1000 ? "k" : "m") +
                    "' is not a number (optionally with k or m) that fits in 64 bits");
  }
  return static_cast<std::size_t>(value * scale);
}

void ParseOption(const std::string& key, std::string_view token, DatasetSpec& spec, std::vector<std::string>& seen) {
  std::string name{token};
  if (token.starts_with("bones")) {
    name = "bones";
    spec.bones = static_cast<int>(ParseField(key, token, "bones", kMaxBones, "bone count"));
  } else if (token.starts_with("seed")) {
    name = "seed";
    spec.seed = ParseField(key, token, "seed", std::numeric_limits<std::uint64_t>::max(), "seed");
  } else if (token == "random") {
    spec.random_bones = true;
  } else if (token == "rigid") {
    spec.rigid = true;
  } else if (token.starts_with("morph")) {
    name = "morph";
    spec.morph_targets = static_cast<int>(ParseField(key, token, "morph", kMaxSyntheticMorphTargets, "morph target count"));
  } else if (token == "normals") {
    spec.normals = true;
  } else if (token == "tangents") {
    spec.normals = spec.tangents = true;
  } else {
    BadKey(key, "unknown option '" + name + "'");
  }
  if (std::find(seen.begin(), seen.end(), name) != seen.end()) BadKey(key, "option '" + name + "' given twice");
  seen.push_back(name);
}

std::string VertexText(std::size_t n) {
  if (n % 1000000 == 0) return std::to_string(n / 1000000) + "m";
  if (n % 1000 == 0) return std::to_string(n / 1000) + "k";
  return std::to_string(n);
}

}  // namespace

void DatasetSpec::Validate() const {
  const std::string problem = Problem(*this);
  if (!problem.empty()) throw Error("dataset '" + Key() + "': " + problem);
}

std::uint64_t DatasetBytesPerVertex(const DatasetSpec& spec) {
  const std::uint64_t streams = 1 + (spec.normals ? 1 : 0) + (spec.tangents ? 1 : 0);
  return MeshBytesPerVertex(spec.influences, spec.normals) + (spec.tangents ? 16 : 0) +
         static_cast<std::uint64_t>(spec.morph_targets) * streams * sizeof(glm::vec3);
}

std::string DatasetSpec::Key() const {
  std::string key = VertexText(vertices) + "-b" + std::to_string(influences);
  if (bones != 77) key += "-bones" + std::to_string(bones);
  if (random_bones) key += "-random";
  if (seed != 1) key += "-seed" + std::to_string(seed);
  if (rigid) key += "-rigid";
  if (morph_targets > 0) key += "-morph" + std::to_string(morph_targets);
  if (tangents) key += "-tangents";
  else if (normals) key += "-normals";
  return key;
}

DatasetSpec ParseDatasetKey(const std::string& key) {
  if (key == "default") return DatasetSpec{};
  if (key.empty()) BadKey(key, "empty key");
  std::vector<std::string_view> tokens;
  std::string_view rest{key};
  for (std::size_t dash; (dash = rest.find('-')) != std::string_view::npos; rest.remove_prefix(dash + 1)) {
    tokens.push_back(rest.substr(0, dash));
  }
  tokens.push_back(rest);
  if (std::count(tokens.begin(), tokens.end(), std::string_view{}) > 0) BadKey(key, "empty field (stray '-')");
  DatasetSpec spec;
  spec.vertices = ParseVertices(key, tokens[0]);
  if (tokens.size() < 2 || !tokens[1].starts_with("b")) BadKey(key, "missing influence count '-b<influences>'");
  spec.influences = static_cast<int>(ParseField(key, tokens[1], "b", 1000, "influence count"));
  std::vector<std::string> seen;
  for (std::size_t i = 2; i < tokens.size(); ++i) ParseOption(key, tokens[i], spec, seen);
  const std::string problem = Problem(spec);
  if (!problem.empty()) BadKey(key, problem);
  return spec;
}

SkinnedAsset GenerateDataset(const DatasetSpec& spec) {
  spec.Validate();
  // Before anything is allocated: the mesh is nearly all of it.
  CheckMemoryFor("dataset '" + spec.Key() + "'", spec.vertices, DatasetBytesPerVertex(spec),
                 "the generated mesh", HostMemoryAvailable());
  const std::vector<Bone> bones = BuildRig(spec.bones);
  const std::vector<dquat> frames = RestFrames(bones, spec.seed);
  SkinnedAsset asset;
  asset.source = spec.Key();
  asset.skeleton = MakeSkeleton(bones, frames);
  asset.mesh = BuildMesh(spec, bones, frames);
  asset.animations.push_back(BuildAnimation(spec, asset.skeleton));
  asset.mesh.morph = BuildMorphTargets(spec, asset.mesh);
  return asset;
}

}  // namespace skintune::internal
