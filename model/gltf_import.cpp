// skintune: glTF 2.0 import through tinygltf. tinygltf parses the JSON/GLB and
// decodes the buffers; everything read from the buffers goes through our own
// bounds-checked accessor reader (gltf_accessor.h), so a malformed file gives
// an Error naming the accessor / bufferView / buffer instead of reading out of
// bounds. This file: file loading, mesh selection, mesh, skeleton, animations.
#include "model/gltf_import.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "base/error.h"
#include "model/gltf_accessor.h"
#include "base/input_file.h"

namespace skintune::internal {
namespace {

using namespace gltf_detail;  // Ctx, naming helpers, ReadAccessor
using std::size_t;
using std::to_string;

// ---------------------------------------------------------------- helpers

// tinygltf's messages: one line, data URIs cut short.
std::string Tidy(std::string message) {
  std::replace_if(
      message.begin(), message.end(), [](char c) { return c == '\n' || c == '\r'; }, ' ');
  for (size_t at = message.find("base64,"); at != std::string::npos; at = message.find("base64,", at + 1)) {
    const size_t begin = at + 7, end = std::min(message.find(' ', begin), message.size());
    if (end - begin > 16) message.replace(begin + 16, end - begin - 16, "...");
  }
  while (!message.empty() && message.back() == ' ') message.pop_back();
  if (message.size() > 400) message = message.substr(0, 400) + "...";
  return message.empty() ? "no details" : message;
}

// ---------------------------------------------------------------- file loading

std::vector<unsigned char> ReadFileBytes(const std::string& path) { return ReadInputBytes(path, kGltfInput); }

bool LooksLikeGltfJson(const std::vector<unsigned char>& bytes) {
  const nlohmann::json j = nlohmann::json::parse(bytes.begin(), bytes.end(), nullptr, false);
  return !j.is_discarded() && j.is_object() && j.contains("asset");
}

// Images are irrelevant to skinning: keep them undecoded.
bool SkipImage(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
               void*) {
  return true;
}

// External files (buffer and image URIs) are read through these, not tinygltf's
// defaults, which open anything: for a directory they allocate the size lseek
// reports (2^63 - 1 bytes on ext4: std::bad_alloc), a FIFO blocks forever.
// Regular files only.
bool RegularFileExists(const std::string& path, void*) {
  std::error_code ec;
  return std::filesystem::is_regular_file(path, ec);
}

bool ReadRegularFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
  auto fail = [&](const char* what) {
    if (err) *err += what + path + "\n";
    return false;
  };
  try {
    *out = ReadInputBytes(path, kGltfInput);
  } catch (const Error& e) {
    if (err) *err += std::string(e.what()) + "\n";
    return false;
  }
  return out->empty() ? fail("File is empty : ") : true;
}

// tinygltf recurses once per nesting level of `extras` / `extensions` values;
// some 20000 levels overflow the stack. Real files nest a handful of levels.
constexpr size_t kMaxJsonDepth = 512;

// The deepest nesting of [ and { in JSON text, strings skipped (exact for valid JSON).
size_t JsonDepth(const unsigned char* text, size_t size) {
  size_t depth = 0, deepest = 0;
  bool in_string = false;
  for (size_t i = 0; i < size; ++i) {
    const unsigned char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;  // the escaped character
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

std::uint32_t LoadU32(const std::vector<unsigned char>& bytes, size_t at) {
  return static_cast<std::uint32_t>(bytes[at]) | static_cast<std::uint32_t>(bytes[at + 1]) << 8 |
         static_cast<std::uint32_t>(bytes[at + 2]) << 16 | static_cast<std::uint32_t>(bytes[at + 3]) << 24;
}

// What tinygltf must not be given: JSON nested too deeply, and (GLB) a BIN chunk
// that runs past the end of the file. tinygltf 2.7.0 checks the BIN chunk's
// length without its 8-byte header, so it would read up to 8 bytes past the end.
void PrecheckForTinygltf(const std::string& path, const std::vector<unsigned char>& bytes, bool binary) {
  const unsigned char* json = bytes.data();
  size_t json_size = bytes.size();
  if (binary && bytes.size() >= 20) {
    const std::uint64_t length = LoadU32(bytes, 8), json_end = 20 + std::uint64_t{LoadU32(bytes, 12)};
    json = bytes.data() + 20;
    json_size = static_cast<size_t>(std::min<std::uint64_t>(json_end, bytes.size()) - 20);
    if (length <= bytes.size() && json_end + 12 <= length) {  // a BIN chunk: tinygltf reads it
      const std::uint64_t bin_length = LoadU32(bytes, static_cast<size_t>(json_end));
      if (json_end + 8 + bin_length > length) {
        throw Error(path + ": invalid glTF file: BIN chunk of " + to_string(bin_length) + " bytes at byte " +
                    to_string(json_end + 8) + " runs past the end of the GLB (" + to_string(length) +
                    " bytes)");
      }
    }
  }
  // Text that is not JSON at all fails tinygltf's parser first: leave its message to tinygltf.
  if (JsonDepth(json, json_size) > kMaxJsonDepth && nlohmann::json::accept(json, json + json_size)) {
    throw Error(path + ": invalid glTF file: JSON nested more than " + to_string(kMaxJsonDepth) +
                " levels deep");
  }
}

// Parses the file with tinygltf: GLB when it starts with the magic "glTF", JSON otherwise.
tinygltf::Model LoadModel(const std::string& path, std::vector<std::string>& warnings) {
  const std::vector<unsigned char> bytes = ReadFileBytes(path);
  if (bytes.empty()) throw Error(path + ": not a glTF 2.0 file (empty file)");
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) throw Error(path + ": file of 4 GiB or more");
  const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  PrecheckForTinygltf(path, bytes, binary);
  const std::string base_dir = std::filesystem::path(path).parent_path().string();
  const auto size = static_cast<unsigned int>(bytes.size());
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&SkipImage, nullptr);
  loader.SetFsCallbacks({&RegularFileExists, &tinygltf::ExpandFilePath, &ReadRegularFile,
                         &tinygltf::WriteWholeFile, nullptr});
  tinygltf::Model model;
  std::string err, warn;
  bool ok = false;
  try {
    ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), size, base_dir)
                : loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                             size, base_dir);
  } catch (const std::exception& e) {
    // tinygltf 2.7.0 throws on some malformed files, e.g. std::out_of_range
    // for a GLB buffer whose byteLength is 0.
    throw Error(path + ": invalid glTF file: tinygltf failed (" + Tidy(e.what()) + ")");
  }
  if (!ok && (binary || LooksLikeGltfJson(bytes))) throw Error(path + ": invalid glTF file: " + Tidy(err));
  if (!ok) throw Error(path + ": not a glTF 2.0 file (" + Tidy(err) + ")");
  if (!warn.empty()) warnings.push_back(path + ": tinygltf: " + Tidy(warn));
  return model;
}

// ---------------------------------------------------------------- mesh selection

std::string NodeLabel(const tinygltf::Model& model, size_t n) {
  const tinygltf::Node& node = model.nodes[n];
  std::string s = Idx("nodes", n);
  if (!node.name.empty()) s += " '" + node.name + "'";
  return s + " / mesh '" + model.meshes[Z(node.mesh)].name + "'";
}

// The node that carries the skinned mesh to import.
size_t FindSkinnedNode(const Ctx& ctx, const std::string& wanted) {
  const tinygltf::Model& model = ctx.model;
  std::vector<size_t> skinned;
  for (size_t n = 0; n < model.nodes.size(); ++n) {
    const tinygltf::Node& node = model.nodes[n];
    if (node.mesh < 0 || node.skin < 0) continue;
    if (!InRange(node.mesh, model.meshes))
      ctx.Fail(Idx("nodes", n) + ": " + Idx("meshes", node.mesh) + " does not exist");
    if (!InRange(node.skin, model.skins))
      ctx.Fail(Idx("nodes", n) + ": " + Idx("skins", node.skin) + " does not exist");
    skinned.push_back(n);
  }
  if (skinned.empty()) ctx.Fail("no skinned mesh (no node has both a mesh and a skin)");
  if (wanted.empty()) return skinned.front();
  for (size_t n : skinned) {
    if (model.nodes[n].name == wanted || model.meshes[Z(model.nodes[n].mesh)].name == wanted) return n;
  }
  std::string list;
  for (size_t n : skinned) list += (list.empty() ? "" : ", ") + NodeLabel(model, n);
  ctx.Fail("no skinned mesh named '" + wanted + "' (skinned meshes: " + list + ")");
}

// ---------------------------------------------------------------- mesh

bool IsTriangles(int mode) {
  return mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
         mode == TINYGLTF_MODE_TRIANGLE_FAN;
}

// Number of JOINTS_n/WEIGHTS_n sets; every set must have both.
size_t InfluenceSets(const Ctx& ctx, const tinygltf::Primitive& prim, const std::string& where) {
  size_t sets = 0;
  for (;; ++sets) {
    const std::string n = to_string(sets);
    const bool joints = prim.attributes.count("JOINTS_" + n) > 0,
               weights = prim.attributes.count("WEIGHTS_" + n) > 0;
    if (!joints && !weights) break;
    if (!joints) ctx.Fail(where + ": WEIGHTS_" + n + " without JOINTS_" + n);
    if (!weights) ctx.Fail(where + ": JOINTS_" + n + " without WEIGHTS_" + n);
  }
  if (sets == 0) ctx.Fail(where + ": no JOINTS_0/WEIGHTS_0 (every primitive of a skinned mesh needs them)");
  return sets;
}

// Reads attribute `name` of an attribute map (a primitive's, or one of its
// morph targets'), which must have `count` elements (POSITION's count).
AccessorData ReadAttribute(const Ctx& ctx, const std::map<std::string, int>& attributes, const std::string& name,
                           const std::string& where, AccessorSpec spec, size_t count) {
  const int index = attributes.at(name);
  spec.role = name + " of " + where;
  AccessorData data = ReadAccessor(ctx, index, spec);
  if (data.count != count) {
    ctx.Fail(AccessorName(index, spec.role) + ": count " + to_string(data.count) +
             " differs from POSITION's count " + to_string(count));
  }
  return data;
}

// Reads influence set `set` of a primitive into the mesh slots [4*set, 4*set+4) of
// vertices [first, first+count), checking every weight and joint.
void ReadInfluenceSet(const Ctx& ctx, const tinygltf::Primitive& prim, const std::string& where, size_t set,
                      size_t first, size_t count, SkinnedMesh& mesh) {
  const std::string n = to_string(set);
  const AccessorData joints =
      ReadAttribute(ctx, prim.attributes, "JOINTS_" + n, where, {"", kJointTypes, {TINYGLTF_TYPE_VEC4}, true}, count);
  const AccessorData weights =
      ReadAttribute(ctx, prim.attributes, "WEIGHTS_" + n, where, {"", kWeightTypes, {TINYGLTF_TYPE_VEC4}}, count);
  const auto slots = static_cast<size_t>(mesh.influences);
  for (size_t v = 0; v < count; ++v) {
    for (int k = 0; k < 4; ++k) {
      const double w = weights.at(v, k), j = joints.at(v, k);
      auto fail = [&](const std::string& name, const std::string& problem) {
        ctx.Fail(AccessorName(prim.attributes.at(name + n), name + n + " of " + where) + ": vertex " +
                 to_string(v) + " slot " + to_string(k) + ": " + problem);
      };
      if (std::isnan(w)) fail("WEIGHTS_", "weight is NaN");
      if (!std::isfinite(w)) fail("WEIGHTS_", "weight is infinite");
      if (w < 0.0) fail("WEIGHTS_", "weight " + Num(w) + " is negative");
      if (w != 0.0 && j >= mesh.joint_count) {
        fail("JOINTS_", "joint " + Num(j) + " is outside the skin (" + to_string(mesh.joint_count) +
                            " joints) with weight " + Num(w));
      }
      const size_t at = (first + v) * slots + set * 4 + Z(k);
      mesh.weights[at] = static_cast<float>(w);
      mesh.joints[at] = w != 0.0 ? static_cast<std::uint16_t>(j) : 0;  // unused slots: joint 0
    }
  }
}

void AppendPrimitive(const Ctx& ctx, const tinygltf::Primitive& prim, const std::string& where,
                     bool with_normals, bool with_tangents, SkinnedMesh& mesh) {
  if (!prim.attributes.count("POSITION")) ctx.Fail(where + ": no POSITION attribute");
  const AccessorData pos = ReadAccessor(ctx, prim.attributes.at("POSITION"),
                                        {"POSITION of " + where, kFloat, {TINYGLTF_TYPE_VEC3}});
  const size_t first = mesh.positions.size(), count = pos.count;
  for (size_t v = 0; v < count; ++v) mesh.positions.emplace_back(pos.at(v, 0), pos.at(v, 1), pos.at(v, 2));
  if (with_normals) {
    const AccessorData nrm =
        ReadAttribute(ctx, prim.attributes, "NORMAL", where, {"", kFloat, {TINYGLTF_TYPE_VEC3}}, count);
    for (size_t v = 0; v < count; ++v) mesh.normals.emplace_back(nrm.at(v, 0), nrm.at(v, 1), nrm.at(v, 2));
  }
  if (with_tangents) {
    if (!prim.attributes.count("TANGENT")) ctx.Fail(where + ": no TANGENT attribute (tangents were asked for)");
    const AccessorData tan =
        ReadAttribute(ctx, prim.attributes, "TANGENT", where, {"", kRotationTypes, {TINYGLTF_TYPE_VEC4}}, count);
    for (size_t v = 0; v < count; ++v) {
      const double w = tan.at(v, 3);
      if (w != 1.0 && w != -1.0)
        ctx.Fail(AccessorName(prim.attributes.at("TANGENT"), "TANGENT of " + where) + ": vertex " + to_string(v) +
                 ": handedness (w) is " + Num(w) + ", not +1 or -1");
      mesh.tangents.emplace_back(tan.at(v, 0), tan.at(v, 1), tan.at(v, 2), w);
    }
  }
  const auto slots = static_cast<size_t>(mesh.influences);
  mesh.joints.resize(mesh.positions.size() * slots, 0);
  mesh.weights.resize(mesh.positions.size() * slots, 0.0f);
  const size_t sets = InfluenceSets(ctx, prim, where);
  for (size_t s = 0; s < sets; ++s) ReadInfluenceSet(ctx, prim, where, s, first, count, mesh);
  for (size_t v = 0; v < count; ++v) {
    const float* w = &mesh.weights[(first + v) * slots];
    if (std::all_of(w, w + slots, [](float x) { return x == 0.0f; })) {
      ctx.Fail(where + ": vertex " + to_string(v) + ": all weights are zero (" +
               AccessorName(prim.attributes.at("WEIGHTS_0"), "WEIGHTS_0") + ")");
    }
  }
}

// Compacts the influences, then rejects (strict) or renormalises weights whose sum is not 1.
void FinishWeights(const Ctx& ctx, const std::string& mesh_name, bool strict, SkinnedMesh& mesh,
                   std::vector<std::string>& warnings) {
  if (const size_t cut = CompactInfluences(mesh); cut > 0) {
    warnings.push_back(ctx.path + ": " + to_string(cut) + " vertices have more than " +
                       to_string(kMaxInfluences) + " influences: kept the largest " +
                       to_string(kMaxInfluences) + " and renormalised them");
  }
  const auto slots = static_cast<size_t>(mesh.influences);
  size_t bad = 0, first = 0;
  double first_sum = 1.0;
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    double sum = 0.0;
    for (size_t k = 0; k < slots; ++k) sum += mesh.weights[v * slots + k];
    if (std::abs(sum - 1.0) <= kWeightSumTolerance) continue;
    if (bad++ > 0) continue;
    first = v;
    first_sum = sum;
  }
  if (bad == 0) return;
  if (strict) {
    ctx.Fail(mesh_name + ": vertex " + to_string(first) + ": weights sum to " + Num(first_sum) + ", not 1 (" +
             to_string(bad) + " such vertices; strict import does not renormalise)");
  }
  // Problems renormalising cannot fix (a non-finite position, say) first, named
  // with the file: Renormalize's own message for them has no file name.
  ValidateOptions any_sum;
  any_sum.weight_sum_tolerance = std::numeric_limits<double>::infinity();
  ThrowIfInvalid(mesh, ctx.path, any_sum);
  const RenormalizeReport r = Renormalize(mesh);
  warnings.push_back(ctx.path + ": renormalised weights of " + to_string(r.changed_vertices) +
                     " vertices (worst: vertex " + to_string(r.worst_vertex) + ", sum " + Num(r.worst_sum) +
                     ")");
}

SkinnedMesh ReadMesh(const Ctx& ctx, size_t node_index, const GltfImportOptions& options,
                     std::vector<std::string>& warnings) {
  const tinygltf::Node& node = ctx.model.nodes[node_index];
  const tinygltf::Mesh& src = ctx.model.meshes[Z(node.mesh)];
  const std::string mesh_ref = Idx("meshes", node.mesh);
  SkinnedMesh mesh;
  mesh.name = !src.name.empty() ? src.name : !node.name.empty() ? node.name : mesh_ref;
  mesh.joint_count = static_cast<int>(ctx.model.skins[Z(node.skin)].joints.size());
  std::vector<size_t> used;
  size_t sets = 0;
  bool normals = options.normals, every_tangent = true;
  for (size_t p = 0; p < src.primitives.size(); ++p) {
    if (!IsTriangles(src.primitives[p].mode)) continue;
    used.push_back(p);
    sets = std::max(sets, InfluenceSets(ctx, src.primitives[p], mesh_ref + "." + Idx("primitives", p)));
    normals = normals && src.primitives[p].attributes.count("NORMAL") > 0;
    every_tangent = every_tangent && src.primitives[p].attributes.count("TANGENT") > 0;
  }
  const bool tangents = options.tangents || (options.tangents_when_present && every_tangent && normals);
  if (used.empty()) ctx.Fail(mesh_ref + " '" + src.name + "': no triangle primitives");
  if (used.size() < src.primitives.size()) {
    warnings.push_back(ctx.path + ": " + mesh_ref + ": skipped " +
                       to_string(src.primitives.size() - used.size()) + " non-triangle primitives");
  }
  mesh.influences = static_cast<int>(4 * sets);
  for (size_t p : used)
    AppendPrimitive(ctx, src.primitives[p], mesh_ref + "." + Idx("primitives", p), normals, tangents, mesh);
  FinishWeights(ctx, mesh_ref + " '" + mesh.name + "'", options.strict, mesh, warnings);
  ThrowIfInvalid(mesh, ctx.path);
  return mesh;
}

// ---------------------------------------------------------------- skeleton

void CheckLength(const Ctx& ctx, size_t n, const char* field, const std::vector<double>& v, size_t want) {
  if (!v.empty() && v.size() != want) {
    ctx.Fail(Idx("nodes", n) + ": " + field + " has " + to_string(v.size()) + " numbers (expected " +
             to_string(want) + ")");
  }
}

Node ReadNode(const Ctx& ctx, size_t n) {
  const tinygltf::Node& src = ctx.model.nodes[n];
  CheckLength(ctx, n, "translation", src.translation, 3);
  CheckLength(ctx, n, "rotation", src.rotation, 4);
  CheckLength(ctx, n, "scale", src.scale, 3);
  CheckLength(ctx, n, "matrix", src.matrix, 16);
  Node node;
  node.name = src.name;
  if (!src.translation.empty()) node.rest.translation = glm::make_vec3(src.translation.data());
  if (!src.scale.empty()) node.rest.scale = glm::make_vec3(src.scale.data());
  if (!src.rotation.empty()) {
    const std::vector<double>& r = src.rotation;  // glTF: x, y, z, w; glm::dquat(w, x, y, z)
    node.rest.rotation = glm::dquat(r[3], r[0], r[1], r[2]);
  }
  if (!src.matrix.empty()) {
    node.has_matrix = true;
    node.matrix = glm::make_mat4(src.matrix.data());  // column-major, like glTF
  }
  return node;
}

// Every node of the file (parents from `children`), the skin's joints and inverse bind matrices.
Skeleton ReadSkeleton(const Ctx& ctx, int skin_index) {
  const tinygltf::Model& model = ctx.model;
  Skeleton skeleton;
  for (size_t n = 0; n < model.nodes.size(); ++n) skeleton.nodes.push_back(ReadNode(ctx, n));
  for (size_t n = 0; n < model.nodes.size(); ++n) {
    for (int child : model.nodes[n].children) {
      if (!InRange(child, model.nodes))
        ctx.Fail(Idx("nodes", n) + ": child " + to_string(child) + " does not exist");
      Node& c = skeleton.nodes[Z(child)];
      if (c.parent >= 0) {
        ctx.Fail(Idx("nodes", child) + " has two parents (" + Idx("nodes", c.parent) + " and " +
                 Idx("nodes", n) + ")");
      }
      c.parent = static_cast<int>(n);
    }
  }
  const tinygltf::Skin& skin = model.skins[Z(skin_index)];
  const std::string skin_ref = Idx("skins", skin_index);
  if (skin.joints.empty()) ctx.Fail(skin_ref + ": no joints");
  for (size_t j = 0; j < skin.joints.size(); ++j) {
    if (!InRange(skin.joints[j], model.nodes)) {
      ctx.Fail(skin_ref + "." + Idx("joints", j) + ": node " + to_string(skin.joints[j]) + " does not exist");
    }
  }
  skeleton.joints = skin.joints;
  skeleton.inverse_bind.assign(skin.joints.size(), glm::dmat4(1.0));
  if (skin.inverseBindMatrices >= 0) {
    const std::string role = "inverseBindMatrices of " + skin_ref;
    const AccessorData ibm =
        ReadAccessor(ctx, skin.inverseBindMatrices, {role, kFloat, {TINYGLTF_TYPE_MAT4}});
    if (ibm.count < skin.joints.size()) {
      ctx.Fail(AccessorName(skin.inverseBindMatrices, role) + ": " + to_string(ibm.count) + " matrices for " +
               to_string(skin.joints.size()) + " joints");
    }
    for (size_t j = 0; j < skin.joints.size(); ++j)
      skeleton.inverse_bind[j] = glm::make_mat4(&ibm.values[j * 16]);
  }
  skeleton.Validate(ctx.path);
  return skeleton;
}

// ---------------------------------------------------------------- animations

bool ParsePath(const std::string& s, ChannelPath* path) {
  static const std::map<std::string, ChannelPath> paths = {{"translation", ChannelPath::kTranslation},
                                                           {"rotation", ChannelPath::kRotation},
                                                           {"scale", ChannelPath::kScale}};
  const auto it = paths.find(s);
  if (it != paths.end()) *path = it->second;
  return it != paths.end();
}

Interpolation ParseInterpolation(const Ctx& ctx, const std::string& s, const std::string& where) {
  if (s == "LINEAR") return Interpolation::kLinear;
  if (s == "STEP") return Interpolation::kStep;
  if (s == "CUBICSPLINE") return Interpolation::kCubicSpline;
  ctx.Fail(where + ": unknown interpolation '" + s + "' (expected LINEAR, STEP or CUBICSPLINE)");
}

Channel ReadChannel(const Ctx& ctx, const tinygltf::Animation& anim, const std::string& where, size_t c,
                    ChannelPath path) {
  const tinygltf::AnimationChannel& src = anim.channels[c];
  const std::string channel_ref = where + "." + Idx("channels", c);
  if (!InRange(src.target_node, ctx.model.nodes)) {
    ctx.Fail(channel_ref + ": target node " + to_string(src.target_node) + " does not exist");
  }
  if (!InRange(src.sampler, anim.samplers)) {
    ctx.Fail(channel_ref + ": sampler " + to_string(src.sampler) + " does not exist");
  }
  const tinygltf::AnimationSampler& sampler = anim.samplers[Z(src.sampler)];
  const std::string sampler_ref = where + "." + Idx("samplers", src.sampler);
  Channel ch;
  ch.node = src.target_node;
  ch.path = path;
  ch.interpolation = ParseInterpolation(ctx, sampler.interpolation, sampler_ref);
  const bool rotation = path == ChannelPath::kRotation;
  const AccessorData in =
      ReadAccessor(ctx, sampler.input, {"input of " + sampler_ref, kFloat, {TINYGLTF_TYPE_SCALAR}});
  const AccessorData out = ReadAccessor(ctx, sampler.output,
                                        {"output of " + sampler_ref,
                                         rotation ? kRotationTypes : kFloat,
                                         {rotation ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3}});
  const size_t per_key = ch.interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (out.count != in.count * per_key) {
    ctx.Fail(sampler_ref + ": output " + Idx("accessors", sampler.output) + " has " + to_string(out.count) +
             " values for " + to_string(in.count) + " keys (expected " + to_string(in.count * per_key) + ")");
  }
  for (size_t k = 0; k < in.count; ++k) ch.times.push_back(static_cast<float>(in.values[k]));
  for (size_t k = 0; k < out.count; ++k) {
    ch.values.emplace_back(out.at(k, 0), out.at(k, 1), out.at(k, 2), rotation ? out.at(k, 3) : 0.0);
  }
  return ch;
}

// The skinned mesh's morph targets (every triangle primitive's `targets`, in
// the mesh's vertex order; glTF gives every primitive of a mesh the same
// number of targets), and their default weights: the node's, else the
// mesh's, else zero. POSITION offsets are read, and NORMAL and TANGENT ones
// where the mesh's normals and tangents are.
MorphTargets ReadMorphTargets(const Ctx& ctx, size_t node_index, const SkinnedMesh& mesh,
                              std::vector<std::string>& warnings) {
  const tinygltf::Node& node = ctx.model.nodes[node_index];
  const tinygltf::Mesh& src = ctx.model.meshes[Z(node.mesh)];
  const std::string mesh_ref = Idx("meshes", node.mesh);
  MorphTargets morph;
  size_t targets = 0;
  for (size_t p = 0; p < src.primitives.size(); ++p) {
    if (!IsTriangles(src.primitives[p].mode) || src.primitives[p].targets.empty()) continue;
    const std::string where = mesh_ref + "." + Idx("primitives", p) + ".targets";
    if (targets != 0 && src.primitives[p].targets.size() != targets)
      ctx.Fail(where + ": " + to_string(src.primitives[p].targets.size()) + " morph targets, where " + morph.where +
               " has " + to_string(targets) + " (every primitive of a mesh has the same number)");
    if (targets == 0) morph.where = where;
    targets = src.primitives[p].targets.size();
  }
  if (targets == 0) return morph;
  const size_t n = mesh.positions.size();
  morph.positions.assign(targets, std::vector<glm::vec3>(n, glm::vec3(0.0f)));
  if (mesh.has_normals()) morph.normals.assign(targets, std::vector<glm::vec3>(n, glm::vec3(0.0f)));
  if (mesh.has_tangents()) morph.tangents.assign(targets, std::vector<glm::vec3>(n, glm::vec3(0.0f)));
  size_t first = 0;
  std::set<std::string> unmorphed;  // offsets of attributes skintune does not carry (TEXCOORD_0, COLOR_0, ...)
  for (size_t p = 0; p < src.primitives.size(); ++p) {
    const tinygltf::Primitive& prim = src.primitives[p];
    if (!IsTriangles(prim.mode)) continue;
    const size_t count = ctx.model.accessors[Z(prim.attributes.at("POSITION"))].count;
    for (size_t k = 0; k < prim.targets.size(); ++k) {
      const std::string where = mesh_ref + "." + Idx("primitives", p) + "." + Idx("targets", k);
      for (const auto& [name, accessor] : prim.targets[k]) {
        std::vector<std::vector<glm::vec3>>* into = name == "POSITION"                         ? &morph.positions
                                                    : name == "NORMAL" && mesh.has_normals()   ? &morph.normals
                                                    : name == "TANGENT" && mesh.has_tangents() ? &morph.tangents
                                                                                               : nullptr;
        if (!into) {  // NORMAL or TANGENT offsets of a mesh imported without them are left out as asked
          if (name != "NORMAL" && name != "TANGENT") unmorphed.insert(name);
          continue;
        }
        const AccessorData d =
            ReadAttribute(ctx, prim.targets[k], name, where, {"", kRotationTypes, {TINYGLTF_TYPE_VEC3}}, count);
        for (size_t v = 0; v < count; ++v) {
          const glm::dvec3 delta(d.at(v, 0), d.at(v, 1), d.at(v, 2));
          if (!std::isfinite(delta.x) || !std::isfinite(delta.y) || !std::isfinite(delta.z))
            ctx.Fail(AccessorName(accessor, name + " of " + where) + ": vertex " + to_string(v) + ": not finite");
          (*into)[k][first + v] = glm::vec3(delta);
        }
      }
    }
    first += count;
  }
  if (!unmorphed.empty()) {
    std::string names;
    for (const std::string& name : unmorphed) names += (names.empty() ? "" : ", ") + name;
    warnings.push_back(ctx.path + ": " + morph.where + ": offsets of " + names +
                       " not applied (skintune morphs POSITION, NORMAL and TANGENT only)");
  }
  const std::vector<double>& weights = !node.weights.empty() ? node.weights : src.weights;
  const std::string weights_ref = !node.weights.empty() ? Idx("nodes", node_index) + ".weights" : mesh_ref + ".weights";
  if (!weights.empty() && weights.size() != targets)
    ctx.Fail(weights_ref + ": " + to_string(weights.size()) + " weights for " + to_string(targets) + " morph targets");
  for (size_t k = 0; k < weights.size(); ++k)
    if (!std::isfinite(weights[k])) ctx.Fail(weights_ref + "[" + to_string(k) + "] is not finite");
  morph.weights = weights;
  morph.weights.resize(targets, 0.0);
  return morph;
}

// A `weights` channel on the skinned node: its sampler's output holds the K
// targets' weights per key (3K for CUBICSPLINE), split into Channels of four.
std::vector<Channel> ReadWeightsChannels(const Ctx& ctx, const tinygltf::Animation& anim, const std::string& where,
                                         size_t c, size_t targets) {
  const tinygltf::AnimationChannel& src = anim.channels[c];
  const std::string channel_ref = where + "." + Idx("channels", c);
  if (targets == 0) ctx.Fail(channel_ref + ": animates the morph weights of a mesh without morph targets");
  if (!InRange(src.sampler, anim.samplers)) ctx.Fail(channel_ref + ": sampler " + to_string(src.sampler) + " does not exist");
  const tinygltf::AnimationSampler& sampler = anim.samplers[Z(src.sampler)];
  const std::string sampler_ref = where + "." + Idx("samplers", src.sampler);
  const Interpolation interpolation = ParseInterpolation(ctx, sampler.interpolation, sampler_ref);
  const AccessorData in = ReadAccessor(ctx, sampler.input, {"input of " + sampler_ref, kFloat, {TINYGLTF_TYPE_SCALAR}});
  const AccessorData out =
      ReadAccessor(ctx, sampler.output, {"output of " + sampler_ref, kRotationTypes, {TINYGLTF_TYPE_SCALAR}});
  const size_t per_key = interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (out.count != in.count * per_key * targets)
    ctx.Fail(sampler_ref + ": output " + Idx("accessors", sampler.output) + " has " + to_string(out.count) +
             " values for " + to_string(in.count) + " keys of " + to_string(targets) + " morph targets (expected " +
             to_string(in.count * per_key * targets) + ")");
  std::vector<Channel> channels;
  for (size_t group = 0; group < targets; group += 4) {
    Channel ch;
    ch.node = src.target_node;
    ch.path = ChannelPath::kWeights;
    ch.interpolation = interpolation;
    ch.first_target = static_cast<int>(group);
    for (size_t k = 0; k < in.count; ++k) ch.times.push_back(static_cast<float>(in.values[k]));
    for (size_t e = 0; e < in.count * per_key; ++e) {  // element e: K values
      glm::dvec4 v(0.0);
      for (size_t i = 0; i < 4 && group + i < targets; ++i) v[static_cast<int>(i)] = out.values[e * targets + group + i];
      ch.values.push_back(v);
    }
    channels.push_back(std::move(ch));
  }
  return channels;
}

// Every animation's translation/rotation/scale channels, and the `weights`
// channels of the skinned node (those of other nodes move other meshes).
std::vector<AnimationClip> ReadAnimations(const Ctx& ctx, size_t skinned_node, size_t targets) {
  std::vector<AnimationClip> clips;
  for (size_t a = 0; a < ctx.model.animations.size(); ++a) {
    const tinygltf::Animation& anim = ctx.model.animations[a];
    const std::string where = Idx("animations", a);
    AnimationClip clip;
    clip.name = anim.name;
    for (size_t c = 0; c < anim.channels.size(); ++c) {
      const std::string& target = anim.channels[c].target_path;
      ChannelPath path;
      if (target == "weights") {
        if (anim.channels[c].target_node != static_cast<int>(skinned_node)) continue;
        for (Channel& w : ReadWeightsChannels(ctx, anim, where, c, targets)) clip.channels.push_back(std::move(w));
        continue;
      }
      if (!ParsePath(target, &path))
        ctx.Fail(where + "." + Idx("channels", c) + ": unknown target path '" + target + "'");
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
  const size_t node = FindSkinnedNode(ctx, options.mesh);
  SkinnedAsset& asset = result.asset;
  asset.source = path;
  asset.skeleton = ReadSkeleton(ctx, model.nodes[node].skin);
  asset.mesh = ReadMesh(ctx, node, options, result.warnings);
  asset.mesh.morph = ReadMorphTargets(ctx, node, asset.mesh, result.warnings);
  asset.animations = ReadAnimations(ctx, node, asset.mesh.morph.count());
  return result;
}

}  // namespace skintune::internal
