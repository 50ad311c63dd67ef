// Bytes -> import_tet_mesh, as .msh, .vtk or .vtu (the first byte picks which): our own readers
// of Gmsh (text and binary) and VTK (legacy and XML). A bad file is a MeshError naming it; what
// is accepted is tetrahedra on existing nodes, positively oriented, with finite coordinates.
#include "engine/tet_mesh_import.hpp"
#include "fuzz/temp_file.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const std::filesystem::path files[] = {incise::fuzz::temp_file("mesh.msh"), incise::fuzz::temp_file("mesh.vtk"),
                                                incise::fuzz::temp_file("mesh.vtu")};
  const auto& file = files[data[0] % 3];
  incise::fuzz::write_file(file, data + 1, size - 1);
  try {
    const incise::physics::TetMesh mesh = incise::engine::import_tet_mesh(file);
    const int nodes = static_cast<int>(mesh.rest.size() / 3);
    if (mesh.tets.empty() || mesh.rest.size() % 3 != 0 || !mesh.rest.allFinite()) std::abort();
    for (const auto& t : mesh.tets) {
      for (int v : t)
        if (v < 0 || v >= nodes) std::abort();
      const Eigen::Vector3d a = mesh.rest.segment<3>(3 * t[0]);
      const double volume =
          (mesh.rest.segment<3>(3 * t[1]) - a).cross(mesh.rest.segment<3>(3 * t[2]) - a).dot(mesh.rest.segment<3>(3 * t[3]) - a);
      if (volume < 0) std::abort();  // NaN (from overflowing coordinates) is not a fold
    }
  } catch (const incise::engine::MeshError&) {
  }
  return 0;
}
