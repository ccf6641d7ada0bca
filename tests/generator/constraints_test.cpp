#include <gtest/gtest.h>

#include "generator/constraints.h"

namespace skintune::internal {
namespace {

const DeviceLimits kDevice{};                  // generic: 256 wg, 32 KiB local, 64 KiB constant
const ProblemShape kShape{77, 4, true};

// The variant breaks exactly `expected`, with a message containing `text`.
void ExpectOnly(const Variant& v, Constraint expected, const std::string& text, const DeviceLimits& device = kDevice,
                const ProblemShape& shape = kShape) {
  const std::vector<Violation> broken = CheckVariant(v, device, shape);
  ASSERT_EQ(broken.size(), 1u) << v.Key();
  EXPECT_EQ(broken[0].constraint, expected) << v.Key();
  EXPECT_NE(broken[0].message.find(text), std::string::npos) << broken[0].message;
}

TEST(Constraints, TheDefaultVariantIsValidOnGenericLimits) {
  EXPECT_TRUE(CheckVariant(Variant{}, kDevice, kShape).empty());
}

TEST(Constraints, APackedNormalFormatNeedsNormals) {
  Variant v;
  v.normal_format = NormalFormat::kOct16;
  ExpectOnly(v, Constraint::kNormalFormatUnused, "normal_format oct16 packs normals, but the variant skins none");
  v.normals = Normals::kNormals;
  EXPECT_TRUE(CheckVariant(v, kDevice, kShape).empty());
  EXPECT_STREQ(Name(Constraint::kNormalFormatUnused), "normal_format_unused");
}

// Where the palettes come from is the scene's: the device's forms only on a
// scene animated on the device (-anim), host only elsewhere; neither is
// counted as invalid (NotOfThisDataSet). The palette kernel writes matrices,
// and the tuner animates no scene with morph targets.
TEST(Constraints, TheAnimationAxisFollowsTheScene) {
  Variant v;
  v.animation = Animation::kBaked60;
  ExpectOnly(v, Constraint::kAnimationMissing, "animation baked60: the scene's palettes come from the host");
  ProblemShape animated = kShape;
  animated.animated = true;
  EXPECT_TRUE(CheckVariant(v, kDevice, animated).empty());
  ExpectOnly(Variant{}, Constraint::kAnimationIgnored, "animation host: the scene's palettes are made on the device",
             kDevice, animated);
  EXPECT_TRUE(NotOfThisDataSet(Constraint::kAnimationMissing));
  EXPECT_TRUE(NotOfThisDataSet(Constraint::kAnimationIgnored));
  Variant dq = v;
  dq.palette = PaletteFormat::kDualQuaternion;
  dq.blend = Blend::kDualQuaternion;
  animated.rigid_joints = true;
  ExpectOnly(dq, Constraint::kAnimationPalette, "the palette kernel writes mat3x4 or mat4 palettes", kDevice, animated);
  Variant fused = v;  // each work-group makes its palette in its local copy
  fused.animation = Animation::kFused120;
  ExpectOnly(fused, Constraint::kAnimationFused, "animation fused120: each work-group makes its palette into its local "
             "copy (storage local, not global)", kDevice, animated);
  fused.storage = PaletteStorage::kLocal;
  EXPECT_TRUE(CheckVariant(fused, kDevice, animated).empty());
  ProblemShape morph = animated;
  morph.morph_targets = 4;
  morph.morph_moves = true;
  v.morph = Morph::kDense;
  ExpectOnly(v, Constraint::kAnimationMorph, "an animated scene with morph targets", kDevice, morph);
  EXPECT_STREQ(Name(Constraint::kAnimationMissing), "animation_missing");
  EXPECT_STREQ(Name(Constraint::kAnimationIgnored), "animation_ignored");
  EXPECT_STREQ(Name(Constraint::kAnimationPalette), "animation_palette");
  EXPECT_STREQ(Name(Constraint::kAnimationMorph), "animation_morph");
  EXPECT_STREQ(Name(Constraint::kAnimationFused), "animation_fused");
}

TEST(Constraints, RejectsInfluencesOutsideOneToEight) {
  Variant v;
  v.influences = 9;
  ExpectOnly(v, Constraint::kInfluencesRange, "influences 9 outside 1..8");
}

TEST(Constraints, RejectsFewerInfluencesThanTheMeshNeeds) {
  Variant v;
  v.influences = 2;
  ExpectOnly(v, Constraint::kInfluencesTooFew, "below the mesh's largest per-vertex count 4");
}

TEST(Constraints, RejectsVerticesPerItemOtherThanPowersOfTwoUpToEight) {
  Variant v;
  v.vertices_per_item = 3;
  ExpectOnly(v, Constraint::kVerticesPerItem, "vertices_per_item 3");
}

TEST(Constraints, RejectsStridedAssignmentWithOneVertexPerItem) {
  Variant v;
  v.assignment = Assignment::kStrided;
  ExpectOnly(v, Constraint::kAssignmentRedundant, "use v1c");
}

TEST(Constraints, RejectsWorkGroupSizesThatAreNotMultiplesOf32) {
  Variant v;
  v.wg_size = 100;
  ExpectOnly(v, Constraint::kWgSizeRange, "wg_size 100");
}

TEST(Constraints, RejectsWorkGroupsAboveTheDeviceLimit) {
  Variant v;
  v.wg_size = 512;
  ExpectOnly(v, Constraint::kWgSizeDevice, "above the device's limit 256");
}

TEST(Constraints, GlslVertexNeedsNoWorkGroupsAndOneVertexPerInvocation) {
  Variant v;
  v.lang = Lang::kGlslVertex;
  ExpectOnly(v, Constraint::kNoWorkGroups, "needs v1c and wg0");
  v.wg_size = 0;
  EXPECT_TRUE(CheckVariant(v, kDevice, kShape).empty());
}

TEST(Constraints, RejectsLocalStorageLargerThanLocalMemory) {
  Variant v;
  v.storage = PaletteStorage::kLocal;
  DeviceLimits small = kDevice;
  small.local_memory_bytes = 4096;
  ExpectOnly(v, Constraint::kLocalMemory, "palette 1000 x 48 B = 48000 B exceeds local memory 32768 B", kDevice,
             {1000, 4, true});
  EXPECT_TRUE(CheckVariant(v, small, kShape).empty());  // 3696 B fits 4096
  v.palette = PaletteFormat::kMat4;
  ExpectOnly(v, Constraint::kLocalMemory, "4928 B exceeds local memory 4096 B", small);
}

TEST(Constraints, RejectsLocalStorageInAVertexShader) {
  Variant v;
  v.lang = Lang::kGlslVertex;
  v.wg_size = 0;
  v.storage = PaletteStorage::kLocal;
  ExpectOnly(v, Constraint::kLocalMemory, "vertex shaders have no shared memory");
}

TEST(Constraints, RejectsConstantStorageLargerThanTheConstantBufferOrUniformBlock) {
  Variant v;
  v.storage = PaletteStorage::kConstant;
  ExpectOnly(v, Constraint::kConstantMemory, "exceeds the constant buffer 65536 B", kDevice, {2000, 4, true});
  v.lang = Lang::kGlslCompute;
  ExpectOnly(v, Constraint::kConstantMemory, "exceeds the uniform block limit 16384 B", kDevice, {400, 4, true});
}

TEST(Constraints, RejectsImageStorageWithoutImagesOrBeyondTheTexelLimit) {
  Variant v;
  v.storage = PaletteStorage::kImage;
  DeviceLimits no_images = kDevice;
  no_images.image_support = false;
  ExpectOnly(v, Constraint::kImageSupport, "no image support", no_images);
  DeviceLimits tiny = kDevice;
  tiny.image_buffer_max_texels = 100;
  ExpectOnly(v, Constraint::kImageSize, "231 texels exceed the image buffer limit 100", tiny);
}

TEST(Constraints, RejectsVertexShadersWithoutStorageBlocks) {
  Variant v;
  v.lang = Lang::kGlslVertex;
  v.wg_size = 0;
  DeviceLimits gl = kDevice;
  gl.vertex_shader_storage_blocks = false;
  ExpectOnly(v, Constraint::kStorageBlocks, "no storage blocks in vertex shaders", gl);
}

TEST(Constraints, RejectsIndexFormatsTooSmallForTheJointCount) {
  Variant v;
  v.index = IndexFormat::kU8;
  ExpectOnly(v, Constraint::kIndexRange, "300 joints do not fit (at most 256)", kDevice, {300, 4, true});
  v.index = IndexFormat::kU16;
  EXPECT_TRUE(CheckVariant(v, kDevice, {300, 4, true}).empty());
}

TEST(Constraints, RejectsNormalsWhenTheMeshHasNone) {
  Variant v;
  v.normals = Normals::kNormals;
  ExpectOnly(v, Constraint::kNormalsMissing, "mesh has none", kDevice, {77, 4, false});
}

TEST(Constraints, RejectsTangentsWhenTheMeshHasNoneAndWithFloat3Positions) {
  Variant v;
  v.normals = Normals::kTangents;
  ExpectOnly(v, Constraint::kTangentsMissing, "mesh has none", kDevice, {77, 4, true, 1, false});
  v.position = PositionFormat::kFloat3;
  ExpectOnly(v, Constraint::kTangentsFormat, "float4 position format", kDevice, {77, 4, true, 1, true});
  v.position = PositionFormat::kFloat4;
  EXPECT_TRUE(CheckVariant(v, kDevice, {77, 4, true, 1, true}).empty());
}

TEST(Constraints, DualQuaternionsReadTheirOwnPaletteAndNeedRigidJoints) {
  Variant v;
  v.blend = Blend::kDualQuaternion;
  ExpectOnly(v, Constraint::kBlendPalette, "blend dq reads the dualquat palette", kDevice,
             {77, 4, false, 1, false, true});
  v.palette = PaletteFormat::kDualQuaternion;
  EXPECT_TRUE(CheckVariant(v, kDevice, {77, 4, false, 1, false, true}).empty());
  ExpectOnly(v, Constraint::kJointsNotRigid, "scale, shear or mirror", kDevice, {77, 4, false, 1, false, false});
  v.blend = Blend::kMatrix;
  ExpectOnly(v, Constraint::kBlendPalette, "read by blend dq only", kDevice, {77, 4, false, 1, false, true});
}

// Instanced launches (docs/VARIANTS.md "Instancing"): K palettes live in
// constant or image storage together; a local copy holds one.
TEST(Constraints, RejectsInstancedConstantStorageWhenKPalettesExceedTheLimit) {
  Variant v;
  v.storage = PaletteStorage::kConstant;  // 77 x 48 B = 3696 B per palette
  ExpectOnly(v, Constraint::kConstantMemory, "18 palettes of 77 x 48 B = 66528 B exceeds the constant buffer 65536 B",
             kDevice, {77, 4, true, 18});
  EXPECT_TRUE(CheckVariant(v, kDevice, {77, 4, true, 17}).empty());  // 62832 B
  v.lang = Lang::kGlslCompute;
  ExpectOnly(v, Constraint::kConstantMemory, "5 palettes of 77 x 48 B = 18480 B exceeds the uniform block limit",
             kDevice, {77, 4, true, 5});
}

TEST(Constraints, RejectsInstancedImageStorageBeyondTheTexelLimit) {
  Variant v;
  v.storage = PaletteStorage::kImage;
  DeviceLimits small = kDevice;
  small.image_buffer_max_texels = 1000;
  EXPECT_TRUE(CheckVariant(v, small, {77, 4, true, 4}).empty());  // 924 texels
  ExpectOnly(v, Constraint::kImageSize, "1155 texels exceed the image buffer limit 1000", small, {77, 4, true, 5});
}

TEST(Constraints, InstancedLocalStorageCopiesOnePalettePerWorkGroup) {
  Variant v;
  v.storage = PaletteStorage::kLocal;
  DeviceLimits small = kDevice;
  small.local_memory_bytes = 4096;
  EXPECT_TRUE(CheckVariant(v, small, {77, 4, true, 1000}).empty());  // 3696 B, whatever K
}

TEST(Constraints, RejectsInstanceCountsALaunchCannotHold) {
  Variant v;
  ExpectOnly(v, Constraint::kInstanceCount, "instances 0 below 1", kDevice, {77, 4, true, 0});
  EXPECT_TRUE(CheckVariant(v, kDevice, {77, 4, true, 100000}).empty());  // OpenCL: global size, no small limit
  v.lang = Lang::kCuda;
  ExpectOnly(v, Constraint::kInstanceCount, "100000 instances exceed the launch's instance dimension (grid y) 65535",
             kDevice, {77, 4, true, 100000});
  EXPECT_TRUE(CheckVariant(v, kDevice, {77, 4, true, 65535}).empty());
  v.lang = Lang::kGlslCompute;
  ExpectOnly(v, Constraint::kInstanceCount, "(work-group count y) 65535", kDevice, {77, 4, true, 65536});
  v.lang = Lang::kGlslVertex;
  v.wg_size = 0;
  EXPECT_TRUE(CheckVariant(v, kDevice, {77, 4, true, 100000}).empty());  // instanced draws
}

TEST(Constraints, ReportsEveryBrokenConstraint) {
  Variant v;
  v.influences = 1;
  v.wg_size = 2048;
  v.normals = Normals::kNormals;
  EXPECT_EQ(CheckVariant(v, kDevice, {77, 4, false}).size(), 3u);
}

}  // namespace
}  // namespace skintune::internal
