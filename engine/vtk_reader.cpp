// VTK legacy files (vtk.org's "VTK File Formats"), ASCII DATASET UNSTRUCTURED_GRID: POINTS,
// CELLS (the classic layout "n i j k l" per cell, or version 5's OFFSETS and CONNECTIVITY)
// and CELL_TYPES; attribute sections after them are ignored. Numbers run free across lines,
// so the reader walks fields, not lines.
#include "engine/tet_mesh_file.hpp"

#include <map>

namespace incise::engine::tet_file {

namespace {

constexpr long long kTetra = 10;

const std::map<long long, std::string>& volume_types() {
  static const std::map<long long, std::string> names = {
      {11, "voxel"}, {12, "hexahedron"}, {13, "wedge"}, {14, "pyramid"}, {15, "pentagonal prism"},
      {16, "hexagonal prism"}, {24, "quadratic tetrahedron"}, {25, "quadratic hexahedron"}, {26, "quadratic wedge"},
      {27, "quadratic pyramid"}, {42, "polyhedron"}, {71, "Lagrange tetrahedron"}, {72, "Lagrange hexahedron"}};
  return names;
}

// Vertices, lines, triangles, polygons, quads, of any order: a surface in the grid.
bool below_3d(long long type) {
  return (type >= 1 && type <= 9) || (type >= 21 && type <= 23) || type == 28 || type == 30 || type == 68 ||
         type == 69 || type == 70;
}

// Fields one after another, whatever the lines.
class Fields {
 public:
  explicit Fields(Lines& lines) : lines_(lines) {}
  std::string_view next(const std::string& what) {
    while (at_ >= line_.size()) {
      if (lines_.done()) lines_.fail("the file ends where " + what + " was expected");
      line_ = lines_.next();
      at_ = 0;
    }
    return line_[at_++];
  }
  // The rest of the current line is skipped (after a section's header).
  void end_line() { at_ = line_.size(); }
  long long integer(const std::string& what) { return lines_.integer(next(what), what); }
  double real(const std::string& what) { return lines_.real(next(what), what); }
  long long count(const std::string& what) {
    const long long n = integer(what);
    if (n < 0 || n > static_cast<long long>(lines_.bytes())) lines_.fail(what + " " + std::to_string(n) + " is negative or more than the file's " + std::to_string(lines_.bytes()) + " bytes could hold");
    return n;
  }
  Lines& lines() { return lines_; }

 private:
  Lines& lines_;
  std::vector<std::string_view> line_;
  std::size_t at_ = 0;
};

void read_points(Fields& f, RawTets& raw) {
  const long long n = f.count("the point count");
  f.next("the points' data type");
  for (long long i = 0; i < n; ++i) {
    const std::string name = "point " + std::to_string(i);
    raw.node_ids.push_back(i);
    raw.positions.push_back({f.real(name + " x"), f.real(name + " y"), f.real(name + " z")});
  }
}

// Each cell's point indices, either layout.
std::vector<std::vector<long long>> read_cells(Fields& f) {
  const long long first = f.count("the cell count"), second = f.count("the cells' size");
  std::vector<std::vector<long long>> cells;
  const std::string_view word = f.next("the cells");
  if (word == "OFFSETS") {  // version 5: first offsets (cells + 1), second connectivity entries
    f.next("the offsets' data type");
    std::vector<long long> offsets(static_cast<std::size_t>(first));
    for (auto& o : offsets) o = f.integer("an offset");
    const std::string_view connectivity = f.next("CONNECTIVITY");
    if (connectivity != "CONNECTIVITY") f.lines().fail("expected CONNECTIVITY, found '" + std::string(connectivity) + "'");
    f.next("the connectivity's data type");
    std::vector<long long> ids(static_cast<std::size_t>(second));
    for (auto& id : ids) id = f.integer("a point index");
    for (std::size_t c = 0; c + 1 < offsets.size(); ++c) {
      if (offsets[c] < 0 || offsets[c] > offsets[c + 1] || offsets[c + 1] > second)
        f.lines().fail("cell " + std::to_string(c) + "'s offsets are out of range");
      cells.emplace_back(ids.begin() + offsets[c], ids.begin() + offsets[c + 1]);
    }
    return cells;
  }
  long long used = 0;
  for (long long c = 0; c < first; ++c) {
    const long long n = c == 0 ? f.lines().integer(word, "cell 0's point count") : f.integer("cell " + std::to_string(c) + "'s point count");
    used += n + 1;
    if (n < 0 || used > second) f.lines().fail("cell " + std::to_string(c) + " has more points than CELLS' size " + std::to_string(second) + " leaves");
    auto& cell = cells.emplace_back(static_cast<std::size_t>(n));
    for (auto& id : cell) id = f.integer("cell " + std::to_string(c) + "'s point index");
  }
  return cells;
}

}  // namespace

void keep_vtk_tetrahedra(const std::filesystem::path& file, const std::vector<std::vector<long long>>& cells,
                         const std::vector<long long>& types, RawTets& raw) {
  for (std::size_t c = 0; c < cells.size(); ++c) {
    const std::string name = "cell " + std::to_string(c);
    if (below_3d(types[c])) {
      ++raw.skipped_elements;
      continue;
    }
    if (types[c] != kTetra) {
      const auto it = volume_types().find(types[c]);
      throw MeshError(file.string() + ": " + name + " is a " +
                      (it != volume_types().end() ? it->second + " (type " + std::to_string(types[c]) + ")"
                                                  : "cell of type " + std::to_string(types[c])) +
                      "; only tetrahedra (type 10) are read");
    }
    if (cells[c].size() != 4)
      throw MeshError(file.string() + ": " + name + " is a tetrahedron with " + std::to_string(cells[c].size()) + " points, not 4");
    RawTet tet{{}, name};
    for (int k = 0; k < 4; ++k) tet.nodes[k] = cells[c][k];
    raw.tets.push_back(tet);
  }
}

RawTets read_vtk(Lines& lines) {
  RawTets raw;
  const auto& magic = lines.next();
  if (magic.size() < 2 || magic[0] != "#" || magic[1] != "vtk") lines.fail("a legacy .vtk file starts with '# vtk DataFile Version'");
  lines.next();  // the title
  const auto& encoding = lines.next();
  if (encoding.empty() || encoding[0] != "ASCII")
    lines.fail("only ASCII legacy VTK is read, not '" + (encoding.empty() ? std::string() : std::string(encoding[0])) +
               "' (ParaView: File > Save Data, File type ASCII)");
  const auto dataset = lines.next();
  if (dataset.size() < 2 || dataset[0] != "DATASET" || dataset[1] != "UNSTRUCTURED_GRID")
    lines.fail("only DATASET UNSTRUCTURED_GRID is read");
  Fields f(lines);
  std::vector<std::vector<long long>> cells;
  std::vector<long long> types;
  bool points = false, have_cells = false;
  while (!lines.done() && !(points && have_cells && !types.empty())) {
    const std::string_view section = f.next("a section");
    if (section == "POINTS") {
      read_points(f, raw);
      points = true;
    } else if (section == "CELLS") {
      cells = read_cells(f);
      have_cells = true;
    } else if (section == "CELL_TYPES") {
      const long long n = f.count("the cell type count");
      if (n != static_cast<long long>(cells.size()))
        lines.fail("CELL_TYPES gives " + std::to_string(n) + " types for " + std::to_string(cells.size()) + " cells");
      for (long long c = 0; c < n; ++c) types.push_back(f.integer("cell " + std::to_string(c) + "'s type"));
    } else if (section == "FIELD" || section == "METADATA") {
      f.end_line();
    } else {
      lines.fail("unexpected '" + std::string(section.substr(0, 40)) + "' before POINTS, CELLS and CELL_TYPES were read");
    }
  }
  if (!points || !have_cells || types.size() != cells.size())
    lines.fail("the grid needs POINTS, CELLS and CELL_TYPES");
  keep_vtk_tetrahedra(lines.file(), cells, types, raw);
  return raw;
}

}  // namespace incise::engine::tet_file
