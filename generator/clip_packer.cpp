#include "generator/clip_packer.h"

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>
#include <string>
#include <utility>

#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtc/quaternion.hpp>

#include "base/error.h"
#include "reference/skinning.h"

namespace skintune::internal {
namespace {

std::string ClipName(const SkinnedAsset& asset, int clip) {
  const std::string& name = asset.animations[static_cast<std::size_t>(clip)].name;
  return "animations[" + std::to_string(clip) + "]" + (name.empty() ? "" : " '" + name + "'");
}

std::string Number(double v) {
  char text[40];
  std::snprintf(text, sizeof text, "%.9g", v);
  return text;
}

// v as float32; Error naming `what` when it is beyond float's range.
float ToFloat(double v, const std::string& what) {
  if (!std::isfinite(v) || std::fabs(v) > FLT_MAX) throw Error(what + " is " + Number(v) + ", beyond float32");
  return static_cast<float>(v);
}

void PutRow(float (&row)[4], const glm::dvec4& v, const std::string& what) {
  for (int c = 0; c < 4; ++c) row[c] = ToFloat(v[c], what);
}

// The three rows of an affine matrix (glm: m[column][row]); Error naming
// `what` when its last row is not 0 0 0 1 (a 3x4 palette cannot hold it).
void PutAffineRows(float (&rows)[3][4], const glm::dmat4& m, const std::string& what) {
  for (int c = 0; c < 4; ++c) {
    const double expected = c == 3 ? 1.0 : 0.0;
    if (std::fabs(m[c][3] - expected) > 1e-6)
      throw Error(what + ": last row [" + Number(m[0][3]) + " " + Number(m[1][3]) + " " + Number(m[2][3]) + " " +
                  Number(m[3][3]) + "] is not 0 0 0 1 (the palette is 3x4, affine)");
  }
  for (int r = 0; r < 3; ++r) PutRow(rows[r], glm::dvec4(m[0][r], m[1][r], m[2][r], m[3][r]), what);
}

std::vector<AnimNodeRecord> PackNodes(const SkinnedAsset& asset) {
  const Skeleton& s = asset.skeleton;
  std::vector<AnimNodeRecord> nodes(s.nodes.size());
  for (std::size_t i = 0; i < s.nodes.size(); ++i) {
    const Node& node = s.nodes[i];
    const std::string what = asset.source + ": nodes[" + std::to_string(i) + "]";
    nodes[i].parent = node.parent;
    nodes[i].fixed = node.has_matrix ? 1 : 0;
    if (node.has_matrix) {
      PutAffineRows(nodes[i].rows, node.matrix, what + " matrix");
      continue;
    }
    // Normalised here, once, as Transform::ToMatrix normalises it for the gold.
    const glm::dquat q = glm::normalize(node.rest.rotation);
    PutRow(nodes[i].rows[0], glm::dvec4(node.rest.translation, 0.0), what + " translation");
    PutRow(nodes[i].rows[1], glm::dvec4(q.x, q.y, q.z, q.w), what + " rotation");
    PutRow(nodes[i].rows[2], glm::dvec4(node.rest.scale, 0.0), what + " scale");
  }
  return nodes;
}

std::vector<AnimJointRecord> PackJoints(const SkinnedAsset& asset) {
  const Skeleton& s = asset.skeleton;
  std::vector<AnimJointRecord> joints(s.joints.size());
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    joints[j].node = s.joints[j];
    PutAffineRows(joints[j].inverse_bind, s.inverse_bind[j],
                  asset.source + ": inverse bind matrix of joint " + std::to_string(j));
  }
  return joints;
}

// Appends one channel's keys and values and fills its header.
void PackChannel(const Channel& c, const std::string& where, PackedAnimation& out, AnimChannelHeader& header) {
  if (out.times.size() + c.times.size() > kAnimMaxKeys || out.values.size() / 4 + c.values.size() > kAnimMaxKeys)
    throw Error(where + ": the clips hold more than " + std::to_string(kAnimMaxKeys) + " keys or values in all");
  header.interpolation =
      static_cast<std::uint32_t>(c.interpolation == Interpolation::kStep     ? AnimInterpolation::kStep
                                 : c.interpolation == Interpolation::kLinear ? AnimInterpolation::kLinear
                                                                             : AnimInterpolation::kCubicSpline);
  header.key_count = static_cast<std::uint32_t>(c.times.size());
  header.time_offset = static_cast<std::uint32_t>(out.times.size());
  header.value_offset = static_cast<std::uint32_t>(out.values.size() / 4);
  out.times.insert(out.times.end(), c.times.begin(), c.times.end());
  for (std::size_t k = 0; k < c.values.size(); ++k) {
    float row[4];
    PutRow(row, c.values[k], where + ": value " + std::to_string(k));
    out.values.insert(out.values.end(), row, row + 4);
  }
}

// Packed clip `packed` (asset.animations[clip]): its headers, keys and values.
void PackClip(const SkinnedAsset& asset, int clip, std::size_t packed, PackedAnimation& out) {
  const AnimationClip& a = asset.animations[static_cast<std::size_t>(clip)];
  const std::string name = asset.source + ": " + ClipName(asset, clip);
  a.Validate(static_cast<int>(asset.skeleton.nodes.size()), name);
  std::set<std::pair<int, ChannelPath>> seen;
  for (std::size_t i = 0; i < a.channels.size(); ++i) {
    const Channel& c = a.channels[i];
    const std::string where = name + ": channels[" + std::to_string(i) + "] (" + ChannelPathName(c.path) + " of node " +
                              std::to_string(c.node) + ")";
    if (c.path == ChannelPath::kWeights) {
      out.not_packed.push_back(where + ": morph target weights are not part of the palette");
      continue;
    }
    if (asset.skeleton.nodes[static_cast<std::size_t>(c.node)].has_matrix)
      throw Error(where + ": the node has a fixed matrix, which glTF does not let an animation target");
    if (!seen.emplace(c.node, c.path).second)
      throw Error(where + ": a second channel on the same node and path (glTF allows one per clip)");
    const std::size_t path = c.path == ChannelPath::kTranslation ? 0 : c.path == ChannelPath::kRotation ? 1 : 2;
    PackChannel(c, where, out,
                out.channels[(packed * out.nodes.size() + static_cast<std::size_t>(c.node)) * kAnimPaths + path]);
  }
}

void CheckCounts(const SkinnedAsset& asset, std::span<const int> clips) {
  const std::size_t nodes = asset.skeleton.nodes.size(), joints = asset.skeleton.joints.size();
  if (nodes > kAnimMaxNodes)
    throw Error(asset.source + ": " + std::to_string(nodes) + " nodes (at most " + std::to_string(kAnimMaxNodes) +
                " packed: the device palette kernels hold an instance's nodes in local memory)");
  if (joints > kAnimMaxJoints)
    throw Error(asset.source + ": " + std::to_string(joints) + " joints (at most " + std::to_string(kAnimMaxJoints) +
                " packed)");
  if (clips.size() > kAnimMaxClips)
    throw Error(asset.source + ": " + std::to_string(clips.size()) + " clips to pack (at most " +
                std::to_string(kAnimMaxClips) + ": 16-bit clip indices)");
  if (clips.size() * nodes * kAnimPaths > kAnimMaxHeaders)
    throw Error(asset.source + ": " + std::to_string(clips.size()) + " clips x " + std::to_string(nodes) +
                " nodes x 3 paths = " + std::to_string(clips.size() * nodes * kAnimPaths) +
                " channel headers (at most " + std::to_string(kAnimMaxHeaders) + ")");
  for (std::size_t c = 0; c < clips.size(); ++c) {
    if (clips[c] < 0 || static_cast<std::size_t>(clips[c]) >= asset.animations.size())
      throw Error(asset.source + ": clips[" + std::to_string(c) + "]: animation " + std::to_string(clips[c]) +
                  " out of range (" + std::to_string(asset.animations.size()) + " animations)");
  }
}

}  // namespace

AnimationView PackedAnimation::View() const {
  return AnimationView{static_cast<std::uint32_t>(clips.size()), nodes, channels, times, values, joints, clip_ranges,
                       frames, baked_rows, baked_local, steady, steady_rows};
}

std::size_t PackedAnimation::Bytes() const {
  if (baked_local) return BufferBytes(frames).size() + BufferBytes(steady).size() + BufferBytes(clip_ranges).size() +
                          BufferBytes(nodes).size() + BufferBytes(joints).size();
  if (!frames.empty()) return BufferBytes(frames).size() + BufferBytes(clip_ranges).size();
  return BufferBytes(nodes).size() + BufferBytes(channels).size() + BufferBytes(times).size() +
         BufferBytes(values).size() + BufferBytes(joints).size() + BufferBytes(clip_ranges).size();
}

PackedAnimation PackAnimation(const SkinnedAsset& asset, std::span<const int> clips) {
  CheckCounts(asset, clips);
  asset.skeleton.Validate(asset.source);
  PackedAnimation out;
  out.source = asset.source;
  out.clips.assign(clips.begin(), clips.end());
  out.nodes = PackNodes(asset);
  out.joints = PackJoints(asset);
  out.channels.assign(clips.size() * out.nodes.size() * kAnimPaths, AnimChannelHeader{});
  for (std::size_t c = 0; c < clips.size(); ++c) PackClip(asset, clips[c], c, out);
  for (const int c : clips) {
    const AnimationClip& clip = asset.animations[static_cast<std::size_t>(c)];
    out.clip_ranges.insert(out.clip_ranges.end(), {static_cast<float>(clip.start),
                                                   static_cast<float>(clip.start + clip.duration()), 0.0f, 0.0f});
  }
  ValidateAnimation(out.View());  // what the kernels rely on, checked as for any outside packing
  return out;
}

namespace {

// A joint's skinning transform M = T(t) R(q) S as baked (S symmetric).
struct BakedJoint {
  glm::dquat q;
  glm::dvec3 t;
  glm::dmat3 s;
};

// The rotation of `m`'s polar decomposition (det m > 0): Higham's iteration
// R <- (R + R^-T) / 2, which converges quadratically (glm has none).
glm::dmat3 PolarRotation(const glm::dmat3& m) {
  glm::dmat3 r = m;
  for (int k = 0; k < 64; ++k) {
    const glm::dmat3 next = 0.5 * (r + glm::transpose(glm::inverse(r)));
    double change = 0.0;
    for (int c = 0; c < 3; ++c) change = std::max(change, glm::length(next[c] - r[c]));
    r = next;
    if (change < 1e-15) break;
  }
  return r;
}

// Shoemake and Duff's split of an affine M: rotation, symmetric stretch
// (negative where M mirrors), translation.
BakedJoint BakeJoint(const glm::dmat4& m, const std::string& what) {
  const glm::dmat3 l(m);
  const double det = glm::determinant(l);
  if (!std::isfinite(det) || std::fabs(det) < 1e-300) throw Error(what + ": a singular transform (no rotation to bake)");
  const glm::dmat3 r = PolarRotation(det < 0.0 ? -l : l);
  glm::dmat3 stretch = glm::transpose(r) * l;
  stretch = 0.5 * (stretch + glm::transpose(stretch));
  return {glm::normalize(glm::quat_cast(r)), glm::dvec3(m[3]), stretch};
}

// Whether S is s I within 1e-5 of s (a similarity: the record's 2-row form).
// Exporters leave float noise in scales (CesiumMan's nodes scale unevenly by
// up to 7.5e-7, compounding down its chains); each clip's stated error
// includes what the similarity leaves out.
bool Similar(const glm::dmat3& s) {
  const double mean = (s[0][0] + s[1][1] + s[2][2]) / 3.0;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      if (std::fabs(s[c][r] - (r == c ? mean : 0.0)) > 1e-5 * std::fabs(mean)) return false;
  return true;
}

// x towards y by u as the kernels mix records (BakedMix), in float64.
BakedJoint MixBaked(const BakedJoint& x, const BakedJoint& y, double u) {
  const glm::dquat q2 = glm::dot(x.q, y.q) < 0.0 ? -y.q : y.q;
  return {glm::normalize(x.q + u * (q2 - x.q)), x.t + u * (y.t - x.t), x.s + u * (y.s - x.s)};
}

// Appends `b` to `frames` as a record of `rows` float4s (cpu_kernels/palette_kernel.h)
// and gives it back as stored: float32, in that form.
BakedJoint PutBaked(const BakedJoint& b, std::uint32_t rows, std::vector<float>& frames, const std::string& what) {
  const glm::dmat3& s = b.s;
  const double mean = (s[0][0] + s[1][1] + s[2][2]) / 3.0;
  const std::size_t at = frames.size();
  frames.insert(frames.end(), {ToFloat(b.q.x, what), ToFloat(b.q.y, what), ToFloat(b.q.z, what), ToFloat(b.q.w, what),
                               ToFloat(b.t.x, what), ToFloat(b.t.y, what), ToFloat(b.t.z, what),
                               rows == kBakedRowsSimilar ? ToFloat(mean, what) : 0.0f});
  if (rows == kBakedRowsAffine)
    frames.insert(frames.end(), {ToFloat(s[0][0], what), ToFloat(s[1][1], what), ToFloat(s[2][2], what),
                                 ToFloat(s[1][0], what), ToFloat(s[2][0], what), ToFloat(s[2][1], what), 0.0f, 0.0f});
  if (rows == kBakedRowsLocalScaled)  // a local record's scale: S's diagonal
    frames.insert(frames.end(), {ToFloat(s[0][0], what), ToFloat(s[1][1], what), ToFloat(s[2][2], what), 0.0f});
  const float* p = frames.data() + at;
  BakedJoint stored{glm::dquat(p[3], p[0], p[1], p[2]), glm::dvec3(p[4], p[5], p[6]), glm::dmat3(double{p[7]})};
  if (rows == kBakedRowsAffine) {
    stored.s = glm::dmat3(p[8], p[11], p[12], p[11], p[9], p[13], p[12], p[13], p[10]);
  } else if (rows == kBakedRowsLocalScaled) {
    stored.s = glm::dmat3(glm::dvec3(p[8], 0.0, 0.0), glm::dvec3(0.0, p[9], 0.0), glm::dvec3(0.0, 0.0, p[10]));
  }
  return stored;
}

// T(t) R(q) S of a record: a joint's palette entry, or a node's local transform.
glm::dmat4 MatrixOf(const BakedJoint& b) {
  glm::dmat4 m(glm::mat3_cast(b.q) * b.s);
  m[3] = glm::dvec4(b.t, 1.0);
  return m;
}

// A node's local transform as a record (a fixed-matrix node: the identity,
// its matrix is read from `nodes`).
BakedJoint LocalRecord(const Node& node, const Transform& local) {
  if (node.has_matrix) return {glm::dquat(1.0, 0.0, 0.0, 0.0), glm::dvec3(0.0), glm::dmat3(1.0)};
  const glm::dvec3& s = local.scale;
  return {glm::normalize(local.rotation), local.translation,
          glm::dmat3(glm::dvec3(s.x, 0.0, 0.0), glm::dvec3(0.0, s.y, 0.0), glm::dvec3(0.0, 0.0, s.z))};
}

// The palette of local records: each node's transform from its record, the
// hierarchy composed in float64 (Skeleton::PaletteD).
std::vector<glm::dmat4> PaletteOfLocals(const Skeleton& skeleton, std::span<const BakedJoint> locals) {
  Pose pose = skeleton.RestPose();
  for (std::size_t n = 0; n < pose.size(); ++n) {
    pose[n].translation = locals[n].t;
    pose[n].rotation = locals[n].q;
    pose[n].scale = glm::dvec3(locals[n].s[0][0], locals[n].s[1][1], locals[n].s[2][2]);
  }
  return skeleton.PaletteD(pose);
}

// The largest distance between a vertex of `mesh` skinned by the `baked`
// palette and by the `exact` one: |sum_i w_i (B - E)[d_i] v|.
double BakeError(const SkinnedMesh& mesh, std::span<const glm::dmat4> baked, std::span<const glm::dmat4> exact) {
  std::vector<glm::dmat4> difference(baked.size());
  for (std::size_t j = 0; j < baked.size(); ++j) difference[j] = baked[j] - exact[j];
  double worst = 0.0;
  const auto b = static_cast<std::size_t>(mesh.influences);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const glm::dvec4 p(glm::dvec3(mesh.positions[v]), 1.0);
    glm::dvec3 moved(0.0);
    for (std::size_t i = 0; i < b; ++i)
      if (const double w = mesh.weights[v * b + i]; w != 0.0)
        moved += w * glm::dvec3(difference[static_cast<std::size_t>(mesh.joints[v * b + i])] * p);
    worst = std::max(worst, glm::length(moved));
  }
  return worst;
}

}  // namespace

PackedAnimation BakeAnimation(const SkinnedAsset& asset, std::span<const int> clips, double rate, BakeSpace space) {
  if (!(rate > 0.0) || rate > kAnimMaxBakeRate)
    throw Error(asset.source + ": bake rate " + Number(rate) + " frames a second, outside (0, " +
                Number(kAnimMaxBakeRate) + "]");
  if (space == BakeSpace::kHybrid) {  // both, of the same frames (one rate, one clip list)
    PackedAnimation out = BakeAnimation(asset, clips, rate, BakeSpace::kLocal);
    PackedAnimation palette = BakeAnimation(asset, clips, rate, BakeSpace::kPalette);
    out.steady = std::move(palette.frames);
    out.steady_rows = palette.baked_rows;
    for (std::size_t c = 0; c < out.baked.size(); ++c) {
      out.baked[c].bytes += palette.baked[c].bytes;
      out.baked[c].max_error = std::max(out.baked[c].max_error, palette.baked[c].max_error);
    }
    ValidateBakedAnimation(out.View());
    return out;
  }
  PackedAnimation out = PackAnimation(asset, clips);  // every check of the clips and the skeleton
  out.channels.clear();
  out.times.clear();
  out.values.clear();
  out.clip_ranges.clear();
  out.bake_rate = rate;
  out.baked_local = space == BakeSpace::kLocal;  // kHybrid returned above
  const std::size_t joints = out.View().baked_items();  // records a frame: joints, or nodes
  // The frames: the rest pose, then each clip's evenly spaced times. Their
  // records are made twice (below) rather than kept in float64 between the
  // two passes: a baking near kMaxBakedFloats would otherwise hold 8 times
  // its own size in host memory.
  struct Frame {
    int clip = -1;  // asset clip (-1: the rest pose)
    double t = 0.0;
  };
  std::vector<Frame> frames = {Frame{}};
  std::vector<std::uint32_t> counts(clips.size());
  for (std::size_t c = 0; c < clips.size(); ++c) {
    const AnimationClip& clip = asset.animations[static_cast<std::size_t>(clips[c])];
    const double duration = clip.duration();
    counts[c] =
        static_cast<std::uint32_t>(duration > 0.0 ? std::max(2.0, std::ceil(duration * rate - 1e-9) + 1.0) : 1.0);
    if ((frames.size() + counts[c]) * joints * 4 * kBakedRowsAffine > kMaxBakedFloats)
      throw Error(asset.source + ": baked at " + Number(rate) + " frames a second, more than " +
                  std::to_string(kMaxBakedFloats) + " floats of frames");
    const double step = counts[c] > 1 ? duration / (counts[c] - 1) : 0.0;
    for (std::uint32_t k = 0; k < counts[c]; ++k) frames.push_back({clips[c], clip.start + k * step});
  }
  std::vector<BakedJoint> records(joints);
  const auto records_of = [&](const Frame& f) -> const std::vector<BakedJoint>& {
    const Pose pose = asset.PoseAt(f.clip, f.t);
    if (out.baked_local) {
      for (std::size_t n = 0; n < joints; ++n) records[n] = LocalRecord(asset.skeleton.nodes[n], pose[n]);
      return records;
    }
    const std::vector<glm::dmat4> palette = asset.skeleton.PaletteD(pose);
    const std::string what = asset.source + ": " +
                             (f.clip < 0 ? std::string("rest pose") : ClipName(asset, f.clip) + " at t=" + Number(f.t) + " s");
    for (std::size_t j = 0; j < joints; ++j) records[j] = BakeJoint(palette[j], what + " joint " + std::to_string(j));
    return records;
  };
  // The palette skinned by a frame's (or a mix's) records.
  const auto palette_of = [&](std::span<const BakedJoint> mixed) {
    if (out.baked_local) return PaletteOfLocals(asset.skeleton, mixed);
    std::vector<glm::dmat4> palette(mixed.size());
    for (std::size_t j = 0; j < mixed.size(); ++j) palette[j] = MatrixOf(mixed[j]);
    return palette;
  };
  // 1: the form the records need: 2 rows where every transform is a
  // similarity (in local space: every scale uniform), else 4 (3).
  out.baked_rows = kBakedRowsSimilar;
  for (std::size_t f = 0; f < frames.size() && out.baked_rows == kBakedRowsSimilar; ++f)
    for (const BakedJoint& b : records_of(frames[f]))
      if (!Similar(b.s)) out.baked_rows = out.baked_local ? kBakedRowsLocalScaled : kBakedRowsAffine;
  // 2: stored as float32 in that form; each clip's error measured with the
  // records as stored, at its frames and 1/4, 1/2, 3/4 between them.
  const double diagonal = BoundingBoxDiagonal(asset.mesh.positions);
  std::vector<BakedJoint> stored(joints), previous(joints), mixed(joints);
  const auto put = [&](const Frame& f) {
    const std::vector<BakedJoint>& made = records_of(f);
    for (std::size_t j = 0; j < joints; ++j)
      stored[j] = PutBaked(made[j], out.baked_rows, out.frames,
                           asset.source + (out.baked_local ? ": frames node " : ": frames joint ") + std::to_string(j));
  };
  put(frames[0]);
  std::size_t next = 1;
  for (std::size_t c = 0; c < clips.size(); ++c) {
    const std::uint32_t count = counts[c], first = static_cast<std::uint32_t>(next);
    const AnimationClip& clip = asset.animations[static_cast<std::size_t>(clips[c])];
    const double step = count > 1 ? clip.duration() / (count - 1) : 0.0;
    double worst = 0.0;
    for (std::uint32_t k = 0; k < count; ++k, ++next) {
      const Frame& f = frames[next];
      put(f);
      for (const double u : {0.0, 0.25, 0.5, 0.75, 1.0}) {  // between the last frame and this one
        if ((k == 0 && count > 1) || (u != 1.0 && (k == 0 || (u == 0.0 && k > 1)))) continue;
        for (std::size_t j = 0; j < joints; ++j) mixed[j] = k == 0 ? stored[j] : MixBaked(previous[j], stored[j], u);
        const std::vector<glm::dmat4> exact = asset.skeleton.PaletteD(asset.PoseAt(clips[c], f.t - (1.0 - u) * step));
        worst = std::max(worst, BakeError(asset.mesh, palette_of(mixed), exact));
      }
      previous = stored;
    }
    out.clip_ranges.insert(out.clip_ranges.end(), {static_cast<float>(clip.start),
                                                   static_cast<float>(clip.start + clip.duration()),
                                                   std::bit_cast<float>(count), std::bit_cast<float>(first)});
    out.baked.push_back({ClipName(asset, clips[c]), count,
                         std::size_t{count} * joints * out.baked_rows * 16,
                         diagonal > 0.0 ? worst / diagonal : std::numeric_limits<double>::quiet_NaN()});
  }
  ValidateBakedAnimation(out.View());
  return out;
}

PackedAnimation BakeAnimation(const SkinnedAsset& asset, double rate, BakeSpace space) {
  std::vector<int> all(asset.animations.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return BakeAnimation(asset, all, rate, space);
}

PackedAnimation PackForm(const SkinnedAsset& asset, Animation form) {
  if (!AnimatesOnDevice(form)) throw Error(asset.source + ": animation 'host' packs no clips (the host uploads palettes)");
  const double rate = BakeRateOf(form);
  const BakeSpace space = BakesHybrid(form)    ? BakeSpace::kHybrid
                          : BakesLocally(form) ? BakeSpace::kLocal
                                               : BakeSpace::kPalette;
  return rate > 0.0 ? BakeAnimation(asset, rate, space) : PackAnimation(asset);
}

PackedAnimation PackAnimation(const SkinnedAsset& asset) {
  std::vector<int> all(asset.animations.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return PackAnimation(asset, all);
}

}  // namespace skintune::internal
