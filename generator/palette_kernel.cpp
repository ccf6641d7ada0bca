#include "generator/palette_kernel.h"

#include <algorithm>
#include <optional>
#include <string>

#include "base/error.h"
#include "generator/languages.h"

namespace skintune::internal {

std::span<const std::uint8_t> AnimationBufferBytes(const AnimationView& animation, std::string_view name) {
  const auto bytes = [](auto span) { return std::as_bytes(span); };
  const std::span<const std::byte> found = name == kAnimInputs[0]  ? bytes(animation.nodes)
                                           : name == kAnimInputs[1] ? bytes(animation.channels)
                                           : name == kAnimInputs[2] ? bytes(animation.times)
                                           : name == kAnimInputs[3] ? bytes(animation.values)
                                           : name == kAnimInputs[4] ? bytes(animation.joints)
                                           : name == kAnimClips     ? bytes(animation.clip_ranges)
                                           : name == kAnimFrames    ? bytes(animation.frames)
                                           : name == kAnimSteady    ? bytes(animation.steady)
                                                                    : std::span<const std::byte>();
  return {reinterpret_cast<const std::uint8_t*>(found.data()), found.size()};
}

namespace {

// A buffer argument of elements of `element` bytes, one after another.
KernelArgument BufferArgument(const char* name, const char* format, std::size_t element, ArgumentDirection direction,
                              const char* indexing = "") {
  return {name, format, element, element, indexing, direction, ArgumentKind::kBuffer};
}

}  // namespace

int AnimJumpRounds(std::span<const AnimNodeRecord> nodes) {
  std::size_t deepest = 0;
  for (std::size_t n = 0; n < nodes.size(); ++n) {
    std::size_t depth = 0;  // ancestors, at most every other node (a cycle, refused elsewhere, stops here)
    for (std::int32_t p = nodes[n].parent; p >= 0 && static_cast<std::size_t>(p) < nodes.size() && depth < nodes.size();
         p = nodes[static_cast<std::size_t>(p)].parent)
      ++depth;
    deepest = std::max(deepest, depth);
  }
  int rounds = 0;
  while ((std::size_t{1} << rounds) <= deepest) ++rounds;
  return rounds;
}

int BakedDefine(const AnimationView& animation) {
  if (!animation.baked()) return 0;
  if (animation.baked_local) return animation.baked_rows == kBakedRowsLocalScaled ? 4 : 3;
  return animation.baked_rows == kBakedRowsAffine ? 2 : 1;
}

BakedForm BakedFormOf(long long define) {
  if (define < 0 || define > 4) throw Error("palette kernel: ANIM_BAKED " + std::to_string(define) + " (0 to 4)");
  const std::uint32_t rows[] = {0, kBakedRowsSimilar, kBakedRowsAffine, kBakedRowsSimilar, kBakedRowsLocalScaled};
  return {define != 0, define >= 3, rows[define]};
}

PaletteKernel EmitPalette(Lang lang, const AnimationView& animation, int palette_rows) {
  if (palette_rows != 3 && palette_rows != 4)
    throw Error("palette kernel: " + std::to_string(palette_rows) + " rows per joint (3 or 4)");
  if (animation.nodes.empty() || animation.joints.empty())
    throw Error("palette kernel: an animation of " + std::to_string(animation.nodes.size()) + " nodes and " +
                std::to_string(animation.joints.size()) + " joints (at least one of each)");
  if (animation.nodes.size() > kAnimMaxNodes)
    throw Error("palette kernel: " + std::to_string(animation.nodes.size()) + " nodes, more than the " +
                std::to_string(kAnimMaxNodes) + " the kernels hold in local memory");
  const Language& language = LanguageOf(lang);
  PaletteKernel out;
  Variant& variant = out.variant;
  variant.lang = language.copy_lang;
  variant.influences = 1;
  variant.storage = PaletteStorage::kGlobal;
  const bool baked = animation.baked(), local = baked && animation.baked_local;
  const int group = local   ? AnimBakedGroupFor(animation.nodes.size())
                    : baked ? AnimBakedGroupFor(animation.joints.size())
                            : AnimGroupFor(animation.nodes.size());
  variant.wg_size = group;
  variant.normals = Normals::kNone;

  KernelSource& k = out.kernel;
  k.lang = variant.lang;
  k.entry_point = IsGlslText(variant.lang) ? "main" : "skintune_palette";
  k.influences = 1;
  k.joints = static_cast<int>(animation.joints.size());
  k.instanced = true;
  k.defines = {{"ANIM_NODE_COUNT", static_cast<long long>(animation.nodes.size())},
               {"ANIM_JOINT_COUNT", static_cast<long long>(animation.joints.size())},
               {"ANIM_CLIP_COUNT", static_cast<long long>(animation.clip_count)},
               {"ANIM_PALETTE_ROWS", palette_rows},
               {"ANIM_GROUP", group},
               {"ANIM_BAKED", BakedDefine(animation)},
               {"ANIM_JUMPS", AnimJumpRounds(animation.nodes)},
               {"ANIM_STEADY", local ? static_cast<long long>(animation.steady_rows) : 0}};
  k.arguments = {BufferArgument(kAnimInputs[0], "record", sizeof(AnimNodeRecord), ArgumentDirection::kIn),
                 BufferArgument(kAnimInputs[1], "record", sizeof(AnimChannelHeader), ArgumentDirection::kIn),
                 BufferArgument(kAnimInputs[2], "f32", 4, ArgumentDirection::kIn),
                 BufferArgument(kAnimInputs[3], "float4", 16, ArgumentDirection::kIn),
                 BufferArgument(kAnimInputs[4], "record", sizeof(AnimJointRecord), ArgumentDirection::kIn),
                 BufferArgument(kAnimInputs[5], "record", sizeof(AnimInstance), ArgumentDirection::kIn),
                 BufferArgument(kAnimOutput, "float4 rows", 16 * static_cast<std::size_t>(palette_rows),
                                ArgumentDirection::kOut),
                 BufferArgument(kAnimClips, "float4", 16, ArgumentDirection::kIn),
                 BufferArgument(kAnimStates, "record", sizeof(AnimInstance), ArgumentDirection::kOut),
                 {kAnimDelta, "f32", 4, 0, "", ArgumentDirection::kIn, ArgumentKind::kScalar},
                 {kAnimFresh, "u32", 4, 0, "", ArgumentDirection::kIn, ArgumentKind::kScalar}};
  const KernelArgument frames =
      BufferArgument(kAnimFrames, "float4 records", 16 * std::size_t{animation.baked_rows}, ArgumentDirection::kIn);
  if (local) {  // frames in place of channels, times and values: nodes, frames, [steady,] joints, ...
    k.arguments.erase(k.arguments.begin() + 1, k.arguments.begin() + 4);
    k.arguments.insert(k.arguments.begin() + 1, frames);
    if (!animation.steady.empty())
      k.arguments.insert(k.arguments.begin() + 2,
                         BufferArgument(kAnimSteady, "float4 records", 16 * std::size_t{animation.steady_rows},
                                        ArgumentDirection::kIn));
  } else if (baked) {  // frames in place of the five buffers of sampled clips
    k.arguments.erase(k.arguments.begin(), k.arguments.begin() + 5);
    k.arguments.insert(k.arguments.begin(), frames);
  }
  for (KernelArgument& a : k.arguments)
    if (a.name == kAnimOutput) a.indexing = "(i*J+j)*R+r";
  k.launch.vertices_per_item = 1;
  k.launch.wg_size = group;
  k.launch.instanced = true;
  k.launch.rule = "one work-group of " + std::to_string(group) + " per instance: " + language.instance_rule;

  k.text = SpecialisedText(language.palette_template,
                           "the palette kernel of " + std::to_string(animation.clip_count) +
                               (!animation.steady.empty() ? " clips baked in local space, with palette records"
                                : local                     ? " clips baked in local space"
                                : baked                     ? " baked clips"
                                                            : " clips"),
                           k.defines);
  k.source_hash = SourceHash(k.text);
  return out;
}

KernelSource EmitFused(const KernelSource& skin, const AnimationView& animation) {
  const auto define = [&](const char* name) -> std::optional<long long> {
    for (const auto& [key, value] : skin.defines)
      if (key == name) return value;
    return std::nullopt;
  };
  const std::string what = "fused skin kernel";
  if (!animation.baked())
    throw Error(what + ": the animation is sampled clips; the skin launch makes palettes from baked records only "
                       "(BakeSpace kPalette, kLocal or kHybrid)");
  const bool local = animation.baked_local;
  if (local && animation.nodes.size() > kAnimMaxNodes)
    throw Error(what + ": " + std::to_string(animation.nodes.size()) + " nodes, more than the " +
                std::to_string(kAnimMaxNodes) + " a work-group holds in local memory");
  if (define("STORAGE") != 1)
    throw Error(what + ": the skin kernel's storage is not local (STORAGE 1): each work-group makes its palette "
                       "into its local copy");
  if (define("BLEND") == 2) throw Error(what + ": the records make matrices, the skin kernel blends dual quaternions");
  if (skin.joints != static_cast<int>(animation.joints.size()))
    throw Error(what + ": the skin kernel's palette has " + std::to_string(skin.joints) + " joints, the animation " +
                std::to_string(animation.joints.size()));
  if (define("ANIM_FUSED").value_or(0) != 0) throw Error(what + ": the kernel is fused already");
  const std::optional<long long> group = define("WG_SIZE");
  if (!group || *group < 1) throw Error(what + ": the skin kernel has no work-group size (WG_SIZE)");
  KernelSource out = skin;
  const auto palette = std::find_if(out.arguments.begin(), out.arguments.end(),
                                    [](const KernelArgument& a) { return a.name == "palette"; });
  if (palette == out.arguments.end()) throw Error(what + ": the skin kernel takes no palette");
  const auto in = ArgumentDirection::kIn;
  // templates/anim_records.clh ANIM_RECORDS_PARAMS: [nodes,] frames, [steady,] [joints,] then instances, clips.
  std::vector<KernelArgument> records;
  if (local) records.push_back(BufferArgument(kAnimInputs[0], "record", sizeof(AnimNodeRecord), in));
  records.push_back(BufferArgument(kAnimFrames, "float4 records", 16 * std::size_t{animation.baked_rows}, in));
  if (local && !animation.steady.empty())
    records.push_back(BufferArgument(kAnimSteady, "float4 records", 16 * std::size_t{animation.steady_rows}, in));
  if (local) records.push_back(BufferArgument(kAnimInputs[4], "record", sizeof(AnimJointRecord), in));
  records.push_back(BufferArgument(kAnimInputs[5], "record", sizeof(AnimInstance), in, skin.instanced ? "i" : "0"));
  records.push_back(BufferArgument(kAnimClips, "float4", 16, in));
  const auto at = out.arguments.erase(palette);
  out.arguments.insert(at, records.begin(), records.end());
  out.arguments.push_back({kAnimElapsed, "f32", 4, 0, "", ArgumentDirection::kIn, ArgumentKind::kScalar});

  // The skin's defines but GLSL's bindings, then the animation's; the bindings again from the new arguments.
  out.defines.clear();
  for (const auto& d : skin.defines)
    if (!d.first.starts_with("BINDING_")) out.defines.push_back(d);
  out.defines.insert(out.defines.end(), {{"ANIM_FUSED", 1},
                                         {"ANIM_BAKED", BakedDefine(animation)},
                                         {"ANIM_JOINT_COUNT", static_cast<long long>(animation.joints.size())},
                                         {"ANIM_CLIP_COUNT", static_cast<long long>(animation.clip_count)},
                                         {"ANIM_GROUP", *group}});
  if (local)
    out.defines.insert(out.defines.end(), {{"ANIM_NODE_COUNT", static_cast<long long>(animation.nodes.size())},
                                           {"ANIM_JUMPS", AnimJumpRounds(animation.nodes)},
                                           {"ANIM_STEADY", static_cast<long long>(animation.steady.empty() ? 0 : animation.steady_rows)}});
  if (IsGlslText(out.lang)) {
    const auto bindings = BindingDefines(out.lang, out.arguments);
    out.defines.insert(out.defines.end(), bindings.begin(), bindings.end());
  }
  out.text = SpecialisedText(LanguageOf(out.lang).kernel_template,
                             std::string("a skin kernel that makes its palette from the ") +
                                 (!local                      ? "palette records"
                                  : animation.steady.empty() ? "local records"
                                                             : "hybrid records") +
                                 " of " + std::to_string(animation.clip_count) + " clips",
                             out.defines);
  out.source_hash = SourceHash(out.text);
  return out;
}

}  // namespace skintune::internal
