// Tetrahedral meshes from files, through a body's `mesh` key when the extension is one of
// is_tet_mesh_file's: Gmsh .msh (versions 2 and 4, ASCII or binary), VTK legacy .vtk (ASCII
// UNSTRUCTURED_GRID) and VTK XML .vtu (ascii or base64 DataArrays, uncompressed), the formats
// Gmsh, TetGen, 3D Slicer and SOFA write. The readers are our own (engine/gmsh_reader.cpp,
// gmsh_binary_reader.cpp, vtk_reader.cpp, vtu_reader.cpp): the Gmsh API in
// libgmsh-dev would bring OpenCASCADE and the whole of Gmsh into the build for two simple
// formats, and VTK is larger still.
#pragma once

#include "engine/mesh_up.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <filesystem>
#include <string_view>

namespace incise::engine {

struct TetImportReport {
  long long reoriented = 0;        // tetrahedra whose file order was clockwise (all of them, or none)
  long long skipped_elements = 0;  // points, lines and triangles of a .msh / cells of a .vtk below 3D
  long long dropped_nodes = 0;     // nodes no tetrahedron uses
};

// .msh, .vtk or .vtu (any case).
bool is_tet_mesh_file(const std::filesystem::path& file);

// The file's tetrahedra, positively oriented (physics/fem/tet_mesh.hpp), scaled by `scale` and
// turned so that the file's `up` axis is +z (turn_up). Nodes keep the file's order; those no
// tetrahedron uses are dropped. Throws MeshError naming the file, and the element or node and
// why (and the line, or the byte in a binary file), for: an empty file or no tetrahedra, another volume element (hexahedra, prisms,
// pyramids, 10-node tetrahedra), a node id missing from the nodes or an index out of range, a
// coordinate that is not finite, a number that does not fit, a degenerate tetrahedron (|volume|
// under 1e-12 of the mean) and an inverted one (its sign against the file's other tetrahedra;
// a file whose tetrahedra are all clockwise is reoriented, reported in `report`).
physics::TetMesh import_tet_mesh(const std::filesystem::path& file, double scale = 1.0, std::string_view up = "z",
                                 TetImportReport* report = nullptr);

// Mean edge length of the tetrahedra: the `resolution` a body built from them has unless its
// scene gives one.
double mean_edge_length(const physics::TetMesh& mesh);

}  // namespace incise::engine
