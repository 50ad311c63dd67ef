// Bytes -> import_surface as a file named .obj, .stl or .ply (a target per format,
// fuzz/mesh_*_fuzzer.cpp: each reaches its own executions, not a third of a mix held back by the
// slowest reader): incise's own readers for OBJ and PLY (engine/surface_file.hpp), assimp for
// STL (the importer chooses by extension and content). A file
// that is not a closed surface is a MeshError naming it; what is accepted is a closed surface
// whose triangles index its vertices.
#pragma once

#include "engine/mesh_import.hpp"
#include "fuzz/huge_pages.hpp"
#include "fuzz/temp_file.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace incise::fuzz {

inline void import_surface_bytes(const std::filesystem::path& file, const std::uint8_t* data, std::size_t size) {
  back_large_allocations_with_huge_pages();
  write_file(file, data, size);
  try {
    const engine::TriangleSoup soup = engine::import_surface(file);
    const int vertices = static_cast<int>(soup.vertices.size());
    for (const auto& t : soup.triangles)
      for (int v : t)
        if (v < 0 || v >= vertices) std::abort();
    if (!std::isfinite(engine::winding_number(soup, {0, 0, 0}))) std::abort();
  } catch (const engine::MeshError&) {
  }
}

}  // namespace incise::fuzz
