#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include "base/error.h"
#include "reference/mesh_io.h"
#include "tests/common/scratch_dir.h"

namespace skintune::internal {
namespace {

namespace fs = std::filesystem;

fs::path TempDir() { return testing::ScratchDir("skintune_mesh_io"); }

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

const std::vector<glm::vec3> kPositions = {{1.5f, -2.0f, 0.125f}, {3.0f, 4.0f, 5.0f}};
const std::vector<glm::vec3> kNormals = {{0, 1, 0}, {1, 0, 0}};

// docs/INPUTS.md "Finite outputs": a NaN or infinite value is never written ("-nan" was
// not even readable back by --check); an existing file is kept.
TEST(MeshIo, NonFiniteValuesAreRefusedAndNothingIsWritten) {
  const fs::path dir = TempDir();
  for (const char* name : {"out.obj", "out.stv"}) {
    const fs::path file = dir / name;
    std::ofstream(file) << "earlier";
    std::vector<glm::vec3> positions = kPositions;
    positions[1].y = std::numeric_limits<float>::quiet_NaN();
    try {
      WriteSkinnedVertices(file.string(), positions);
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()), file.string() + ": vertex 1: position is not finite; nothing written");
    }
    std::vector<glm::vec3> normals = kNormals;
    normals[0].z = std::numeric_limits<float>::infinity();
    EXPECT_THROW(WriteSkinnedVertices(file.string(), kPositions, normals), Error);
    EXPECT_EQ(Slurp(file), "earlier");
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2);  // no temporary left
}

// docs/INPUTS.md "Limits": whether an output can be written is known before the work.
TEST(MeshIo, CheckWritableRefusesFoldersAndMissingFoldersAndTouchesNothing) {
  const fs::path dir = TempDir();
  fs::create_directories(dir / "folder");
  EXPECT_THROW(CheckWritable((dir / "folder").string()), Error);
  EXPECT_THROW(CheckWritable((dir / "missing" / "x.obj").string()), Error);
  std::ofstream(dir / "existing.obj") << "kept";
  EXPECT_NO_THROW(CheckWritable((dir / "existing.obj").string()));
  EXPECT_NO_THROW(CheckWritable((dir / "new.obj").string()));
  EXPECT_EQ(Slurp(dir / "existing.obj"), "kept");
  EXPECT_FALSE(fs::exists(dir / "new.obj"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2);
}

TEST(MeshIo, ObjHasOneVLinePerVertexInOrder) {
  const fs::path file = TempDir() / "out.obj";
  WriteSkinnedVertices(file.string(), kPositions);
  EXPECT_EQ(Slurp(file), "v 1.5 -2 0.125\nv 3 4 5\n");
}

TEST(MeshIo, BinaryHasTheDocumentedHeaderAndRoundTrips) {
  const fs::path file = TempDir() / "out.stv";
  WriteSkinnedVertices(file.string(), kPositions, kNormals);
  const std::string data = Slurp(file);
  ASSERT_EQ(data.size(), 16u + 2 * 2 * 12);
  EXPECT_EQ(data.substr(0, 4), "STV1");
  EXPECT_EQ(data[4], 2);
  EXPECT_EQ(data[8], 1);
  const SkinnedVertices back = ReadSkinnedVertices(file.string());
  EXPECT_EQ(back.positions, kPositions);
  EXPECT_EQ(back.normals, kNormals);
}

// Tangents (flag bit 1) follow the normals as 4 floats a vertex, and round
// trip; with them a .obj is refused before anything is written, an unknown
// flag is an error, and a non-finite tangent writes nothing.
TEST(MeshIo, BinaryWithTangentsHasFlagBitOneAndRoundTrips) {
  const std::vector<glm::vec4> tangents = {{0, 0, 1, -1}, {0.6f, 0.8f, 0, 1}};
  const fs::path file = TempDir() / "out.stv";
  WriteSkinnedVertices(file.string(), kPositions, kNormals, tangents);
  std::string data = Slurp(file);
  ASSERT_EQ(data.size(), 16u + 2 * 2 * 12 + 2 * 16);
  EXPECT_EQ(data[8], 3);
  const SkinnedVertices back = ReadSkinnedVertices(file.string());
  EXPECT_EQ(back.positions, kPositions);
  EXPECT_EQ(back.normals, kNormals);
  EXPECT_EQ(back.tangents, tangents);
  WriteSkinnedVertices(file.string(), kPositions, {}, tangents);
  EXPECT_EQ(ReadSkinnedVertices(file.string()).tangents, tangents) << "without normals";
  EXPECT_THROW(WriteSkinnedVertices((TempDir() / "out.obj").string(), kPositions, kNormals, tangents), Error);
  EXPECT_FALSE(fs::exists(TempDir() / "out.obj"));
  const std::vector<glm::vec4> bad = {{0, 0, 1, 1}, {std::numeric_limits<float>::quiet_NaN(), 0, 0, 1}};
  EXPECT_THROW(WriteSkinnedVertices((TempDir() / "bad.stv").string(), kPositions, kNormals, bad), Error);
  EXPECT_FALSE(fs::exists(TempDir() / "bad.stv"));
  data[8] = 4;
  const fs::path odd = TempDir() / "odd.stv";
  std::ofstream(odd, std::ios::binary) << data;
  try {
    (void)ReadSkinnedVertices(odd.string());
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("unknown flags 4"), std::string::npos) << e.what();
  }
}

TEST(MeshIo, ObjWithNormalsRoundTrips) {
  const fs::path file = TempDir() / "out.OBJ";
  WriteSkinnedVertices(file.string(), kPositions, kNormals);
  const SkinnedVertices back = ReadSkinnedVertices(file.string());
  EXPECT_EQ(back.positions, kPositions);
  EXPECT_EQ(back.normals, kNormals);
}

TEST(MeshIo, FailedWriteLeavesTheExistingFileUntouched) {
  const fs::path dir = TempDir();
  const fs::path file = dir / "keep.obj";
  WriteSkinnedVertices(file.string(), kPositions);
  const std::string before = Slurp(file);
  EXPECT_THROW(WriteSkinnedVertices(file.string(), kPositions, std::vector<glm::vec3>(1)), Error);
  EXPECT_THROW(WriteSkinnedVertices((dir / "missing-dir" / "x.obj").string(), kPositions), Error);
  EXPECT_EQ(Slurp(file), before);
  for (const auto& entry : fs::directory_iterator(dir)) EXPECT_EQ(entry.path().filename(), "keep.obj");
}

TEST(MeshIo, ReadingATruncatedBinaryFileNamesTheFile) {
  const fs::path file = TempDir() / "cut.stv";
  WriteSkinnedVertices(file.string(), kPositions);
  fs::resize_file(file, 20);
  try {
    ReadSkinnedVertices(file.string());
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(file.string() + ": size 20 bytes"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skintune::internal
