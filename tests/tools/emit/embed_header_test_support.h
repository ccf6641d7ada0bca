// What the tests of the `skintune emit --db` header share
// (embed_header_test.cpp, embed_header_scenes_test.cpp): the fixture
// databases, a mesh as the header's packers take it, and the header's packed
// inputs against a launch of skintune's packer. Templates over the header's types, whose namespace
// each test's header names.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generator/packer.h"
#include "model/mesh.h"
#include "runtime/winners_db.h"

namespace skintune::internal::testing {

// A winners database of tests/data, by file name.
inline std::vector<WinnersEntry> TestDataWinnersDb(const std::string& name) {
  const std::string path = std::string(SKINTUNE_TEST_DATA_DIR) + "/" + name;
  std::ifstream in(path);
  return WinnersDbFromJson(nlohmann::json::parse(in), path);
}

// A mesh's arrays as PackMesh and BatchMesh take them: 3 floats per position
// and normal, `influences` joints and weights per vertex.
struct MeshArrays {
  std::vector<float> positions, normals, tangents, weights;
  std::vector<std::uint32_t> joints;
};

inline MeshArrays ArraysOf(const SkinnedMesh& mesh) {
  MeshArrays a;
  for (const glm::vec3& p : mesh.positions) a.positions.insert(a.positions.end(), {p.x, p.y, p.z});
  for (const glm::vec3& p : mesh.normals) a.normals.insert(a.normals.end(), {p.x, p.y, p.z});
  for (const glm::vec4& t : mesh.tangents) a.tangents.insert(a.tangents.end(), {t.x, t.y, t.z, t.w});
  a.weights = mesh.weights;
  a.joints.assign(mesh.joints.begin(), mesh.joints.end());
  return a;
}

// The header's PackedInputs buffer of an input argument's name.
template <typename PackedInputs>
const std::vector<std::uint8_t>& Field(const PackedInputs& p, const std::string& name) {
  if (name == "records") return p.records;
  if (name == "positions") return p.positions;
  if (name == "indices") return p.indices;
  if (name == "weights") return p.weights;
  if (name == "tangents") return p.tangents;
  if (name == "morph_offsets") return p.morph_offsets;
  if (name == "morph_targets") return p.morph_targets;
  if (name == "morph_positions") return p.morph_positions;
  if (name == "morph_normals") return p.morph_normals;
  if (name == "morph_tangents") return p.morph_tangents;
  return p.normals;
}

// Every input of `want` byte for byte in `packed`, whole 32-bit words, and
// the buffers the layout has not empty.
template <typename PackedInputs>
void ExpectInputsOf(const PackedInputs& packed, const Launch& want) {
  std::set<std::string> names;
  for (const PackedBuffer& buffer : want.inputs) {
    names.insert(buffer.name);
    EXPECT_EQ(Field(packed, buffer.name), buffer.bytes) << buffer.name;
    EXPECT_EQ(Field(packed, buffer.name).size() % 4, 0u) << buffer.name;
  }
  for (const char* name : {"records", "positions", "indices", "weights", "normals", "tangents", "morph_offsets",
                           "morph_targets", "morph_positions", "morph_normals", "morph_tangents"}) {
    if (!names.count(name)) {
      EXPECT_TRUE(Field(packed, name).empty()) << name << " is not an input of the layout";
    }
  }
}

}  // namespace skintune::internal::testing
