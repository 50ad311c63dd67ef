#include "engine/mesh_import.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

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
#include <vector>

namespace incise::engine {

namespace {

bool is_ply_type(const std::string& t) {
  static const std::set<std::string> types = {"char",  "uchar", "short", "ushort", "int",   "uint",    "float",
                                              "double", "int8", "uint8", "int16",  "uint16", "int32", "uint32",
                                              "float32", "float64"};
  return types.count(t) > 0;
}

// A PLY file's header, checked before assimp reads the file: assimp 5.2.5 loops without end on
// a property line it cannot parse (found by fuzz_mesh_ply), and allocates whatever an element count
// says. Each line must be one the format defines, and no element may claim more entries than
// the file has bytes. Returns the problem, naming the header line.
std::optional<std::string> ply_header_problem(std::istream& in, std::uintmax_t file_bytes) {
  std::string line;
  for (int number = 1; std::getline(in, line) && number <= 10000; ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // assimp separates a header's words by spaces and tabs only: a line that read here as
    // 'end_header' and a vertical tab was to it no end of the header, and it read the data as
    // header lines until it hung or read out of bounds (found by fuzz_mesh_ply).
    for (std::size_t column = 0; column < line.size(); ++column) {
      const auto c = static_cast<unsigned char>(line[column]);
      if ((c < 0x20 && c != '\t') || c == 0x7f) {
        char code[8];
        std::snprintf(code, sizeof code, "0x%02x", c);
        return "PLY header line " + std::to_string(number) + ": control character " + code + " at column " +
               std::to_string(column + 1) + " (words are separated by spaces or tabs)";
      }
    }
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string word; words >> word;) w.push_back(word);
    const std::string where = "PLY header line " + std::to_string(number) + " ('" + line.substr(0, 80) + "'): ";
    if (number == 1) {
      if (w.size() != 1 || w[0] != "ply") return where + "must be 'ply'";
    } else if (w.empty() || w[0] == "comment" || w[0] == "obj_info") {
    } else if (w[0] == "end_header") {
      return std::nullopt;
    } else if (w[0] == "format") {
      if (w.size() != 3 || (w[1] != "ascii" && w[1] != "binary_little_endian" && w[1] != "binary_big_endian"))
        return where + "format must be ascii, binary_little_endian or binary_big_endian, with a version";
    } else if (w[0] == "element") {
      char* end = nullptr;
      const unsigned long long count = w.size() == 3 ? std::strtoull(w[2].c_str(), &end, 10) : 0;
      if (w.size() != 3 || !end || *end != '\0' || w[2][0] == '-')
        return where + "must be 'element NAME COUNT'";
      if (count > file_bytes)
        return where + "claims " + w[2] + " entries, more than the file's " + std::to_string(file_bytes) + " bytes";
    } else if (w[0] == "property") {
      const bool list = w.size() == 5 && w[1] == "list" && is_ply_type(w[2]) && is_ply_type(w[3]);
      if (!list && !(w.size() == 3 && is_ply_type(w[1])))
        return where + "must be 'property TYPE NAME' or 'property list TYPE TYPE NAME' (TYPE: char, uchar, short, "
                       "ushort, int, uint, float, double or their sized names)";
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
