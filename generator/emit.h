// skintune: a variant -> kernel source plus its machine-readable interface.
//
// The source is the language's template (templates/, embedded into the
// binary at build time) with the preludes it #includes expanded and one
// `#define` per parameter prepended, as in CLBlast: every template compiles
// alone with default parameters, and the generator only specialises it. The
// interface (argument list in the order of docs/VARIANTS.md, element formats,
// strides, launch geometry) is data, so a program can bind the kernel from the
// sidecar JSON without reading skintune.
//
// A language whose template is not embedded yet throws "not implemented yet".
// GLSL templates start with #version; the defines go after it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iterator>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/variant.h"

namespace skintune::internal {

// Part of every measurement's cache key: a change of what the kernels compute
// (or of the data sets they are verified on) makes earlier records unusable.
// 0.2.0: normals by the normal matrix (sign(det A) cofactor(A)) instead of the
// blended matrix's upper 3x3, and the synthetic rigs' joints scale.
inline constexpr const char* kGeneratorVersion = "0.2.0";

// The kernel's outputs, in argument order: positions, then normals and
// tangents where the variant skins them. Runners, the Skinner and the tuner
// iterate this list.
enum class Output { kPositions, kNormals, kTangents };
struct OutputSpec {
  Output output;
  const char* argument;  // the kernel argument ("out_normals")
  const char* varying;   // glsl-vertex's captured output ("out_normal")
  const char* what;      // in messages ("normals")
};
inline constexpr OutputSpec kOutputs[] = {
    {Output::kPositions, "out_positions", "out_position", "positions"},
    {Output::kNormals, "out_normals", "out_normal", "normals"},
    {Output::kTangents, "out_tangents", "out_tangent", "tangents"},
};
inline constexpr std::size_t kOutputCount = std::size(kOutputs);
constexpr const OutputSpec& SpecOf(Output o) { return kOutputs[static_cast<std::size_t>(o)]; }
// Whether `v` writes output `o`.
constexpr bool Writes(const Variant& v, Output o) {
  return o == Output::kPositions || (o == Output::kNormals ? SkinsNormals(v) : SkinsTangents(v));
}
// Bytes per vertex of output `o`: positions in the position format (16 or
// 12); normals likewise, or one 32-bit word where the variant packs them
// (normal_format); tangents 16 (x y z w floats), or one word packed.
std::size_t OutputStrideBytes(const Variant& v, Output o);
// The output whose kernel argument is `argument`, or null.
const OutputSpec* OutputOfArgument(std::string_view argument);

// The argument holding a frame's morph weights (the runner binds it per
// palette slot, as the palette).
inline constexpr const char* kMorphWeightsArgument = "morph_weights";

enum class ArgumentKind { kScalar, kBuffer, kImage };
enum class ArgumentDirection { kIn, kOut };
const char* Name(ArgumentKind);
const char* Name(ArgumentDirection);

struct KernelArgument {
  std::string name;          // "n", "first", "vertex_count" (instanced), "records", "positions", "indices",
                             // "weights", "normals", "palette", "out_positions", "out_normals"
  std::string format;        // "u32", "float4", "float3", "i32", "u16", "u8", "f32", "unorm16",
                             // "unorm8", "record", "float4 rows", "half4" (morph offsets)
  std::size_t element_bytes = 0;  // one element of `format` (a whole record for "record")
  std::size_t stride_bytes = 0;   // between consecutive vertices (palette: between joints; morph offsets and
                                  // targets: between entries; morph weights: between targets; 0 for scalars)
  std::string indexing;      // where vertex v's data is: "v", "v*B+i", "i*S+v", "first+v", "j*R+r";
                             // instanced: "i*vertex_count+first+v" (outputs), "(i*J+j)*R+r" (palette)
  ArgumentDirection direction = ArgumentDirection::kIn;
  ArgumentKind kind = ArgumentKind::kBuffer;
};

// Work items = ceil(count / vertices_per_item) rounded up to a multiple of wg_size.
struct LaunchGeometry {
  int vertices_per_item = 1;
  bool strided = false;
  int wg_size = 128;
  bool instanced = false;  // the grid's second dimension is the instance (EmitOptions::instanced)
  std::string rule;  // the rule above, in words, with the numbers filled in
  std::size_t GlobalItems(std::size_t count) const;
};

// How a kernel is emitted beyond its variant (docs/VARIANTS.md "Instancing").
struct EmitOptions {
  // One launch skins K instances of the mesh, each with its own palette: the
  // grid's second dimension (glsl-vertex: gl_InstanceID of an instanced draw)
  // is the instance; instance i reads palette joints i*J.. and writes its
  // outputs at i*vertex_count + first + v (vertex_count: a new scalar
  // argument after `first`; glsl-vertex: the capture order, no argument).
  // Needs the joint count (the palette stride).
  bool instanced = false;
  // Instanced `constant` storage in CUDA and GLSL: the __constant__ symbol /
  // uniform block is an array sized at compile time, so it holds this many
  // palettes (required there: >= 1; a launch may skin fewer). Ignored
  // elsewhere: OpenCL's __constant pointer and the other storages take any K.
  int max_instances = 0;
  // The mesh's morph targets: required (>= 1) for a variant that skins them
  // (MORPH_TARGETS: the weights' count per instance), ignored otherwise.
  int morph_targets = 0;
};

struct KernelSource {
  Lang lang = Lang::kOpenCl;
  std::string entry_point = "skin";
  std::string text;                                   // defines + template: what is compiled
  std::vector<std::pair<std::string, long long>> defines;  // in the order they are prepended
  int influences = 0;                                 // B the kernel is specialised for
  int joints = 0;                                     // palette entries (0: not specialised)
  bool instanced = false;                             // EmitOptions::instanced
  int max_instances = 0;                              // instances the kernel can skin per launch (0: any)
  int instances = 0;  // instanced: EmitOptions::max_instances as asked (the K of `emit --instances K`), 0 if none
  int morph_targets = 0;  // MORPH_TARGETS where the variant skins morph targets, else 0
  std::vector<KernelArgument> arguments;              // in kernel argument order
  LaunchGeometry launch;
  std::string generator_version = kGeneratorVersion;
  std::string source_hash;                            // FNV-1a 64 of `text`, 16 hex digits
};

// The kernel of `variant`. `influences_override` (> 0) specialises it for
// another B (one bucket of a `bucketed` variant); `joints` is the palette size,
// required for `local` storage (it sizes the local copy) and for instanced
// kernels (the palette stride), and recorded in the kernel otherwise.
// Throws Error for an unimplemented language, influences outside 1..8, local
// storage or an instanced kernel without a joint count, or instanced CUDA/GLSL
// constant storage without max_instances.
KernelSource Emit(const Variant& variant, int influences_override = 0, int joints = 0,
                  const EmitOptions& options = {});

// GLSL and Vulkan: whether the argument takes a binding (buffers, images and
// the palette, in argument order; not scalars, nor glsl-vertex's outputs,
// which transform feedback captures).
bool TakesBinding(Lang lang, const KernelArgument& a);
// GLSL: BINDING_<NAME> of every argument that takes a binding, its place
// among them (skin_body.glsl reads them).
std::vector<std::pair<std::string, long long>> BindingDefines(Lang lang, std::span<const KernelArgument> arguments);

// Whether an instanced kernel of `variant` takes K palettes only up to its
// compile-time max_instances (CUDA and GLSL constant storage).
bool InstancesBoundAtCompileTime(const Variant& variant);

// Vulkan: a scalar argument's byte offset in the kernel's push-constant block
// (n 0, first 4, vertex_count 8, a fused kernel's elapsed 12;
// kPushConstantBytes in all). Throws Error for another name.
inline constexpr std::size_t kPushConstantBytes = 16;
std::size_t PushConstantOffset(const std::string& scalar);

// Everything a program needs to bind and launch the kernel.
nlohmann::json SidecarJson(const KernelSource& source, const Variant& variant);

// An embedded file of templates/ by name ("skin.cl", "skin_params.h") as it
// is in the source tree, its #include lines unresolved; throws Error listing
// the embedded names when there is none.
std::string TemplateText(const std::string& name);
std::vector<std::string> TemplateNames();

// An embedded kernel template with its `#include "FILE"` lines replaced by the
// embedded files' text (ExpandIncludes, generator/template_includes.h) and no
// defines: what Emit specialises, and what compiles alone with every parameter
// at its default. Throws Error as TemplateText does, or naming the template
// and line of an include that cannot be resolved.
std::string ExpandedTemplate(const std::string& name);

// An embedded template specialised (what Emit, EmitCopy and EmitPalette
// compile): "// Generated by skintune <version>: <heading>", one
// `#define NAME VALUE` per define in order, then a #line so that compilers'
// messages count the template's own lines; a GLSL template's #version line
// stays first. Throws Error as ExpandedTemplate does.
std::string SpecialisedText(const std::string& template_name, const std::string& heading,
                            const std::vector<std::pair<std::string, long long>>& defines);

// FNV-1a 64 of `text` as 16 lower-case hex digits.
std::string SourceHash(const std::string& text);

}  // namespace skintune::internal
