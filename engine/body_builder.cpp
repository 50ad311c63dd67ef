#include "engine/body_builder.hpp"

#include "engine/mesh_import.hpp"
#include "physics/core/contact.hpp"
#include "physics/cut/voxel_boundary.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

namespace incise::engine {

namespace {

physics::Vec3 vec(const Point& p) { return {p[0], p[1], p[2]}; }

// The "organ" generator: a lobe shaped like a small liver segment — an ellipsoid whose
// upper surface is tilted and bulged, cut flat underneath so that it rests on supports.
bool inside_organ(const GeneratorSpec& g, const physics::Vec3& p) {
  double u = (p.x() - g.center[0]) / g.radii[0];
  double v = (p.y() - g.center[1]) / g.radii[1];
  double w = (p.z() - g.center[2]) / g.radii[2];
  if (w < -0.55) return false;  // flat base
  // Thicker on the -x side, thinning towards +x like a hepatic lobe's edge.
  double thickness = 1.0 - 0.35 * u;
  double wz = (w + 0.25 * (u * u + v * v)) / thickness;
  double lateral = u * u + 1.15 * v * v * (1 + 0.3 * u);
  return lateral + wz * wz <= 1.0;
}

std::function<bool(const physics::Vec3&)> inside_test(const GeneratorSpec& g) {
  if (g.type == "box") {
    return [g](const physics::Vec3& p) {
      for (int i = 0; i < 3; ++i)
        if (p[i] < g.box.min[i] || p[i] > g.box.max[i]) return false;
      return true;
    };
  }
  if (g.type == "ellipsoid") {
    return [g](const physics::Vec3& p) {
      double s = 0;
      for (int i = 0; i < 3; ++i) {
        double d = (p[i] - g.center[i]) / g.radii[i];
        s += d * d;
      }
      return s <= 1.0;
    };
  }
  if (g.type == "cylinder") {
    return [g](const physics::Vec3& p) {
      const physics::Vec3 d = p - vec(g.center);
      const int u = (g.axis + 1) % 3, v = (g.axis + 2) % 3;
      return std::abs(d[g.axis]) <= 0.5 * g.length && d[u] * d[u] + d[v] * d[v] <= g.radius * g.radius;
    };
  }
  if (g.type == "torus") {
    return [g](const physics::Vec3& p) {
      const physics::Vec3 d = p - vec(g.center);
      const int u = (g.axis + 1) % 3, v = (g.axis + 2) % 3;
      const double ring = std::sqrt(d[u] * d[u] + d[v] * d[v]) - g.major_radius;
      return ring * ring + d[g.axis] * d[g.axis] <= g.radius * g.radius;
    };
  }
  return [g](const physics::Vec3& p) { return inside_organ(g, p); };
}

// What the body occupies: an inside test and its bounding box.
struct BodyShape {
  std::function<bool(const physics::Vec3&)> inside;
  physics::Vec3 lo, hi;
};

BodyShape body_shape(const BodySpec& spec) {
  BodyShape shape;
  if (spec.generator) {
    const auto& g = *spec.generator;
    shape.inside = inside_test(g);
    if (g.type == "box") {
      shape.lo = vec(g.box.min);
      shape.hi = vec(g.box.max);
    } else if (g.type == "cylinder" || g.type == "torus") {
      physics::Vec3 half = physics::Vec3::Constant(g.type == "torus" ? g.major_radius + g.radius : g.radius);
      half[g.axis] = g.type == "torus" ? g.radius : 0.5 * g.length;
      shape.lo = vec(g.center) - half;
      shape.hi = vec(g.center) + half;
    } else {
      shape.lo = vec(g.center) - vec(g.radii);
      shape.hi = vec(g.center) + vec(g.radii);
    }
  } else {
    auto soup = std::make_shared<TriangleSoup>(import_surface(*spec.mesh, spec.mesh_scale));
    shape.inside = [soup](const physics::Vec3& p) {
      return winding_number(*soup, {p.x(), p.y(), p.z()}) > 0.5;
    };
    shape.lo = vec(soup->min);
    shape.hi = vec(soup->max);
  }
  return shape;
}

// Tetrahedra filling the shape with cells of about `resolution`: a box exactly, anything
// else by voxels whose boundary nodes are snapped onto the true surface.
physics::TetMesh fill_with_tets(const BodySpec& spec, const BodyShape& shape, double resolution,
                                physics::SnapReport* snap) {
  if (spec.generator && spec.generator->type == "box") {
    std::array<int, 3> cells{};
    for (int i = 0; i < 3; ++i)
      cells[i] = std::max(1, static_cast<int>(std::lround((shape.hi[i] - shape.lo[i]) / resolution)));
    return physics::make_box_tets(shape.lo, shape.hi, cells);
  }
  physics::TetMesh mesh = physics::make_tets_inside(shape.inside, shape.lo, shape.hi, resolution);
  // Voxel boundaries are staircases of one cell; the surgeon should see the organ's shape.
  const physics::SnapReport report =
      physics::snap_boundary_to_surface(mesh, shape.inside, 1.5 * resolution, 0.1);
  if (snap) *snap = report;
  return mesh;
}

void fix_nodes(physics::BodyData& body, const BodySpec& spec, const physics::Vector& rest) {
  const int n = static_cast<int>(rest.size() / 3);
  body.fixed.assign(n, 0);
  for (const auto& box : spec.fixed) {
    auto in = physics::nodes_in_box(rest, vec(box.min), vec(box.max));
    for (int i = 0; i < n; ++i) body.fixed[i] |= in[i];
  }
}

// The read-only part every body has: name, kind, integrator, gravity.
std::shared_ptr<physics::BodyModel> body_model(const BodySpec& spec, const SolverSpec& solver) {
  auto model = std::make_shared<physics::BodyModel>();
  model->name = spec.name;
  model->kind = spec.model;
  model->integrator.dt = solver.dt;
  model->integrator.rayleigh_mass = spec.damping_mass;
  model->integrator.rayleigh_stiffness = spec.damping_stiffness;
  model->integrator.cg.tolerance = solver.tolerance;
  model->integrator.cg.max_iterations = solver.max_iterations;
  model->gravity = vec(solver.gravity);
  return model;
}

void start_at_rest(physics::BodyData& body) {
  const int n = body.mechanics->node_count();
  body.state.positions = body.mechanics->rest_positions();
  body.state.velocities = physics::Vector::Zero(3 * n);
  body.velocity_change = physics::Vector::Zero(3 * n);
}

Body build_fem_body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body result;
  auto model = body_model(spec, solver);
  physics::BodyData& body = result.data;
  const std::string where = "body '" + spec.name + "'";
  physics::TetMesh mesh;
  try {
    mesh = fill_with_tets(spec, shape, spec.resolution, &model->snap);
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  model->elements = mesh.tets.size();
  physics::Material material{spec.material.youngs_modulus, spec.material.poisson_ratio,
                             spec.material.density};
  body.surface = physics::boundary_triangles(mesh.tets);
  body.mechanics = std::make_unique<physics::CorotationalTetFem>(mesh, material);
  const int n = body.mechanics->node_count();
  start_at_rest(body);
  fix_nodes(body, spec, body.mechanics->rest_positions());
  body.gravity = physics::gravity_forces(body.mechanics->lumped_masses(), model->gravity);
  if (solver.start == "settled") {
    // Start from static equilibrium under gravity (small-strain solve, exact enough for the
    // sag of a supported organ), so a replay does not begin with the body dropping.
    try {
      body.state.positions += physics::solve_static_linear(mesh, material, body.fixed,
                                                           spec.material.density * model->gravity);
    } catch (const std::exception& e) {
      throw std::runtime_error(where + ": solver.start 'settled' needs a body held in place by its "
                               "fixed regions: " + e.what());
    }
  }
  std::vector<int> surface_index(n, -1);
  for (const auto& t : body.surface)
    for (int v : t) surface_index[v] = 0;
  for (int i = 0; i < n; ++i)
    if (surface_index[i] == 0) {
      surface_index[i] = static_cast<int>(model->surface_nodes.size());
      model->surface_nodes.push_back(i);
    }
  body.render_triangles.reserve(body.surface.size() * 3);
  for (const auto& t : body.surface)
    for (int v : t) body.render_triangles.push_back(static_cast<std::uint32_t>(surface_index[v]));
  result.model = std::move(model);
  return result;
}

// The render surface of a meshless body: the imported mesh itself, or (generated bodies) the
// boundary of a voxel fill at surface_resolution (default a / 2, finer than the integration
// grid as seed-004 §2.6 requires), snapped onto the true surface.
void make_render_surface(physics::BodyModel& model, physics::BodyData& body, const BodySpec& spec, const BodyShape& shape,
                         physics::Vector& rest_vertices) {
  if (spec.mesh) {
    const TriangleSoup soup = import_surface(*spec.mesh, spec.mesh_scale);
    rest_vertices.resize(3 * static_cast<Eigen::Index>(soup.vertices.size()));
    for (std::size_t v = 0; v < soup.vertices.size(); ++v)
      for (int c = 0; c < 3; ++c) rest_vertices[3 * static_cast<Eigen::Index>(v) + c] = soup.vertices[v][c];
    body.surface = soup.triangles;
  } else {
    const double resolution = spec.efg.surface_resolution.value_or(0.5 * spec.resolution);
    const physics::TetMesh mesh = fill_with_tets(spec, shape, resolution, &model.snap);
    const auto boundary = physics::boundary_triangles(mesh.tets);
    std::vector<int> vertex_of(mesh.rest.size() / 3, -1);
    int vertices = 0;
    for (const auto& t : boundary)
      for (int node : t)
        if (vertex_of[node] < 0) vertex_of[node] = 0;
    for (std::size_t node = 0; node < vertex_of.size(); ++node)
      if (vertex_of[node] == 0) vertex_of[node] = vertices++;
    rest_vertices.resize(3 * vertices);
    for (std::size_t node = 0; node < vertex_of.size(); ++node)
      if (vertex_of[node] >= 0)
        rest_vertices.segment<3>(3 * vertex_of[node]) = mesh.rest.segment<3>(3 * static_cast<Eigen::Index>(node));
    body.surface.clear();
    for (const auto& t : boundary) body.surface.push_back({vertex_of[t[0]], vertex_of[t[1]], vertex_of[t[2]]});
    // Embedded, this surface carries no element: onto the shape and evened out along it.
    std::vector<physics::Vec3> faired(static_cast<std::size_t>(vertices));
    for (int v = 0; v < vertices; ++v) faired[static_cast<std::size_t>(v)] = rest_vertices.segment<3>(3 * v);
    physics::fair_surface_onto_shape(faired, body.surface, shape.inside, resolution);
    for (int v = 0; v < vertices; ++v) rest_vertices.segment<3>(3 * v) = faired[static_cast<std::size_t>(v)];
  }
  body.render_triangles.clear();
  for (const auto& t : body.surface)
    for (int v : t) body.render_triangles.push_back(static_cast<std::uint32_t>(v));
}

physics::EfgSettings efg_settings(const BodySpec& spec) {
  physics::EfgSettings settings;
  settings.spacing = spec.resolution;
  settings.neighbours = spec.efg.neighbours;
  if (spec.efg.support_factor) settings.support_factor = *spec.efg.support_factor;
  settings.samples_per_axis = spec.efg.samples_per_axis;
  settings.estimate_volumes = spec.efg.estimate_volumes;
  return settings;
}

// A cuttable body's cut state, its first surface the voxel boundary at the surface resolution
// put onto the shape: no element carries this surface, so its vertices go onto the shape and
// even out along it (the voxel snap stops short where its tetrahedra would flatten).
void make_cut(Body& result, const physics::BodyModel& model, const BodySpec& spec, const BodyShape& shape) {
  auto cut_model = std::make_shared<physics::CutModel>();
  cut_model->spacing = spec.resolution;
  cut_model->surface_cell = spec.efg.surface_resolution.value_or(0.5 * spec.resolution);
  physics::TriangleSurface initial = physics::voxel_boundary(shape.inside, shape.lo, shape.hi, cut_model->surface_cell);
  physics::fair_surface_onto_shape(initial.vertices, initial.triangles, shape.inside, cut_model->surface_cell);
  result.cut = std::make_unique<physics::CutData>(
      physics::make_cut_data(model, result.data, *cut_model, std::move(initial.vertices), std::move(initial.triangles)));
  result.cut_model = std::move(cut_model);
}

Body build_efg_body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body result;
  auto model = body_model(spec, solver);
  model->rest_lo = shape.lo;
  model->rest_hi = shape.hi;
  physics::BodyData& body = result.data;
  const std::string where = "body '" + spec.name + "'";
  physics::Material material{spec.material.youngs_modulus, spec.material.poisson_ratio,
                             spec.material.density};
  result.executor = std::make_unique<ThreadPoolExecutor>(spec.efg.threads, spec.cuttable && spec.efg.threads >= 2);
  physics::Vector rest_vertices;
  try {
    auto efg = std::make_unique<physics::CorotationalEfg>(shape.inside, shape.lo, shape.hi, material, efg_settings(spec),
                                                          result.executor.get());
    body.efg = efg.get();
    body.mechanics = std::move(efg);
    if (spec.cuttable)
      make_cut(result, *model, spec, shape);
    else
      make_render_surface(*model, body, spec, shape, rest_vertices);
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  const physics::CorotationalEfg& efg = *body.efg;
  model->elements = static_cast<std::size_t>(efg.element_count());
  if (!body.embedding) body.embedding = efg.embed_surface(rest_vertices);
  start_at_rest(body);
  fix_nodes(body, spec, efg.rest_positions());
  body.gravity = physics::gravity_forces(efg.lumped_masses(), model->gravity);
  if (solver.start == "settled") {
    try {
      body.state.positions += physics::solve_static(physics::assemble_stiffness(efg), body.gravity, body.fixed);
    } catch (const std::exception& e) {
      throw std::runtime_error(where + ": solver.start 'settled' needs a body held in place by its "
                               "fixed regions: " + e.what());
    }
  }
  physics::set_fixed_vertices(body);
  physics::CorotationalEfg::surface_positions(*body.embedding, body.state.positions, body.surface_positions);
  if (result.cut) result.cut->previous_positions = body.state.positions;
  result.model = std::move(model);
  return result;
}

}  // namespace

Body build_body(const BodySpec& spec, const SolverSpec& solver) {
  BodyShape shape;
  try {
    shape = body_shape(spec);
  } catch (const std::exception& e) {
    throw std::runtime_error("body '" + spec.name + "': " + e.what());
  }
  Body result = spec.model == "efg" ? build_efg_body(spec, solver, shape) : build_fem_body(spec, solver, shape);
  physics::BodyData& body = result.data;
  // The energy watchdog compares each step with the one before; a settled start begins with
  // the elastic energy of the sag, not zero.
  body.last_energy = body.mechanics->elastic_energy(body.state.positions) +
                     physics::kinetic_energy(body.mechanics->lumped_masses(), body.state.velocities);
  for (std::size_t i = 0; i < spec.fixed.size(); ++i) {
    const auto in = physics::nodes_in_box(body.mechanics->rest_positions(), vec(spec.fixed[i].min), vec(spec.fixed[i].max));
    if (std::find(in.begin(), in.end(), 1) == in.end())
      throw std::runtime_error("body '" + spec.name + "': fixed[" + std::to_string(i) + "] contains no " +
                               (spec.model == "efg" ? "particle" : "node") + " of the body");
  }
  return result;
}

}  // namespace incise::engine
