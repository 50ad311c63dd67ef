// Wavefront OBJ (paulbourke.net/dataformats/obj): `v` positions (x y z, x y z w or x y z r g b)
// and `f` faces of at least 3 corners, each corner
// `v`, `v/vt`, `v//vn` or `v/vt/vn`, 1-based or negative (counted back from the latest of its
// kind). `vt` and `vn` are counted so that a corner's texture and normal indices are checked;
// every other statement (o, g, s, usemtl, mtllib, l, p, ...) is left: objects and groups are one
// surface, as assimp's import joined its meshes into one. '#' starts a comment.
#include "engine/surface_file.hpp"

#include <limits>

namespace incise::engine {

namespace {

using surface_text::quote;

// A kind of index a corner holds: the statements counted so far, and the largest positive
// index seen (which may name a later statement: checked at the end).
struct Kind {
  const char* statement;
  std::uint64_t count = 0;
  std::int64_t largest = 0;
  int largest_line = 0;
};

class Reader {
 public:
  explicit Reader(const std::filesystem::path& file) : file_(file.string()) {}
  SurfaceFile read(const std::string& data);

 private:
  [[noreturn]] void fail(const std::string& why) const { throw MeshError(file_ + ": " + why); }
  void read_vertex(const std::vector<std::string_view>& w);
  void read_face(const std::vector<std::string_view>& w);
  std::int64_t index(std::string_view word, Kind& kind, std::string_view corner);
  std::string where() const { return "OBJ line " + std::to_string(line_); }

  std::string file_;
  int line_ = 0;
  Kind positions_{"v"}, textures_{"vt"}, normals_{"vn"};
  SurfaceFile surface_;
};

// x y z; x y z w, a homogeneous point (assimp divided by w in float); or x y z r g b, a
// coloured one. assimp skipped a `v` of another count without a word, shifting every later
// index: refused here.
void Reader::read_vertex(const std::vector<std::string_view>& w) {
  const std::size_t values = w.size() - 1;
  if (values != 3 && values != 4 && values != 6)
    fail(where() + ": 'v' takes x y z, x y z w or x y z r g b, found " + std::to_string(values) + " values");
  std::array<double, 4> p{0, 0, 0, 1};
  for (std::size_t i = 1; i < w.size(); ++i) {
    if (i > 4 || (i == 4 && values == 6)) {
      if (!surface_text::real(w[i])) fail(where() + ": 'v' value " + quote(w[i]) + " is not a number");
      continue;
    }
    const auto single = surface_text::single_as_assimp_read(w[i]);
    if (!single) fail(where() + ": coordinate " + quote(w[i]) + " is not a number finite in single precision");
    p[i - 1] = *single;
  }
  if (values == 4) {
    if (p[3] == 0) fail(where() + ": homogeneous coordinate w is 0");
    for (int i = 0; i < 3; ++i) {
      const auto single = surface_text::single_precision(static_cast<float>(p[i]) / static_cast<float>(p[3]));
      if (!single) fail(where() + ": x y z over w is not finite in single precision");
      p[i] = *single;
    }
  }
  surface_.vertices.push_back({p[0], p[1], p[2]});
  ++positions_.count;
}

// A corner's index of `kind`, 0-based.
std::int64_t Reader::index(std::string_view word, Kind& kind, std::string_view corner) {
  const auto n = surface_text::integer(word);
  const auto what = [&] { return where() + ": corner " + quote(corner) + ": " + kind.statement + " index " + quote(word); };
  if (!n || *n == 0) fail(what() + " is not a nonzero integer");
  if (*n < 0) {
    if (static_cast<std::uint64_t>(-(*n + 1)) >= kind.count)  // -(n+1): no overflow at the smallest n
      fail(what() + " reaches back past the first '" + kind.statement + "' (" + std::to_string(kind.count) + " so far)");
    return static_cast<std::int64_t>(kind.count) + *n;
  }
  if (*n > kind.largest) {
    kind.largest = *n;
    kind.largest_line = line_;
  }
  return *n - 1;
}

void Reader::read_face(const std::vector<std::string_view>& w) {
  // assimp refused a face of one or two corners (a point or line its mesh did not declare).
  if (w.size() < 4) fail(where() + ": 'f' with " + std::to_string(w.size() - 1) + " corners, a face needs at least 3");
  for (std::size_t i = 1; i < w.size(); ++i) {
    const std::string_view corner = w[i];
    const std::size_t slash = corner.find('/');
    const std::int64_t v = index(corner.substr(0, slash), positions_, corner);
    if (slash != std::string_view::npos) {
      const std::string_view rest = corner.substr(slash + 1);
      const std::size_t second = rest.find('/');
      const std::string_view texture = rest.substr(0, second);
      if (!texture.empty()) index(texture, textures_, corner);
      if (second != std::string_view::npos) {
        const std::string_view normal = rest.substr(second + 1);
        if (normal.find('/') != std::string_view::npos) fail(where() + ": corner " + quote(corner) + " has more than 3 parts");
        index(normal, normals_, corner);
      } else if (texture.empty()) {
        fail(where() + ": corner " + quote(corner) + " has an empty texture index and no normal");
      }
    }
    // Indices past the vertices so far are checked at the end; the surface holds < 2^32 of them.
    if (v > std::numeric_limits<std::uint32_t>::max()) fail(where() + ": corner " + quote(corner) + ": index too large");
    surface_.corners.push_back(static_cast<std::uint32_t>(v));
  }
  surface_.polygon_sizes.push_back(static_cast<std::uint32_t>(w.size() - 1));
}

SurfaceFile Reader::read(const std::string& data) {
  std::vector<std::string_view> w;
  for (std::size_t at = 0; at < data.size();) {
    const std::size_t end = std::min(data.find('\n', at), data.size());
    std::string_view line(data.data() + at, end - at);
    at = end + 1;
    ++line_;
    line = line.substr(0, line.find('#'));
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (auto problem = surface_text::control_character(line)) fail(where() + ": " + *problem);
    surface_text::split_words(line, w);
    if (w.empty()) continue;
    if (w[0] == "v")
      read_vertex(w);
    else if (w[0] == "vt")
      ++textures_.count;
    else if (w[0] == "vn")
      ++normals_.count;
    else if (w[0] == "f")
      read_face(w);
  }
  for (const Kind* kind : {&positions_, &textures_, &normals_})
    if (static_cast<std::uint64_t>(kind->largest) > kind->count)
      fail("OBJ line " + std::to_string(kind->largest_line) + ": " + kind->statement + " index " + std::to_string(kind->largest) +
           " out of range (the file has " + std::to_string(kind->count) + " '" + kind->statement + "')");
  surface_.vertices_in_use_order = true;
  return std::move(surface_);
}

}  // namespace

SurfaceFile read_obj_surface(const std::filesystem::path& file) {
  return Reader(file).read(surface_text::read_whole_file(file));
}

}  // namespace incise::engine
