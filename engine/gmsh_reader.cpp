// Gmsh .msh, versions 2.x and 4.x, ASCII (gmsh.info/doc/texinfo/gmsh.html#MSH-file-format);
// binary ones are handed to gmsh_binary_reader.cpp after their format line.
// Only $MeshFormat, $Nodes and $Elements are read; other sections ($PhysicalNames, $Entities,
// $NodeData, ...) are skipped. Elements are one per line in both versions, so an element type
// below 3D is skipped without knowing its node count.
#include "engine/tet_mesh_file.hpp"

#include <algorithm>
#include <map>

namespace incise::engine::tet_file {

namespace {

constexpr int kTetrahedron = 4;

// Gmsh's volume element types other than the 4-node tetrahedron, by name for the refusal.
const std::map<long long, std::string>& volume_types() {
  static const std::map<long long, std::string> names = {
      {5, "8-node hexahedron"},   {6, "6-node prism"},        {7, "5-node pyramid"},    {11, "10-node tetrahedron"},
      {12, "27-node hexahedron"}, {13, "18-node prism"},      {14, "14-node pyramid"},  {17, "20-node hexahedron"},
      {18, "15-node prism"},      {19, "13-node pyramid"},    {29, "20-node tetrahedron"}, {30, "35-node tetrahedron"},
      {31, "56-node tetrahedron"}, {92, "64-node hexahedron"}, {93, "125-node hexahedron"}};
  return names;
}


// Skips to the line after `$End<section>`.
void skip_section(Lines& lines, std::string_view section) {
  const std::string end = "$End" + std::string(section.substr(1));
  while (!lines.done()) {
    const auto& f = lines.next();
    if (!f.empty() && f[0] == end) return;
  }
  lines.fail("section " + std::string(section) + " has no " + end);
}

void expect_end(Lines& lines, std::string_view end) {
  const auto& f = lines.next();
  if (f.empty() || f[0] != end) lines.fail("expected " + std::string(end) + (f.empty() ? ", found the end of the file" : ", found '" + std::string(f[0]) + "'"));
}

// A count the file gives, refused when negative or larger than the file could hold.
long long count(Lines& lines, std::string_view field, const std::string& what) {
  const long long n = lines.integer(field, what);
  if (n < 0 || n > static_cast<long long>(lines.bytes())) lines.fail(what + " " + std::to_string(n) + " is negative or more than the file's " + std::to_string(lines.bytes()) + " bytes could hold");
  return n;
}

std::string_view first_field(Lines& lines) {
  const auto& f = lines.next();
  if (f.empty()) lines.fail("the file ends where a count was expected");
  return f[0];
}

void read_node(Lines& lines, const std::vector<std::string_view>& f, std::size_t at, long long id, RawTets& raw) {
  const std::string node = "node " + std::to_string(id);
  if (f.size() < at + 3) lines.fail(node + " needs x y z");
  raw.positions.push_back({lines.real(f[at], node + " x"), lines.real(f[at + 1], node + " y"), lines.real(f[at + 2], node + " z")});
}

// One element line from `at` on: its tag then its nodes. `index` counts the file's elements.
void read_element(Lines& lines, const std::vector<std::string_view>& f, long long type, std::size_t nodes_at,
                  long long index, RawTets& raw) {
  const std::string name = "element " + std::to_string(index) + " (tag " + std::string(f[0]) + ")";
  if (gmsh_below_3d(type)) {
    ++raw.skipped_elements;
    return;
  }
  if (type != kTetrahedron) lines.fail(gmsh_volume_problem(name, type));
  if (f.size() != nodes_at + 4) lines.fail(name + " is a tetrahedron with " + std::to_string(f.size() - nodes_at) + " nodes, not 4");
  RawTet tet{{}, name};
  for (int k = 0; k < 4; ++k) tet.nodes[k] = lines.integer(f[nodes_at + k], name + " node " + std::to_string(k));
  raw.tets.push_back(tet);
}

}  // namespace

// Points, lines, triangles and quadrangles of any order: Gmsh's boundary and physical groups.
bool gmsh_below_3d(long long type) {
  return type == 1 || type == 2 || type == 3 || type == 8 || type == 9 || type == 10 || type == 15 || type == 16 ||
         (type >= 20 && type <= 28) || (type >= 36 && type <= 47);
}

std::string gmsh_volume_problem(const std::string& element, long long type) {
  const auto it = volume_types().find(type);
  return (element + " is of type " + std::to_string(type) + (it != volume_types().end() ? " (" + it->second + ")" : "") +
             "; only 4-node tetrahedra (type 4) are read (Gmsh: Mesh.ElementOrder = 1, no recombination)");
}

int gmsh_node_count(long long type) {
  static const std::map<long long, int> nodes = {
      {1, 2},   {2, 3},   {3, 4},   {4, 4},   {5, 8},   {6, 6},   {7, 5},   {8, 3},   {9, 6},   {10, 9},  {11, 10},
      {12, 27}, {13, 18}, {14, 14}, {15, 1},  {16, 8},  {17, 20}, {18, 15}, {19, 13}, {20, 9},  {21, 10}, {22, 12},
      {23, 15}, {24, 15}, {25, 21}, {26, 4},  {27, 5},  {28, 6},  {29, 20}, {30, 35}, {31, 56}, {92, 64}, {93, 125}};
  const auto it = nodes.find(type);
  return it == nodes.end() ? 0 : it->second;
}

namespace {

void read_v2(Lines& lines, RawTets& raw) {
  while (!lines.done()) {
    const auto head = lines.next();
    if (head.empty()) break;
    if (head[0] == "$Nodes") {
      const long long n = count(lines, first_field(lines), "the node count");
      for (long long i = 0; i < n; ++i) {
        const auto& f = lines.next();
        if (f.empty()) lines.fail("the file ends after " + std::to_string(i) + " of its " + std::to_string(n) + " nodes");
        raw.node_ids.push_back(lines.integer(f[0], "a node's id"));
        read_node(lines, f, 1, raw.node_ids.back(), raw);
      }
      expect_end(lines, "$EndNodes");
    } else if (head[0] == "$Elements") {
      const long long n = count(lines, first_field(lines), "the element count");
      for (long long i = 0; i < n; ++i) {
        const auto& f = lines.next();
        if (f.size() < 3) lines.fail("element " + std::to_string(i) + (f.empty() ? " is missing: the file ends" : " needs a tag, a type and its tags"));
        const long long type = lines.integer(f[1], "element " + std::to_string(i) + "'s type");
        // tag type number-of-tags tags... nodes...
        const long long tags = lines.integer(f[2], "element " + std::to_string(i) + "'s tag count");
        if (tags < 0 || static_cast<std::size_t>(tags) + 3 > f.size()) lines.fail("element " + std::to_string(i) + "'s tag count is out of range");
        read_element(lines, f, type, 3 + static_cast<std::size_t>(tags), i, raw);
      }
      expect_end(lines, "$EndElements");
    } else if (head[0].starts_with("$")) {
      skip_section(lines, head[0]);
    }
  }
}

void read_v4_nodes(Lines& lines, RawTets& raw) {
  const auto head = lines.next();
  if (head.size() < 2) lines.fail("$Nodes needs numEntityBlocks numNodes minNodeTag maxNodeTag");
  const long long blocks = count(lines, head[0], "the node block count");
  for (long long b = 0; b < blocks; ++b) {
    const auto block = lines.next();
    if (block.size() < 4) lines.fail("node block " + std::to_string(b) + " needs entityDim entityTag parametric numNodesInBlock");
    const long long dim = lines.integer(block[0], "the entity dimension");
    const bool parametric = lines.integer(block[2], "parametric") != 0;
    const long long n = count(lines, block[3], "the block's node count");
    const std::size_t first = raw.node_ids.size();
    for (long long i = 0; i < n; ++i) {
      const auto& f = lines.next();
      if (f.empty()) lines.fail("the file ends in node block " + std::to_string(b));
      raw.node_ids.push_back(lines.integer(f[0], "a node's tag"));
    }
    for (long long i = 0; i < n; ++i) {
      const auto& f = lines.next();
      if (parametric && f.size() < 3 + static_cast<std::size_t>(std::max(0LL, dim))) lines.fail("a parametric node needs x y z and its parameters");
      read_node(lines, f, 0, raw.node_ids[first + static_cast<std::size_t>(i)], raw);
    }
  }
  expect_end(lines, "$EndNodes");
}

void read_v4_elements(Lines& lines, RawTets& raw) {
  const auto head = lines.next();
  if (head.size() < 2) lines.fail("$Elements needs numEntityBlocks numElements minElementTag maxElementTag");
  const long long blocks = count(lines, head[0], "the element block count");
  long long index = 0;
  for (long long b = 0; b < blocks; ++b) {
    const auto block = lines.next();
    if (block.size() < 4) lines.fail("element block " + std::to_string(b) + " needs entityDim entityTag elementType numElementsInBlock");
    const long long dim = lines.integer(block[0], "the entity dimension");
    const long long type = lines.integer(block[2], "the element type");
    const long long n = count(lines, block[3], "the block's element count");
    for (long long i = 0; i < n; ++i, ++index) {
      const auto& f = lines.next();
      if (f.empty()) lines.fail("the file ends in element block " + std::to_string(b));
      if (dim < 3 && !gmsh_below_3d(type)) lines.fail("element block " + std::to_string(b) + " of dimension " + std::to_string(dim) + " has element type " + std::to_string(type));
      read_element(lines, f, type, 1, index, raw);
    }
  }
  expect_end(lines, "$EndElements");
}

void read_v4(Lines& lines, RawTets& raw) {
  while (!lines.done()) {
    const auto head = lines.next();
    if (head.empty()) break;
    if (head[0] == "$Nodes") read_v4_nodes(lines, raw);
    else if (head[0] == "$Elements") read_v4_elements(lines, raw);
    else if (head[0].starts_with("$")) skip_section(lines, head[0]);
  }
}

}  // namespace

RawTets read_gmsh(Lines& lines) {
  RawTets raw;
  const auto first = lines.next();
  if (first.empty()) lines.fail("the file is empty");
  if (first[0] == "$NOD") lines.fail("MSH version 1 is not read (versions 2 and 4 are)");
  if (first[0] != "$MeshFormat") lines.fail("a .msh file starts with $MeshFormat, not '" + std::string(first[0].substr(0, 40)) + "'");
  const auto format = lines.next();
  if (format.size() < 3) lines.fail("$MeshFormat needs version file-type data-size");
  const double version = lines.real(format[0], "the version");
  if (!(version >= 2 && version < 3) && !(version >= 4 && version < 5))
    lines.fail("MSH version " + std::string(format[0]) + " is not read (versions 2 and 4 are)");
  if (lines.integer(format[1], "the file type") != 0)
    return read_gmsh_binary(lines, version, lines.integer(format[2], "the data size"));
  expect_end(lines, "$EndMeshFormat");
  if (version < 3) read_v2(lines, raw);
  else read_v4(lines, raw);
  return raw;
}

}  // namespace incise::engine::tet_file
