// PLY (paulbourke.net/dataformats/ply), ascii, binary_little_endian and binary_big_endian.
// The `vertex` element's x, y and z (any numeric type) and the `face` element's vertex_indices
// or vertex_index list (any integer count and index types) are read; every other element and
// property is read past by its declared type and left. An ASCII entry is one line.
#include "engine/surface_file.hpp"

#include <array>
#include <bit>
#include <cstring>
#include <limits>

namespace incise::engine {

namespace {

using surface_text::quote;

enum class Type { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

std::optional<Type> type_named(std::string_view name) {
  static constexpr std::pair<std::string_view, Type> names[] = {
      {"char", Type::Int8},     {"int8", Type::Int8},     {"uchar", Type::UInt8},     {"uint8", Type::UInt8},
      {"short", Type::Int16},   {"int16", Type::Int16},   {"ushort", Type::UInt16},   {"uint16", Type::UInt16},
      {"int", Type::Int32},     {"int32", Type::Int32},   {"uint", Type::UInt32},     {"uint32", Type::UInt32},
      {"float", Type::Float32}, {"float32", Type::Float32}, {"double", Type::Float64}, {"float64", Type::Float64}};
  for (const auto& [n, t] : names)
    if (n == name) return t;
  return std::nullopt;
}

std::size_t bytes_of(Type t) {
  switch (t) {
    case Type::Int8: case Type::UInt8: return 1;
    case Type::Int16: case Type::UInt16: return 2;
    case Type::Float64: return 8;
    default: return 4;
  }
}

bool is_integer(Type t) { return t != Type::Float32 && t != Type::Float64; }

std::pair<std::int64_t, std::int64_t> range_of(Type t) {
  switch (t) {
    case Type::Int8: return {-128, 127};
    case Type::UInt8: return {0, 255};
    case Type::Int16: return {-32768, 32767};
    case Type::UInt16: return {0, 65535};
    case Type::Int32: return {std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()};
    default: return {0, std::numeric_limits<std::uint32_t>::max()};
  }
}

struct Property {
  std::string name;
  bool list = false;
  Type count_type = Type::UInt8;  // a list's
  Type type = Type::Float32;      // the value's, or each list item's
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  int line = 0;  // in the header
  std::vector<Property> properties;
};

// What the data is read for: the vertex element's x, y, z and the face element's index list
// (property positions, -1 where absent).
struct Roles {
  int vertex = -1, face = -1;
  std::array<int, 3> xyz{-1, -1, -1};
  int indices = -1;
};

struct Header {
  bool ascii = false, big_endian = false;
  std::vector<Element> elements;
  std::size_t data_start = 0;
  int lines = 0;
};

class Reader {
 public:
  Reader(const std::filesystem::path& file, std::string data) : file_(file.string()), data_(std::move(data)) {}
  SurfaceFile read();

 private:
  [[noreturn]] void fail(const std::string& why) const { throw MeshError(file_ + ": " + why); }
  Header read_header();
  void read_property(std::vector<Element>& elements, const std::vector<std::string_view>& w, const std::string& where);
  Roles find_roles(const Header& header);
  void check_size(const Header& header);
  void read_ascii(const Header& header, const Roles& roles);
  void read_ascii_entry(const Element& element, std::size_t e, const Roles& roles, const std::vector<std::string_view>& w);
  double ascii_value(Type t, const std::vector<std::string_view>& w, std::size_t& next, const std::string& name);
  void read_binary(const Header& header, const Roles& roles);
  void read_binary_element(const Element& element, std::size_t e, const Roles& roles);
  double binary_value(Type t, const Property& property);
  void add_corner(std::int64_t index);
  // Where the data is, for a refusal (built only then): the line (ASCII) or the byte (binary)
  // and the entry.
  [[noreturn]] void fail_here(const std::string& why) const {
    fail((ascii_ ? "PLY line " + std::to_string(line_) : "PLY data at byte " + std::to_string(item_)) + " (" +
         element_->name + " " + std::to_string(entry_) + "): " + why);
  }

  std::string file_;
  std::string data_;
  bool ascii_ = false;
  std::size_t at_ = 0;    // binary: the next byte
  std::size_t item_ = 0;  // binary: the value being read
  int line_ = 0;          // ASCII: the entry's line
  const Element* element_ = nullptr;
  std::uint64_t entry_ = 0;
  bool big_endian_ = false;
  std::uint64_t vertex_count_ = 0;
  SurfaceFile surface_;
};

// A header of at most this many lines: a file that reads as a header without end is refused
// rather than read to its end line by line.
constexpr int kMaxHeaderLines = 10000;

Header Reader::read_header() {
  Header header;
  bool format = false;
  std::vector<std::string_view> w;
  std::size_t at = 0;
  for (int number = 1; number <= kMaxHeaderLines && at < data_.size(); ++number) {
    const std::size_t end = std::min(data_.find('\n', at), data_.size());
    std::string_view line(data_.data() + at, end - at);
    at = std::min(end + 1, data_.size());
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::string where = "PLY header line " + std::to_string(number);
    if (auto problem = surface_text::control_character(line)) fail(where + ": " + *problem + " (words are separated by spaces or tabs)");
    surface_text::split_words(line, w);
    const std::string quoted = where + " ('" + std::string(line.substr(0, 80)) + "'): ";
    if (number == 1) {
      if (w.size() != 1 || w[0] != "ply") fail(quoted + "must be 'ply'");
    } else if (w.empty() || w[0] == "comment" || w[0] == "obj_info") {
    } else if (w[0] == "end_header") {
      if (!format) fail(quoted + "ends a header with no 'format' line");
      header.data_start = at;
      header.lines = number;
      return header;
    } else if (w[0] == "format") {
      if (w.size() != 3 || (w[1] != "ascii" && w[1] != "binary_little_endian" && w[1] != "binary_big_endian"))
        fail(quoted + "format must be ascii, binary_little_endian or binary_big_endian, with a version");
      format = true;
      header.ascii = w[1] == "ascii";
      header.big_endian = w[1] == "binary_big_endian";
    } else if (w[0] == "element") {
      const auto count = w.size() == 3 ? surface_text::integer(w[2]) : std::nullopt;
      if (!count || *count < 0) fail(quoted + "must be 'element NAME COUNT'");
      if (!std::isalpha(static_cast<unsigned char>(w[1][0])) && w[1][0] != '_')
        fail(quoted + "an element's name must start with a letter or '_'");
      if (static_cast<std::uint64_t>(*count) > data_.size())
        fail(quoted + "claims " + std::string(w[2]) + " entries, more than the file's " + std::to_string(data_.size()) + " bytes");
      header.elements.push_back({std::string(w[1]), static_cast<std::uint64_t>(*count), number, {}});
    } else if (w[0] == "property") {
      read_property(header.elements, w, quoted);
    } else {
      fail(quoted + "is not a PLY header line");
    }
  }
  fail(at < data_.size() ? "the PLY header has no 'end_header' line in its first " + std::to_string(kMaxHeaderLines) + " lines"
                         : "the PLY header has no 'end_header' line");
}

void Reader::read_property(std::vector<Element>& elements, const std::vector<std::string_view>& w, const std::string& where) {
  const bool list = w.size() >= 2 && w[1] == "list";
  if (list ? w.size() != 5 : w.size() != 3)
    fail(where + "must be 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'");
  const auto check = [&](std::string_view name) {
    const auto t = type_named(name);
    if (!t)
      fail(where + "unsupported property type " + quote(name) + " (char, uchar, short, ushort, int, uint, float, double or "
                   "their sized names int8 ... float64)");
    return *t;
  };
  Property property{std::string(w.back()), list, Type::UInt8, check(list ? w[3] : w[1])};
  if (list) {
    property.count_type = check(w[2]);
    if (!is_integer(property.count_type)) fail(where + "a list's count type must be an integer type, not " + quote(w[2]));
  }
  if (elements.empty()) fail(where + "a property before any element");
  elements.back().properties.push_back(property);
}

Roles Reader::find_roles(const Header& header) {
  Roles roles;
  for (std::size_t e = 0; e < header.elements.size(); ++e) {
    const auto& element = header.elements[e];
    if (element.name == "vertex" && roles.vertex < 0) roles.vertex = static_cast<int>(e);
    if (element.name == "face" && roles.face < 0) roles.face = static_cast<int>(e);
  }
  if (roles.vertex < 0) fail("the PLY header declares no 'vertex' element");
  if (roles.face < 0) fail("the PLY header declares no 'face' element (a point cloud holds no surface)");
  const auto& vertex = header.elements[roles.vertex];
  const auto& face = header.elements[roles.face];
  const std::string axes[3] = {"x", "y", "z"};
  for (std::size_t p = 0; p < vertex.properties.size(); ++p)
    for (int i = 0; i < 3; ++i)
      if (vertex.properties[p].name == axes[i] && roles.xyz[i] < 0) {
        if (vertex.properties[p].list) fail("PLY header: element vertex (line " + std::to_string(vertex.line) + "): " + axes[i] + " is a list");
        roles.xyz[i] = static_cast<int>(p);
      }
  for (int i = 0; i < 3; ++i)
    if (roles.xyz[i] < 0) fail("PLY header: element vertex (line " + std::to_string(vertex.line) + ") has no property " + axes[i]);
  for (std::size_t p = 0; p < face.properties.size() && roles.indices < 0; ++p)
    if (face.properties[p].list && (face.properties[p].name == "vertex_indices" || face.properties[p].name == "vertex_index"))
      roles.indices = static_cast<int>(p);
  if (roles.indices < 0)
    fail("PLY header: element face (line " + std::to_string(face.line) + ") has no list vertex_indices or vertex_index");
  if (!is_integer(face.properties[roles.indices].type))
    fail("PLY header: element face (line " + std::to_string(face.line) + "): unsupported index type: the list '" +
         face.properties[roles.indices].name + "' holds floating-point values, not vertex indices");
  return roles;
}

// Each entry takes at least its values' bytes (binary) or a character and a separator a value
// (ASCII); elements claiming more than the file holds are refused before anything is allocated.
void Reader::check_size(const Header& header) {
  const std::uint64_t left = data_.size() - header.data_start;
  std::uint64_t least = 0;
  for (const auto& element : header.elements) {
    std::uint64_t entry = 0;
    for (const auto& p : element.properties) entry += header.ascii ? 2 : bytes_of(p.list ? p.count_type : p.type);
    least += element.count * entry;  // count <= file size, entry <= 8 * header lines: no overflow
    if (least > left)
      fail("PLY header line " + std::to_string(element.line) + ": element " + element.name + "'s " +
           std::to_string(element.count) + " entries need at least " + std::to_string(least) +
           " bytes of data with those before it, the file has " + std::to_string(left) + " after its header");
  }
}

void Reader::add_corner(std::int64_t index) {
  if (index < 0 || static_cast<std::uint64_t>(index) >= vertex_count_)
    fail_here("vertex index " + std::to_string(index) + " out of range (the file has " + std::to_string(vertex_count_) + " vertices)");
  surface_.corners.push_back(static_cast<std::uint32_t>(index));
}

SurfaceFile Reader::read() {
  const Header header = read_header();
  check_size(header);
  const Roles roles = find_roles(header);
  vertex_count_ = header.elements[roles.vertex].count;
  surface_.vertices.reserve(vertex_count_);
  ascii_ = header.ascii;
  if (header.ascii)
    read_ascii(header, roles);
  else
    read_binary(header, roles);
  return std::move(surface_);
}

void Reader::read_ascii(const Header& header, const Roles& roles) {
  std::size_t at = header.data_start;
  line_ = header.lines;
  std::vector<std::string_view> w;
  for (std::size_t e = 0; e < header.elements.size(); ++e) {
    element_ = &header.elements[e];
    if (element_->properties.empty()) continue;
    for (entry_ = 0; entry_ < element_->count; ++entry_) {
      do {  // the entry's line: the next that is not blank
        if (at >= data_.size())
          fail("PLY file truncated: it ends at line " + std::to_string(line_) + " before " + element_->name + " " + std::to_string(entry_));
        const std::size_t end = std::min(data_.find('\n', at), data_.size());
        std::string_view line(data_.data() + at, end - at);
        at = std::min(end + 1, data_.size());
        ++line_;
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        // A NUL or other control byte is refused, not taken for a separator or the line's end.
        if (auto problem = surface_text::control_character(line)) fail("PLY line " + std::to_string(line_) + ": " + *problem);
        surface_text::split_words(line, w);
      } while (w.empty());
      read_ascii_entry(*element_, e, roles, w);
    }
  }
}

// The next word as a value of type `t`: an integer in the type's range, or a number.
double Reader::ascii_value(Type t, const std::vector<std::string_view>& w, std::size_t& next, const std::string& name) {
  if (next >= w.size()) fail_here("the line ends before " + name);
  const std::string_view word = w[next++];
  if (is_integer(t)) {
    const auto n = surface_text::integer(word);
    const auto [low, high] = range_of(t);
    if (!n || *n < low || *n > high) fail_here(name + " " + quote(word) + " is not an integer of the property's type");
    return static_cast<double>(*n);
  }
  const auto x = surface_text::real(word);
  if (!x) fail_here(name + " " + quote(word) + " is not a number");
  return *x;
}

void Reader::read_ascii_entry(const Element& element, std::size_t e, const Roles& roles, const std::vector<std::string_view>& w) {
  std::size_t next = 0;
  std::array<double, 3> position{};
  const bool vertex = static_cast<int>(e) == roles.vertex;
  for (std::size_t p = 0; p < element.properties.size(); ++p) {
    const Property& property = element.properties[p];
    if (!property.list) {
      const std::string_view word = next < w.size() ? w[next] : std::string_view();
      const double x = ascii_value(property.type, w, next, property.name);
      for (int i = 0; i < 3; ++i)
        if (vertex && static_cast<int>(p) == roles.xyz[i]) {
          // A float as assimp read it (surface_file.hpp); other types are exact in a double.
          const auto single = property.type == Type::Float32 ? surface_text::single_as_assimp_read(word)
                                                             : surface_text::single_precision(x);
          if (!single) fail_here("coordinate " + property.name + " " + quote(word) + " is not finite in single precision");
          position[i] = *single;
        }
      continue;
    }
    if (next >= w.size()) fail_here("the line ends before list '" + property.name + "'");
    const auto claimed = surface_text::integer(w[next]);
    const std::size_t left = w.size() - next - 1;
    if (claimed && *claimed >= 0 && static_cast<std::uint64_t>(*claimed) > left)
      fail_here("list '" + property.name + "' claims " + std::string(w[next].substr(0, 40)) + " values, its line has " +
                std::to_string(left) + " left");
    const double count = ascii_value(property.count_type, w, next, "list '" + property.name + "' count");
    if (count < 0) fail_here("list '" + property.name + "' has a negative count");
    const bool indices = static_cast<int>(e) == roles.face && static_cast<int>(p) == roles.indices;
    if (indices && count == 0) fail_here("a face with no vertices");
    for (std::size_t k = 0; k < static_cast<std::size_t>(count); ++k) {
      const double x = ascii_value(property.type, w, next, "list '" + property.name + "' value");
      if (indices) add_corner(static_cast<std::int64_t>(x));
    }
    if (indices) surface_.polygon_sizes.push_back(static_cast<std::uint32_t>(count));
  }
  if (next != w.size()) fail_here(std::to_string(w.size()) + " values, the element's properties take " + std::to_string(next));
  if (vertex) surface_.vertices.push_back(position);
}

// The next value as a double (every PLY type is exact in one).
double Reader::binary_value(Type t, const Property& property) {
  item_ = at_;
  const std::size_t n = bytes_of(t);
  if (data_.size() - at_ < n)
    fail("PLY file truncated: " + element_->name + " " + std::to_string(entry_) + "'s " + property.name + " needs bytes " +
         std::to_string(at_) + "-" + std::to_string(at_ + n - 1) + ", the file has " + std::to_string(data_.size()));
  std::uint64_t bits = 0;
  for (std::size_t i = 0; i < n; ++i)
    bits |= static_cast<std::uint64_t>(static_cast<unsigned char>(data_[at_ + i])) << (8 * (big_endian_ ? n - 1 - i : i));
  at_ += n;
  switch (t) {
    case Type::Int8: return static_cast<std::int8_t>(bits);
    case Type::UInt8: case Type::UInt16: case Type::UInt32: return static_cast<double>(bits);
    case Type::Int16: return static_cast<std::int16_t>(bits);
    case Type::Int32: return static_cast<std::int32_t>(bits);
    case Type::Float32: return std::bit_cast<float>(static_cast<std::uint32_t>(bits));
    case Type::Float64: return std::bit_cast<double>(bits);
  }
  return 0;
}

void Reader::read_binary_element(const Element& element, std::size_t e, const Roles& roles) {
  const bool vertex = static_cast<int>(e) == roles.vertex;
  for (entry_ = 0; entry_ < element.count; ++entry_) {
    std::array<double, 3> position{};
    for (std::size_t p = 0; p < element.properties.size(); ++p) {
      const Property& property = element.properties[p];
      if (!property.list) {
        const double x = binary_value(property.type, property);
        for (int i = 0; i < 3; ++i)
          if (vertex && static_cast<int>(p) == roles.xyz[i]) {
            const auto single = surface_text::single_precision(x);
            if (!single) fail_here("coordinate " + property.name + " is not finite in single precision");
            position[i] = *single;
          }
        continue;
      }
      const double count = binary_value(property.count_type, property);
      if (count < 0) fail_here("list '" + property.name + "' has a negative count");
      const std::uint64_t left = data_.size() - at_;
      if (count > static_cast<double>(left / bytes_of(property.type)))
        fail_here("list '" + property.name + "' claims " + std::to_string(static_cast<std::uint64_t>(count)) +
                  " values, more than the file's " + std::to_string(left) + " bytes left hold");
      const bool indices = static_cast<int>(e) == roles.face && static_cast<int>(p) == roles.indices;
      if (indices && count == 0) fail_here("a face with no vertices");
      for (std::uint64_t k = 0; k < static_cast<std::uint64_t>(count); ++k) {
        const double x = binary_value(property.type, property);
        if (indices) add_corner(static_cast<std::int64_t>(x));
      }
      if (indices) surface_.polygon_sizes.push_back(static_cast<std::uint32_t>(count));
    }
    if (vertex) surface_.vertices.push_back(position);
  }
}

void Reader::read_binary(const Header& header, const Roles& roles) {
  at_ = header.data_start;
  big_endian_ = header.big_endian;
  for (std::size_t e = 0; e < header.elements.size(); ++e) {
    element_ = &header.elements[e];
    read_binary_element(*element_, e, roles);
  }
}

}  // namespace

SurfaceFile read_ply_surface(const std::filesystem::path& file) {
  Reader reader(file, surface_text::read_whole_file(file));
  return reader.read();
}

}  // namespace incise::engine
