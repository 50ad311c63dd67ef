#include "engine/mesh_import.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace incise::engine {

namespace {

bool is_ply_type(const std::string& t) {
  static const std::set<std::string> types = {"char",  "uchar", "short", "ushort", "int",   "uint",    "float",
                                              "double", "int8", "uint8", "int16",  "uint16", "int32", "uint32",
                                              "float32", "float64"};
  return types.count(t) > 0;
}

// A line of a PLY header or ASCII data holds words separated by spaces or tabs.
std::optional<std::string> control_character_problem(const std::string& line, const std::string& where) {
  for (std::size_t column = 0; column < line.size(); ++column) {
    const auto c = static_cast<unsigned char>(line[column]);
    if ((c < 0x20 && c != '\t') || c == 0x7f) {
      char code[8];
      std::snprintf(code, sizeof code, "0x%02x", c);
      return where + ": control character " + code + " at column " + std::to_string(column + 1) +
             " (words are separated by spaces or tabs)";
    }
  }
  return std::nullopt;
}

struct PlyProperty {
  std::string name;
  bool list = false;
  std::string count_type;  // a list's
  std::string type;        // the value's, or each list item's
};

struct PlyElement {
  std::string name;
  unsigned long long count = 0;
  std::vector<PlyProperty> properties;
};

int ply_type_bytes(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "double" || t == "float64") return 8;
  return 4;
}

// The data of a binary PLY file, entry by entry: as in ASCII (below), assimp allocates what a
// list's count says; a face list of 400000000 ints in an 86-byte file took 3 GB. A list may
// claim no more bytes than the file has left; a file that ends early is assimp's to judge.
std::optional<std::string> ply_binary_data_problem(std::istream& in, const std::vector<PlyElement>& elements,
                                                   std::uintmax_t file_bytes, bool big_endian) {
  std::uintmax_t at = static_cast<std::uintmax_t>(in.tellg());  // counted, not asked: tellg costs a seek
  const auto skip = [&](std::uintmax_t bytes) {
    in.ignore(static_cast<std::streamsize>(bytes));
    at += static_cast<std::uintmax_t>(in.gcount());
    return static_cast<std::uintmax_t>(in.gcount()) == bytes;
  };
  for (const auto& element : elements)
    for (unsigned long long entry = 0; entry < element.count; ++entry)
      for (const auto& property : element.properties) {
        const auto value_bytes = static_cast<std::uintmax_t>(ply_type_bytes(property.type));
        if (!property.list) {
          if (!skip(value_bytes)) return std::nullopt;
          continue;
        }
        const int size = ply_type_bytes(property.count_type);
        unsigned char bytes[8] = {};
        if (!in.read(reinterpret_cast<char*>(bytes), size)) return std::nullopt;
        at += static_cast<std::uintmax_t>(size);
        unsigned long long count = 0;
        for (int i = 0; i < size; ++i) count |= static_cast<unsigned long long>(bytes[big_endian ? size - 1 - i : i]) << (8 * i);
        const bool is_signed = property.count_type[0] != 'u';
        if (is_signed && (bytes[big_endian ? 0 : size - 1] & 0x80)) count = ~0ull;  // negative
        const std::uintmax_t left = file_bytes > at ? file_bytes - at : 0;
        if (count > left / value_bytes)
          return "PLY data at byte " + std::to_string(at - static_cast<std::uintmax_t>(size)) + " (" + element.name + " " +
                 std::to_string(entry) + "): list '" + property.name + "' claims more values than the file's " +
                 std::to_string(left) + " bytes left";
        if (!skip(count * value_bytes)) return std::nullopt;
      }
  return std::nullopt;
}

// The data of an ASCII PLY file, an entry a line in the header's order (assimp skips empty
// lines): assimp 5.2.5 takes a list's count as written and fills what its line lacks with
// zeros, so a count of 344444444444444444 in a 235-byte file took 12 GB and more than a minute
// (found by fuzz_mesh_ply). A list may claim no more values than its line has left; lines
// past the last entry, or too few of them, are assimp's to judge.
std::optional<std::string> ply_ascii_data_problem(std::istream& in, const std::vector<PlyElement>& elements,
                                                  int number) {
  std::string line;
  std::vector<std::string_view> w;
  for (const auto& element : elements)
    for (unsigned long long entry = 0; entry < element.count; ++entry) {
      do {
        if (!std::getline(in, line)) return std::nullopt;
        ++number;
        if (!line.empty() && line.back() == '\r') line.pop_back();
      } while (line.empty());
      // Numbers, spaces and tabs, as in the header: assimp's parser takes a NUL for the line's
      // end and reads the rest of it as the next entry.
      if (auto problem = control_character_problem(line, "PLY line " + std::to_string(number))) return problem;
      w.clear();  // words, split by hand: a stream per line cost a tenth of a large file's import
      for (std::size_t at = 0; at < line.size();) {
        const std::size_t begin = line.find_first_not_of(" \t", at);
        if (begin == std::string::npos) break;
        at = std::min(line.find_first_of(" \t", begin), line.size());
        w.emplace_back(line.data() + begin, at - begin);
      }
      std::size_t next = 0;
      for (const auto& [name, list, count_type, type] : element.properties) {
        if (next >= w.size()) break;
        if (!list) {
          ++next;
          continue;
        }
        const double count = std::strtod(std::string(w[next]).c_str(), nullptr);
        const std::size_t left = w.size() - ++next;
        if (!(count >= 0 && count <= static_cast<double>(left)))
          return "PLY line " + std::to_string(number) + " (" + element.name + " " + std::to_string(entry) + "): list '" +
                 name + "' claims " + std::string(w[next - 1].substr(0, 40)) + " values, its line has " + std::to_string(left) + " left";
        next += static_cast<std::size_t>(count);
      }
    }
  return std::nullopt;
}

// A PLY file's header, checked before assimp reads the file: assimp 5.2.5 loops without end on
// a property line it cannot parse (found by fuzz_mesh_ply), and allocates whatever an element count
// says. Each line must be one the format defines, and no element may claim more entries than
// the file has bytes; the data's list counts are checked too (ply_*_data_problem). Returns the
// problem, naming the line.
std::optional<std::string> ply_header_problem(std::istream& in, std::uintmax_t file_bytes) {
  std::string line;
  std::vector<PlyElement> elements;
  bool ascii = false, big_endian = false;
  for (int number = 1; std::getline(in, line) && number <= 10000; ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // assimp separates a header's words by spaces and tabs only: a line that read here as
    // 'end_header' and a vertical tab was to it no end of the header, and it read the data as
    // header lines until it hung or read out of bounds (found by fuzz_mesh_ply).
    if (auto problem = control_character_problem(line, "PLY header line " + std::to_string(number))) return problem;
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string word; words >> word;) w.push_back(word);
    const std::string where = "PLY header line " + std::to_string(number) + " ('" + line.substr(0, 80) + "'): ";
    if (number == 1) {
      if (w.size() != 1 || w[0] != "ply") return where + "must be 'ply'";
    } else if (w.empty() || w[0] == "comment" || w[0] == "obj_info") {
    } else if (w[0] == "end_header") {
      return ascii ? ply_ascii_data_problem(in, elements, number)
                   : ply_binary_data_problem(in, elements, file_bytes, big_endian);
    } else if (w[0] == "format") {
      if (w.size() != 3 || (w[1] != "ascii" && w[1] != "binary_little_endian" && w[1] != "binary_big_endian"))
        return where + "format must be ascii, binary_little_endian or binary_big_endian, with a version";
      ascii = w[1] == "ascii";
      big_endian = w[1] == "binary_big_endian";
    } else if (w[0] == "element") {
      char* end = nullptr;
      const unsigned long long count = w.size() == 3 ? std::strtoull(w[2].c_str(), &end, 10) : 0;
      if (w.size() != 3 || !end || *end != '\0' || w[2][0] == '-')
        return where + "must be 'element NAME COUNT'";
      // assimp reads a name's leading digits as the count: '666...6vertex 4' asked for 64 GB.
      if (!std::isalpha(static_cast<unsigned char>(w[1][0])) && w[1][0] != '_')
        return where + "an element's name must start with a letter or '_'";
      if (count > file_bytes)
        return where + "claims " + w[2] + " entries, more than the file's " + std::to_string(file_bytes) + " bytes";
      elements.push_back({w[1], count, {}});
    } else if (w[0] == "property") {
      const bool list = w.size() == 5 && w[1] == "list" && is_ply_type(w[2]) && is_ply_type(w[3]);
      if (!list && !(w.size() == 3 && is_ply_type(w[1])))
        return where + "must be 'property TYPE NAME' or 'property list TYPE TYPE NAME' (TYPE: char, uchar, short, "
                       "ushort, int, uint, float, double or their sized names)";
      if (!elements.empty())
        elements.back().properties.push_back({w.back(), list, list ? w[2] : "", list ? w[3] : w[1]});
    } else {
      return where + "is not a PLY header line";
    }
  }
  return "the PLY header has no 'end_header' line";
}

// Refuses a file assimp would read as PLY (named .ply, or starting with 'ply') whose header is
// bad.
void check_ply(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string extension = file.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  char start[3] = {};
  const bool starts_ply = in.read(start, 3) && std::string(start, 3) == "ply";
  if (extension != ".ply" && !starts_ply) return;
  in.clear();
  in.seekg(0);
  std::error_code error;
  const auto bytes = std::filesystem::file_size(file, error);
  if (auto problem = ply_header_problem(in, error ? 0 : bytes)) throw MeshError(file.string() + ": " + *problem);
}

// Reads the file and post-processes it in a second pass. First assimp validates what its reader
// made (an index past the vertices is an import error, not an out-of-bounds read in
// import_surface); then a face without vertices is refused and each mesh's primitive types are
// recomputed from its faces: assimp 5.2.5's triangulation aborts the whole process on an
// assertion when a PLY reader's empty face made it claim polygons (found by fuzz_mesh_ply),
// and a face with more corners than its mesh has vertices, or than kMaxPolygonCorners, is
// refused before triangulation.
constexpr unsigned kMaxPolygonCorners = 1024;

const aiScene* read_scene(Assimp::Importer& importer, const std::filesystem::path& file) {
  const aiScene* scene = importer.ReadFile(file.string(), aiProcess_ValidateDataStructure);
  if (!scene) return nullptr;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    aiMesh* mesh = scene->mMeshes[m];
    unsigned types = 0;
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const unsigned n = mesh->mFaces[f].mNumIndices;
      const auto face = [&] { return file.string() + ": mesh " + std::to_string(m) + " face " + std::to_string(f); };
      if (n == 0) throw MeshError(face() + " has no vertices");
      // A polygon visits each of its corners once; and triangulation takes time quadratic in
      // the corners: a PLY face claiming 32214 corners on 4 vertices held assimp for minutes
      // (found by fuzz_mesh_ply).
      if (n > mesh->mNumVertices)
        throw MeshError(face() + " has " + std::to_string(n) + " corners, more than the mesh's " +
                        std::to_string(mesh->mNumVertices) + " vertices");
      if (n > kMaxPolygonCorners)
        throw MeshError(face() + " has " + std::to_string(n) + " corners, more than the " +
                        std::to_string(kMaxPolygonCorners) + " a polygon may have");
      types |= n == 1 ? aiPrimitiveType_POINT : n == 2 ? aiPrimitiveType_LINE : n == 3 ? aiPrimitiveType_TRIANGLE
                                                                                         : aiPrimitiveType_POLYGON;
    }
    mesh->mPrimitiveTypes = types;
  }
  return importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                      aiProcess_PreTransformVertices | aiProcess_FindDegenerates);
}

}  // namespace

void fit_bounds(TriangleSoup& soup) {
  soup.min = soup.max = soup.vertices.front();
  for (const auto& v : soup.vertices)
    for (int i = 0; i < 3; ++i) {
      soup.min[i] = std::min(soup.min[i], v[i]);
      soup.max[i] = std::max(soup.max[i], v[i]);
    }
}

TriangleSoup import_surface(const std::filesystem::path& file, double scale, std::string_view up) {
  turn_up({}, up);  // an unknown axis is refused before the file is read
  if (!std::filesystem::exists(file)) throw MeshError(file.string() + ": file does not exist");
  check_ply(file);
  Assimp::Importer importer;
  const aiScene* scene = read_scene(importer, file);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw MeshError(file.string() + ": cannot read mesh: " + importer.GetErrorString());
  TriangleSoup soup;
  // Vertices of separate meshes (and duplicated by some exporters per face) are merged
  // by exact position so that closedness can be checked on shared edges.
  std::map<std::array<double, 3>, int> index_of;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    std::vector<int> remap(mesh->mNumVertices);
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      std::array<double, 3> q = turn_up({p.x * scale, p.y * scale, p.z * scale}, up);
      if (!std::isfinite(q[0]) || !std::isfinite(q[1]) || !std::isfinite(q[2]))
        throw MeshError(file.string() + ": mesh " + std::to_string(m) + " vertex " +
                        std::to_string(v) + " is not finite");
      auto [it, inserted] = index_of.emplace(q, static_cast<int>(soup.vertices.size()));
      if (inserted) soup.vertices.push_back(q);
      remap[v] = it->second;
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines
      std::array<int, 3> t{remap[face.mIndices[0]], remap[face.mIndices[1]], remap[face.mIndices[2]]};
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
      soup.triangles.push_back(t);
    }
  }
  if (soup.triangles.empty()) throw MeshError(file.string() + ": holds no triangles");
  std::map<std::pair<int, int>, int> edge_use;
  for (const auto& t : soup.triangles)
    for (int k = 0; k < 3; ++k) {
      int a = t[k], b = t[(k + 1) % 3];
      edge_use[{std::min(a, b), std::max(a, b)}]++;
    }
  int open = 0;
  std::pair<int, int> first{};
  for (const auto& [edge, count] : edge_use)
    if (count != 2 && open++ == 0) first = edge;
  if (open > 0) {
    const auto& a = soup.vertices[first.first];
    const auto& b = soup.vertices[first.second];
    throw MeshError(file.string() + ": the surface is not closed: " + std::to_string(open) +
                    " edges are not shared by exactly two triangles, e.g. (" + std::to_string(a[0]) +
                    ", " + std::to_string(a[1]) + ", " + std::to_string(a[2]) + ")-(" +
                    std::to_string(b[0]) + ", " + std::to_string(b[1]) + ", " + std::to_string(b[2]) + ")");
  }
  fit_bounds(soup);
  return soup;
}

double winding_number(const TriangleSoup& mesh, const std::array<double, 3>& p) {
  double total = 0;
  for (const auto& t : mesh.triangles) {
    double a[3], b[3], c[3];
    for (int i = 0; i < 3; ++i) {
      a[i] = mesh.vertices[t[0]][i] - p[i];
      b[i] = mesh.vertices[t[1]][i] - p[i];
      c[i] = mesh.vertices[t[2]][i] - p[i];
    }
    double la = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    double lb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    double lc = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                 a[2] * (b[0] * c[1] - b[1] * c[0]);
    double dot_ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    double dot_bc = b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
    double dot_ca = c[0] * a[0] + c[1] * a[1] + c[2] * a[2];
    double denominator = la * lb * lc + dot_ab * lc + dot_bc * la + dot_ca * lb;
    total += 2 * std::atan2(det, denominator);
  }
  return total / (4 * std::numbers::pi);
}

}  // namespace incise::engine
