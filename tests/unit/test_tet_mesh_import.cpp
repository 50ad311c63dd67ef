// Tetrahedral meshes in (engine/tet_mesh_import.hpp): the three formats agree on the committed
// lobe, and each bad file is refused naming the file, the element and why.
#include "engine/tet_mesh_import.hpp"

#include "tests/unit/temp_dir.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>

using incise::engine::import_tet_mesh;
using incise::engine::MeshError;
using incise::engine::TetImportReport;

namespace {

const std::filesystem::path kMeshes = std::filesystem::path(INCISE_SOURCE_DIR) / "assets" / "meshes";

// Two tetrahedra sharing the face (2, 3, 4), both positive, plus an unused node 6 and a triangle.
const char* kTwoTetsV2 = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Comments
anything
$EndComments
$Nodes
6
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
5 1 1 1
6 9 9 9
$EndNodes
$Elements
3
1 2 2 0 1 2 3 4
2 4 2 0 1 1 2 3 4
7 4 2 0 1 5 4 3 2
$EndElements
)";

struct Files {
  incise::testing::TempDir dir{"incise_tet_mesh_import"};
  std::filesystem::path write(const std::string& name, const std::string& text) const {
    const auto path = dir.path / name;
    std::ofstream(path) << text;
    return path;
  }
};

// The message of the refusal, or a failure when the file is accepted.
std::string refusal(const std::filesystem::path& file) {
  try {
    import_tet_mesh(file);
  } catch (const MeshError& e) {
    return e.what();
  }
  ADD_FAILURE() << file << " was accepted";
  return "";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

}  // namespace

TEST(TetMeshImport, TheLobeReadsTheSameFromEveryFormat) {
  TetImportReport report;
  const auto v4 = import_tet_mesh(kMeshes / "lobe_tets.msh", 0.001, "y", &report);
  EXPECT_EQ(report.skipped_elements, 828);  // the boundary triangles
  EXPECT_EQ(report.reoriented, 0);
  const auto v2 = import_tet_mesh(kMeshes / "lobe_tets_v2.msh", 0.001, "y");
  const auto vtk = import_tet_mesh(kMeshes / "lobe_tets.vtk", 0.001, "y");
  const auto v4_binary = import_tet_mesh(kMeshes / "lobe_tets_binary.msh", 0.001, "y", &report);
  EXPECT_EQ(report.skipped_elements, 828);
  const auto v2_binary = import_tet_mesh(kMeshes / "lobe_tets_v2_binary.msh", 0.001, "y");
  const auto vtu = import_tet_mesh(kMeshes / "lobe_tets.vtu", 0.001, "y", &report);
  EXPECT_EQ(report.skipped_elements, 828);
  ASSERT_EQ(v4.tets.size(), 2454u);
  ASSERT_EQ(v4.rest.size(), 3 * 646);
  EXPECT_EQ(v2.tets, v4.tets);
  EXPECT_EQ(vtk.tets, v4.tets);
  EXPECT_EQ(v2.rest, v4.rest);
  EXPECT_EQ(vtk.rest, v4.rest);
  EXPECT_EQ(v4_binary.tets, v4.tets);
  EXPECT_EQ(v2_binary.tets, v4.tets);
  // Text keeps 9 significant digits, binary all 17: the same to a micrometre (in m, 1e-9 of 70 mm).
  EXPECT_LT((v4_binary.rest - v4.rest).lpNorm<Eigen::Infinity>(), 1e-9);
  EXPECT_EQ(v2_binary.rest, v4_binary.rest);
  EXPECT_EQ(vtu.tets, v4.tets);
  EXPECT_EQ(vtu.rest, v4_binary.rest);  // its points are base64 doubles
  // mesh_up "y": the file's y is the scene's z, so the lobe rests on z = 0 and is 140 mm long in x (its boundary snapped to within 0.4 mm).
  EXPECT_NEAR(v4.rest.reshaped(3, 646).row(2).minCoeff(), 0.0, 0.004);
  EXPECT_NEAR(v4.rest.reshaped(3, 646).row(0).maxCoeff(), 0.07, 0.001);
  EXPECT_GT(incise::physics::total_volume(v4.rest, v4.tets), 0);
}

TEST(TetMeshImport, SkipsLowerElementsDropsUnusedNodesAndTurnsAxes) {
  Files files;
  TetImportReport report;
  const auto mesh = import_tet_mesh(files.write("two.msh", kTwoTetsV2), 2.0, "x", &report);
  ASSERT_EQ(mesh.tets.size(), 2u);
  EXPECT_EQ(mesh.rest.size(), 15);  // node 6 is dropped
  EXPECT_EQ(report.dropped_nodes, 1);
  EXPECT_EQ(report.skipped_elements, 1);
  // Up "x": the file's x is +z, its y is x, its z is y. Node 2 (1, 0, 0) -> (0, 0, 2).
  EXPECT_EQ(mesh.rest.segment<3>(3).transpose(), Eigen::RowVector3d(0, 0, 2));
  EXPECT_NEAR(incise::physics::total_volume(mesh.rest, mesh.tets), 8 * (1.0 / 6 + 1.0 / 3), 1e-12);
}

TEST(TetMeshImport, AFileOfClockwiseTetrahedraIsReoriented) {
  Files files;
  std::string mirrored = replaced(kTwoTetsV2, "1 1 2 3 4", "1 1 3 2 4");
  mirrored = replaced(mirrored, "1 5 4 3 2", "1 5 3 4 2");
  TetImportReport report;
  const auto mesh = import_tet_mesh(files.write("mirrored.msh", mirrored), 1.0, "z", &report);
  EXPECT_EQ(report.reoriented, 2);
  EXPECT_NEAR(incise::physics::total_volume(mesh.rest, mesh.tets), 0.5, 1e-12);
}

TEST(TetMeshImport, BadTetrahedraAreRefusedNamingFileElementAndWhy) {
  Files files;
  struct Case {
    std::string name, text, expected;
  };
  const std::vector<Case> cases = {
      {"inverted.msh", replaced(kTwoTetsV2, "1 5 4 3 2", "1 5 3 4 2"), "element 2 (tag 7) is inverted: volume -0.333"},
      {"flat.msh", replaced(kTwoTetsV2, "5 1 1 1", "5 0.5 0.5 0"), "element 2 (tag 7) is degenerate: volume"},
      {"missing_node.msh", replaced(kTwoTetsV2, "1 5 4 3 2", "1 8 4 3 2"),
       "element 2 (tag 7) uses node 8, which is not among the file's 6 nodes"},
      {"nan.msh", replaced(kTwoTetsV2, "5 1 1 1", "5 1 nan 1"), "node 5 y is not finite"},
      {"inf.msh", replaced(kTwoTetsV2, "5 1 1 1", "5 1 1e999 1"), "node 5 y '1e999' is out of range"},
      {"overflow.msh", replaced(kTwoTetsV2, "1 5 4 3 2", "1 99999999999999999999 4 3 2"), "does not fit in 64 bits"},
      {"count.msh", replaced(kTwoTetsV2, "$Nodes\n6\n", "$Nodes\n9000000000\n"), "node count 9000000000 is negative or more than"},
      {"hex.msh", replaced(kTwoTetsV2, "7 4 2 0 1 5 4 3 2", "7 5 2 0 1 1 2 3 4 5 6 1 2"),
       "element 2 (tag 7) is of type 5 (8-node hexahedron); only 4-node tetrahedra"},
      {"tet10.msh", replaced(kTwoTetsV2, "7 4 2 0 1 5 4 3 2", "7 11 2 0 1 1 2 3 4 5 6 1 2 3 4"), "element 2 (tag 7) is of type 11 (10-node tetrahedron)"},
      {"twice.msh", replaced(kTwoTetsV2, "1 5 4 3 2", "1 5 4 4 2"), "element 2 (tag 7) uses node 4 twice"},
      {"triangles_only.msh", replaced(replaced(replaced(kTwoTetsV2, "2 4 2 0 1 1 2 3 4\n", ""), "7 4 2 0 1 5 4 3 2\n", ""), "$Elements\n3\n", "$Elements\n1\n"),
       "holds no tetrahedra"},
      {"empty.msh", "", "the file is empty"},
      {"binary.msh", "$MeshFormat\n4.1 1 8\n$EndMeshFormat\n", "byte 24: the endianness check reads 1684948260, not 1"},
      {"binary_size4.msh", "$MeshFormat\n4.1 1 4\n$EndMeshFormat\n", "data size 4 is not read"},
      {"version3.msh", "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n", "MSH version 3.0 is not read"},
      {"empty.vtk", " \n", "the file is empty"},
      {"binary.vtk", "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\n", "only ASCII legacy VTK"},
      {"wedge.vtk", "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 6 float\n0 0 0 1 0 0 0 1 0 0 0 1 1 0 1 0 1 1\n"
                    "CELLS 1 7\n6 0 1 2 3 4 5\nCELL_TYPES 1\n13\n", "cell 0 is a wedge (type 13); only tetrahedra (type 10)"},
      {"index.vtk", "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\n"
                    "CELLS 1 5\n4 0 1 2 4\nCELL_TYPES 1\n10\n", "cell 0 uses node 4, which is not among the file's 4 nodes"},
      {"grid.vtu", "<VTKFile/>", "only VTKFile type=\"UnstructuredGrid\" is read"},
      {"zlib.vtu", "<VTKFile type=\"UnstructuredGrid\" compressor=\"vtkZLibDataCompressor\">",
       "compressed data is not read"},
      {"appended.vtu", "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece><Points>"
                       "<DataArray type=\"Float32\" format=\"appended\" offset=\"0\"/></Points>",
       "Points: format 'appended' is not read"},
      {"hex.vtu", "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece><Points><DataArray format=\"ascii\">"
                  "0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1</DataArray></Points><Cells>"
                  "<DataArray Name=\"connectivity\" format=\"ascii\">0 1 2 3 4 5 6 7</DataArray>"
                  "<DataArray Name=\"offsets\" format=\"ascii\">8</DataArray>"
                  "<DataArray Name=\"types\" format=\"ascii\">12</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>",
       "cell 0 is a hexahedron (type 12)"},
  };
  for (const auto& c : cases) {
    const auto path = files.write(c.name, c.text);
    const std::string message = refusal(path);
    EXPECT_NE(message.find(c.name), std::string::npos) << c.name << ": " << message;
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.name << ": " << message;
  }
}

TEST(TetMeshImport, TruncatedFilesAreRefusedWithTheirLine) {
  Files files;
  const std::string text = kTwoTetsV2;
  const std::string message = refusal(files.write("cut.msh", text.substr(0, text.find("7 4 2"))));
  EXPECT_NE(message.find("cut.msh: line 19: element 2 is missing: the file ends"), std::string::npos) << message;
  const std::string v4 = refusal(files.write("cut4.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n"));
  EXPECT_NE(v4.find("cut4.msh"), std::string::npos) << v4;
}

TEST(TetMeshImport, VtkVersion5OffsetsAndConnectivity) {
  Files files;
  const auto mesh = import_tet_mesh(files.write("v5.vtk",
      "# vtk DataFile Version 5.1\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 float\n0 0 0 1 0 0 0 1 0 0 0 1\n1 1 1\n"
      "CELLS 3 8\nOFFSETS vtktypeint64\n0 4 8\nCONNECTIVITY vtktypeint64\n0 1 2 3 4 3 2 1\nCELL_TYPES 2\n10\n10\n"
      "POINT_DATA 5\n"));
  EXPECT_EQ(mesh.tets.size(), 2u);
  EXPECT_NEAR(incise::physics::total_volume(mesh.rest, mesh.tets), 0.5, 1e-12);
}

TEST(TetMeshImport, TruncatedBinaryMshIsRefusedWithTheByte) {
  Files files;
  std::ifstream in(kMeshes / "lobe_tets_binary.msh", std::ios::binary);
  const std::string whole((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const std::size_t keep : {std::size_t{60}, whole.size() / 2, whole.size() - 20}) {
    const std::string message = refusal(files.write("cut_binary.msh", whole.substr(0, keep)));
    EXPECT_NE(message.find("cut_binary.msh: byte "), std::string::npos) << keep << ": " << message;
  }
  // The fuzzer's finding: a binary format line that ends the file without a newline left the
  // byte reader one past the end, and its first read overran the buffer.
  for (const char* text : {"$MeshFormat\n4.1 1 8", "$MeshFormat\n2.2 1 8", "$MeshFormat\n4.1 1 8\n"}) {
    const std::string message = refusal(files.write("no_newline.msh", text));
    EXPECT_NE(message.find("no_newline.msh: byte "), std::string::npos) << message;
  }
}
