#include "engine/mesh_import.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <map>
#include <numbers>
#include <string>

namespace incise::engine {

TriangleSoup import_surface(const std::filesystem::path& file, double scale) {
  if (!std::filesystem::exists(file)) throw MeshError(file.string() + ": file does not exist");
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(
      file.string(), aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                         aiProcess_PreTransformVertices | aiProcess_FindDegenerates);
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
      std::array<double, 3> q{p.x * scale, p.y * scale, p.z * scale};
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
  soup.min = soup.max = soup.vertices.front();
  for (const auto& v : soup.vertices)
    for (int i = 0; i < 3; ++i) {
      soup.min[i] = std::min(soup.min[i], v[i]);
      soup.max[i] = std::max(soup.max[i], v[i]);
    }
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
