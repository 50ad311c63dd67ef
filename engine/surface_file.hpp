// Surface files incise reads itself (PLY: ply_surface_reader.cpp, OBJ: obj_surface_reader.cpp)
// rather than through assimp: assimp 5.2.5's PLY reader wrote into freed memory under the fuzzer
// and its OBJ reader filled two 16 MiB buffers per file (docs/status.md, Reliability). Each
// reader refuses a bad file with a MeshError naming the file and the line (text) or byte
// (binary) and why, and allocates no more than the file's size can justify.
#pragma once

#include "engine/mesh_up.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace incise::engine {

// A surface as its file lists it: positions, and polygons of indices into them (any corner
// count; 1 and 2 are points and lines, which hold no triangle but whose vertices count as used,
// as assimp counted them).
struct SurfaceFile {
  // Single-precision values, widened: assimp keeps positions as float, and the shipped scenes'
  // states were built from those.
  std::vector<std::array<double, 3>> vertices;
  std::vector<std::uint32_t> corners;        // the polygons' corners, one polygon after another
  std::vector<std::uint32_t> polygon_sizes;  // each polygon's corner count, in file order
  // The order the used vertices take in the surface: OBJ's first use by a face corner (assimp
  // made a vertex per corner), or PLY's own order. Unused vertices are dropped either way.
  bool vertices_in_use_order = false;
};

SurfaceFile read_ply_surface(const std::filesystem::path& file);
SurfaceFile read_obj_surface(const std::filesystem::path& file);

// What the two text formats share (surface_text.cpp).
namespace surface_text {

std::string read_whole_file(const std::filesystem::path& file);

// The words of a line, split at spaces and tabs, into `words` (reused: no allocation a line).
void split_words(std::string_view line, std::vector<std::string_view>& words);

// "control character 0x0b at column 11" for the first byte below 0x20 other than a tab, or DEL.
std::optional<std::string> control_character(std::string_view line);

// A whole word as a number (a leading '+' allowed); nullopt when it is not, or out of range.
std::optional<double> real(std::string_view word);
std::optional<std::int64_t> integer(std::string_view word);

// The value in single precision, widened back; nullopt when that is not finite.
std::optional<double> single_precision(double value);

// A decimal word (one `real` takes) in single precision as assimp 5.2.5 rounded it, widened
// back: its integer and fraction parts each to float, then added in float (and an exponent's
// power of ten multiplied in float), one float step from the nearest at times. The shipped
// meshes' scenes were built from those values, so text coordinates are read the same way;
// nullopt when not finite.
std::optional<double> single_as_assimp_read(std::string_view word);

// A word for a message: at most 40 characters of it.
std::string quote(std::string_view word);

}  // namespace surface_text

}  // namespace incise::engine
