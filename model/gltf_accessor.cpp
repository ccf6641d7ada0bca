// skintune: the bounds-checked glTF accessor reader (see gltf_accessor.h).
#include "model/gltf_accessor.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "base/error.h"

namespace skintune::internal::gltf_detail {

using std::size_t;
using std::to_string;

std::string Num(double x) {
  std::ostringstream s;
  s.precision(7);
  s << x;
  return s.str();
}

std::string Idx(const char* array, long long i) { return std::string(array) + "[" + to_string(i) + "]"; }

const std::vector<int> kFloat = {TINYGLTF_COMPONENT_TYPE_FLOAT};
const std::vector<int> kJointTypes = {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
const std::vector<int> kWeightTypes = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                       TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
const std::vector<int> kRotationTypes = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
const std::vector<int> kIndexTypes = {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                      TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                      TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT};

std::string AccessorName(int index, const std::string& role) {
  return Idx("accessors", index) + " (" + role + ")";
}

namespace {

std::string NameOf(const std::map<int, const char*>& names, const char* what, int value) {
  const auto it = names.find(value);
  return it != names.end() ? it->second : what + to_string(value);
}

std::string ComponentTypeName(int t) {
  static const std::map<int, const char*> names = {
      {TINYGLTF_COMPONENT_TYPE_BYTE, "BYTE"},   {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, "UNSIGNED_BYTE"},
      {TINYGLTF_COMPONENT_TYPE_SHORT, "SHORT"}, {TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, "UNSIGNED_SHORT"},
      {TINYGLTF_COMPONENT_TYPE_INT, "INT"},     {TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, "UNSIGNED_INT"},
      {TINYGLTF_COMPONENT_TYPE_FLOAT, "FLOAT"}, {TINYGLTF_COMPONENT_TYPE_DOUBLE, "DOUBLE"}};
  return NameOf(names, "componentType ", t);
}

std::string TypeName(int t) {
  static const std::map<int, const char*> names = {
      {TINYGLTF_TYPE_SCALAR, "SCALAR"}, {TINYGLTF_TYPE_VEC2, "VEC2"}, {TINYGLTF_TYPE_VEC3, "VEC3"},
      {TINYGLTF_TYPE_VEC4, "VEC4"},     {TINYGLTF_TYPE_MAT2, "MAT2"}, {TINYGLTF_TYPE_MAT3, "MAT3"},
      {TINYGLTF_TYPE_MAT4, "MAT4"}};
  return NameOf(names, "type ", t);
}

bool Contains(const std::vector<int>& v, int x) { return std::find(v.begin(), v.end(), x) != v.end(); }

size_t ComponentSize(int type) {
  return Z(tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(type)));
}

// Checks that bufferViews[view_index] lies inside its buffer, then that `count`
// elements of `element_size` bytes from `offset` (every *stride bytes; 0 = the
// view's byteStride, or tightly packed) lie inside the view. Returns the first.
const unsigned char* CheckedBytes(const Ctx& ctx, const std::string& who, int view_index, size_t offset,
                                  size_t count, size_t element_size, size_t* stride) {
  const auto& views = ctx.model.bufferViews;
  if (!InRange(view_index, views)) {
    ctx.Fail(who + ": " + Idx("bufferViews", view_index) + " does not exist (the file has " +
             to_string(views.size()) + " buffer views)");
  }
  const tinygltf::BufferView& view = views[Z(view_index)];
  const std::string view_name = Idx("bufferViews", view_index);
  if (!InRange(view.buffer, ctx.model.buffers)) {
    ctx.Fail(who + ": " + view_name + ": " + Idx("buffers", view.buffer) + " does not exist");
  }
  const std::vector<unsigned char>& buffer = ctx.model.buffers[Z(view.buffer)].data;
  if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset) {
    ctx.Fail(who + ": " + view_name + " (byteOffset " + to_string(view.byteOffset) + ", byteLength " +
             to_string(view.byteLength) + ") does not fit in " + Idx("buffers", view.buffer) + " (" +
             to_string(buffer.size()) + " bytes): truncated buffer");
  }
  if (*stride == 0) *stride = view.byteStride != 0 ? view.byteStride : element_size;
  if (*stride < element_size) {
    ctx.Fail(who + ": " + view_name + ": byteStride " + to_string(*stride) +
             " is smaller than the element (" + to_string(element_size) + " bytes)");
  }
  // Nothing to read: `offset` (unchecked, maybe past the end of the buffer) is not applied.
  if (count == 0) return buffer.data() + view.byteOffset;
  const size_t max = std::numeric_limits<size_t>::max();
  const bool overflow = offset > max - element_size || (count - 1) > (max - offset - element_size) / *stride;
  const size_t needed = overflow ? max : offset + *stride * (count - 1) + element_size;
  if (needed > view.byteLength) {
    ctx.Fail(who + ": " + to_string(count) + " elements from byteOffset " + to_string(offset) + " need " +
             (overflow ? std::string("more than 2^64") : to_string(needed)) + " bytes, but " + view_name +
             " has byteLength " + to_string(view.byteLength) + ": truncated buffer");
  }
  return buffer.data() + view.byteOffset + offset;
}

template <typename T>
double Load(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return static_cast<double>(v);
}

// One component as double; normalized integers map to [0, 1] or [-1, 1].
double ReadComponent(const unsigned char* p, int type, bool normalized) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return normalized ? std::max(Load<std::int8_t>(p) / 127.0, -1.0) : Load<std::int8_t>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return Load<std::uint8_t>(p) / (normalized ? 255.0 : 1.0);
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return normalized ? std::max(Load<std::int16_t>(p) / 32767.0, -1.0) : Load<std::int16_t>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return Load<std::uint16_t>(p) / (normalized ? 65535.0 : 1.0);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return Load<std::uint32_t>(p);
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return Load<float>(p);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

// Overwrites the elements listed in the accessor's `sparse` object.
void ApplySparse(const Ctx& ctx, const std::string& who, const tinygltf::Accessor& acc, bool normalized,
                 AccessorData& out) {
  const auto& sparse = acc.sparse;
  if (sparse.count < 1 || Z(sparse.count) > acc.count) {
    ctx.Fail(who + ": sparse.count " + to_string(sparse.count) + " is not in 1.." + to_string(acc.count));
  }
  const int index_type = sparse.indices.componentType;
  if (!Contains(kIndexTypes, index_type)) {
    ctx.Fail(who + ": sparse.indices component type " + ComponentTypeName(index_type) +
             " not allowed (expected " + OneOf(kIndexTypes, ComponentTypeName) + ")");
  }
  if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0)
    ctx.Fail(who + ": negative sparse byteOffset");
  const size_t n = Z(sparse.count), index_size = ComponentSize(index_type);
  const size_t comp_size = ComponentSize(acc.componentType), value_size = comp_size * out.components;
  size_t index_stride = index_size, value_stride = value_size;  // sparse arrays are tightly packed
  const unsigned char* indices = CheckedBytes(ctx, who + " sparse.indices", sparse.indices.bufferView,
                                              Z(sparse.indices.byteOffset), n, index_size, &index_stride);
  const unsigned char* values = CheckedBytes(ctx, who + " sparse.values", sparse.values.bufferView,
                                             Z(sparse.values.byteOffset), n, value_size, &value_stride);
  for (size_t i = 0; i < n; ++i) {
    const double target = ReadComponent(indices + i * index_size, index_type, false);
    if (target >= static_cast<double>(acc.count)) {
      ctx.Fail(who + ": sparse.indices[" + to_string(i) + "] = " + Num(target) +
               " is outside the accessor (" + to_string(acc.count) + " elements)");
    }
    for (size_t c = 0; c < out.components; ++c) {
      out.values[static_cast<size_t>(target) * out.components + c] =
          ReadComponent(values + i * value_size + c * comp_size, acc.componentType, normalized);
    }
  }
}

// Checks that accessors[index] exists and matches `spec`.
const tinygltf::Accessor& CheckedAccessor(const Ctx& ctx, int index, const AccessorSpec& spec) {
  const std::string who = AccessorName(index, spec.role);
  if (!InRange(index, ctx.model.accessors)) {
    ctx.Fail(who + ": does not exist (the file has " + to_string(ctx.model.accessors.size()) + " accessors)");
  }
  const tinygltf::Accessor& acc = ctx.model.accessors[Z(index)];
  const std::string component = ComponentTypeName(acc.componentType);
  if (!Contains(spec.component_types, acc.componentType)) {
    ctx.Fail(who + ": component type " + component + " not allowed (expected " +
             OneOf(spec.component_types, ComponentTypeName) + ")");
  }
  if (!Contains(spec.types, acc.type)) {
    ctx.Fail(who + ": type " + TypeName(acc.type) + " not allowed (expected " + OneOf(spec.types, TypeName) +
             ")");
  }
  if (spec.integers && acc.normalized) ctx.Fail(who + ": must not be normalized");
  if (!spec.integers && acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !acc.normalized) {
    ctx.Fail(who + ": component type " + component + " must be normalized");
  }
  if (acc.count > (size_t{1} << 31)) ctx.Fail(who + ": count " + to_string(acc.count) + " is too large");
  return acc;
}

}  // namespace

AccessorData ReadAccessor(const Ctx& ctx, int index, const AccessorSpec& spec) {
  const tinygltf::Accessor& acc = CheckedAccessor(ctx, index, spec);
  const std::string who = AccessorName(index, spec.role);
  const bool normalized = acc.normalized && !spec.integers;
  const size_t comp_size = ComponentSize(acc.componentType);
  AccessorData out;
  out.count = acc.count;
  out.components = Z(tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(acc.type)));
  // Check before allocating, so memory stays proportional to the data the file holds.
  const unsigned char* p = nullptr;
  size_t stride = 0;
  if (acc.bufferView != -1) {
    p = CheckedBytes(ctx, who, acc.bufferView, acc.byteOffset, acc.count, comp_size * out.components, &stride);
  } else if (acc.count * out.components > kMaxZeroFilledValues) {
    ctx.Fail(who + ": count " + to_string(acc.count) + " without a bufferView is too large (at most " +
             to_string(kMaxZeroFilledValues) + " zero-filled values)");
  }
  out.values.assign(acc.count * out.components, 0.0);  // without a bufferView: zeros, as glTF specifies
  if (p != nullptr) {
    for (size_t e = 0; e < acc.count; ++e) {
      for (size_t c = 0; c < out.components; ++c) {
        out.values[e * out.components + c] =
            ReadComponent(p + e * stride + c * comp_size, acc.componentType, normalized);
      }
    }
  }
  if (acc.sparse.isSparse) ApplySparse(ctx, who, acc, normalized, out);
  return out;
}

}  // namespace skintune::internal::gltf_detail
