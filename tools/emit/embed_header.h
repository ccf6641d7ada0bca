// skintune (internal): the dependency-free C++ header that `skintune emit --db`
// writes (docs/RUNTIME.md "Emitting kernels into other builds"): winning
// kernels of a winners database, their parameters, argument lists and launch
// geometry as constexpr data, plus packing helpers, needing only the C++17
// standard library.
//
// The hand-written part (types, FindKernel, PackMesh, PackPalette, ...) is
// templates/embedded_support.h, embedded into the generator like the kernel
// templates; EmbedHeader() puts the namespace and the kernel table into it.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "generator/emit.h"
#include "generator/variant.h"
#include "runtime/winners_db.h"

namespace skintune::internal {

struct Axis;  // generator/axes.h

// One entry of the header's kernel table.
struct EmbeddedKernel {
  WinnersEntry entry;   // the winner as the database has it (its variant may be `bucketed`)
  Variant variant;      // the variant emitted: `padded` (a bucketed winner's padded twin)
  // Emit(variant, 0, joints), joints > 0; for a crowd's winner (entry.shape
  // instances) instanced, for its K instances (max_instances K); a batch's
  // winner holds its meshes' palettes together.
  KernelSource source;
};

struct EmbedHeaderOptions {
  std::string name_space = "skintune_kernels";  // a C++ namespace name, nested ones as a::b
  // For the banner: where the kernels come from.
  std::string database;                 // the winners database file
  std::string device_pattern;           // --device
  std::vector<std::string> langs;       // --lang (empty: every language)
  // The error budget the winners were chosen under (--max-error): the header's kMaxError.
  double max_error = 0.0;
};

// Whether `name` can name a namespace: identifiers (not keywords, not
// reserved: no "__", no leading "_X") joined by "::".
bool IsCppNamespaceName(std::string_view name);

// `text` as the inside of a C++ string literal: \\ \" \n \t \r escaped, other
// bytes outside printable ASCII as 3-digit octal escapes, "??" as "?\?" (no
// trigraphs); no quotes around it.
std::string CppEscaped(std::string_view text);

// How the header spells value `code` of an axis with an embedded_enum
// (generator/axes.h): "Layout::kSoaSplit", "PaletteFormat::kMat3x4".
std::string EmbeddedEnumerator(const Axis& axis, int code);

// The whole header: the banner, templates/embedded_support.h with its
// namespace set and its kernel table filled in. Kernels share one source
// literal and one argument array when their text is the same. Throws Error
// for no kernels, an invalid namespace, a kernel that is not padded or not
// specialised for a joint count (source.joints == 0), or instanced for a
// winner that is not a crowd's (or plain for a crowd's).
std::string EmbedHeader(const std::vector<EmbeddedKernel>& kernels, const EmbedHeaderOptions& options);

}  // namespace skintune::internal
