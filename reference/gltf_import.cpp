// skintune: glTF 2.0 import through tinygltf. tinygltf parses the JSON/GLB and
// decodes the buffers; everything read from the buffers goes through our own
// bounds-checked accessor reader, so a malformed file gives an Error naming
// the accessor / bufferView / buffer instead of reading out of bounds.
#include "reference/gltf_import.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "reference/error.h"

namespace skintune {
namespace {

// ---------------------------------------------------------------- helpers

// The model and the file name every message starts with.
struct Ctx {
  const tinygltf::Model& model;
  std::string path;
  [[noreturn]] void Fail(const std::string& what) const { throw Error(path + ": " + what); }
};

std::string Num(double x) {
  std::ostringstream s;
  s.precision(7);
  s << x;
  return s.str();
}

std::string Idx(const char* array, long long i) {
  return std::string(array) + "[" + std::to_string(i) + "]";
}

std::string ComponentTypeName(int t) {
  switch (t) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_INT: return "INT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "FLOAT";
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: return "DOUBLE";
  }
  return "componentType " + std::to_string(t);
}

std::string TypeName(int t) {
  switch (t) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
  }
  return "type " + std::to_string(t);
}

// "A", "A or B", "A, B or C".
template <typename F>
std::string OneOf(const std::vector<int>& values, F name) {
  std::string s;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) s += (i + 1 == values.size()) ? " or " : ", ";
    s += name(values[i]);
  }
  return s;
}

bool Contains(const std::vector<int>& v, int x) { return std::find(v.begin(), v.end(), x) != v.end(); }

// tinygltf's messages: one line, data URIs cut short.
std::string Tidy(std::string message) {
  for (char& ch : message) {
    if (ch == '\n' || ch == '\r') ch = ' ';
  }
  for (std::size_t at = message.find("base64,"); at != std::string::npos;
       at = message.find("base64,", at + 1)) {
    std::size_t begin = at + 7, end = message.find(' ', begin);
    if (end == std::string::npos) end = message.size();
    if (end - begin > 16) message.replace(begin + 16, end - begin - 16, "...");
  }
  while (!message.empty() && message.back() == ' ') message.pop_back();
  if (message.size() > 400) message = message.substr(0, 400) + "...";
  return message.empty() ? "no details" : message;
}

// ---------------------------------------------------------------- file loading

std::vector<unsigned char> ReadFileBytes(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(path + ": cannot open file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open file");
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw Error(path + ": cannot read file");
  return bytes;
}

bool LooksLikeGltfJson(const std::vector<unsigned char>& bytes) {
  nlohmann::json j = nlohmann::json::parse(bytes.begin(), bytes.end(), nullptr, false);
  return !j.is_discarded() && j.is_object() && j.contains("asset");
}

// Images are irrelevant to skinning: keep them undecoded.
bool SkipImage(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*,
               int, void*) {
  return true;
}

tinygltf::Model LoadModel(const std::string& path, std::vector<std::string>& warnings) {
  const std::vector<unsigned char> bytes = ReadFileBytes(path);
  if (bytes.empty()) throw Error(path + ": not a glTF 2.0 file (empty file)");
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) throw Error(path + ": file too large (4 GiB or more)");
  const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  const std::string base_dir = std::filesystem::path(path).parent_path().string();

  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&SkipImage, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  const auto size = static_cast<unsigned int>(bytes.size());
  const bool ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), size, base_dir)
                         : loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                                      size, base_dir);
  if (!ok) {
    if (binary || LooksLikeGltfJson(bytes)) throw Error(path + ": invalid glTF file: " + Tidy(err));
    throw Error(path + ": not a glTF 2.0 file (" + Tidy(err) + ")");
  }
  if (!warn.empty()) warnings.push_back(path + ": tinygltf: " + Tidy(warn));
  return model;
}

// ---------------------------------------------------------------- accessors

// What an accessor may be, and how it is named in messages.
struct AccessorSpec {
  std::string role;                  // e.g. "JOINTS_0 of meshes[0].primitives[0]"
  std::vector<int> component_types;  // allowed
  std::vector<int> types;            // allowed
  bool integers = false;             // raw integers (joint indices): `normalized` not allowed
};

// Decoded accessor: count * components values, row-major per element.
struct AccessorData {
  std::size_t count = 0;
  int components = 0;
  std::vector<double> values;
  double at(std::size_t element, int component) const {
    return values[element * static_cast<std::size_t>(components) + static_cast<std::size_t>(component)];
  }
};

// The bytes of `count` elements of `element_size` bytes at `offset` in
// bufferViews[view_index], every range checked; *stride: 0 = use the view's.
const unsigned char* CheckedBytes(const Ctx& ctx, const std::string& who, int view_index, std::size_t offset,
                                  std::size_t count, std::size_t element_size, std::size_t* stride) {
  const auto& views = ctx.model.bufferViews;
  if (view_index < 0 || static_cast<std::size_t>(view_index) >= views.size()) {
    ctx.Fail(who + ": " + Idx("bufferViews", view_index) + " does not exist (the file has " +
             std::to_string(views.size()) + " buffer views)");
  }
  const tinygltf::BufferView& view = views[static_cast<std::size_t>(view_index)];
  const std::string view_name = Idx("bufferViews", static_cast<std::size_t>(view_index));
  if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= ctx.model.buffers.size()) {
    ctx.Fail(who + ": " + view_name + ": " + Idx("buffers", view.buffer) + " does not exist");
  }
  const std::size_t buffer_size = ctx.model.buffers[static_cast<std::size_t>(view.buffer)].data.size();
  if (view.byteOffset > buffer_size || view.byteLength > buffer_size - view.byteOffset) {
    ctx.Fail(who + ": " + view_name + " (byteOffset " + std::to_string(view.byteOffset) + ", byteLength " +
             std::to_string(view.byteLength) + ") does not fit in " + Idx("buffers", view.buffer) + " (" +
             std::to_string(buffer_size) + " bytes): truncated buffer");
  }
  if (*stride == 0) *stride = view.byteStride != 0 ? view.byteStride : element_size;
  if (*stride < element_size) {
    ctx.Fail(who + ": " + view_name + ": byteStride " + std::to_string(*stride) + " is smaller than the element (" +
             std::to_string(element_size) + " bytes)");
  }
  if (count > 0) {
    const std::size_t max = std::numeric_limits<std::size_t>::max();
    const bool overflow = offset > max - element_size || (count - 1) > (max - offset - element_size) / *stride;
    const std::size_t needed = overflow ? max : offset + *stride * (count - 1) + element_size;
    if (needed > view.byteLength) {
      ctx.Fail(who + ": " + std::to_string(count) + " elements from byteOffset " + std::to_string(offset) +
               " need " + (overflow ? std::string("more than 2^64") : std::to_string(needed)) + " bytes, but " +
               view_name + " has byteLength " + std::to_string(view.byteLength) + ": truncated buffer");
    }
  }
  return ctx.model.buffers[static_cast<std::size_t>(view.buffer)].data.data() + view.byteOffset + offset;
}

template <typename T>
T Load(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// One component as double; normalized integers map to [0, 1] / [-1, 1].
double ReadComponent(const unsigned char* p, int type, bool normalized) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      double v = Load<std::int8_t>(p);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return Load<std::uint8_t>(p) / (normalized ? 255.0 : 1.0);
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      double v = Load<std::int16_t>(p);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return Load<std::uint16_t>(p) / (normalized ? 65535.0 : 1.0);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return Load<std::uint32_t>(p);
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return Load<float>(p);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

void ApplySparse(const Ctx& ctx, const std::string& who, const tinygltf::Accessor& acc, bool normalized,
                 AccessorData& out) {
  const auto& sparse = acc.sparse;
  if (sparse.count < 1 || static_cast<std::size_t>(sparse.count) > acc.count) {
    ctx.Fail(who + ": sparse.count " + std::to_string(sparse.count) + " is not in 1.." + std::to_string(acc.count));
  }
  const int index_type = sparse.indices.componentType;
  if (!Contains({TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                 TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT}, index_type)) {
    ctx.Fail(who + ": sparse.indices component type " + ComponentTypeName(index_type) +
             " not allowed (expected UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT)");
  }
  if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) ctx.Fail(who + ": negative sparse byteOffset");
  const auto n = static_cast<std::size_t>(sparse.count);
  const auto index_size = static_cast<std::size_t>(tinygltf::GetComponentSizeInBytes(index_type));
  const auto comp_size = static_cast<std::size_t>(tinygltf::GetComponentSizeInBytes(acc.componentType));
  const auto value_size = comp_size * static_cast<std::size_t>(out.components);
  std::size_t index_stride = index_size, value_stride = value_size;
  const unsigned char* indices = CheckedBytes(ctx, who + " sparse.indices", sparse.indices.bufferView,
                                              static_cast<std::size_t>(sparse.indices.byteOffset), n, index_size,
                                              &index_stride);
  const unsigned char* values = CheckedBytes(ctx, who + " sparse.values", sparse.values.bufferView,
                                             static_cast<std::size_t>(sparse.values.byteOffset), n, value_size,
                                             &value_stride);
  for (std::size_t i = 0; i < n; ++i) {
    const double target = ReadComponent(indices + i * index_size, index_type, false);
    if (target >= static_cast<double>(acc.count)) {
      ctx.Fail(who + ": sparse.indices[" + std::to_string(i) + "] = " + Num(target) + " is outside the accessor (" +
               std::to_string(acc.count) + " elements)");
    }
    for (int c = 0; c < out.components; ++c) {
      out.values[static_cast<std::size_t>(target) * static_cast<std::size_t>(out.components) +
                 static_cast<std::size_t>(c)] =
          ReadComponent(values + i * value_size + static_cast<std::size_t>(c) * comp_size, acc.componentType,
                        normalized);
    }
  }
}

std::string AccessorName(int index, const std::string& role) {
  return Idx("accessors", index) + " (" + role + ")";
}

// Checks that accessors[index] exists and matches `spec`.
const tinygltf::Accessor& CheckedAccessor(const Ctx& ctx, int index, const AccessorSpec& spec) {
  const std::string who = AccessorName(index, spec.role);
  if (index < 0 || static_cast<std::size_t>(index) >= ctx.model.accessors.size()) {
    ctx.Fail(who + ": does not exist (the file has " + std::to_string(ctx.model.accessors.size()) + " accessors)");
  }
  const tinygltf::Accessor& acc = ctx.model.accessors[static_cast<std::size_t>(index)];
  if (!Contains(spec.component_types, acc.componentType)) {
    ctx.Fail(who + ": component type " + ComponentTypeName(acc.componentType) + " not allowed (expected " +
             OneOf(spec.component_types, ComponentTypeName) + ")");
  }
  if (!Contains(spec.types, acc.type)) {
    ctx.Fail(who + ": type " + TypeName(acc.type) + " not allowed (expected " + OneOf(spec.types, TypeName) + ")");
  }
  if (spec.integers && acc.normalized) ctx.Fail(who + ": must not be normalized");
  if (!spec.integers && acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !acc.normalized) {
    ctx.Fail(who + ": component type " + ComponentTypeName(acc.componentType) + " must be normalized");
  }
  return acc;
}

AccessorData ReadAccessor(const Ctx& ctx, int index, const AccessorSpec& spec) {
  const tinygltf::Accessor& acc = CheckedAccessor(ctx, index, spec);
  const std::string who = AccessorName(index, spec.role);
  AccessorData out;
  out.count = acc.count;
  out.components = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(acc.type));
  const auto comps = static_cast<std::size_t>(out.components);
  const auto comp_size = static_cast<std::size_t>(tinygltf::GetComponentSizeInBytes(acc.componentType));
  const bool normalized = acc.normalized && !spec.integers;
  if (acc.count > (std::size_t{1} << 31)) ctx.Fail(who + ": count " + std::to_string(acc.count) + " is too large");
  out.values.assign(acc.count * comps, 0.0);  // no bufferView: zeros (then sparse values)
  if (acc.bufferView != -1) {  // -1: no bufferView: zeros, as glTF 2.0 specifies
    std::size_t stride = 0;
    const unsigned char* p = CheckedBytes(ctx, who, acc.bufferView, acc.byteOffset, acc.count, comp_size * comps, &stride);
    for (std::size_t e = 0; e < acc.count; ++e) {
      for (std::size_t c = 0; c < comps; ++c) {
        out.values[e * comps + c] = ReadComponent(p + e * stride + c * comp_size, acc.componentType, normalized);
      }
    }
  }
  if (acc.sparse.isSparse) ApplySparse(ctx, who, acc, normalized, out);
  return out;
}

const std::vector<int> kFloat = {TINYGLTF_COMPONENT_TYPE_FLOAT};
const std::vector<int> kJointTypes = {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
const std::vector<int> kWeightTypes = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                       TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
const std::vector<int> kRotationTypes = {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};

// ---------------------------------------------------------------- mesh selection

std::string NodeLabel(const tinygltf::Model& model, std::size_t n) {
  const auto& node = model.nodes[n];
  std::string s = Idx("nodes", n);
  if (!node.name.empty()) s += " '" + node.name + "'";
  if (node.mesh >= 0 && static_cast<std::size_t>(node.mesh) < model.meshes.size()) {
    s += " / mesh '" + model.meshes[static_cast<std::size_t>(node.mesh)].name + "'";
  }
  return s;
}

// The node that carries the skinned mesh to import.
std::size_t FindSkinnedNode(const Ctx& ctx, const std::string& wanted) {
  const auto& model = ctx.model;
  std::vector<std::size_t> skinned;
  for (std::size_t n = 0; n < model.nodes.size(); ++n) {
    const auto& node = model.nodes[n];
    if (node.mesh < 0 || node.skin < 0) continue;
    if (static_cast<std::size_t>(node.mesh) >= model.meshes.size()) ctx.Fail(Idx("nodes", n) + ": " + Idx("meshes", node.mesh) + " does not exist");
    if (static_cast<std::size_t>(node.skin) >= model.skins.size()) ctx.Fail(Idx("nodes", n) + ": " + Idx("skins", node.skin) + " does not exist");
    skinned.push_back(n);
  }
  if (skinned.empty()) ctx.Fail("no skinned mesh (no node has both a mesh and a skin)");
  if (wanted.empty()) return skinned.front();
  for (std::size_t n : skinned) {
    const auto& node = model.nodes[n];
    if (node.name == wanted || model.meshes[static_cast<std::size_t>(node.mesh)].name == wanted) return n;
  }
  std::string list;
  for (std::size_t n : skinned) list += (list.empty() ? "" : ", ") + NodeLabel(model, n);
  ctx.Fail("no skinned mesh named '" + wanted + "' (skinned meshes: " + list + ")");
}

// ---------------------------------------------------------------- mesh

bool IsTriangles(int mode) {
  return mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP || mode == TINYGLTF_MODE_TRIANGLE_FAN;
}

// Number of JOINTS_n/WEIGHTS_n sets; every set must have both.
std::size_t InfluenceSets(const Ctx& ctx, const tinygltf::Primitive& prim, const std::string& where) {
  std::size_t sets = 0;
  while (prim.attributes.count("JOINTS_" + std::to_string(sets)) || prim.attributes.count("WEIGHTS_" + std::to_string(sets))) {
    const std::string n = std::to_string(sets);
    if (!prim.attributes.count("JOINTS_" + n)) ctx.Fail(where + ": WEIGHTS_" + n + " without JOINTS_" + n);
    if (!prim.attributes.count("WEIGHTS_" + n)) ctx.Fail(where + ": JOINTS_" + n + " without WEIGHTS_" + n);
    ++sets;
  }
  if (sets == 0) ctx.Fail(where + ": no JOINTS_0/WEIGHTS_0 (every primitive of a skinned mesh needs them)");
  return sets;
}

void CheckCount(const Ctx& ctx, const AccessorData& data, int index, const std::string& role, std::size_t expected) {
  if (data.count != expected) {
    ctx.Fail(AccessorName(index, role) + ": count " + std::to_string(data.count) + " differs from POSITION's count " +
             std::to_string(expected));
  }
}

// Reads influence set `set` of a primitive into the mesh slots [4*set, 4*set+4) of
// vertices [first, first+count), checking every weight and joint.
void ReadInfluenceSet(const Ctx& ctx, const tinygltf::Primitive& prim, const std::string& where, std::size_t set,
                      std::size_t first, std::size_t count, SkinnedMesh& mesh) {
  const std::string n = std::to_string(set);
  const int ji = prim.attributes.at("JOINTS_" + n), wi = prim.attributes.at("WEIGHTS_" + n);
  const std::string jrole = "JOINTS_" + n + " of " + where, wrole = "WEIGHTS_" + n + " of " + where;
  const AccessorData joints = ReadAccessor(ctx, ji, {jrole, kJointTypes, {TINYGLTF_TYPE_VEC4}, true});
  const AccessorData weights = ReadAccessor(ctx, wi, {wrole, kWeightTypes, {TINYGLTF_TYPE_VEC4}, false});
  CheckCount(ctx, joints, ji, jrole, count);
  CheckCount(ctx, weights, wi, wrole, count);
  const auto slots = static_cast<std::size_t>(mesh.influences);
  for (std::size_t v = 0; v < count; ++v) {
    for (int k = 0; k < 4; ++k) {
      const double w = weights.at(v, k), j = joints.at(v, k);
      const std::string vertex = "vertex " + std::to_string(v) + " slot " + std::to_string(k);
      if (std::isnan(w)) ctx.Fail(AccessorName(wi, wrole) + ": " + vertex + ": weight is NaN");
      if (!std::isfinite(w)) ctx.Fail(AccessorName(wi, wrole) + ": " + vertex + ": weight is infinite");
      if (w < 0.0) ctx.Fail(AccessorName(wi, wrole) + ": " + vertex + ": weight " + Num(w) + " is negative");
      if (w != 0.0 && j >= mesh.joint_count) {
        ctx.Fail(AccessorName(ji, jrole) + ": " + vertex + ": joint " + Num(j) + " is outside the skin (" +
                 std::to_string(mesh.joint_count) + " joints) with weight " + Num(w));
      }
      const std::size_t at = (first + v) * slots + set * 4 + static_cast<std::size_t>(k);
      mesh.weights[at] = static_cast<float>(w);
      mesh.joints[at] = w != 0.0 ? static_cast<std::uint16_t>(j) : 0;  // unused slots: joint 0
    }
  }
}

void AppendPrimitive(const Ctx& ctx, const tinygltf::Primitive& prim, const std::string& where, bool with_normals,
                     SkinnedMesh& mesh) {
  if (!prim.attributes.count("POSITION")) ctx.Fail(where + ": no POSITION attribute");
  const int pi = prim.attributes.at("POSITION");
  const AccessorData pos = ReadAccessor(ctx, pi, {"POSITION of " + where, kFloat, {TINYGLTF_TYPE_VEC3}});
  const std::size_t first = mesh.positions.size(), count = pos.count;
  for (std::size_t v = 0; v < count; ++v) mesh.positions.emplace_back(pos.at(v, 0), pos.at(v, 1), pos.at(v, 2));
  if (with_normals) {
    const int ni = prim.attributes.at("NORMAL");
    const AccessorData nrm = ReadAccessor(ctx, ni, {"NORMAL of " + where, kFloat, {TINYGLTF_TYPE_VEC3}});
    CheckCount(ctx, nrm, ni, "NORMAL of " + where, count);
    for (std::size_t v = 0; v < count; ++v) mesh.normals.emplace_back(nrm.at(v, 0), nrm.at(v, 1), nrm.at(v, 2));
  }
  const auto slots = static_cast<std::size_t>(mesh.influences);
  mesh.joints.resize(mesh.positions.size() * slots, 0);
  mesh.weights.resize(mesh.positions.size() * slots, 0.0f);
  const std::size_t sets = InfluenceSets(ctx, prim, where);
  for (std::size_t s = 0; s < sets; ++s) ReadInfluenceSet(ctx, prim, where, s, first, count, mesh);
  for (std::size_t v = 0; v < count; ++v) {
    const float* w = &mesh.weights[(first + v) * slots];
    if (std::all_of(w, w + slots, [](float x) { return x == 0.0f; })) {
      ctx.Fail(where + ": vertex " + std::to_string(v) + ": all weights are zero (" +
               AccessorName(prim.attributes.at("WEIGHTS_0"), "WEIGHTS_0") + ")");
    }
  }
}

// Compacts the influences, then rejects (strict) or renormalises weights whose sum is not 1.
void FinishWeights(const Ctx& ctx, const std::string& mesh_name, bool strict, SkinnedMesh& mesh,
                   std::vector<std::string>& warnings) {
  if (const std::size_t cut = CompactInfluences(mesh); cut > 0) {
    warnings.push_back(ctx.path + ": " + std::to_string(cut) + " vertices have more than " +
                       std::to_string(kMaxInfluences) + " influences: kept the largest " +
                       std::to_string(kMaxInfluences) + " and renormalised them");
  }
  const auto slots = static_cast<std::size_t>(mesh.influences);
  std::size_t bad = 0, first = 0;
  double first_sum = 1.0;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    double sum = 0.0;
    for (std::size_t k = 0; k < slots; ++k) sum += mesh.weights[v * slots + k];
    if (std::abs(sum - 1.0) > kWeightSumTolerance) {
      if (bad == 0) {
        first = v;
        first_sum = sum;
      }
      ++bad;
    }
  }
  if (bad == 0) return;
  if (strict) {
    ctx.Fail(mesh_name + ": vertex " + std::to_string(first) + ": weights sum to " + Num(first_sum) + ", not 1 (" +
             std::to_string(bad) + " such vertices; strict import does not renormalise)");
  }
  const RenormalizeReport r = Renormalize(mesh);
  warnings.push_back(ctx.path + ": renormalised weights of " + std::to_string(r.changed_vertices) +
                     " vertices (worst: vertex " + std::to_string(r.worst_vertex) + ", sum " + Num(r.worst_sum) + ")");
}

SkinnedMesh ReadMesh(const Ctx& ctx, std::size_t node_index, const GltfImportOptions& options,
                     std::vector<std::string>& warnings) {
  const auto& node = ctx.model.nodes[node_index];
  const auto mesh_index = static_cast<std::size_t>(node.mesh);
  const tinygltf::Mesh& src = ctx.model.meshes[mesh_index];
  SkinnedMesh mesh;
  mesh.name = !src.name.empty() ? src.name : !node.name.empty() ? node.name : Idx("meshes", mesh_index);
  mesh.joint_count = static_cast<int>(ctx.model.skins[static_cast<std::size_t>(node.skin)].joints.size());
  std::vector<std::size_t> used;
  std::size_t sets = 0;
  bool normals = options.normals;
  for (std::size_t p = 0; p < src.primitives.size(); ++p) {
    const auto& prim = src.primitives[p];
    if (!IsTriangles(prim.mode)) continue;
    used.push_back(p);
    sets = std::max(sets, InfluenceSets(ctx, prim, Idx("meshes", mesh_index) + "." + Idx("primitives", p)));
    normals = normals && prim.attributes.count("NORMAL") > 0;
  }
  if (used.empty()) ctx.Fail(Idx("meshes", mesh_index) + " '" + src.name + "': no triangle primitives");
  if (used.size() < src.primitives.size()) {
    warnings.push_back(ctx.path + ": " + Idx("meshes", mesh_index) + ": skipped " +
                       std::to_string(src.primitives.size() - used.size()) + " non-triangle primitives");
  }
  mesh.influences = static_cast<int>(4 * sets);
  for (std::size_t p : used) {
    AppendPrimitive(ctx, src.primitives[p], Idx("meshes", mesh_index) + "." + Idx("primitives", p), normals, mesh);
  }
  FinishWeights(ctx, Idx("meshes", mesh_index) + " '" + mesh.name + "'", options.strict, mesh, warnings);
  ThrowIfInvalid(mesh, ctx.path);
  return mesh;
}

// ---------------------------------------------------------------- skeleton

void CheckLength(const Ctx& ctx, std::size_t n, const char* field, const std::vector<double>& v, std::size_t want) {
  if (!v.empty() && v.size() != want) {
    ctx.Fail(Idx("nodes", n) + ": " + field + " has " + std::to_string(v.size()) + " numbers (expected " +
             std::to_string(want) + ")");
  }
}

Node ReadNode(const Ctx& ctx, std::size_t n) {
  const tinygltf::Node& src = ctx.model.nodes[n];
  Node node;
  node.name = src.name;
  CheckLength(ctx, n, "translation", src.translation, 3);
  CheckLength(ctx, n, "rotation", src.rotation, 4);
  CheckLength(ctx, n, "scale", src.scale, 3);
  CheckLength(ctx, n, "matrix", src.matrix, 16);
  if (!src.translation.empty()) node.rest.translation = glm::make_vec3(src.translation.data());
  if (!src.rotation.empty()) {
    const auto& r = src.rotation;  // glTF: x, y, z, w
    node.rest.rotation = glm::dquat(r[3], r[0], r[1], r[2]);
  }
  if (!src.scale.empty()) node.rest.scale = glm::make_vec3(src.scale.data());
  if (!src.matrix.empty()) {
    node.has_matrix = true;
    node.matrix = glm::make_mat4(src.matrix.data());  // column-major, like glTF
  }
  return node;
}

Skeleton ReadSkeleton(const Ctx& ctx, int skin_index) {
  const auto& model = ctx.model;
  Skeleton skeleton;
  for (std::size_t n = 0; n < model.nodes.size(); ++n) skeleton.nodes.push_back(ReadNode(ctx, n));
  for (std::size_t n = 0; n < model.nodes.size(); ++n) {
    for (int child : model.nodes[n].children) {
      if (child < 0 || static_cast<std::size_t>(child) >= model.nodes.size()) {
        ctx.Fail(Idx("nodes", n) + ": child " + std::to_string(child) + " does not exist");
      }
      Node& c = skeleton.nodes[static_cast<std::size_t>(child)];
      if (c.parent >= 0) {
        ctx.Fail(Idx("nodes", static_cast<std::size_t>(child)) + " has two parents (" +
                 Idx("nodes", static_cast<std::size_t>(c.parent)) + " and " + Idx("nodes", n) + ")");
      }
      c.parent = static_cast<int>(n);
    }
  }
  const tinygltf::Skin& skin = model.skins[static_cast<std::size_t>(skin_index)];
  const std::string skin_name = Idx("skins", static_cast<std::size_t>(skin_index));
  if (skin.joints.empty()) ctx.Fail(skin_name + ": no joints");
  for (std::size_t j = 0; j < skin.joints.size(); ++j) {
    if (skin.joints[j] < 0 || static_cast<std::size_t>(skin.joints[j]) >= model.nodes.size()) {
      ctx.Fail(skin_name + ".joints[" + std::to_string(j) + "]: node " + std::to_string(skin.joints[j]) + " does not exist");
    }
  }
  skeleton.joints = skin.joints;
  skeleton.inverse_bind.assign(skin.joints.size(), glm::dmat4(1.0));
  if (skin.inverseBindMatrices >= 0) {
    const std::string role = "inverseBindMatrices of " + skin_name;
    const AccessorData ibm = ReadAccessor(ctx, skin.inverseBindMatrices, {role, kFloat, {TINYGLTF_TYPE_MAT4}});
    if (ibm.count < skin.joints.size()) {
      ctx.Fail(AccessorName(skin.inverseBindMatrices, role) + ": " + std::to_string(ibm.count) + " matrices for " +
               std::to_string(skin.joints.size()) + " joints");
    }
    for (std::size_t j = 0; j < skin.joints.size(); ++j) skeleton.inverse_bind[j] = glm::make_mat4(&ibm.values[j * 16]);
  }
  skeleton.Validate(ctx.path);
  return skeleton;
}

// ---------------------------------------------------------------- animations

bool ParsePath(const std::string& s, ChannelPath* path) {
  if (s == "translation") *path = ChannelPath::kTranslation;
  else if (s == "rotation") *path = ChannelPath::kRotation;
  else if (s == "scale") *path = ChannelPath::kScale;
  else return false;
  return true;
}

Interpolation ParseInterpolation(const Ctx& ctx, const std::string& s, const std::string& where) {
  if (s == "LINEAR") return Interpolation::kLinear;
  if (s == "STEP") return Interpolation::kStep;
  if (s == "CUBICSPLINE") return Interpolation::kCubicSpline;
  ctx.Fail(where + ": unknown interpolation '" + s + "' (expected LINEAR, STEP or CUBICSPLINE)");
}

Channel ReadChannel(const Ctx& ctx, const tinygltf::Animation& anim, const std::string& where, std::size_t c,
                    ChannelPath path) {
  const tinygltf::AnimationChannel& src = anim.channels[c];
  const std::string channel_name = where + "." + Idx("channels", c);
  if (src.target_node < 0 || static_cast<std::size_t>(src.target_node) >= ctx.model.nodes.size()) {
    ctx.Fail(channel_name + ": target node " + std::to_string(src.target_node) + " does not exist");
  }
  if (src.sampler < 0 || static_cast<std::size_t>(src.sampler) >= anim.samplers.size()) {
    ctx.Fail(channel_name + ": sampler " + std::to_string(src.sampler) + " does not exist");
  }
  const tinygltf::AnimationSampler& sampler = anim.samplers[static_cast<std::size_t>(src.sampler)];
  const std::string sampler_name = where + "." + Idx("samplers", static_cast<std::size_t>(src.sampler));
  Channel ch;
  ch.node = src.target_node;
  ch.path = path;
  ch.interpolation = ParseInterpolation(ctx, sampler.interpolation, sampler_name);
  const AccessorData in = ReadAccessor(ctx, sampler.input, {"input of " + sampler_name, kFloat, {TINYGLTF_TYPE_SCALAR}});
  const bool rotation = path == ChannelPath::kRotation;
  const AccessorData out = ReadAccessor(ctx, sampler.output, {"output of " + sampler_name, rotation ? kRotationTypes : kFloat,
                                                              {rotation ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3}});
  const std::size_t per_key = ch.interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (out.count != in.count * per_key) {
    ctx.Fail(sampler_name + ": output " + Idx("accessors", sampler.output) + " has " + std::to_string(out.count) +
             " values for " + std::to_string(in.count) + " keys (expected " + std::to_string(in.count * per_key) + ")");
  }
  for (std::size_t k = 0; k < in.count; ++k) ch.times.push_back(static_cast<float>(in.values[k]));
  for (std::size_t k = 0; k < out.count; ++k) {
    ch.values.emplace_back(out.at(k, 0), out.at(k, 1), out.at(k, 2), rotation ? out.at(k, 3) : 0.0);
  }
  return ch;
}

std::vector<AnimationClip> ReadAnimations(const Ctx& ctx) {
  std::vector<AnimationClip> clips;
  for (std::size_t a = 0; a < ctx.model.animations.size(); ++a) {
    const tinygltf::Animation& anim = ctx.model.animations[a];
    const std::string where = Idx("animations", a);
    AnimationClip clip;
    clip.name = anim.name;
    for (std::size_t c = 0; c < anim.channels.size(); ++c) {
      const std::string& target = anim.channels[c].target_path;
      if (target == "weights") continue;  // morph targets: not skinning
      ChannelPath path;
      if (!ParsePath(target, &path)) {
        ctx.Fail(where + "." + Idx("channels", c) + ": unknown target path '" + target + "'");
      }
      clip.channels.push_back(ReadChannel(ctx, anim, where, c, path));
    }
    clip.UpdateRange();
    clip.Validate(static_cast<int>(ctx.model.nodes.size()),
                  ctx.path + ": " + where + (anim.name.empty() ? "" : " '" + anim.name + "'"));
    clips.push_back(std::move(clip));
  }
  return clips;
}

}  // namespace

GltfImportResult ImportGltf(const std::string& path, const GltfImportOptions& options) {
  GltfImportResult result;
  const tinygltf::Model model = LoadModel(path, result.warnings);
  const Ctx ctx{model, path};
  const std::size_t node = FindSkinnedNode(ctx, options.mesh);
  SkinnedAsset& asset = result.asset;
  asset.source = path;
  asset.skeleton = ReadSkeleton(ctx, model.nodes[node].skin);
  asset.mesh = ReadMesh(ctx, node, options, result.warnings);
  asset.animations = ReadAnimations(ctx);
  return result;
}

}  // namespace skintune
