// skintune: a variant -> kernel source plus its machine-readable interface.
//
// The source is the language's template (templates/, embedded into the
// binary at build time) with one `#define` per parameter prepended, as in
// CLBlast: every template compiles alone with default parameters, and the
// generator only specialises it. The interface (argument list in the order of
// docs/VARIANTS.md, element formats, strides, launch geometry) is data, so a
// program can bind the kernel from the sidecar JSON without reading skintune.
//
// A language whose template is not embedded yet throws "not implemented yet".
// GLSL templates start with #version; the defines go after it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "generator/variant.h"

namespace skintune {

inline constexpr const char* kGeneratorVersion = "0.1.0";

enum class ArgumentKind { kScalar, kBuffer, kImage };
enum class ArgumentDirection { kIn, kOut };
const char* Name(ArgumentKind);
const char* Name(ArgumentDirection);

struct KernelArgument {
  std::string name;          // "n", "first", "records", "positions", "indices", "weights", "normals",
                             // "palette", "out_positions", "out_normals"
  std::string format;        // "u32", "float4", "float3", "i32", "u16", "u8", "f32", "unorm16",
                             // "unorm8", "record", "float4 rows"
  std::size_t element_bytes = 0;  // one element of `format` (a whole record for "record")
  std::size_t stride_bytes = 0;   // between consecutive vertices (palette: between joints; 0 for scalars)
  std::string indexing;      // where vertex v's data is: "v", "v*B+i", "i*S+v", "first+v", "j*R+r"
  ArgumentDirection direction = ArgumentDirection::kIn;
  ArgumentKind kind = ArgumentKind::kBuffer;
};

// Work items = ceil(count / vertices_per_item) rounded up to a multiple of wg_size.
struct LaunchGeometry {
  int vertices_per_item = 1;
  bool strided = false;
  int wg_size = 128;
  std::string rule;  // the rule above, in words, with the numbers filled in
  std::size_t GlobalItems(std::size_t count) const;
};

struct KernelSource {
  Lang lang = Lang::kOpenCl;
  std::string entry_point = "skin";
  std::string text;                                   // defines + template: what is compiled
  std::vector<std::pair<std::string, long long>> defines;  // in the order they are prepended
  int influences = 0;                                 // B the kernel is specialised for
  int joints = 0;                                     // palette entries (0: not specialised)
  std::vector<KernelArgument> arguments;              // in kernel argument order
  LaunchGeometry launch;
  std::string generator_version = kGeneratorVersion;
  std::string source_hash;                            // FNV-1a 64 of `text`, 16 hex digits
};

// The kernel of `variant`. `influences_override` (> 0) specialises it for
// another B (one bucket of a `bucketed` variant); `joints` is the palette size,
// required for `local` storage (it sizes the local copy) and recorded in the
// kernel otherwise. Throws Error for an unimplemented language, influences
// outside 1..8, or local storage without a joint count.
KernelSource Emit(const Variant& variant, int influences_override = 0, int joints = 0);

// Everything a program needs to bind and launch the kernel.
nlohmann::json SidecarJson(const KernelSource& source, const Variant& variant);

// An embedded template by file name ("skin.cl"); throws Error listing the
// embedded names when there is none.
std::string TemplateText(const std::string& name);
std::vector<std::string> TemplateNames();

// FNV-1a 64 of `text` as 16 lower-case hex digits.
std::string SourceHash(const std::string& text);

}  // namespace skintune
