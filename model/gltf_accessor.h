// skintune: the bounds-checked glTF accessor reader behind ImportGltf
// (internal to reference/; include it from gltf_import.cpp and tests only).
//
// tinygltf parses the JSON/GLB and decodes the buffers but does not check that
// an accessor's elements lie inside its bufferView, nor the view inside its
// buffer. Everything the importer reads from a buffer goes through
// ReadAccessor, which guarantees:
//
//  - every byte read lies inside the bufferView it is read through, and that
//    view lies inside its buffer (byteOffset + byteLength <= buffer size);
//    otherwise Error "... truncated buffer";
//  - the size arithmetic cannot overflow: offset + stride * (count - 1) +
//    element size is checked against 2^64 before it is computed, a byteStride
//    smaller than the element is rejected, and count is capped at 2^31;
//  - the accessor exists, and its componentType, type and `normalized` flag
//    are among those the caller allows (AccessorSpec);
//  - an accessor cannot make the reader allocate more than its data warrants:
//    the data is checked against its bufferView before anything is allocated,
//    and an accessor without a bufferView (zeros, as glTF specifies, plus its
//    sparse values) holds at most kMaxZeroFilledValues values;
//  - sparse accessors are applied: sparse.count in 1..count, indices of an
//    unsigned integer type, every index inside the accessor, indices and
//    values each bounds-checked like the main data (tightly packed);
//  - normalized integers map to [0, 1] (unsigned) or [-1, 1] (signed).
//
// Every failure throws skintune::internal::Error through Ctx::Fail, so the message
// starts with the file path and names the accessor with its role, then the
// bufferView / buffer at fault, e.g.
//   "model.gltf: accessors[3] (JOINTS_0 of meshes[0].primitives[0]): bufferViews[2]
//    (byteOffset 0, byteLength 4096) does not fit in buffers[0] (1024 bytes): truncated buffer"
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "base/error.h"

namespace skintune::internal::gltf_detail {

// ---------------------------------------------------------------- naming helpers

// The model and the file name every message starts with.
struct Ctx {
  const tinygltf::Model& model;
  std::string path;
  [[noreturn]] void Fail(const std::string& what) const { throw Error(path + ": " + what); }
};

// glTF indices are int (-1 = absent); containers are indexed by size_t.
inline std::size_t Z(long long i) { return static_cast<std::size_t>(i); }

template <typename V>
bool InRange(long long i, const V& v) {
  return i >= 0 && Z(i) < v.size();
}

// A number as messages print it (7 significant digits).
std::string Num(double x);

// "array[i]", e.g. Idx("bufferViews", 3) == "bufferViews[3]".
std::string Idx(const char* array, long long i);

// ---------------------------------------------------------------- accessors

// What an accessor may be, and how it is named in messages.
struct AccessorSpec {
  std::string role;                  // e.g. "JOINTS_0 of meshes[0].primitives[0]"
  std::vector<int> component_types;  // allowed
  std::vector<int> types;            // allowed
  bool integers = false;             // raw integers (joint indices): `normalized` not allowed
};

// Decoded accessor: count * components values, element by element.
struct AccessorData {
  std::size_t count = 0;
  std::size_t components = 0;
  std::vector<double> values;
  double at(std::size_t element, int component) const { return values[element * components + Z(component)]; }
};

// Allowed component types, by use.
extern const std::vector<int> kFloat;          // FLOAT
extern const std::vector<int> kJointTypes;     // UNSIGNED_BYTE, UNSIGNED_SHORT
extern const std::vector<int> kWeightTypes;    // FLOAT, UNSIGNED_BYTE, UNSIGNED_SHORT
extern const std::vector<int> kRotationTypes;  // FLOAT, BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT
extern const std::vector<int> kIndexTypes;     // UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT

// The most values (count * components) of an accessor without a bufferView:
// 2^24, 128 MiB decoded, so a few bytes of JSON cannot ask for gigabytes.
constexpr std::size_t kMaxZeroFilledValues = std::size_t{1} << 24;

// "accessors[index] (role)": how messages name an accessor.
std::string AccessorName(int index, const std::string& role);

// Decodes accessors[index] (sparse part included) as doubles after checking it
// against `spec`; throws Error (see the top of this file) when it does not match
// or does not fit in its bufferView / buffer.
AccessorData ReadAccessor(const Ctx& ctx, int index, const AccessorSpec& spec);

}  // namespace skintune::internal::gltf_detail
