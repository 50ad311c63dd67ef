#include "engine/tet_mesh_import.hpp"

#include "common/missing_reason.hpp"
#include "engine/tet_mesh_file.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>

namespace incise::engine {

namespace tet_file {

Lines::Lines(const std::filesystem::path& file) : file_(file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw MeshError(file.string() + ": cannot open the file");
  std::ostringstream all;
  all << in.rdbuf();
  text_ = all.str();
}

const std::vector<std::string_view>& Lines::next() {
  fields_.clear();
  while (fields_.empty() && at_ < text_.size()) {
    std::size_t end = text_.find('\n', at_);
    if (end == std::string::npos) end = text_.size();
    const std::string_view line(text_.data() + at_, end - at_);
    at_ = end + 1;
    ++line_;
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
      std::size_t j = i;
      while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
      if (j > i) fields_.push_back(line.substr(i, j - i));
      i = j;
    }
  }
  return fields_;
}

void Lines::fail(const std::string& why) const {
  throw MeshError(file_.string() + ": line " + std::to_string(line_) + ": " + why);
}

long long Lines::integer(std::string_view field, const std::string& what) const {
  long long value = 0;
  const auto [end, error] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (error == std::errc::result_out_of_range) fail(what + " '" + std::string(field) + "' does not fit in 64 bits");
  if (error != std::errc() || end != field.data() + field.size())
    fail(what + " must be an integer, not '" + std::string(field.substr(0, 40)) + "'");
  return value;
}

double Lines::real(std::string_view field, const std::string& what) const {
  double value = 0;
  const auto [end, error] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (error == std::errc::result_out_of_range) fail(what + " '" + std::string(field.substr(0, 40)) + "' is out of range");
  if (error != std::errc() || end != field.data() + field.size())
    fail(what + " must be a number, not '" + std::string(field.substr(0, 40)) + "'");
  if (!std::isfinite(value)) fail(what + " is not finite ('" + std::string(field) + "')");
  return value;
}

}  // namespace tet_file

namespace {

std::string lower_extension(const std::filesystem::path& file) {
  std::string extension = file.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

double signed_volume(const physics::Vector& x, const std::array<int, 4>& t) {
  const physics::Vec3 a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]),
                      d = x.segment<3>(3 * t[3]);
  return (b - a).cross(c - a).dot(d - a) / 6;
}

std::string number(double x) {
  std::ostringstream out;
  out.precision(3);
  out << x;
  return out.str();
}

// The file's tetrahedra on its used nodes, in file order, turned and scaled.
physics::TetMesh index_nodes(const std::filesystem::path& file, const tet_file::RawTets& raw, double scale,
                             std::string_view up, TetImportReport& report) {
  if (raw.tets.empty()) throw MeshError(file.string() + ": holds no tetrahedra");
  std::unordered_map<long long, int> slot_of;
  slot_of.reserve(raw.node_ids.size());
  for (std::size_t i = 0; i < raw.node_ids.size(); ++i)
    if (!slot_of.emplace(raw.node_ids[i], static_cast<int>(i)).second)
      throw MeshError(file.string() + ": node " + std::to_string(raw.node_ids[i]) + " is given twice");
  std::vector<int> index(raw.node_ids.size(), -1);
  physics::TetMesh mesh;
  mesh.tets.reserve(raw.tets.size());
  for (const auto& t : raw.tets) {
    std::array<int, 4> tet{};
    for (int k = 0; k < 4; ++k) {
      const auto it = slot_of.find(t.nodes[k]);
      if (it == slot_of.end())
        throw MeshError(file.string() + ": " + t.name + " uses node " + std::to_string(t.nodes[k]) +
                        ", which is not among the file's " + std::to_string(raw.node_ids.size()) + " nodes");
      tet[k] = it->second;
    }
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        if (tet[a] == tet[b])
          throw MeshError(file.string() + ": " + t.name + " uses node " + std::to_string(t.nodes[a]) + " twice");
    mesh.tets.push_back(tet);
  }
  int used = 0;
  for (auto& t : mesh.tets)
    for (int& v : t) {
      if (index[v] < 0) index[v] = 0;
    }
  for (int& i : index)
    if (i == 0) i = used++;
  report.dropped_nodes = static_cast<long long>(raw.node_ids.size()) - used;
  mesh.rest.resize(3 * used);
  for (std::size_t i = 0; i < raw.node_ids.size(); ++i) {
    if (index[i] < 0) continue;
    const auto p = turn_up(raw.positions[i], up);
    for (int k = 0; k < 3; ++k) mesh.rest[3 * index[i] + k] = p[k] * scale;
  }
  for (auto& t : mesh.tets)
    for (int& v : t) v = index[v];
  return mesh;
}

// Degenerate tetrahedra are refused; the orientation most of them share is the file's
// convention (Gmsh's and VTK's are ours; some exporters write the mirror), and one against it is
// inverted, so refused rather than flipped: flipping would hide a tangled mesh.
void orient(const std::filesystem::path& file, const tet_file::RawTets& raw, physics::TetMesh& mesh,
            TetImportReport& report) {
  std::vector<double> volume(mesh.tets.size());
  double mean = 0;
  long long negative = 0;
  for (std::size_t e = 0; e < mesh.tets.size(); ++e) {
    volume[e] = signed_volume(mesh.rest, mesh.tets[e]);
    mean += std::abs(volume[e]) / static_cast<double>(mesh.tets.size());
    negative += volume[e] < 0;
  }
  const bool mirrored = 2 * negative > static_cast<long long>(mesh.tets.size());
  for (std::size_t e = 0; e < mesh.tets.size(); ++e) {
    if (!(std::abs(volume[e]) >= 1e-12 * mean) || volume[e] == 0)
      throw MeshError(file.string() + ": " + raw.tets[e].name + " is degenerate: volume " + number(volume[e]) +
                      " m^3 against a mean of " + number(mean) + " m^3");
    if ((volume[e] < 0) != mirrored)
      throw MeshError(file.string() + ": " + raw.tets[e].name + " is inverted: volume " + number(volume[e]) +
                      " m^3 while " + std::to_string(mirrored ? negative : mesh.tets.size() - negative) + " of the " +
                      std::to_string(mesh.tets.size()) + " tetrahedra have the other sign");
    if (mirrored) std::swap(mesh.tets[e][1], mesh.tets[e][2]);
  }
  report.reoriented = mirrored ? static_cast<long long>(mesh.tets.size()) : 0;
}

}  // namespace

bool is_tet_mesh_file(const std::filesystem::path& file) {
  const std::string extension = lower_extension(file);
  return extension == ".msh" || extension == ".vtk" || extension == ".vtu";
}

physics::TetMesh import_tet_mesh(const std::filesystem::path& file, double scale, std::string_view up,
                                 TetImportReport* report) {
  if (const std::string why = common::missing_reason(file); !why.empty()) throw MeshError(file.string() + ": file " + why);
  turn_up({}, up);  // an unknown axis is refused before the file is read
  const std::string extension = lower_extension(file);
  tet_file::Lines lines(file);
  if (lines.empty_file()) throw MeshError(file.string() + ": the file is empty");
  tet_file::RawTets raw = extension == ".msh"   ? tet_file::read_gmsh(lines)
                          : extension == ".vtu" ? tet_file::read_vtu(file, lines.text())
                                                : tet_file::read_vtk(lines);
  TetImportReport local;
  TetImportReport& out = report ? *report : local;
  out = {};
  out.skipped_elements = raw.skipped_elements;
  physics::TetMesh mesh = index_nodes(file, raw, scale, up, out);
  orient(file, raw, mesh, out);
  return mesh;
}

double mean_edge_length(const physics::TetMesh& mesh) {
  double total = 0;
  for (const auto& t : mesh.tets)
    for (const auto& [a, b] : physics::quadratic_tet_edges)
      total += (mesh.rest.segment<3>(3 * t[a]) - mesh.rest.segment<3>(3 * t[b])).norm();
  return mesh.tets.empty() ? 0 : total / (6.0 * static_cast<double>(mesh.tets.size()));
}

}  // namespace incise::engine
