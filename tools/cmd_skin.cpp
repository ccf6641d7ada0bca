// skintune skin: the CPU reference on a dataset or glTF model, rest pose or
// an animation sampled at a time, written as .obj or skintune's binary format;
// optionally the palette it used (--palette-out) and a check of another
// program's output against it (--check, --variant: the gold on the weights as
// that variant quantises them).
#include <chrono>
#include <cstring>
#include <cmath>
#include <iostream>

#include "generator/packer.h"
#include "generator/variant.h"
#include "base/error.h"
#include "reference/mesh_io.h"
#include "reference/skinning.h"
#include "tools/commands.h"

namespace skintune::internal::tools {

namespace {

struct SkinOptions {
  MeshSource source;
  std::string animation;
  double time = 0.0;
  bool time_given = false;
  std::string out;
  std::string implementation = "gold";
  std::string palette_out;   // raw float32 palette (joints x 16, column-major)
  std::string check;         // a skinned-vertex file to compare with the result
  std::string check_variant; // quantise the weights as this variant does first
  double tolerance = 1e-5;   // largest relative error CompareToGold may report
  std::string blend = "linear";  // "linear" (the kernels' blend) or "dq" (dual quaternions: the gold only)
};

// The gold of `o.blend`.
GoldResult BlendGold(const SkinOptions& o, const SkinnedMesh& mesh, const std::vector<glm::mat4>& palette,
                     bool normals = false, bool tangents = false) {
  return o.blend == "dq" ? SkinGoldDualQuaternion(mesh, palette, normals, tangents)
                         : SkinGold(mesh, palette, normals, tangents);
}

void WritePalette(const std::string& path, const std::vector<glm::mat4>& palette) {
  CheckPaletteFinite(palette, path);
  std::string bytes(palette.size() * sizeof(glm::mat4), '\0');
  for (std::size_t j = 0; j < palette.size(); ++j)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) {
        const float value = palette[j][c][r];
        std::memcpy(&bytes[(j * 16 + c * 4 + r) * sizeof(float)], &value, sizeof value);
      }
  WriteFileAtomically(path, bytes);
}

// Exit 0 when `o.check`'s positions agree with the gold of `mesh` (its
// weights quantised as `o.check_variant` does, when given) within tolerance.
// `weighted`: the mesh with its morph targets at the frame's weights, not
// applied: a variant that applies them (with half offsets: rounded as it
// stores them) is checked against the gold of their float64 morph.
int Check(const SkinOptions& o, const SkinnedMesh& mesh, const SkinnedMesh& weighted,
          const std::vector<glm::mat4>& palette) {
  const SkinnedVertices theirs = ReadSkinnedVertices(o.check);
  if (theirs.positions.size() != mesh.vertex_count())
    throw Error(o.check + ": " + std::to_string(theirs.positions.size()) + " vertices, the mesh has " +
                std::to_string(mesh.vertex_count()));
  std::string what = "the gold";
  SkinnedMesh reference = mesh;
  if (!o.check_variant.empty()) {
    const Variant variant = ParseVariantKey(o.check_variant);
    const bool morph = SkinsMorph(variant) && weighted.has_morph();
    reference = QuantisedMesh(morph ? weighted : mesh, variant);
    what += " with " + std::string(Name(variant.weight)) + " weights" +
            (morph ? std::string(" and ") + Name(variant.morph) + " morph targets" : "");
  }
  const GoldResult gold = BlendGold(o, reference, palette);
  const GoldComparison c = CompareToGold(gold.positions, theirs.positions);
  const bool ok = c.non_finite == 0 && c.max_relative <= o.tolerance;
  std::cout << o.check << (ok ? " agrees with " : " DISAGREES with ") << what << ": largest relative error "
            << c.max_relative << " at vertex " << c.worst_vertex << " (absolute " << c.max_absolute << ", "
            << c.non_finite << " non-finite; tolerance " << o.tolerance << ")\n";
  if (!o.check_variant.empty()) {
    // What the file is worth against the unquantised source (docs/TUNING.md
    // "Precision"): shown, never a failure: the quantisation is the variant's choice.
    const double diagonal = BoundingBoxDiagonal(mesh.positions);
    const GoldResult source_gold = BlendGold(o, mesh, palette);
    const GoldComparison source = CompareToGold(source_gold.positions, theirs.positions);
    const double quantisation = MaxDistance(gold.positions, source_gold.positions);
    std::cout << o.check << " against the unquantised source: largest error " << source.max_absolute
              << " (mesh units), " << (diagonal > 0.0 ? source.max_absolute / diagonal : 0.0)
              << " of the bounding-box diagonal " << diagonal << "; the "
              << Name(ParseVariantKey(o.check_variant).weight) << " weights"
              << (MorphHalf(ParseVariantKey(o.check_variant)) ? " and half morph offsets" : "") << " alone cost "
              << (diagonal > 0.0 ? quantisation / diagonal : 0.0) << " of it\n";
  }
  if (!ok)
    throw Error(o.check + ": vertex " + std::to_string(c.worst_vertex) + " is off by " +
                std::to_string(c.max_relative) + " relative (tolerance " + std::to_string(o.tolerance) + ")" +
                (c.non_finite ? ", " + std::to_string(c.non_finite) + " non-finite vertices" : ""));
  return 0;
}

std::vector<glm::vec3> ToFloat(const std::vector<glm::dvec3>& values) {
  return std::vector<glm::vec3>(values.begin(), values.end());
}

// Bytes per vertex skinning needs beyond the mesh: the float64 reference
// (positions and normals), the float32 output, and for --impl fast its
// structure-of-arrays copy of the mesh (at most as large as the mesh: 40 B).
std::uint64_t SkinWorkBytesPerVertex(const SkinOptions& o) {
  const std::uint64_t sides = (o.source.normals ? 2 : 1) + (o.source.tangents ? 2 : 0);  // a tangent ~ 1.3 normals
  return sides * (24 + 12) + (o.implementation == "fast" ? 40 + 12 * sides : 0) + (o.check.empty() ? 0 : 24 + 12);
}

int RunSkin(const SkinOptions& o) {
  if (!std::isfinite(o.time)) throw Error("--time must be a finite number of seconds");
  if (o.blend == "dq" && o.implementation != "gold")
    throw UsageError("--blend dq: only --impl gold skins with dual quaternions yet");
  if (o.source.tangents && o.implementation == "fast")
    throw UsageError("--tangents: --impl fast skins no tangents yet (use gold or serial)");
  if (o.source.tangents && IsObjPath(o.out))
    throw UsageError("--tangents: " + o.out + ": a .obj file holds no tangents (write a .stv)");
  // Every output can be written, before any work.
  if (!o.out.empty()) CheckWritable(o.out);
  if (!o.palette_out.empty()) CheckWritable(o.palette_out);
  const SkinnedAsset asset = LoadAsset(o.source, SkinWorkBytesPerVertex(o), "skinning");
  int clip = -1;
  if (!o.animation.empty()) {
    clip = asset.FindAnimation(o.animation);
  } else if (o.time_given) {
    if (asset.animations.empty()) throw Error(asset.source + ": --time given but it has no animations");
    clip = 0;
  }
  const double t = o.time_given || clip < 0 ? o.time : asset.animations[clip].start;
  const std::vector<glm::mat4> palette = asset.PaletteAt(clip, t);
  // Morph targets first, at the clip's weights (the defaults at the rest pose), then the skin.
  const SkinnedMesh morphed = asset.mesh.morph.count() > 0 ? asset.MeshAt(clip, t) : SkinnedMesh{};
  const SkinnedMesh& mesh = asset.mesh.morph.count() > 0 ? morphed : asset.mesh;
  const std::size_t n = mesh.vertex_count();
  std::vector<glm::vec3> positions(n), normals(o.source.normals && mesh.has_normals() ? n : 0);
  std::vector<glm::vec4> tangents(o.source.tangents && mesh.has_tangents() ? n : 0);
  const auto start = std::chrono::steady_clock::now();
  if (o.implementation == "gold") {
    const GoldResult gold = BlendGold(o, mesh, palette, !normals.empty(), !tangents.empty());
    positions = ToFloat(gold.positions);
    normals = ToFloat(gold.normals);
    tangents.assign(gold.tangents.begin(), gold.tangents.end());
  } else if (o.implementation == "serial") {
    ThrowIfInvalid(mesh, asset.source);
    SkinSerial(mesh, palette, positions, normals, tangents);
  } else {
    FastSkinner(mesh).Run(palette, positions, normals);
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  // A NaN or infinite output is an error naming its vertex, never a file.
  CheckSkinnedOutput(mesh, positions, normals,
                     asset.source + ": " + (clip < 0 ? std::string("rest pose") : "t=" + std::to_string(t) + " s of animation " + std::to_string(clip)));
  if (!o.out.empty()) WriteSkinnedVertices(o.out, positions, normals, tangents);
  if (!o.palette_out.empty()) WritePalette(o.palette_out, palette);
  std::cout << "skinned " << n << " vertices (" << mesh.influences << " influences, " << mesh.joint_count
            << " joints) of " << asset.source << " at "
            << (clip < 0 ? std::string("rest pose") : "t=" + std::to_string(t) + " s of animation " +
                                                          std::to_string(clip))
            << " with " << o.implementation << (o.blend == "dq" ? " (dual quaternions)" : "") << " in " << ms << " ms"
            << (o.out.empty() ? "" : " -> " + o.out) << "\n";
  if (asset.mesh.morph.count() > 0) {
    std::cout << "morph targets applied first: " << asset.mesh.morph.count() << ", weights";
    for (const double w : asset.MorphWeightsAt(clip, t)) std::cout << " " << w;
    std::cout << "\n";
  }
  return o.check.empty() ? 0 : Check(o, mesh, asset.MeshWithMorphWeightsAt(clip, t), palette);
}

}  // namespace

Command RegisterSkin(CLI::App& app) {
  auto o = std::make_shared<SkinOptions>();
  auto* sub = app.add_subcommand("skin", "skin a dataset or glTF model on the CPU and write the positions");
  AddMeshSourceOptions(*sub, o->source);
  sub->add_option("--animation", o->animation, "animation name or index (default: rest pose)");
  sub->add_option("--time", o->time, "time in seconds within the animation (default: its start)")
      ->check(CLI::NonNegativeNumber)
      ->each([o](const std::string&) { o->time_given = true; });
  // At least one output: a usage error (exit 2) otherwise.
  auto* outputs = sub->add_option_group("outputs", "what to write or check (at least one)");
  outputs->add_option("--out", o->out, "output file: .obj (v x y z lines) or skintune binary (docs/FORMATS.md)")
      ->check(NonEmptyPath());
  outputs->add_option("--palette-out", o->palette_out,
                      "also write the palette used: joints x 16 float32, column-major 4x4 (docs/FORMATS.md)")
      ->check(NonEmptyPath());
  CLI::Option* check =
      outputs->add_option("--check", o->check,
                          "compare this skinned-vertex file (.obj or binary, e.g. your kernel's output) with the gold; "
                          "exit 1 naming the worst vertex when it is off by more than --tolerance")
          ->check(NonEmptyPath());
  outputs->require_option(1, 3);
  sub->add_option("--variant", o->check_variant,
                  "with --check: quantise the weights as this variant does (e.g. unorm8) before the gold")
      ->needs(check);
  sub->add_option("--tolerance", o->tolerance, "with --check: largest relative error (default 1e-5)")
      ->check(CLI::PositiveNumber)
      ->needs(check);
  sub->add_flag("--normals", o->source.normals, "also skin and write normals (when the mesh has them)");
  sub->add_flag("--tangents", o->source.tangents,
                "also skin and write tangents (glTF TANGENT, every primitive; binary output; --impl gold or serial)")
      ->needs("--mesh");
  sub->add_option("--blend", o->blend,
                  "linear (linear blend skinning, default) or dq (dual quaternions, scale and shear by the two-phase "
                  "method; --impl gold)")
      ->check(CLI::IsMember({"linear", "dq"}));
  sub->add_option("--impl", o->implementation, "CPU implementation: gold (float64), serial (paper baseline), fast")
      ->check(CLI::IsMember({"gold", "serial", "fast"}));
  return {sub, [o] {
            if (o->source.dataset.empty() && o->source.mesh_file.empty())
              throw Error("skin: give --dataset NAME or --mesh FILE");
            return RunSkin(*o);
          }};
}

}  // namespace skintune::internal::tools
