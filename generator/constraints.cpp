#include "generator/constraints.h"

#include <algorithm>
#include <string>

#include "generator/axes.h"

namespace skintune::internal {

namespace {

std::string B(std::uint64_t bytes) { return std::to_string(bytes) + " B"; }

void CheckShape(const Variant& v, const ProblemShape& shape, std::vector<Violation>& out) {
  if (v.influences < 1 || v.influences > 8) {
    out.push_back({Constraint::kInfluencesRange, "influences " + std::to_string(v.influences) + " outside 1..8"});
  } else if (v.influences < shape.max_influences) {
    out.push_back({Constraint::kInfluencesTooFew, "influences " + std::to_string(v.influences) +
                                                      " below the mesh's largest per-vertex count " +
                                                      std::to_string(shape.max_influences)});
  }
  const std::uint64_t index_limit = v.index == IndexFormat::kU8 ? 256u : v.index == IndexFormat::kU16 ? 65536u : 0u;
  if (index_limit != 0 && static_cast<std::uint64_t>(shape.joints) > index_limit) {
    out.push_back({Constraint::kIndexRange, std::string("index ") + Name(v.index) + ": " +
                                                std::to_string(shape.joints) + " joints do not fit (at most " +
                                                std::to_string(index_limit) + ")"});
  }
  if (SkinsNormals(v) && !shape.has_normals) {
    out.push_back({Constraint::kNormalsMissing, "normals requested but the mesh has none"});
  }
  if (SkinsTangents(v) && !shape.has_tangents) {
    out.push_back({Constraint::kTangentsMissing, "tangents requested but the mesh has none"});
  }
  if ((v.blend == Blend::kDualQuaternion) != (v.palette == PaletteFormat::kDualQuaternion)) {
    out.push_back({Constraint::kBlendPalette, v.blend == Blend::kDualQuaternion
                                                  ? "blend dq reads the dualquat palette (2 rows a joint), not " +
                                                        std::string(Name(v.palette))
                                                  : "the dualquat palette is read by blend dq only"});
  }
  if (v.blend == Blend::kDualQuaternion && !shape.rigid_joints) {
    out.push_back({Constraint::kJointsNotRigid,
                   "blend dq: the mesh's palettes scale, shear or mirror; dual quaternions hold rotations and "
                   "translations only (use matrix blending, or a rigid animation)"});
  }
  if (SkinsMorph(v) && shape.morph_targets == 0) {
    out.push_back({Constraint::kMorphMissing,
                   std::string("morph ") + Name(v.morph) + " requested but the mesh has no morph targets"});
  }
  if (!SkinsMorph(v) && shape.morph_moves) {
    out.push_back({Constraint::kMorphIgnored,
                   "morph none: the mesh's " + std::to_string(shape.morph_targets) +
                       " morph targets move its vertices, and a variant without them would skin the wrong shape"});
  }
  if (AnimatesOnDevice(v) && !shape.animated) {
    out.push_back({Constraint::kAnimationMissing, std::string("animation ") + Name(v.animation) +
                                                      ": the scene's palettes come from the host (an animated scene's key ends in -anim)"});
  }
  if (!AnimatesOnDevice(v) && shape.animated) {
    out.push_back({Constraint::kAnimationIgnored,
                   "animation host: the scene's palettes are made on the device from its model's clips"});
  }
  if (AnimatesOnDevice(v) && v.palette == PaletteFormat::kDualQuaternion) {
    out.push_back({Constraint::kAnimationPalette,
                   std::string("animation ") + Name(v.animation) + ": the palette kernel writes mat3x4 or mat4 palettes, not dualquat"});
  }
  if (AnimatesOnDevice(v) && shape.morph_targets > 0) {
    out.push_back({Constraint::kAnimationMorph,
                   "an animated scene with morph targets: the tuner animates scenes without them (a Skinner animates "
                   "crowds with morph targets: docs/ANIMATION.md)"});
  }
  if (FusesPalette(v.animation) && v.storage != PaletteStorage::kLocal) {
    out.push_back({Constraint::kAnimationFused, std::string("animation ") + Name(v.animation) +
                                                    ": each work-group makes its palette into its local copy (storage local, not " +
                                                    Name(v.storage) + ")"});
  }
  if (PacksNormals(v) && !SkinsNormals(v)) {
    out.push_back({Constraint::kNormalFormatUnused,
                   std::string("normal_format ") + Name(v.normal_format) + " packs normals, but the variant skins none"});
  }
  if (SkinsTangents(v) && v.position != PositionFormat::kFloat4) {
    out.push_back({Constraint::kTangentsFormat,
                   "tangents need the float4 position format (tangents are float4, and every output has one stride)"});
  }
}

void CheckGeometry(const Variant& v, const DeviceLimits& device, std::vector<Violation>& out) {
  const bool valid_vpi = v.vertices_per_item == 1 || v.vertices_per_item == 2 || v.vertices_per_item == 4 ||
                         v.vertices_per_item == 8;
  if (!valid_vpi) {
    out.push_back({Constraint::kVerticesPerItem,
                   "vertices_per_item " + std::to_string(v.vertices_per_item) + " not 1, 2, 4 or 8"});
  }
  if (v.vertices_per_item == 1 && v.assignment == Assignment::kStrided) {
    out.push_back({Constraint::kAssignmentRedundant,
                   "strided assignment with 1 vertex per item is the contiguous kernel (use v1c)"});
  }
  if (!HasWorkGroups(v.lang)) {
    if (v.wg_size != 0 || v.vertices_per_item != 1) {
      out.push_back({Constraint::kNoWorkGroups,
                     v.lang == Lang::kCpu
                         ? "cpu has no work-groups (its threads and chunks are chosen per machine): needs v1c and wg0"
                         : "glsl-vertex runs one vertex per invocation without work-groups: needs v1c and wg0"});
    }
    return;
  }
  if (v.wg_size < 32 || v.wg_size > 1024 || v.wg_size % 32 != 0) {
    out.push_back({Constraint::kWgSizeRange, "wg_size " + std::to_string(v.wg_size) +
                                                 " not a multiple of 32 in 32..1024"});
  } else if (static_cast<std::size_t>(v.wg_size) > device.max_wg_size) {
    out.push_back({Constraint::kWgSizeDevice, "wg_size " + std::to_string(v.wg_size) +
                                                  " above the device's limit " + std::to_string(device.max_wg_size)});
  }
}

void CheckInstances(const Variant& v, const DeviceLimits& device, const ProblemShape& shape,
                    std::vector<Violation>& out) {
  const bool grid_limited = v.lang == Lang::kCuda || v.lang == Lang::kGlslCompute || v.lang == Lang::kVulkan;
  if (shape.instances < 1) {
    out.push_back({Constraint::kInstanceCount, "instances " + std::to_string(shape.instances) + " below 1"});
  } else if (grid_limited && static_cast<std::uint64_t>(shape.instances) > device.max_grid_y) {
    out.push_back({Constraint::kInstanceCount,
                   std::to_string(shape.instances) + " instances exceed the launch's instance dimension " +
                       (v.lang == Lang::kCuda ? "(grid y) " : "(work-group count y) ") +
                       std::to_string(device.max_grid_y)});
  }
}

void CheckStorage(const Variant& v, const DeviceLimits& device, const ProblemShape& shape,
                  std::vector<Violation>& out) {
  // Constant and image storage hold every instance's palette; a local copy one.
  const std::uint64_t bytes = PaletteBytes(v, shape.joints);
  const std::uint64_t instances = static_cast<std::uint64_t>(std::max(shape.instances, 1));
  const std::string palette = "palette " + std::to_string(shape.joints) + " x " +
                              std::to_string(BytesOf(v.palette)) + " B = " + B(bytes);
  const std::string palettes =
      instances == 1 ? palette
                     : std::to_string(instances) + " palettes of " + std::to_string(shape.joints) + " x " +
                           std::to_string(BytesOf(v.palette)) + " B = " + B(instances * bytes);
  const bool glsl = IsGlslText(v.lang);  // a uniform block (Vulkan: maxUniformBufferRange)
  switch (v.storage) {
    case PaletteStorage::kConstant: {
      const std::uint64_t limit = glsl ? device.uniform_block_bytes : device.constant_memory_bytes;
      if (instances * bytes > limit) {
        out.push_back({Constraint::kConstantMemory, "storage constant: " + palettes + " exceeds the " +
                                                        (glsl ? "uniform block limit " : "constant buffer ") +
                                                        B(limit)});
      }
      break;
    }
    case PaletteStorage::kLocal:
      if (v.lang == Lang::kGlslVertex) {
        out.push_back({Constraint::kLocalMemory, "storage local: vertex shaders have no shared memory"});
      } else if (bytes > device.local_memory_bytes) {
        out.push_back({Constraint::kLocalMemory,
                       "storage local: " + palette + " exceeds local memory " + B(device.local_memory_bytes)});
      }
      break;
    case PaletteStorage::kImage: {
      const std::uint64_t texels = instances * bytes / 16;
      if (!device.image_support) {
        out.push_back({Constraint::kImageSupport, "storage image: the device has no image support"});
      } else if (texels > device.image_buffer_max_texels) {
        out.push_back({Constraint::kImageSize, "storage image: " + std::to_string(texels) +
                                                   " texels exceed the image buffer limit " +
                                                   std::to_string(device.image_buffer_max_texels)});
      }
      break;
    }
    case PaletteStorage::kGlobal:
      break;
  }
  if (v.lang == Lang::kGlslVertex && !device.vertex_shader_storage_blocks) {
    out.push_back({Constraint::kStorageBlocks, "glsl-vertex: the GL context allows no storage blocks in vertex shaders"});
  }
}

}  // namespace

const char* Name(Constraint c) {
  switch (c) {
    case Constraint::kInfluencesRange: return "influences_range";
    case Constraint::kInfluencesTooFew: return "influences_too_few";
    case Constraint::kVerticesPerItem: return "vertices_per_item";
    case Constraint::kAssignmentRedundant: return "assignment_redundant";
    case Constraint::kWgSizeRange: return "wg_size_range";
    case Constraint::kWgSizeDevice: return "wg_size_device";
    case Constraint::kNoWorkGroups: return "no_work_groups";
    case Constraint::kLocalMemory: return "local_memory";
    case Constraint::kConstantMemory: return "constant_memory";
    case Constraint::kImageSupport: return "image_support";
    case Constraint::kImageSize: return "image_size";
    case Constraint::kStorageBlocks: return "storage_blocks";
    case Constraint::kIndexRange: return "index_range";
    case Constraint::kNormalsMissing: return "normals_missing";
    case Constraint::kTangentsMissing: return "tangents_missing";
    case Constraint::kTangentsFormat: return "tangents_format";
    case Constraint::kInstanceCount: return "instance_count";
    case Constraint::kBlendPalette: return "blend_palette";
    case Constraint::kJointsNotRigid: return "joints_not_rigid";
    case Constraint::kMorphMissing: return "morph_missing";
    case Constraint::kMorphIgnored: return "morph_ignored";
    case Constraint::kNormalFormatUnused: return "normal_format_unused";
    case Constraint::kAnimationMissing: return "animation_missing";
    case Constraint::kAnimationIgnored: return "animation_ignored";
    case Constraint::kAnimationPalette: return "animation_palette";
    case Constraint::kAnimationMorph: return "animation_morph";
    case Constraint::kAnimationFused: return "animation_fused";
  }
  return "unknown";
}

ProblemShape WithMorphOf(ProblemShape shape, const MorphTargets& morph) {
  shape.morph_targets = static_cast<int>(morph.count());
  shape.morph_moves = morph.count() > 0;  // their weights may change any frame
  return shape;
}

std::uint64_t PaletteBytes(const Variant& v, int joints) {
  return static_cast<std::uint64_t>(joints) * BytesOf(v.palette);
}

std::vector<Violation> CheckVariant(const Variant& v, const DeviceLimits& device, const ProblemShape& shape) {
  std::vector<Violation> out;
  CheckShape(v, shape, out);
  CheckGeometry(v, device, out);
  CheckStorage(v, device, shape, out);
  CheckInstances(v, device, shape, out);
  return out;
}

}  // namespace skintune::internal
