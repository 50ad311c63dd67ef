// VTK XML unstructured grids (.vtu, vtk.org's "VTK File Formats", XML section): one Piece, its
// Points and its Cells' connectivity, offsets (each cell's end) and types, as DataArrays in
// format "ascii" or "binary" (base64 of a byte-count header then the values, uncompressed).
// Compressed and appended data are refused by name. A small scanner for the few elements and
// attributes needed, not an XML parser: VTK and meshio write these files in this one shape.
#include "engine/tet_mesh_file.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>

namespace incise::engine::tet_file {

namespace {

class Xml {
 public:
  Xml(std::filesystem::path file, std::string text) : file_(std::move(file)), text_(std::move(text)) {}

  [[noreturn]] void fail(const std::string& why) const { throw MeshError(file_.string() + ": " + why); }

  // The start of the next element `<name` at or after `from`, npos if none before `before`.
  std::size_t find(std::string_view name, std::size_t from, std::size_t before = std::string::npos) const {
    std::string open(1, '<');
    open.append(name);
    for (std::size_t at = text_.find(open, from); at != std::string::npos && at < before; at = text_.find(open, at + 1)) {
      const char next = at + 1 + name.size() < text_.size() ? text_[at + 1 + name.size()] : '\0';
      if (next == ' ' || next == '>' || next == '\n' || next == '\t' || next == '/' || next == '\r') return at;
    }
    return std::string::npos;
  }
  std::size_t require(std::string_view name, std::size_t from, std::size_t before = std::string::npos) const {
    const std::size_t at = find(name, from, before);
    if (at == std::string::npos) fail("has no <" + std::string(name) + "> where one is needed");
    return at;
  }
  std::size_t end_of(std::string_view name, std::size_t from) const {
    const std::size_t at = text_.find("</" + std::string(name) + ">", from);
    if (at == std::string::npos) fail("<" + std::string(name) + "> is not closed");
    return at;
  }
  // The attribute's value in the start tag at `tag`, empty when absent.
  std::string attribute(std::size_t tag, std::string_view name) const {
    const std::size_t close = text_.find('>', tag);
    const std::string_view head(text_.data() + tag, (close == std::string::npos ? text_.size() : close) - tag);
    for (std::size_t at = head.find(std::string(name) + "=\""); at != std::string_view::npos;
         at = head.find(std::string(name) + "=\"", at + 1)) {
      if (at == 0 || head[at - 1] != ' ') continue;
      const std::size_t start = at + name.size() + 2, end = head.find('"', start);
      if (end == std::string_view::npos) fail("an attribute " + std::string(name) + " is not closed");
      return std::string(head.substr(start, end - start));
    }
    return "";
  }
  // The text between the start tag at `tag` and its </DataArray>.
  std::string_view content(std::size_t tag) const {
    const std::size_t open = text_.find('>', tag);
    if (open == std::string::npos) fail("a DataArray's tag is not closed");
    const std::size_t close = end_of("DataArray", open);
    return std::string_view(text_.data() + open + 1, close - open - 1);
  }
  const std::string& text() const { return text_; }

 private:
  std::filesystem::path file_;
  std::string text_;
};

std::string base64_decode(const Xml& xml, std::string_view text, const std::string& what) {
  static const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  unsigned buffer = 0;
  int bits = 0;
  for (const char c : text) {
    if (c == '=' || std::isspace(static_cast<unsigned char>(c))) continue;
    const std::size_t value = alphabet.find(c);
    if (value == std::string::npos) xml.fail(what + ": '" + std::string(1, c) + "' is not base64");
    buffer = (buffer << 6) | static_cast<unsigned>(value);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<char>((buffer >> bits) & 0xff));
    }
  }
  return out;
}

template <class T>
void append_decoded(const std::string& bytes, std::size_t from, std::vector<double>& out) {
  for (std::size_t at = from; at + sizeof(T) <= bytes.size(); at += sizeof(T)) {
    T value;
    std::memcpy(&value, bytes.data() + at, sizeof(T));
    out.push_back(static_cast<double>(value));
  }
}

// A DataArray's values as doubles (indices under 2^53 are exact), checked finite.
std::vector<double> values(const Xml& xml, std::size_t tag, const std::string& what, bool header64) {
  const std::string format = xml.attribute(tag, "format"), type = xml.attribute(tag, "type");
  std::vector<double> out;
  if (format == "ascii") {
    const std::string_view text = xml.content(tag);
    for (std::size_t at = 0; at < text.size();) {
      while (at < text.size() && std::isspace(static_cast<unsigned char>(text[at]))) ++at;
      if (at >= text.size()) break;
      double value = 0;
      const auto [end, error] = std::from_chars(text.data() + at, text.data() + text.size(), value);
      if (error != std::errc()) xml.fail(what + ": '" + std::string(text.substr(at, 20)) + "' is not a number");
      out.push_back(value);
      at = static_cast<std::size_t>(end - text.data());
    }
  } else if (format == "binary") {
    const std::string bytes = base64_decode(xml, xml.content(tag), what);
    const std::size_t header = header64 ? 8 : 4;
    if (bytes.size() < header) xml.fail(what + ": the binary data has no byte count");
    if (type == "Float32") append_decoded<float>(bytes, header, out);
    else if (type == "Float64") append_decoded<double>(bytes, header, out);
    else if (type == "Int8") append_decoded<std::int8_t>(bytes, header, out);
    else if (type == "UInt8") append_decoded<std::uint8_t>(bytes, header, out);
    else if (type == "Int16") append_decoded<std::int16_t>(bytes, header, out);
    else if (type == "UInt16") append_decoded<std::uint16_t>(bytes, header, out);
    else if (type == "Int32") append_decoded<std::int32_t>(bytes, header, out);
    else if (type == "UInt32") append_decoded<std::uint32_t>(bytes, header, out);
    else if (type == "Int64") append_decoded<std::int64_t>(bytes, header, out);
    else if (type == "UInt64") append_decoded<std::uint64_t>(bytes, header, out);
    else xml.fail(what + ": data type '" + type + "' is not read");
  } else {
    xml.fail(what + ": format '" + format + "' is not read (ascii and binary are; save without appended data)");
  }
  for (std::size_t i = 0; i < out.size(); ++i)
    if (!std::isfinite(out[i])) xml.fail(what + ": value " + std::to_string(i) + " is not finite");
  return out;
}

long long index(const Xml& xml, double value, const std::string& what) {
  if (value != std::floor(value) || std::abs(value) > 9.0e15) xml.fail(what + " " + std::to_string(value) + " is not an index");
  return static_cast<long long>(value);
}

}  // namespace

RawTets read_vtu(const std::filesystem::path& file, std::string text) {
  const Xml xml(file, std::move(text));
  const std::size_t root = xml.require("VTKFile", 0);
  if (xml.attribute(root, "type") != "UnstructuredGrid") xml.fail("only VTKFile type=\"UnstructuredGrid\" is read");
  if (!xml.attribute(root, "compressor").empty()) xml.fail("compressed data is not read (save with no compressor)");
  if (xml.attribute(root, "byte_order") == "BigEndian") xml.fail("big-endian data is not read");
  const bool header64 = xml.attribute(root, "header_type") == "UInt64";
  const std::size_t piece = xml.require("Piece", root);
  if (xml.find("Piece", piece + 1) != std::string::npos) xml.fail("has more than one Piece; merge them first");
  const std::size_t points_at = xml.require("Points", piece), points_end = xml.end_of("Points", points_at);
  const std::vector<double> xyz = values(xml, xml.require("DataArray", points_at, points_end), "Points", header64);
  if (xyz.size() % 3 != 0) xml.fail("Points hold " + std::to_string(xyz.size()) + " numbers, not 3 per point");
  RawTets raw;
  for (std::size_t i = 0; i < xyz.size() / 3; ++i) {
    raw.node_ids.push_back(static_cast<long long>(i));
    raw.positions.push_back({xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]});
  }
  const std::size_t cells_at = xml.require("Cells", piece), cells_end = xml.end_of("Cells", cells_at);
  std::vector<double> connectivity, offsets, types;
  for (std::size_t at = xml.find("DataArray", cells_at, cells_end); at != std::string::npos;
       at = xml.find("DataArray", at + 1, cells_end)) {
    const std::string name = xml.attribute(at, "Name");
    if (name == "connectivity") connectivity = values(xml, at, "Cells' connectivity", header64);
    else if (name == "offsets") offsets = values(xml, at, "Cells' offsets", header64);
    else if (name == "types") types = values(xml, at, "Cells' types", header64);
  }
  if (offsets.size() != types.size()) xml.fail("Cells give " + std::to_string(offsets.size()) + " offsets for " + std::to_string(types.size()) + " types");
  std::vector<std::vector<long long>> cells;
  std::vector<long long> cell_types;
  long long start = 0;
  for (std::size_t c = 0; c < offsets.size(); ++c) {
    const long long end = index(xml, offsets[c], "cell " + std::to_string(c) + "'s offset");
    if (end < start || end > static_cast<long long>(connectivity.size()))
      xml.fail("cell " + std::to_string(c) + "'s offset " + std::to_string(end) + " is out of range");
    auto& cell = cells.emplace_back();
    for (long long k = start; k < end; ++k) cell.push_back(index(xml, connectivity[k], "cell " + std::to_string(c) + "'s point"));
    cell_types.push_back(index(xml, types[c], "cell " + std::to_string(c) + "'s type"));
    start = end;
  }
  keep_vtk_tetrahedra(file, cells, cell_types, raw);
  return raw;
}

}  // namespace incise::engine::tet_file
