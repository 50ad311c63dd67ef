#include "engine/mesh_import.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

using incise::engine::import_surface;
using incise::engine::MeshError;
using incise::engine::winding_number;

namespace {

std::filesystem::path write_file(const std::string& name, const std::string& text) {
  // Named after the process: two test runs at once must not share the file.
  auto path = std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_" + name);
  std::ofstream(path) << text;
  return path;
}

const char* kCube = R"(v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
)";

}  // namespace

TEST(MeshImport, ClosedCubeAndWindingNumber) {
  auto path = write_file("incise_cube.obj", kCube);
  auto soup = import_surface(path, 2.0);
  EXPECT_EQ(soup.vertices.size(), 8u);
  EXPECT_EQ(soup.triangles.size(), 12u);
  EXPECT_DOUBLE_EQ(soup.max[0], 2.0);
  EXPECT_NEAR(std::abs(winding_number(soup, {1, 1, 1})), 1.0, 1e-9);
  EXPECT_NEAR(winding_number(soup, {3, 1, 1}), 0.0, 1e-9);
  EXPECT_NEAR(winding_number(soup, {-0.5, -0.5, 2.5}), 0.0, 1e-9);
  std::filesystem::remove(path);
}

TEST(MeshImport, OpenSurfaceIsRefusedWithTheFileNamed) {
  std::string open(kCube);
  open = open.substr(0, open.rfind("f 4 5 8"));  // drop one triangle: a hole
  auto path = write_file("incise_open_cube.obj", open);
  try {
    import_surface(path);
    FAIL() << "accepted an open surface";
  } catch (const MeshError& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("incise_open_cube.obj"), std::string::npos) << m;
    EXPECT_NE(m.find("not closed"), std::string::npos) << m;
    EXPECT_NE(m.find("3 edges"), std::string::npos) << m;
  }
  std::filesystem::remove(path);
}

TEST(MeshImport, GarbageAndMissingFilesAreErrors) {
  auto path = write_file("incise_garbage.obj", "this is not a mesh\n\x01\x02");
  EXPECT_THROW(import_surface(path), MeshError);
  EXPECT_THROW(import_surface("no/such/mesh.stl"), MeshError);
  std::filesystem::remove(path);
}

TEST(MeshImport, StlAndPlyAreReadToo) {
  // The same unit cube as ASCII STL (facets repeat their vertices) and ASCII PLY.
  const int faces[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                            {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};
  const double v[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  std::string stl = "solid cube\n";
  for (const auto& f : faces) {
    stl += "facet normal 0 0 0\nouter loop\n";
    for (int k : f)
      stl += "vertex " + std::to_string(v[k][0]) + " " + std::to_string(v[k][1]) + " " + std::to_string(v[k][2]) + "\n";
    stl += "endloop\nendfacet\n";
  }
  stl += "endsolid cube\n";
  std::string ply = "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 12\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& p : v) ply += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
  for (const auto& f : faces) ply += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + "\n";
  for (const auto& [name, text] : {std::pair{"incise_cube.stl", stl}, std::pair{"incise_cube.ply", ply}}) {
    SCOPED_TRACE(name);
    auto path = write_file(name, text);
    auto soup = import_surface(path);
    EXPECT_EQ(soup.vertices.size(), 8u);  // coincident STL corners merged
    EXPECT_EQ(soup.triangles.size(), 12u);
    EXPECT_NEAR(std::abs(winding_number(soup, {0.5, 0.5, 0.5})), 1.0, 1e-9);
    std::filesystem::remove(path);
  }
}

// assimp 5.2.5 hung on these, read out of bounds or asked for gigabytes
// (fuzz/corpus/mesh_ply/regression_ply_*), or took a NUL for a data line's end; incise's PLY
// reader refuses each, naming the line.
TEST(MeshImport, MalformedPlyHeadersAreRefusedNamingTheLine) {
  const std::string good_start = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n";
  const std::string rest = "element face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                           "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {good_start + "property fload y\n" + rest, "PLY header line 5 ('property fload y'): unsupported property type 'fload'"},
      {good_start + "property float y\nproperty float z\nelement face 4\nproperty list 0 2 1\nend_header\n",
       "PLY header line 8 ('property list 0 2 1')"},
      {"ply\xfc\xff\n" + good_start.substr(4), "PLY header line 1"},
      {"ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nend_header\n",
       "PLY header line 3 ('element vertex 4000000000'): claims 4000000000 entries, more than the file's"},
      {"ply\nformat ascii 1.0\nelement vertex 4\n", "has no 'end_header' line"},
      {good_start + "property float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\v" +
           rest.substr(rest.find("end_header\n") + 11),
       "PLY header line 9: control character 0x0b at column 11"},
      {"ply\nformat ascii 1.0\nelement 66666666666vertex 4\nproperty float x\nend_header\n1\n2\n3\n4\n",
       "PLY header line 3 ('element 66666666666vertex 4'): an element's name must start with a letter or '_'"},
      {good_start + "property float y\nproperty float z\n" + rest.substr(0, rest.find("0 1 0\n")) + std::string("0 \0 1\n", 6) +
           rest.substr(rest.find("0 1 0\n") + 6),
       "PLY line 12: control character 0x00 at column 3"},
  };
  for (const auto& [text, expected] : cases) {
    SCOPED_TRACE(expected);
    auto path = write_file("incise_bad.ply", text);
    try {
      import_surface(path);
      ADD_FAILURE() << "accepted";
    } catch (const MeshError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("incise_bad.ply"), std::string::npos) << e.what();
    }
    std::filesystem::remove(path);
  }
}

// A face list entry of zero vertices made assimp 5.2.5's PLY reader claim polygons and its
// triangulation abort the process on an assertion (fuzz/corpus/mesh_ply/regression_ply_empty_face_abort.ply):
// a face has at least one vertex.
TEST(MeshImport, AnEmptyPlyFaceIsRefusedRatherThanAborting) {
  const std::string ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                          "element face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                          "3 0 2 1\n0\n3 0 3 2\n3 1 2 3\n";
  auto path = write_file("incise_empty_face.ply", ply);
  try {
    import_surface(path);
    ADD_FAILURE() << "accepted";
  } catch (const MeshError& e) {
    EXPECT_NE(std::string(e.what()).find("incise_empty_face.ply: PLY line 15 (face 1): a face with no vertices"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

// assimp's triangulation took time quadratic in a polygon's corners: a PLY face claiming 32214
// corners on 4 vertices held assimp 5.2.5 for minutes (fuzz/corpus/mesh_ply/regression_ply_huge_face_hang.ply).
// A polygon is fanned from its first corner now, in time linear in its corners; triangles whose
// corners repeat are dropped, so 5 corners on 4 vertices make 2 triangles, an open surface.
TEST(MeshImport, APolygonIsFannedWhateverItsCorners) {
  const std::string header = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                             "element face 1\nproperty list int int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
  std::string face = "5";
  for (int i = 0; i < 5; ++i) face += " " + std::to_string(i % 4);
  auto path = write_file("incise_big_face.ply", header + face + "\n");
  try {
    import_surface(path);
    ADD_FAILURE() << "accepted";
  } catch (const MeshError& e) {
    EXPECT_NE(std::string(e.what()).find("incise_big_face.ply: the surface is not closed: 4 edges"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

// assimp 5.2.5 allocates what a PLY list's count says: 344444444444444444 in a 235-byte ASCII
// file took 12 GB (fuzz/corpus/mesh_ply/regression_ply_huge_list_count_oom.ply), 400000000 in
// an 86-byte binary one 3 GB. A list may claim no more values than its line (ASCII) or the
// file (binary) has left.
TEST(MeshImport, APlyListClaimingMoreValuesThanTheFileHasIsRefused) {
  const std::string vertices = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  const std::string ascii = "ply\nformat ascii 1.0\n" + vertices +
                            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n\n1 0 0\n0 1 0\n"
                            "344444444444444444 0 1 2\n";
  std::string binary = "ply\nformat binary_big_endian 1.0\n" + vertices +
                       "element face 1\nproperty list int int vertex_indices\nend_header\n";
  binary += std::string(36, '\0') + std::string("\x17\xd7\x84\x00", 4) + std::string(12, '\0');  // 400000000
  const std::vector<std::pair<std::string, std::string>> cases = {
      {ascii, "PLY line 14 (face 0): list 'vertex_indices' claims 344444444444444444 values, its line has 3 left"},
      {binary, "PLY data at byte 200 (face 0): list 'vertex_indices' claims 400000000 values, more than the file's 12 bytes left hold"},
  };
  for (const auto& [text, expected] : cases) {
    auto path = write_file("incise_big_list.ply", text);
    try {
      import_surface(path);
      ADD_FAILURE() << "accepted";
    } catch (const MeshError& e) {
      EXPECT_NE(std::string(e.what()).find("incise_big_list.ply: " + expected), std::string::npos) << e.what();
    }
    std::filesystem::remove(path);
  }
}

// mesh_up "y": the file's y is +z and its z is -y, a rotation (the cube keeps its volume's sign).
TEST(MeshImport, UpAxisTurnsTheFileSoItsAxisIsZ) {
  auto path = write_file("incise_cube_up.obj", kCube);
  const auto soup = import_surface(path, 2.0, "y");
  EXPECT_DOUBLE_EQ(soup.min[1], -2.0);
  EXPECT_DOUBLE_EQ(soup.max[1], 0.0);
  EXPECT_DOUBLE_EQ(soup.max[2], 2.0);
  EXPECT_NEAR(std::abs(winding_number(soup, {1, -1, 1})), 1.0, 1e-9);
  EXPECT_EQ(incise::engine::turn_up({1, 2, 3}, "-x"), (std::array<double, 3>{3, 2, -1}));
  EXPECT_THROW(import_surface(path, 1.0, "w"), MeshError);
  std::filesystem::remove(path);
}
