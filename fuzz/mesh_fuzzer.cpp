// Bytes -> import_surface through assimp, as OBJ, STL or PLY (the first byte picks which; the
// importer chooses by extension and content): a file that is not a closed surface is a
// MeshError naming it; what is accepted is a closed surface whose triangles index its vertices.
#include "engine/mesh_import.hpp"
#include "fuzz/temp_file.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const std::filesystem::path files[] = {incise::fuzz::temp_file("mesh.obj"), incise::fuzz::temp_file("mesh.stl"),
                                                incise::fuzz::temp_file("mesh.ply")};
  const auto& file = files[data[0] % 3];
  incise::fuzz::write_file(file, data + 1, size - 1);
  try {
    const incise::engine::TriangleSoup soup = incise::engine::import_surface(file);
    const int vertices = static_cast<int>(soup.vertices.size());
    for (const auto& t : soup.triangles)
      for (int v : t)
        if (v < 0 || v >= vertices) std::abort();
    if (!std::isfinite(incise::engine::winding_number(soup, {0, 0, 0}))) std::abort();
  } catch (const incise::engine::MeshError&) {
  }
  return 0;
}
