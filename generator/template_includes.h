// skintune: `#include "FILE"` lines of kernel templates, resolved by the
// generator.
//
// Kernel templates share text through preludes (templates/skin_params.h: the
// parameters every language reads; templates/skin_body.glsl: the skinning both
// GLSL stages run), named by a line `#include "FILE"`, the way CLBlast's
// kernels share common.opencl. The generator replaces each such line by the
// file's text, so an emitted kernel is one self-contained file: programs that
// load it pass no include path (NVRTC and OpenCL builds get none), and GLSL
// has no #include without an extension. templates/README.md, "Preludes".
#pragma once

#include <functional>
#include <optional>
#include <string>

namespace skintune::internal {

// The text of a template file by name; std::nullopt when there is none.
using TemplateLookup = std::function<std::optional<std::string>(const std::string& name)>;

// `text` (the file `name`) with every `#include "FILE"` line replaced by the
// text of FILE from `lookup`, itself expanded the same way (a prelude may
// include another). #line directives frame each included text, so compiler
// messages give the file and line a line came from:
//   OpenCL, CUDA: `#line 1 "FILE"` before it, `#line N "PARENT"` after it;
//   GLSL (a `text` that starts with #version): `#line 1 K  // FILE` and
//   `#line N P  // PARENT`: GLSL's #line takes a source-string number, not a
//   name; `name` is 0 and included files are 1, 2, .. in include order.
// N is the parent's line after the include; the #line back is left out where
// another include or the end of the parent follows.
//
// Includes are found line by line (a line whose first non-blank text is `#`,
// then `include`) before any preprocessing, so an include inside #if is
// expanded whatever the condition. Throws Error, naming the file and line of
// the include and the includes that led to it, for:
//   - a FILE that `lookup` does not have;
//   - any other form than `#include "FILE"` (no <FILE>, no macro);
//   - a file included a second time in one expansion (a cycle included): its
//     text would be compiled twice.
std::string ExpandIncludes(const std::string& name, const std::string& text, const TemplateLookup& lookup);

// For a GLSL compiler's log of an expanded text: " (source strings: 0
// skin.comp, 1 skin_params.h, 2 skin_body.glsl)" from the text's `#line N K
// // FILE` directives, so that "2:48(3): error" (Mesa) or "2(48) : error"
// (NVIDIA) names its file; "" when the text has none.
std::string GlslSourceStrings(const std::string& expanded);

}  // namespace skintune::internal
