// Gmsh .msh binary, versions 2.x and 4.x (gmsh.info/doc/texinfo/gmsh.html#MSH-file-format):
// section names and version 2's counts are text lines, the rest native-endian integers and
// doubles. Version 4 writes size_t as the format line's data size, which must be 8 here.
// A file written on a machine of the other byte order is refused (its endianness check, an int
// 1 after the format line, reads otherwise).
#include "engine/tet_mesh_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace incise::engine::tet_file {

namespace {

// The file's bytes from where the text reader stopped; errors name the byte offset.
class Bytes {
 public:
  // The text reader's position is one past the end when the last line has no newline.
  explicit Bytes(const Lines& lines)
      : lines_(lines), text_(lines.text()), at_(std::min(lines.position(), lines.text().size())) {}

  template <class T>
  T take(const std::string& what) {
    if (at_ > text_.size() || text_.size() - at_ < sizeof(T)) fail("the file ends where " + what + " was expected");
    T value;
    std::memcpy(&value, text_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return value;
  }
  // The next text line (a section name or a version 2 count), newlines before it skipped.
  std::string_view line() {
    while (at_ < text_.size() && (text_[at_] == '\n' || text_[at_] == '\r')) ++at_;
    std::size_t end = text_.find('\n', at_);
    if (end == std::string::npos) end = text_.size();
    std::string_view out(text_.data() + at_, end - at_);
    at_ = std::min(end + 1, text_.size());  // binary data starts after the newline
    while (!out.empty() && (out.back() == '\r' || out.back() == ' ')) out.remove_suffix(1);
    return out;
  }
  bool done() {
    while (at_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[at_]))) ++at_;
    return at_ >= text_.size();
  }
  void skip_to(std::string_view end_line) {
    const std::size_t found = text_.find(end_line, at_);
    if (found == std::string::npos) fail("no " + std::string(end_line.substr(1)) + " follows");
    at_ = found;
  }
  void expect(std::string_view end_line) {
    const std::string_view got = line();
    if (got != end_line) fail("expected " + std::string(end_line) + ", found '" + std::string(got.substr(0, 40)) + "'");
  }
  [[noreturn]] void fail(const std::string& why) const {
    throw MeshError(lines_.file().string() + ": byte " + std::to_string(at_) + ": " + why);
  }
  // A count read as `T`, refused when larger than the bytes left.
  template <class T>
  std::size_t count(const std::string& what) {
    const T n = take<T>(what);
    bool negative = false;
    if constexpr (std::is_signed_v<T>) negative = n < 0;
    if (negative || static_cast<unsigned long long>(n) > text_.size() - at_)
      fail(what + " " + std::to_string(n) + " is negative or more than the file's bytes could hold");
    return static_cast<std::size_t>(n);
  }

 private:
  const Lines& lines_;
  const std::string& text_;
  std::size_t at_;
};

void add_element(Bytes& bytes, long long type, const std::string& name,
                 const std::vector<long long>& nodes, RawTets& raw) {
  if (gmsh_below_3d(type)) {
    ++raw.skipped_elements;
    return;
  }
  if (type != 4) bytes.fail(gmsh_volume_problem(name, type));
  raw.tets.push_back({{nodes[0], nodes[1], nodes[2], nodes[3]}, name});
}

void read_v2_binary(Bytes& bytes, const Lines& lines, RawTets& raw) {
  while (!bytes.done()) {
    const std::string_view section = bytes.line();
    if (section == "$Nodes") {
      const std::string_view count = bytes.line();
      const long long n = lines.integer(count, "the node count");
      for (long long i = 0; i < n; ++i) {
        raw.node_ids.push_back(bytes.take<std::int32_t>("node " + std::to_string(i)));
        std::array<double, 3> p{};
        for (double& c : p) c = bytes.take<double>("node " + std::to_string(raw.node_ids.back()) + "'s coordinates");
        for (double c : p)
          if (!std::isfinite(c)) bytes.fail("node " + std::to_string(raw.node_ids.back()) + " has a coordinate that is not finite");
        raw.positions.push_back(p);
      }
      bytes.expect("$EndNodes");
    } else if (section == "$Elements") {
      const long long n = lines.integer(bytes.line(), "the element count");
      for (long long index = 0; index < n;) {
        const auto type = bytes.take<std::int32_t>("an element block's type");
        const auto in_block = bytes.count<std::int32_t>("element block's element count");
        const auto tags = bytes.count<std::int32_t>("element block's tag count");
        const int nodes = gmsh_node_count(type);
        if (nodes == 0) bytes.fail("element " + std::to_string(index) + " is of unknown type " + std::to_string(type));
        for (std::size_t e = 0; e < in_block; ++e, ++index) {
          const auto tag = bytes.take<std::int32_t>("element " + std::to_string(index));
          for (std::size_t t = 0; t < tags; ++t) bytes.take<std::int32_t>("a tag");
          std::vector<long long> ids(nodes);
          for (auto& id : ids) id = bytes.take<std::int32_t>("element " + std::to_string(index) + "'s nodes");
          add_element(bytes, type, "element " + std::to_string(index) + " (tag " + std::to_string(tag) + ")", ids, raw);
        }
      }
      bytes.expect("$EndElements");
    } else if (section.starts_with("$")) {
      bytes.skip_to("$End" + std::string(section.substr(1)));
      bytes.line();
    } else {
      bytes.fail("expected a section, found '" + std::string(section.substr(0, 40)) + "'");
    }
  }
}

void read_v4_nodes_binary(Bytes& bytes, RawTets& raw) {
  const std::size_t blocks = bytes.count<std::uint64_t>("the node block count");
  bytes.take<std::uint64_t>("the node count");
  bytes.take<std::uint64_t>("the smallest node tag");
  bytes.take<std::uint64_t>("the largest node tag");
  for (std::size_t b = 0; b < blocks; ++b) {
    const auto dim = bytes.take<std::int32_t>("node block " + std::to_string(b) + "'s dimension");
    bytes.take<std::int32_t>("node block " + std::to_string(b) + "'s entity");
    const bool parametric = bytes.take<std::int32_t>("node block " + std::to_string(b) + "'s parametric flag") != 0;
    const std::size_t n = bytes.count<std::uint64_t>("node block " + std::to_string(b) + "'s node count");
    const std::size_t first = raw.node_ids.size();
    for (std::size_t i = 0; i < n; ++i) {
      const auto tag = bytes.take<std::uint64_t>("a node tag");
      if (tag > static_cast<std::uint64_t>(INT64_MAX)) bytes.fail("node tag " + std::to_string(tag) + " does not fit in 64 bits");
      raw.node_ids.push_back(static_cast<long long>(tag));
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::string node = "node " + std::to_string(raw.node_ids[first + i]);
      std::array<double, 3> p{};
      for (double& c : p) c = bytes.take<double>(node + "'s coordinates");
      for (double c : p)
        if (!std::isfinite(c)) bytes.fail(node + " has a coordinate that is not finite");
      for (int k = 0; parametric && k < dim; ++k) bytes.take<double>(node + "'s parameters");
      raw.positions.push_back(p);
    }
  }
  bytes.expect("$EndNodes");
}

void read_v4_elements_binary(Bytes& bytes, RawTets& raw) {
  const std::size_t blocks = bytes.count<std::uint64_t>("the element block count");
  for (int k = 0; k < 3; ++k) bytes.take<std::uint64_t>("the element counts");
  long long index = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    bytes.take<std::int32_t>("element block " + std::to_string(b) + "'s dimension");
    bytes.take<std::int32_t>("element block " + std::to_string(b) + "'s entity");
    const auto type = bytes.take<std::int32_t>("element block " + std::to_string(b) + "'s type");
    const std::size_t n = bytes.count<std::uint64_t>("element block " + std::to_string(b) + "'s element count");
    const int nodes = gmsh_node_count(type);
    if (nodes == 0) bytes.fail("element block " + std::to_string(b) + " has unknown element type " + std::to_string(type));
    for (std::size_t e = 0; e < n; ++e, ++index) {
      const auto tag = bytes.take<std::uint64_t>("element " + std::to_string(index));
      std::vector<long long> ids(nodes);
      for (auto& id : ids) {
        const auto node = bytes.take<std::uint64_t>("element " + std::to_string(index) + "'s nodes");
        id = node > static_cast<std::uint64_t>(INT64_MAX) ? -1 : static_cast<long long>(node);
      }
      add_element(bytes, type, "element " + std::to_string(index) + " (tag " + std::to_string(tag) + ")", ids, raw);
    }
  }
  bytes.expect("$EndElements");
}

void read_v4_binary(Bytes& bytes, RawTets& raw) {
  while (!bytes.done()) {
    const std::string_view section = bytes.line();
    if (section == "$Nodes") {
      read_v4_nodes_binary(bytes, raw);
    } else if (section == "$Elements") {
      read_v4_elements_binary(bytes, raw);
    } else if (section.starts_with("$")) {
      bytes.skip_to("$End" + std::string(section.substr(1)));
      bytes.line();
    } else {
      bytes.fail("expected a section, found '" + std::string(section.substr(0, 40)) + "'");
    }
  }
}

}  // namespace

RawTets read_gmsh_binary(Lines& lines, double version, long long data_size) {
  Bytes bytes(lines);
  if (data_size != 8) bytes.fail("data size " + std::to_string(data_size) + " is not read (8 is)");
  if (const auto one = bytes.take<std::int32_t>("the endianness check"); one != 1)
    bytes.fail("the endianness check reads " + std::to_string(one) +
               ", not 1: the file was written on a machine of the other byte order, or is not binary MSH; save it as "
               "ASCII (Gmsh: Mesh.Binary = 0)");
  bytes.expect("$EndMeshFormat");
  RawTets raw;
  if (version < 3) read_v2_binary(bytes, lines, raw);
  else read_v4_binary(bytes, raw);
  return raw;
}

}  // namespace incise::engine::tet_file
