// Closed surface meshes from files (PLY and OBJ through incise's own readers,
// engine/surface_file.hpp; STL, glTF and anything else assimp reads through assimp), and the
// inside test that fills them with elements.
#pragma once

#include "engine/mesh_up.hpp"

#include <array>
#include <filesystem>
#include <string_view>
#include <vector>

namespace incise::engine {

struct TriangleSoup {
  std::vector<std::array<double, 3>> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::array<double, 3> min{}, max{};
};


// Sets the soup's box to its vertices' (which must not be empty).
void fit_bounds(TriangleSoup& soup);

// Reads every mesh of the file, merges coincident vertices, scales by `scale`. Throws
// MeshError naming the file when it cannot be read, holds no triangles, or is not closed
// (an edge used by other than two triangles: the count and the first such edge are named).
// `up` as turn_up's.
TriangleSoup import_surface(const std::filesystem::path& file, double scale = 1.0, std::string_view up = "z");


// Generalised winding number (sum of solid angles / 4 pi, Van Oosterom–Strackee): about 1
// inside a closed surface and 0 outside, whatever its orientation conventions per shell,
// and robust to small cracks, unlike ray parity.
double winding_number(const TriangleSoup& mesh, const std::array<double, 3>& point);

}  // namespace incise::engine
