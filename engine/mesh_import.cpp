#include "engine/mesh_import.hpp"

#include "common/missing_reason.hpp"
#include "engine/surface_file.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numbers>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace incise::engine {

namespace {

// Reads a file of another format than PLY and OBJ through assimp and post-processes it in a
// second pass. First assimp validates what its reader made (an index past the vertices is an
// import error, not an out-of-bounds read in import_surface); then a face without vertices is
// refused and each mesh's primitive types are recomputed from its faces: assimp 5.2.5's
// triangulation aborts the whole process on an assertion when a reader's empty face made it
// claim polygons (found by fuzz_mesh_ply when PLY went through assimp), and a face with more
// corners than its mesh has vertices, or than kMaxPolygonCorners, is refused before
// triangulation.
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
      // A polygon visits each of its corners once; and assimp's triangulation takes time
      // quadratic in the corners: a PLY face claiming 32214 corners on 4 vertices held it for
      // minutes (found by fuzz_mesh_ply).
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

// A point of the file in the scene's frame, refused when scaling made it infinite.
std::array<double, 3> placed(const std::array<double, 3>& p, double scale, std::string_view up,
                             const std::filesystem::path& file, const std::string& which) {
  std::array<double, 3> q = turn_up({p[0] * scale, p[1] * scale, p[2] * scale}, up);
  if (!std::isfinite(q[0]) || !std::isfinite(q[1]) || !std::isfinite(q[2]))
    throw MeshError(file.string() + ": " + which + " is not finite");
  return q;
}

// Every mesh assimp read, its vertices merged by exact position: separate meshes (and some
// exporters' per-face copies) share their edges so that closedness can be checked.
TriangleSoup soup_from_assimp(const std::filesystem::path& file, double scale, std::string_view up) {
  Assimp::Importer importer;
  const aiScene* scene = read_scene(importer, file);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw MeshError(file.string() + ": cannot read mesh: " + importer.GetErrorString());
  TriangleSoup soup;
  std::map<std::array<double, 3>, int> index_of;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    std::vector<int> remap(mesh->mNumVertices);
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      const auto q = placed({p.x, p.y, p.z}, scale, up, file, "mesh " + std::to_string(m) + " vertex " + std::to_string(v));
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
  return soup;
}

// The surface of a file incise reads itself, as assimp's import made it of the same file:
// the used vertices (in the file's order or, for OBJ, in their first use's), merged by exact
// position; polygons fan-triangulated (assimp fanned a convex quad the same way; for a planar
// polygon any triangulation has the same winding number, the inside test), triangles whose
// corners merged dropped.
TriangleSoup soup_from_file(const SurfaceFile& surface, double scale, std::string_view up,
                            const std::filesystem::path& file) {
  TriangleSoup soup;
  std::map<std::array<double, 3>, int> index_of;
  std::vector<int> remap(surface.vertices.size(), -1);
  const auto take = [&](std::uint32_t v) {
    if (remap[v] >= 0) return;
    const auto q = placed(surface.vertices[v], scale, up, file, "vertex " + std::to_string(v + 1));
    auto [it, inserted] = index_of.emplace(q, static_cast<int>(soup.vertices.size()));
    if (inserted) soup.vertices.push_back(q);
    remap[v] = it->second;
  };
  if (surface.vertices_in_use_order) {
    for (std::uint32_t v : surface.corners) take(v);
  } else {
    std::vector<bool> used(surface.vertices.size());
    for (std::uint32_t v : surface.corners) used[v] = true;
    for (std::uint32_t v = 0; v < surface.vertices.size(); ++v)
      if (used[v]) take(v);
  }
  std::size_t first = 0;
  for (std::uint32_t n : surface.polygon_sizes) {
    for (std::uint32_t k = 1; k + 1 < n; ++k) {
      const std::array<int, 3> t{remap[surface.corners[first]], remap[surface.corners[first + k]],
                                 remap[surface.corners[first + k + 1]]};
      if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) soup.triangles.push_back(t);
    }
    first += n;
  }
  return soup;
}

enum class Format { Ply, Obj, Other };

// By extension, as assimp chose; and a file whose first line is 'ply' is PLY whatever its name
// (assimp read it as PLY by its content) unless it is named .stl (a binary STL's free header).
Format format_of(const std::filesystem::path& file) {
  std::string extension = file.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".ply") return Format::Ply;
  if (extension == ".obj") return Format::Obj;
  if (extension == ".stl") return Format::Other;
  std::ifstream in(file, std::ios::binary);
  char start[4] = {};
  in.read(start, 4);
  const std::string_view first(start, static_cast<std::size_t>(in.gcount()));
  return first == "ply\n" || first == "ply\r" ? Format::Ply : Format::Other;
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
  if (const std::string why = common::missing_reason(file); !why.empty()) throw MeshError(file.string() + ": file " + why);
  TriangleSoup soup;
  switch (format_of(file)) {
    case Format::Ply: soup = soup_from_file(read_ply_surface(file), scale, up, file); break;
    case Format::Obj: soup = soup_from_file(read_obj_surface(file), scale, up, file); break;
    case Format::Other: soup = soup_from_assimp(file, scale, up); break;
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
