#include "engine/body_builder.hpp"

#include "engine/mesh_import.hpp"
#include "engine/mesh_shape.hpp"
#include "engine/tet_mesh_import.hpp"
#include "engine/model_registry.hpp"
#include "physics/core/contact.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>
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

}  // namespace

TriangleSoup boundary_surface(const physics::TetMesh& tets) {
  TriangleSoup soup;
  soup.triangles = physics::boundary_triangles(tets.tets);
  std::vector<int> index(tets.rest.size() / 3, -1);
  for (auto& t : soup.triangles)
    for (int& v : t) {
      if (index[v] < 0) {
        index[v] = static_cast<int>(soup.vertices.size());
        soup.vertices.push_back({tets.rest[3 * v], tets.rest[3 * v + 1], tets.rest[3 * v + 2]});
      }
      v = index[v];
    }
  fit_bounds(soup);
  return soup;
}

namespace {

BodyShape body_shape(const BodySpec& spec) {
  BodyShape shape;
  if (spec.generator) {
    const auto& g = *spec.generator;
    shape.inside = inside_test(g);
    const Box bounds = generator_bounds(g);
    shape.lo = vec(bounds.min);
    shape.hi = vec(bounds.max);
  } else {
    TriangleSoup soup;
    if (is_tet_mesh_file(*spec.mesh)) {
      // Read once: the scene reader's copy when it read the file for the resolution.
      auto tets = spec.tets ? spec.tets
                            : std::make_shared<const physics::TetMesh>(import_tet_mesh(*spec.mesh, spec.mesh_scale, spec.mesh_up));
      soup = boundary_surface(*tets);
      shape.tets = std::move(tets);
    } else {
      soup = import_surface(*spec.mesh, spec.mesh_scale, spec.mesh_up);
    }
    // The fill, the EFG cells' volumes and the fairing ask "inside?" millions of times: the
    // exact winding number's sum over every triangle made a 4k-triangle organ take minutes.
    auto mesh = std::make_shared<const MeshShape>(soup);
    shape.surface = std::make_shared<const TriangleSoup>(std::move(soup));
    const TriangleSoup& surface = *shape.surface;
    shape.inside = [mesh](const physics::Vec3& p) { return mesh->inside(p); };
    shape.along = [mesh](const physics::Vec3& p, const physics::Vec3& n, double reach) { return mesh->along(p, n, reach); };
    shape.lo = vec(surface.min);
    shape.hi = vec(surface.max);
  }
  return shape;
}

// A surface thinner than the resolution everywhere fills no cell: refused here, naming its size
// and the resolution, rather than by the fill or the EFG's sampling in their own terms. The
// grid is make_tets_inside's (cell centres at most `resolution` apart); the EFG samples its
// cubes of side `resolution` alike.
void check_interior(const BodySpec& spec, const BodyShape& shape) {
  if (!spec.mesh || (shape.tets && spec.model == "fem")) return;
  const physics::Vec3 extent = shape.hi - shape.lo;
  std::array<int, 3> count{};
  for (int i = 0; i < 3; ++i) count[i] = std::max(1, static_cast<int>(std::ceil(extent[i] / spec.resolution)));
  for (int k = 0; k < count[2]; ++k)
    for (int j = 0; j < count[1]; ++j)
      for (int i = 0; i < count[0]; ++i) {
        const physics::Vec3 cell((i + 0.5) / count[0], (j + 0.5) / count[1], (k + 0.5) / count[2]);
        if (shape.inside(shape.lo + extent.cwiseProduct(cell))) return;
      }
  std::ostringstream out;
  out.precision(3);
  out << "mesh '" << spec.mesh->filename().string() << "' (" << extent.x() << " x " << extent.y() << " x "
      << extent.z() << " m) has no interior at resolution " << spec.resolution
      << " m: no cell centre of that grid is inside it (a resolution under its thinnest part fills it)";
  throw std::runtime_error(out.str());
}

}  // namespace

physics::TetMesh fill_with_tets(const BodySpec& spec, const BodyShape& shape, double resolution,
                                physics::SnapReport* snap) {
  if (shape.tets) return *shape.tets;
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

void settle_if_asked(Body& result, const SolverSpec& solver, const std::string& where,
                     const std::function<physics::Vector()>& settle) {
  if (solver.start != "settled") return;
  const physics::Stopwatch watch;
  try {
    result.data.state.positions += settle();
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": solver.start 'settled' needs a body held in place by its fixed regions: " +
                             e.what());
  }
  result.build_ms.settle = watch.ms();
}

void fix_nodes(physics::BodyData& body, const BodySpec& spec, const physics::Vector& rest) {
  const int n = static_cast<int>(rest.size() / 3);
  body.fixed.assign(n, 0);
  for (const auto& box : spec.fixed) {
    auto in = physics::nodes_in_box(rest, vec(box.min), vec(box.max));
    for (int i = 0; i < n; ++i) body.fixed[i] |= in[i];
  }
}

physics::HexMesh hex_cells(const BodySpec& spec, const BodyShape& shape, const std::string& cell) {
  if (spec.generator && spec.generator->type == "box") {
    std::array<int, 3> cells{};
    for (int i = 0; i < 3; ++i)
      cells[i] = std::max(1, static_cast<int>(std::lround((shape.hi[i] - shape.lo[i]) / spec.resolution)));
    return physics::make_box_hexes(shape.lo, shape.hi, cells);
  }
  physics::HexMesh mesh = physics::make_hexes_inside(shape.inside, shape.lo, shape.hi, spec.resolution);
  if (mesh.hexes.empty()) {
    std::ostringstream out;
    out << "no " << cell << " of side " << spec.resolution
        << " m has its centre inside the shape (a finer resolution fills it)";
    throw std::runtime_error(out.str());
  }
  return mesh;
}

void index_surface(physics::BodyModel& model, physics::BodyData& body, int node_count) {
  std::vector<int> surface_index(static_cast<std::size_t>(node_count), -1);
  for (const auto& t : body.surface)
    for (int v : t) surface_index[static_cast<std::size_t>(v)] = 0;
  for (int i = 0; i < node_count; ++i)
    if (surface_index[static_cast<std::size_t>(i)] == 0) {
      surface_index[static_cast<std::size_t>(i)] = static_cast<int>(model.surface_nodes.size());
      model.surface_nodes.push_back(i);
    }
  body.render_triangles.reserve(body.surface.size() * 3);
  for (const auto& t : body.surface)
    for (int v : t) body.render_triangles.push_back(static_cast<std::uint32_t>(surface_index[static_cast<std::size_t>(v)]));
}

std::shared_ptr<physics::BodyModel> body_model(const BodySpec& spec, const SolverSpec& solver) {
  auto model = std::make_shared<physics::BodyModel>();
  model->name = spec.name;
  model->kind = spec.model;
  model->integrator.dt = solver.dt;
  model->integrator.rayleigh_mass = spec.damping_mass;
  model->integrator.rayleigh_stiffness = spec.damping_stiffness;
  model->integrator.cg.tolerance = solver.tolerance;
  model->integrator.cg.max_iterations = solver.max_iterations;
  model->preconditioner.kind = solver.preconditioner == "warped_cholesky" ? physics::PreconditionerKind::warped_cholesky
                                : solver.preconditioner == "two_level"     ? physics::PreconditionerKind::two_level
                                : solver.preconditioner == "multigrid"     ? physics::PreconditionerKind::multigrid
                                : solver.preconditioner == "multigrid_current" ? physics::PreconditionerKind::multigrid_current
                                                                           : physics::PreconditionerKind::jacobi;
  model->preconditioner.latency = preconditioner_latency(solver, spec.model);
  model->preconditioner.smoothing = multigrid_smoothing_degree(solver);
  model->preconditioner.single_precision = solver.multigrid_precision == "float";
  // The current system assembled once per step, its products CG's and the smoother's.
  model->integrator.assembled_system = solver.preconditioner == "multigrid_current";
  model->gravity = vec(solver.gravity);
  return model;
}

void start_at_rest(physics::BodyData& body) {
  const int n = body.mechanics->node_count();
  body.state.positions = body.mechanics->rest_positions();
  body.state.velocities = physics::Vector::Zero(3 * n);
  body.warm_start.clear();
}

Body build_body(const BodySpec& spec, const SolverSpec& solver) {
  const physics::Stopwatch whole;
  BodyShape shape;
  try {
    shape = body_shape(spec);
  } catch (const std::exception& e) {
    throw std::runtime_error("body '" + spec.name + "': " + e.what());
  }
  // A mesh's extent is known only now (parse_scene checked the generated shapes).
  if (auto problem = size_problem(spec, {shape.lo.x(), shape.lo.y(), shape.lo.z()}, {shape.hi.x(), shape.hi.y(), shape.hi.z()}))
    throw std::runtime_error("body '" + spec.name + "': " + (spec.mesh ? "mesh " + spec.mesh->string() + ": " : "") +
                             "resolution " + *problem);
  try {
    check_interior(spec, shape);
  } catch (const std::exception& e) {
    throw std::runtime_error("body '" + spec.name + "': " + e.what());
  }
  const ModelEntry* model = models().find(spec.model);
  if (!model)
    throw std::runtime_error("body '" + spec.name + "': model '" + spec.model + "' is not registered (registered: " +
                             alternatives(models().names()) + ")");
  const double shape_ms = whole.ms();
  Body result = model->build(spec, solver, shape);
  result.build_ms.shape = shape_ms;
  physics::BodyData& body = result.data;
  // The energy watchdog compares each step with the one before; a settled start begins with
  // the elastic energy of the sag, not zero.
  body.last_energy = body.mechanics->elastic_energy(body.state.positions) +
                     physics::kinetic_energy(body.mechanics->lumped_masses(), body.state.velocities);
  for (std::size_t i = 0; i < spec.fixed.size(); ++i) {
    const auto in = physics::nodes_in_box(body.mechanics->rest_positions(), vec(spec.fixed[i].min), vec(spec.fixed[i].max));
    if (std::find(in.begin(), in.end(), 1) == in.end())
      throw std::runtime_error("body '" + spec.name + "': fixed[" + std::to_string(i) + "] contains no " +
                               model->node_name + " of the body");
  }
  result.build_ms.total = whole.ms();
  return result;
}

}  // namespace incise::engine
