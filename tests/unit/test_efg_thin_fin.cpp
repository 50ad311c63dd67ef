// Thin features in an EFG body: a fin thinner than the particle spacing (2a) beside the rest of
// the body across a gap narrower than a spacing, as a folded thin edge of an organ lies. Each
// surface vertex must follow an integration point it sees through the body
// (CorotationalEfg::embed_surface with the inside test), and the fin's two faces must stay
// together when the fin is lifted.
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/static_solve.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

namespace incise::physics {
namespace {

const Material tissue{30e3, 0.45, 1050};
constexpr double a = 0.0025;      // integration cubes; particles 5 mm apart
constexpr double length = 0.04;   // the fin's, along x
constexpr double thickness = 0.0015, gap = 0.0008, fin_bottom = 0.0005;

// A block clamped at its back (x < -9.5 mm), the fin above it along x, joined to it by a column
// at the root (x <= 0).
bool in_body(const Vec3& p) {
  if (p.x() < -0.01 || p.x() > length || std::abs(p.y()) > 0.01 || p.z() < -0.01) return false;
  return p.z() <= fin_bottom - gap || (p.z() >= fin_bottom && p.z() <= fin_bottom + thickness) ||
         (p.x() <= 0 && p.z() <= fin_bottom + thickness);
}

// Vertices on the fin's faces, in pairs (bottom, top) one above the other.
std::vector<Vec3> fin_vertices() {
  std::vector<Vec3> points;
  for (double x = 0.005; x < length - 0.001; x += 0.0037)
    for (double y = -0.008; y <= 0.008; y += 0.004) {
      points.push_back(Vec3(x, y, fin_bottom));
      points.push_back(Vec3(x, y, fin_bottom + thickness));
    }
  return points;
}

// How many vertices' segments to their integration point leave the body (sampled 40 times).
int unseen_mappings(const CorotationalEfg& model, const SurfaceEmbedding& embedding, const std::vector<Vec3>& points) {
  int unseen = 0;
  for (size_t v = 0; v < points.size(); ++v) {
    const Vec3 q = model.element_centres()[static_cast<size_t>(embedding.elements[v])];
    for (int k = 1; k <= 40; ++k) {
      const Vec3 s = points[v] + (k / 40.0) * (q - points[v]);
      if ((s - points[v]).norm() > 0.05 * a && !in_body(s)) {
        ++unseen;
        break;
      }
    }
  }
  return unseen;
}

TEST(EfgThinFin, VerticesFollowPointsTheySeeAndTheFinsFacesStayTogether) {
  EfgSettings settings;
  settings.spacing = a;
  settings.neighbours = 8;
  const std::function<bool(const Vec3&)> inside = in_body;
  CorotationalEfg model(inside, Vec3(-0.01, -0.01, -0.01), Vec3(length, 0.01, fin_bottom + thickness), tissue, settings);
  const std::vector<Vec3> points = fin_vertices();
  Vector vertices(3 * static_cast<Eigen::Index>(points.size()));
  for (size_t v = 0; v < points.size(); ++v) vertices.segment<3>(3 * static_cast<Eigen::Index>(v)) = points[v];

  // Nearest point alone: the fin's lower face (half the vertices) takes the block's points
  // across the gap.
  const SurfaceEmbedding nearest = model.embed_surface(vertices);
  EXPECT_EQ(unseen_mappings(model, nearest, points), static_cast<int>(points.size()) / 2);
  int fallbacks = -1;
  const SurfaceEmbedding seen = model.embed_surface(vertices, &inside, &fallbacks);
  EXPECT_EQ(fallbacks, 0);
  EXPECT_EQ(unseen_mappings(model, seen, points), 0);
  for (size_t v = 0; v < points.size(); ++v)
    EXPECT_GE(model.element_centres()[static_cast<size_t>(seen.elements[v])].z(), fin_bottom) << "vertex " << v;

  // The fin lifted at its tip (its outer third's particles pulled up), the block clamped.
  model.update_rotations(model.rest_positions());
  Vector load = Vector::Zero(model.rest_positions().size());
  for (int i = 0; i < model.node_count(); ++i)
    if (model.rest_positions()[3 * i] > 0.7 * length && model.rest_positions()[3 * i + 2] > fin_bottom - 0.5 * gap)
      load[3 * i + 2] = 2e-3;
  const Vector u = solve_static(assemble_stiffness(model), load,
                                nodes_in_box(model.rest_positions(), Vec3::Constant(-1), Vec3(-0.0095, 1, 1)));
  Vector moved;
  CorotationalEfg::surface_positions(seen, model.rest_positions() + u, moved);
  double lift = 0, worst = 0;
  for (size_t v = 0; v < points.size(); v += 2) {
    const Vec3 bottom = moved.segment<3>(3 * static_cast<Eigen::Index>(v));
    const Vec3 top = moved.segment<3>(3 * static_cast<Eigen::Index>(v + 1));
    lift = std::max(lift, top.z() - points[v + 1].z());
    worst = std::max(worst, std::abs((top - bottom).norm() - thickness));
  }
  // A real lift (several thicknesses), and the faces together: the thickness changes by under
  // 10 % (Poisson's thinning of a bent plate is of the order of its strain, a few %).
  EXPECT_GT(lift, 4 * thickness);
  EXPECT_LT(worst, 0.1 * thickness) << "lift " << lift;
}

}  // namespace
}  // namespace incise::physics
