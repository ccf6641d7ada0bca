// The clip packer (generator/clip_packer.h): the buffers hold exactly the
// asset's nodes, joints and keys where docs/ANIMATION.md says, and each bad
// input is refused naming its element.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "base/error.h"
#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "tests/common/test_asset.h"

namespace skintune::internal {
namespace {

using testing::TestAsset;

std::uint32_t PathIndex(ChannelPath path) {
  return static_cast<std::uint32_t>(path == ChannelPath::kTranslation ? AnimPath::kTranslation
                                    : path == ChannelPath::kRotation  ? AnimPath::kRotation
                                                                      : AnimPath::kScale);
}

std::uint32_t InterpolationCode(Interpolation i) {
  return static_cast<std::uint32_t>(i == Interpolation::kStep     ? AnimInterpolation::kStep
                                    : i == Interpolation::kLinear ? AnimInterpolation::kLinear
                                                                  : AnimInterpolation::kCubicSpline);
}

// Every T/R/S channel of asset.animations[clips[c]] is at header
// (c * nodes + node) * 3 + path with its keys and values; no other header has keys.
void ExpectChannelsPacked(const SkinnedAsset& asset, const PackedAnimation& packed) {
  const std::size_t nodes = asset.skeleton.nodes.size();
  ASSERT_EQ(packed.channels.size(), packed.clips.size() * nodes * 3);
  std::size_t with_keys = 0;
  for (const AnimChannelHeader& h : packed.channels) with_keys += h.key_count > 0;
  std::size_t expected = 0;
  for (std::size_t c = 0; c < packed.clips.size(); ++c) {
    for (const Channel& channel : asset.animations[static_cast<std::size_t>(packed.clips[c])].channels) {
      if (channel.path == ChannelPath::kWeights) continue;
      ++expected;
      const AnimChannelHeader& h =
          packed.channels[(c * nodes + static_cast<std::size_t>(channel.node)) * 3 + PathIndex(channel.path)];
      ASSERT_EQ(h.key_count, channel.times.size());
      EXPECT_EQ(h.interpolation, InterpolationCode(channel.interpolation));
      for (std::size_t k = 0; k < channel.times.size(); ++k)
        EXPECT_EQ(packed.times[h.time_offset + k], channel.times[k]);
      for (std::size_t v = 0; v < channel.values.size(); ++v)
        for (int e = 0; e < 4; ++e)
          EXPECT_EQ(packed.values[4 * (h.value_offset + v) + static_cast<std::size_t>(e)],
                    static_cast<float>(channel.values[v][e]));
    }
  }
  EXPECT_EQ(with_keys, expected);
}

TEST(ClipPacker, BuffersHoldTheAssetsNodesJointsAndKeysWhereTheLayoutSays) {
  for (const char* model : {"RiggedSimple.gltf", "CesiumMan.gltf"}) {
    const SkinnedAsset& asset = TestAsset(model);
    const Skeleton& s = asset.skeleton;
    const PackedAnimation packed = PackAnimation(asset);
    ASSERT_EQ(packed.nodes.size(), s.nodes.size()) << model;
    for (std::size_t i = 0; i < s.nodes.size(); ++i) {
      EXPECT_EQ(packed.nodes[i].parent, s.nodes[i].parent);
      EXPECT_EQ(packed.nodes[i].fixed, s.nodes[i].has_matrix ? 1u : 0u);
      if (s.nodes[i].has_matrix) continue;
      const glm::dquat q = glm::normalize(s.nodes[i].rest.rotation);
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(packed.nodes[i].rows[0][c], static_cast<float>(s.nodes[i].rest.translation[c]));
        EXPECT_EQ(packed.nodes[i].rows[2][c], static_cast<float>(s.nodes[i].rest.scale[c]));
      }
      EXPECT_EQ(packed.nodes[i].rows[1][3], static_cast<float>(q.w));
    }
    ASSERT_EQ(packed.joints.size(), s.joints.size());
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      EXPECT_EQ(packed.joints[j].node, s.joints[j]);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
          EXPECT_EQ(packed.joints[j].inverse_bind[r][c], static_cast<float>(s.inverse_bind[j][c][r]));
    }
    ExpectChannelsPacked(asset, packed);
    EXPECT_EQ(BufferBytes(packed.nodes).size(), 64 * s.nodes.size());
    EXPECT_EQ(packed.Bytes(), 64 * s.nodes.size() + 16 * packed.channels.size() + 4 * packed.times.size() +
                                  4 * packed.values.size() + 64 * s.joints.size() + 16 * packed.clips.size());
    EXPECT_TRUE(packed.not_packed.empty());
  }
}

TEST(ClipPacker, PacksTheChosenClipsInTheirOrder) {
  const SkinnedAsset& fox = TestAsset("Fox.gltf");
  const std::vector<int> clips = {2, 0};
  const PackedAnimation packed = PackAnimation(fox, clips);
  EXPECT_EQ(packed.clips, clips);
  EXPECT_EQ(packed.View().clip_count, 2u);
  ExpectChannelsPacked(fox, packed);
  // `clips`: each packed clip's time range (start, end, 0, 0), in packed order.
  ASSERT_EQ(packed.clip_ranges.size(), 8u);
  for (std::size_t c = 0; c < clips.size(); ++c) {
    const AnimationClip& clip = fox.animations[static_cast<std::size_t>(clips[c])];
    EXPECT_EQ(packed.clip_ranges[4 * c], static_cast<float>(clip.start)) << "clip " << c;
    EXPECT_EQ(packed.clip_ranges[4 * c + 1], static_cast<float>(clip.start + clip.duration())) << "clip " << c;
    EXPECT_EQ(packed.clip_ranges[4 * c + 2], 0.0f);
  }
}

// A clip's clock loops in its range: AdvanceAnimInstances, as the device kernels do.
TEST(ClipPacker, AdvancedClocksLoopInTheirClipsRangeAndTheRestPoseStays) {
  const PackedAnimation packed = PackAnimation(TestAsset("Fox.gltf"));
  const float start = packed.clip_ranges[4], end = packed.clip_ranges[5], length = end - start;
  std::vector<AnimInstance> states = {{1, kAnimRestPose, start + 0.25f * length, 7.0f, 0.0f},
                                      {kAnimRestPose, 1, 3.0f, start, 0.5f}};
  AdvanceAnimInstances(packed.View(), states, 1.5f * length);
  EXPECT_NEAR(states[0].time, start + 0.75f * length, 1e-5f * length);
  EXPECT_EQ(states[0].time2, 7.0f) << "the rest pose's clock stays";
  EXPECT_EQ(states[1].time, 3.0f);
  EXPECT_NEAR(states[1].time2, start + 0.5f * length, 1e-5f * length);
  AdvanceAnimInstances(packed.View(), states, -1.0f * length);
  EXPECT_NEAR(states[0].time, start + 0.75f * length, 1e-5f * length) << "backwards, a whole clip: the same time";
  EXPECT_EQ(AnimLoopTime(5.0f, 2.0f, 2.0f), 2.0f) << "a clip of no duration stays at its start";
  EXPECT_EQ(AnimLoopTime(2.0f + 3.0f, 2.0f, 4.0f), 3.0f);
}

TEST(ClipPacker, MorphWeightsChannelsAreLeftOutAndNamed) {
  const SkinnedAsset& asset = TestAsset("RiggedSimple-morph.gltf");
  std::size_t weights = 0;
  for (const Channel& c : asset.animations[0].channels) weights += c.path == ChannelPath::kWeights;
  ASSERT_GT(weights, 0u);
  const PackedAnimation packed = PackAnimation(asset);
  ASSERT_EQ(packed.not_packed.size(), weights);
  EXPECT_NE(packed.not_packed[0].find("animations[0]"), std::string::npos) << packed.not_packed[0];
  EXPECT_NE(packed.not_packed[0].find("morph target weights are not part of the palette"), std::string::npos)
      << packed.not_packed[0];
  ExpectChannelsPacked(asset, packed);
}

std::string ErrorOf(const SkinnedAsset& asset, const std::vector<int>& clips = {0}) {
  try {
    PackAnimation(asset, clips);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

// RiggedSimple with `change` applied.
template <typename Change>
SkinnedAsset Changed(Change change) {
  SkinnedAsset asset = TestAsset("RiggedSimple.gltf");
  asset.source = "rigged";
  change(asset);
  return asset;
}

TEST(ClipPacker, RefusesEachBadInputNamingItsElement) {
  const SkinnedAsset plain = Changed([](SkinnedAsset&) {});
  const Channel first = plain.animations[0].channels[0];
  const std::string channel0 = "rigged: animations[0]: channels[0] (" +
                               std::string(first.path == ChannelPath::kRotation ? "rotation"
                                           : first.path == ChannelPath::kScale  ? "scale"
                                                                                : "translation") +
                               " of node " + std::to_string(first.node) + ")";
  EXPECT_EQ(ErrorOf(plain, {0, 5}), "rigged: clips[1]: animation 5 out of range (1 animations)");
  EXPECT_EQ(ErrorOf(plain, {-1}), "rigged: clips[0]: animation -1 out of range (1 animations)");
  EXPECT_EQ(ErrorOf(plain, std::vector<int>(70000, 0)),
            "rigged: 70000 clips to pack (at most 65535: 16-bit clip indices)");
  EXPECT_EQ(ErrorOf(Changed([](SkinnedAsset& a) { a.skeleton.nodes.resize(70000); })),
            "rigged: 70000 nodes (at most 512 packed: the device palette kernels hold an instance's nodes in local memory)");
  EXPECT_EQ(ErrorOf(Changed([](SkinnedAsset& a) { a.skeleton.nodes.resize(513); })),
            "rigged: 513 nodes (at most 512 packed: the device palette kernels hold an instance's nodes in local memory)");
  EXPECT_EQ(ErrorOf(Changed([&](SkinnedAsset& a) { a.animations[0].channels.push_back(first); })),
            "rigged: animations[0]: channels[" + std::to_string(plain.animations[0].channels.size()) + "]" +
                channel0.substr(channel0.find(" (")) +
                ": a second channel on the same node and path (glTF allows one per clip)");
  EXPECT_EQ(ErrorOf(Changed([&](SkinnedAsset& a) {
              Node& node = a.skeleton.nodes[static_cast<std::size_t>(first.node)];
              node.has_matrix = true;
              node.matrix = node.rest.ToMatrix();
            })),
            channel0 + ": the node has a fixed matrix, which glTF does not let an animation target");
  EXPECT_EQ(ErrorOf(Changed([](SkinnedAsset& a) { a.skeleton.inverse_bind[1][0][3] = 0.5; })),
            "rigged: inverse bind matrix of joint 1: last row [0.5 0 0 1] is not 0 0 0 1 (the palette is 3x4, affine)");
  EXPECT_EQ(ErrorOf(Changed([](SkinnedAsset& a) { a.animations[0].channels[0].values[1].y = 1e300; })),
            channel0 + ": value 1 is 1e+300, beyond float32");
  // The clip's own validation (AnimationClip::Validate) names the clip.
  EXPECT_NE(ErrorOf(Changed([](SkinnedAsset& a) {
              a.animations[0].channels[0].times[1] = a.animations[0].channels[0].times[0];
            })).find("rigged: animations[0]: channels[0]"),
            std::string::npos);
}

std::string ValidationErrorOf(const PackedAnimation& packed) {
  try {
    ValidateAnimation(packed.View());
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

// What an outside program could pack wrong, caught before a kernel reads it.
TEST(ClipPacker, ValidateAnimationNamesTheBadElementOfAnOutsidePacking) {
  const PackedAnimation good = PackAnimation(TestAsset("RiggedSimple.gltf"));
  ASSERT_EQ(ValidationErrorOf(good), "no error");
  std::size_t animated = 0;
  while (good.channels[animated].key_count == 0) ++animated;
  const std::string header = "packed animation: channels[" + std::to_string(animated) + "] (clip 0, node " +
                             std::to_string(animated / 3) + ", " +
                             (animated % 3 == 0   ? "translation"
                              : animated % 3 == 1 ? "rotation"
                                                  : "scale") +
                             ")";
  PackedAnimation bad = good;
  bad.channels[animated].interpolation = 7;
  EXPECT_EQ(ValidationErrorOf(bad), header + ": interpolation 7 is none of 0 (STEP), 1 (LINEAR), 2 (CUBICSPLINE)");
  bad = good;
  bad.channels[animated].time_offset = static_cast<std::uint32_t>(good.times.size());
  EXPECT_NE(ValidationErrorOf(bad).find(header + ": keys " + std::to_string(good.times.size())), std::string::npos)
      << ValidationErrorOf(bad);
  bad = good;
  bad.times[good.channels[animated].time_offset + 1] = bad.times[good.channels[animated].time_offset];
  EXPECT_EQ(ValidationErrorOf(bad), header + ": times not strictly increasing at key 1");
  bad = good;
  bad.channels.pop_back();
  EXPECT_EQ(ValidationErrorOf(bad), "packed animation: " + std::to_string(good.channels.size() - 1) +
                                        " channel headers for 1 clips x " + std::to_string(good.nodes.size()) +
                                        " nodes x 3 paths (expected " + std::to_string(good.channels.size()) + ")");
  bad = good;
  bad.nodes[0].parent = static_cast<std::int32_t>(good.nodes.size() - 1);
  bad.nodes.back().parent = 0;
  EXPECT_NE(ValidationErrorOf(bad).find("the node hierarchy has a cycle"), std::string::npos) << ValidationErrorOf(bad);
  bad = good;
  bad.joints[1].node = 99;
  EXPECT_EQ(ValidationErrorOf(bad),
            "packed animation: joints[1]: node 99 out of range (" + std::to_string(good.nodes.size()) + " nodes)");
}

}  // namespace
}  // namespace skintune::internal
