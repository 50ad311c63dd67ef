// Thin features in a cuttable body (issue 32): a fin thinner than the particle spacing (2a)
// above the rest of the body across a gap narrower than a spacing, as an organ's folded thin
// edge lies. The first mapping of the cut surface (make_cut_data) with the body's inside test
// maps each vertex to an integration point it sees through the body (FrontVisibility::inside);
// by the nearest-point criteria alone the fin's lower face and the block's upper face take
// points across the gap and would follow the other part. Checked by an independent, finer
// sampling of each vertex's segment against the same shape.
#include "physics/cut/cut_body.hpp"
#include "physics/cut/voxel_boundary.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <vector>

using namespace incise::physics;

namespace {

constexpr double a = 0.0025;  // integration cubes; particles 5 mm apart
constexpr double thickness = 0.0015, gap = 0.001, fin_bottom = 0.0005;
const Vec3 lo(-0.01, -0.005, -0.01), hi(0.02, 0.005, fin_bottom + thickness);

// A block (z <= -0.5 mm), the fin above it (0.5 to 2 mm) along x, joined to it by a column at
// the root (x <= 0).
bool in_body(const Vec3& p) {
  if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) return false;
  return p.z() <= fin_bottom - gap || p.z() >= fin_bottom || p.x() <= 0;
}

struct Mapped {
  BodyModel model;
  CutModel cut_model;
  BodyData data;
  CutData cut;
};

std::unique_ptr<Mapped> map_cuttable(bool with_inside, TriangleSurface surface) {
  auto body = std::make_unique<Mapped>();
  body->model.rest_lo = lo;
  body->model.rest_hi = hi;
  EfgSettings settings;
  settings.spacing = a;
  settings.threaded_elements = 0;
  const std::function<bool(const Vec3&)> inside = in_body;
  auto efg = std::make_unique<CorotationalEfg>(inside, lo, hi, Material{30e3, 0.45, 1050}, settings);
  body->data.efg = efg.get();
  body->data.mechanics = std::move(efg);
  body->cut_model.spacing = a;
  body->cut_model.surface_cell = a / 5;
  body->cut = make_cut_data(body->model, body->data, body->cut_model, std::move(surface.vertices),
                            std::move(surface.triangles), with_inside ? &inside : nullptr);
  return body;
}

// How many vertices' segments to their integration point leave the body (sampled 40 times,
// from 5 % of a off the vertex).
int unseen_mappings(const Mapped& body) {
  const std::vector<Vec3>& vertices = body.cut.surface->vertices();
  int unseen = 0;
  for (size_t v = 0; v < vertices.size(); ++v) {
    const Vec3 q = body.data.efg->element_centres()[static_cast<size_t>(body.data.embedding->elements[v])];
    for (int k = 1; k <= 40; ++k) {
      const Vec3 s = vertices[v] + (k / 40.0) * (q - vertices[v]);
      if ((s - vertices[v]).norm() > 0.05 * a && !in_body(s)) {
        ++unseen;
        break;
      }
    }
  }
  return unseen;
}

TEST(CutThinFin, TheFirstMappingFollowsPointsEachVertexSeesThroughTheBody) {
  const TriangleSurface surface = voxel_boundary(in_body, lo, hi, a / 5);
  // The voxels resolve the gap: the fin's lower face has vertices.
  int lower_face = 0;
  for (const Vec3& v : surface.vertices)
    if (v.x() > 0.002 && std::abs(v.z() - fin_bottom) < 1e-4) ++lower_face;
  ASSERT_GT(lower_face, 50);

  const auto nearest = map_cuttable(false, surface);
  const int unseen_before = unseen_mappings(*nearest);
  EXPECT_GT(unseen_before, lower_face / 2) << "the nearest-point criteria alone map across the gap";

  const auto seen = map_cuttable(true, surface);
  EXPECT_EQ(unseen_mappings(*seen), 0) << "before: " << unseen_before;
  EXPECT_EQ(seen->cut.mapping.unseen_at_build, 0);
  std::printf("%zu surface vertices, %d on the fin's lower face; mapped across the gap: %d by the nearest "
              "point, 0 through the body\n", surface.vertices.size(), lower_face, unseen_before);
  // Every fin vertex follows a point of the fin (at or above its lower face).
  const std::vector<Vec3>& vertices = seen->cut.surface->vertices();
  for (size_t v = 0; v < vertices.size(); ++v) {
    if (vertices[v].x() < 0.002 || vertices[v].z() < fin_bottom - 1e-4) continue;
    const Vec3& q = seen->data.efg->element_centres()[static_cast<size_t>(seen->data.embedding->elements[v])];
    EXPECT_GE(q.z(), fin_bottom) << "vertex " << v;
  }
}

}  // namespace
