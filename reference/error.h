// skintune: the one error type of the offline (reference/generator/tuner) code.
//
// Inside skintune, bad input is reported by throwing skintune::internal::Error whose
// message is complete and user-facing: it names the file (when there is one)
// and the offending element, e.g.
//   "CesiumMan.gltf: accessors[7] (JOINTS_0 of meshes[0].primitives[0]): component type FLOAT is not allowed (expected UNSIGNED_BYTE or UNSIGNED_SHORT)"
// The command-line tool prints it as one line on stderr and exits non-zero.
// The runtime's public API (runtime/) turns these into error values.
#pragma once

#include <stdexcept>
#include <string>

namespace skintune::internal {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace skintune::internal
