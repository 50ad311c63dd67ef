// What the tetrahedral readers (gmsh_reader.cpp, vtk_reader.cpp) share: the file read as lines
// of fields, numbers parsed strictly, and the tetrahedra as the file names them, before
// import_tet_mesh checks and orients them. Internal to engine/.
#pragma once

#include "engine/mesh_up.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace incise::engine::tet_file {

// A tetrahedron as the file gives it: node ids (the .msh's tags; the .vtk's point indices),
// and how messages name it ("element 12 (tag 40)", "cell 12").
struct RawTet {
  std::array<long long, 4> nodes;
  std::string name;
};

struct RawTets {
  std::vector<long long> node_ids;                // in file order
  std::vector<std::array<double, 3>> positions;   // of node_ids[i]
  std::vector<RawTet> tets;
  long long skipped_elements = 0;
};

// The file's text, line by line; errors name the file and the line.
class Lines {
 public:
  explicit Lines(const std::filesystem::path& file);
  bool done() const { return at_ >= text_.size(); }
  // The next line that holds anything, split at whitespace; empty at the end of the file.
  const std::vector<std::string_view>& next();
  int line() const { return line_; }
  [[noreturn]] void fail(const std::string& why) const;
  const std::filesystem::path& file() const { return file_; }
  std::size_t bytes() const { return text_.size(); }
  // Where the next line starts, for the binary readers, which take over from there.
  const std::string& text() const { return text_; }
  std::size_t position() const { return at_; }
  bool empty_file() const { return text_.find_first_not_of(" \t\r\n") == std::string::npos; }

  // Fields parsed strictly (the whole field, in range), else fail() naming `what`.
  long long integer(std::string_view field, const std::string& what) const;
  double real(std::string_view field, const std::string& what) const;

 private:
  std::filesystem::path file_;
  std::string text_;
  std::size_t at_ = 0;
  int line_ = 0;
  std::vector<std::string_view> fields_;
};

RawTets read_gmsh(Lines& lines);
// The binary MSH after its format line, version 2.x or 4.x (gmsh_binary_reader.cpp).
RawTets read_gmsh_binary(Lines& lines, double version, long long data_size);

// Gmsh element types (gmsh_reader.cpp): a point, line, triangle or quadrangle, of any order,
// which the readers skip; why another volume element is refused, naming `element` and its type.
bool gmsh_below_3d(long long type);
std::string gmsh_volume_problem(const std::string& element, long long type);
// Nodes of an element of the type, 0 when unknown (binary files need it to step over elements).
int gmsh_node_count(long long type);
RawTets read_vtk(Lines& lines);
RawTets read_vtu(const std::filesystem::path& file, std::string text);  // vtu_reader.cpp

// The tetrahedra among VTK cells (point indices and cell types), the cells below 3D counted as
// skipped, another volume cell refused naming the file, the cell and its type (vtk_reader.cpp).
void keep_vtk_tetrahedra(const std::filesystem::path& file, const std::vector<std::vector<long long>>& cells,
                         const std::vector<long long>& types, RawTets& raw);

}  // namespace incise::engine::tet_file
