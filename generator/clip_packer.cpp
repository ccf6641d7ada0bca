#include "generator/clip_packer.h"

#include <cfloat>
#include <cmath>
#include <cstdio>
#include <set>
#include <string>
#include <utility>

#include "base/error.h"

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
  return AnimationView{static_cast<std::uint32_t>(clips.size()), nodes, channels, times, values, joints, clip_ranges};
}

std::size_t PackedAnimation::Bytes() const {
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

PackedAnimation PackAnimation(const SkinnedAsset& asset) {
  std::vector<int> all(asset.animations.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return PackAnimation(asset, all);
}

}  // namespace skintune::internal
