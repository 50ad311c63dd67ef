#include "engine/world.hpp"

#include "engine/mesh_import.hpp"
#include "physics/core/contact.hpp"
#include "physics/core/mix.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/corotational_fem.hpp"
#include "physics/fem/static_solve.hpp"
#include "physics/fem/surface_snap.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/cut/front_mapping.hpp"
#include "physics/gpu/efg_step.hpp"

#include <algorithm>
#include <bit>
#include <numeric>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>

namespace incise::engine {

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

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

std::array<double, 3> rotate(const std::array<double, 4>& q, const std::array<double, 3>& v) {
  // v' = v + 2 w (u x v) + 2 u x (u x v), q = (w, u)
  double w = q[0];
  double ux = q[1], uy = q[2], uz = q[3];
  double cx = uy * v[2] - uz * v[1];
  double cy = uz * v[0] - ux * v[2];
  double cz = ux * v[1] - uy * v[0];
  double ccx = uy * cz - uz * cy;
  double ccy = uz * cx - ux * cz;
  double ccz = ux * cy - uy * cx;
  return {v[0] + 2 * (w * cx + ccx), v[1] + 2 * (w * cy + ccy), v[2] + 2 * (w * cz + ccz)};
}

}  // namespace

std::array<double, 3> load_force_at(const LoadSpec& load, double time) {
  const auto& e = load.events;
  if (time <= e.front().time) return e.front().force;
  if (time >= e.back().time) return e.back().force;
  auto it = std::upper_bound(e.begin(), e.end(), time,
                             [](double t, const LoadEvent& ev) { return t < ev.time; });
  const LoadEvent& b = *it;
  const LoadEvent& a = *(it - 1);
  double s = (time - a.time) / (b.time - a.time);
  return {a.force[0] + s * (b.force[0] - a.force[0]), a.force[1] + s * (b.force[1] - a.force[1]),
          a.force[2] + s * (b.force[2] - a.force[2])};
}

namespace {

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

void fix_nodes(Body& body, const BodySpec& spec, const physics::Vector& rest) {
  const int n = static_cast<int>(rest.size() / 3);
  body.fixed.assign(n, 0);
  for (const auto& box : spec.fixed) {
    auto in = physics::nodes_in_box(rest, vec(box.min), vec(box.max));
    for (int i = 0; i < n; ++i) body.fixed[i] |= in[i];
  }
}

void set_integrator(Body& body, const BodySpec& spec, const SolverSpec& solver) {
  body.integrator.dt = solver.dt;
  body.integrator.rayleigh_mass = spec.damping_mass;
  body.integrator.rayleigh_stiffness = spec.damping_stiffness;
  body.integrator.cg.tolerance = solver.tolerance;
  body.integrator.cg.max_iterations = solver.max_iterations;
}

void start_at_rest(Body& body, int n) {
  body.state.positions = body.model->rest_positions();
  body.state.velocities = physics::Vector::Zero(3 * n);
  body.velocity_change = physics::Vector::Zero(3 * n);
}

Body build_fem_body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body body;
  body.name = spec.name;
  body.model_name = spec.model;
  const std::string where = "body '" + spec.name + "'";
  physics::TetMesh mesh;
  try {
    mesh = fill_with_tets(spec, shape, spec.resolution, &body.snap);
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  body.elements = mesh.tets.size();
  physics::Material material{spec.material.youngs_modulus, spec.material.poisson_ratio,
                             spec.material.density};
  body.surface = physics::boundary_triangles(mesh.tets);
  auto model = std::make_unique<physics::CorotationalTetFem>(mesh, material);
  const int n = model->node_count();
  body.model = std::move(model);
  start_at_rest(body, n);
  fix_nodes(body, spec, body.model->rest_positions());
  body.gravity = physics::gravity_forces(body.model->lumped_masses(), vec(solver.gravity));
  if (solver.start == "settled") {
    // Start from static equilibrium under gravity (small-strain solve, exact enough for the
    // sag of a supported organ), so a replay does not begin with the body dropping.
    try {
      body.state.positions += physics::solve_static_linear(mesh, material, body.fixed,
                                                           spec.material.density * vec(solver.gravity));
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
      surface_index[i] = static_cast<int>(body.surface_nodes.size());
      body.surface_nodes.push_back(i);
    }
  body.render_triangles.reserve(body.surface.size() * 3);
  for (const auto& t : body.surface)
    for (int v : t) body.render_triangles.push_back(static_cast<std::uint32_t>(surface_index[v]));
  set_integrator(body, spec, solver);
  return body;
}

// The render surface of a meshless body: the imported mesh itself, or (generated bodies) the
// boundary of a voxel fill at surface_resolution (default a / 2, finer than the integration
// grid as seed-004 §2.6 requires), snapped onto the true surface.
void make_render_surface(Body& body, const BodySpec& spec, const BodyShape& shape,
                         physics::Vector& rest_vertices) {
  if (spec.mesh) {
    const TriangleSoup soup = import_surface(*spec.mesh, spec.mesh_scale);
    rest_vertices.resize(3 * static_cast<Eigen::Index>(soup.vertices.size()));
    for (std::size_t v = 0; v < soup.vertices.size(); ++v)
      for (int c = 0; c < 3; ++c) rest_vertices[3 * static_cast<Eigen::Index>(v) + c] = soup.vertices[v][c];
    body.surface = soup.triangles;
  } else {
    const double resolution = spec.efg.surface_resolution.value_or(0.5 * spec.resolution);
    const physics::TetMesh mesh = fill_with_tets(spec, shape, resolution, &body.snap);
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

// A vertex moved only by fixed particles is fixed: the tool cannot push it. 1 when every
// particle of vertex v's row is fixed.
std::uint8_t fixed_vertex(const Body& body, int v) {
  const auto& embedding = *body.embedding;
  for (int k = 0; k < embedding.row_lengths[static_cast<std::size_t>(v)]; ++k)
    if (!body.fixed[embedding.particles[static_cast<std::size_t>(v) * embedding.stride + k]]) return 0;
  return 1;
}

// Surface vertex v's position from its embedding row and the particles' positions (one row of
// CorotationalEfg::surface_positions, for the rows a cut remapped).
void set_surface_position(Body& body, int v) {
  const physics::SurfaceEmbedding& embedding = *body.embedding;
  const std::size_t row = static_cast<std::size_t>(v) * static_cast<std::size_t>(embedding.stride);
  physics::Vec3 position = physics::Vec3::Zero();
  for (int k = 0; k < embedding.row_lengths[static_cast<std::size_t>(v)]; ++k)
    position += embedding.weights[row + static_cast<std::size_t>(k)] *
                body.state.positions.segment<3>(3 * static_cast<Eigen::Index>(embedding.particles[row + static_cast<std::size_t>(k)]));
  body.surface_positions.segment<3>(3 * static_cast<Eigen::Index>(v)) = position;
}

void set_fixed_vertices(Body& body) {
  const auto& embedding = *body.embedding;
  body.fixed_vertices.resize(static_cast<std::size_t>(embedding.vertex_count()));
  for (int v = 0; v < embedding.vertex_count(); ++v) body.fixed_vertices[static_cast<std::size_t>(v)] = fixed_vertex(body, v);
}

Body build_efg_body(const BodySpec& spec, const SolverSpec& solver, const BodyShape& shape) {
  Body body;
  body.name = spec.name;
  body.model_name = spec.model;
  const std::string where = "body '" + spec.name + "'";
  physics::Material material{spec.material.youngs_modulus, spec.material.poisson_ratio,
                             spec.material.density};
  physics::EfgSettings settings;
  settings.spacing = spec.resolution;
  settings.neighbours = spec.efg.neighbours;
  if (spec.efg.support_factor) settings.support_factor = *spec.efg.support_factor;
  settings.samples_per_axis = spec.efg.samples_per_axis;
  settings.estimate_volumes = spec.efg.estimate_volumes;
  body.executor = std::make_unique<ThreadPoolExecutor>(
      spec.efg.threads, spec.cuttable && spec.efg.threads >= 2);
  std::unique_ptr<physics::CorotationalEfg> model;
  physics::Vector rest_vertices;
  try {
    model = std::make_unique<physics::CorotationalEfg>(shape.inside, shape.lo, shape.hi, material, settings,
                                                       body.executor.get());
    if (spec.cuttable) {
      // The thesis's explicit surface cut, starting from the same voxel boundary (snapped
      // onto the shape), its front's width w 1.5 cells (seed 004 §2.5: about the surface's
      // triangle size).
      const double resolution = spec.efg.surface_resolution.value_or(0.5 * spec.resolution);
      physics::TriangleSurface initial = physics::voxel_boundary(shape.inside, shape.lo, shape.hi, resolution);
      std::vector<physics::Vec3>& vertices = initial.vertices;
      // No element carries this surface: its vertices go onto the shape and even out along it
      // (the voxel snap stops short where its tetrahedra would flatten: a hammered look).
      physics::fair_surface_onto_shape(vertices, initial.triangles, shape.inside, resolution);
      body.front_surface = std::make_unique<physics::FrontSurface>(std::move(vertices), initial.triangles, 1.5 * resolution);
      body.front_rest_cut = std::make_unique<physics::RestCut>(2 * resolution);
      body.cutter = std::make_unique<physics::VolumeCutter>(*model, 1e-6, 0.5 * spec.resolution);
      body.embedding.emplace();
      std::vector<int> all(body.front_surface->vertices().size());
      for (std::size_t v = 0; v < all.size(); ++v) all[v] = static_cast<int>(v);
      physics::FrontMappingReport mapping;
      physics::map_front_surface(*model, body.front_surface->vertices(), body.front_surface->triangles(),
                                 body.front_surface->vertex_planes(), all, *body.embedding, mapping);
      body.front_plane_counts.assign(all.size(), 0);
      body.front_mapped_base = body.front_surface->base_vertex_count();
      body.front_identity.first = body.front_mapped_base;
      body.front_topology = physics::surface_topology(body.front_surface->triangles());
      physics::update_elements_linked_across(*model, *body.front_rest_cut, body.linked_across, shape.lo, shape.hi,
                                             nullptr, &body.link_boxes, &body.linked_seen, &body.linked_index);
      body.surface = body.front_surface->triangles();
      body.render_triangles.clear();
      for (const auto& t : body.surface)
        for (int v : t) body.render_triangles.push_back(static_cast<std::uint32_t>(v));
      body.render_cut_face = body.front_surface->on_cut_face();
    } else {
      make_render_surface(body, spec, shape, rest_vertices);
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  body.elements = static_cast<std::size_t>(model->element_count());
  if (!body.embedding) body.embedding = model->embed_surface(rest_vertices);
  body.efg = model.get();
  body.surface_min = shape.lo;
  body.surface_max = shape.hi;
  const int n = model->node_count();
  const physics::CorotationalEfg& efg = *model;
  body.model = std::move(model);
  start_at_rest(body, n);
  fix_nodes(body, spec, body.model->rest_positions());
  body.gravity = physics::gravity_forces(body.model->lumped_masses(), vec(solver.gravity));
  if (solver.start == "settled") {
    try {
      body.state.positions += physics::solve_static(physics::assemble_stiffness(efg), body.gravity, body.fixed);
    } catch (const std::exception& e) {
      throw std::runtime_error(where + ": solver.start 'settled' needs a body held in place by its "
                               "fixed regions: " + e.what());
    }
  }
  set_fixed_vertices(body);
  physics::CorotationalEfg::surface_positions(*body.embedding, body.state.positions, body.surface_positions);
  body.previous_positions = body.state.positions;
  set_integrator(body, spec, solver);
  return body;
}

}  // namespace

Body build_body(const BodySpec& spec, const SolverSpec& solver) {
  BodyShape shape;
  try {
    shape = body_shape(spec);
  } catch (const std::exception& e) {
    throw std::runtime_error("body '" + spec.name + "': " + e.what());
  }
  Body body = spec.model == "efg" ? build_efg_body(spec, solver, shape) : build_fem_body(spec, solver, shape);
  // The energy watchdog compares each step with the one before; a settled start begins with
  // the elastic energy of the sag, not zero.
  body.last_energy = body.model->elastic_energy(body.state.positions) +
                     physics::kinetic_energy(body.model->lumped_masses(), body.state.velocities);
  for (std::size_t i = 0; i < spec.fixed.size(); ++i) {
    const auto in = physics::nodes_in_box(body.model->rest_positions(), vec(spec.fixed[i].min), vec(spec.fixed[i].max));
    if (std::find(in.begin(), in.end(), 1) == in.end())
      throw std::runtime_error("body '" + spec.name + "': fixed[" + std::to_string(i) + "] contains no " +
                               (spec.model == "efg" ? "particle" : "node") + " of the body");
  }
  return body;
}

World::World(const Scene& scene, std::optional<Trajectory> trajectory)
    : scene_(scene), trajectory_(std::move(trajectory)) {
  bounds_min_ = {1e300, 1e300, 1e300};
  bounds_max_ = {-1e300, -1e300, -1e300};
  for (const auto& spec : scene_.bodies) {
    bodies_.push_back(build_body(spec, scene_.solver));
    if (scene_.solver.backend == "gpu") make_gpu_backend(bodies_.back(), bodies_.size() - 1);
    // Particles of a meshless body can lie outside it: frame what is seen.
    const Body& built = bodies_.back();
    const auto& x = built.embedding ? built.surface_positions : built.state.positions;
    for (Eigen::Index i = 0; i < x.size(); ++i) {
      bounds_min_[i % 3] = std::min(bounds_min_[i % 3], x[i]);
      bounds_max_[i % 3] = std::max(bounds_max_[i % 3], x[i]);
    }
  }
  for (std::size_t l = 0; l < scene_.loads.size(); ++l) {
    const auto& load = scene_.loads[l];
    for (auto& body : bodies_) {
      if (body.name != load.body) continue;
      std::vector<int> nodes;
      const auto& x = body.state.positions;
      for (int i = 0; i < body.model->node_count(); ++i)
        if (load.region.contains({x[3 * i], x[3 * i + 1], x[3 * i + 2]}, 1e-9)) nodes.push_back(i);
      if (nodes.empty())
        throw std::runtime_error(scene_.file.string() + ": loads[" + std::to_string(l) +
                                 "].region: contains no node of body '" + body.name + "'");
      body.load_nodes.push_back(std::move(nodes));
      body.load_index.push_back(l);
    }
  }
  if (scene_.tool) {
    if (!trajectory_)
      throw std::runtime_error(scene_.file.string() + ": tool.trajectory: none given (set it in the scene or pass "
                               "--trajectory FILE; `incise run` and `incise session` drive the tool live)");
    if (trajectory_->samples.empty())
      throw std::runtime_error(scene_.file.string() + ": tool.trajectory: holds no sample");
    tool_.present = true;
    tool_.radius = scene_.tool->radius;
  }
  take_tool_input(0.0);
}

void World::take_tool_input(double time) {
  if (!tool_.present) return;
  // Every sample since the last step belongs to the tool's swept path; the probe's contact
  // needs only the pose at the end of the step (the blade's CCD will use the whole sweep).
  tool_.pose = sample_at(trajectory_->samples, time);
  tool_.tip = tool_.pose.position;
  tool_.tail = tool_.tip;
  if (scene_.tool->shape == "blade") {
    // The swept path: the pose at the start of the step, every recorded sample inside it,
    // the pose at its end (seed 004 §2.2: a fast stroke is never skipped).
    const double dt = scene_.solver.dt;
    const double start = std::max(0.0, time - dt);
    std::vector<ToolSample> poses{sample_at(trajectory_->samples, start)};
    for (const ToolSample& sample : samples_between(trajectory_->samples, start, time))
      if (sample.time > start && sample.time < time) poses.push_back(sample);
    poses.push_back(tool_.pose);
    tool_.blade_poses.clear();
    tool_.blade_fractions.clear();
    tool_.blade_active.clear();
    for (std::size_t j = 0; j < poses.size(); ++j) {
      std::vector<physics::Vec3> edge;
      for (const Point& local : scene_.tool->edge) {
        const auto world = rotate(poses[j].orientation, local);
        edge.emplace_back(poses[j].position[0] + world[0], poses[j].position[1] + world[1],
                          poses[j].position[2] + world[2]);
      }
      tool_.blade_poses.push_back(std::move(edge));
      tool_.blade_fractions.push_back(time > start ? std::clamp((poses[j].time - start) / (time - start), 0.0, 1.0) : 0.0);
      if (j > 0) tool_.blade_active.push_back((poses[j].buttons & kToolButtonEngaged) != 0 && time > start ? 1 : 0);
    }
    // sample_at may return the recorded time of the nearest sample: keep the ends exact.
    tool_.blade_fractions.front() = 0;
    tool_.blade_fractions.back() = 1;
    for (std::size_t j = 1; j < tool_.blade_fractions.size(); ++j)
      tool_.blade_fractions[j] = std::max(tool_.blade_fractions[j], tool_.blade_fractions[j - 1]);
  }
  if (scene_.tool->shape == "capsule") {
    auto axis = rotate(tool_.pose.orientation, {0, 0, scene_.tool->length});
    for (int i = 0; i < 3; ++i) tool_.tail[i] = tool_.tip[i] + axis[i];
  }
}

void World::append_tool_samples(std::span<const ToolSample> samples) {
  if (!tool_.present || !trajectory_) throw std::logic_error("World::append_tool_samples: the scene has no tool");
  auto& held = trajectory_->samples;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const ToolSample& s = samples[k];
    const auto at = [&] { return "live tool sample " + std::to_string(k) + " (t = " + std::to_string(s.time) + " s)"; };
    bool finite = std::isfinite(s.time);
    for (double v : s.position) finite = finite && std::isfinite(v);
    for (double v : s.orientation) finite = finite && std::isfinite(v);
    if (!finite) throw std::invalid_argument(at() + ": a time, position or orientation is not finite");
    const double norm = std::sqrt(s.orientation[0] * s.orientation[0] + s.orientation[1] * s.orientation[1] +
                                  s.orientation[2] * s.orientation[2] + s.orientation[3] * s.orientation[3]);
    if (std::abs(norm - 1) > 1e-3) throw std::invalid_argument(at() + ": orientation |q| = " + std::to_string(norm) + " is not 1");
    if (!held.empty() && s.time < held.back().time)
      throw std::invalid_argument(at() + ": earlier than the previous sample (t = " + std::to_string(held.back().time) + " s)");
    held.push_back(s);
  }
  // The next step starts at time_ (computed there as end - dt, which may round below time_):
  // it needs the last sample at or before its start (sample_at's left neighbour) and
  // everything after it. Keeping from one step further back is safe; what is older can go.
  const auto keep = std::upper_bound(held.begin(), held.end(), time_ - scene_.solver.dt,
                                     [](double t, const ToolSample& s) { return t < s.time; });
  if (keep - held.begin() > 1) held.erase(held.begin(), keep - 1);
}

double World::last_tool_sample_time() const {
  return trajectory_ && !trajectory_->samples.empty() ? trajectory_->samples.back().time : 0.0;
}

std::vector<physics::NodalSpring> World::contact(const Body& body, StepStats& stats) const {
  if (!tool_.present || blade()) return {};  // the ideal blade applies no force (seed 004 §2.2)
  if (!body.embedding) {
    auto contact = physics::probe_contact(body.state.positions, body.surface, body.fixed, vec(tool_.tip),
                                          vec(tool_.tail), tool_.radius, scene_.tool->stiffness);
    stats.contacts += contact.triangles_touched;
    return std::move(contact.springs);
  }
  // Embedded surface: the contact acts on surface vertices, and a vertex force f_v goes to the
  // particles with the vertex's weights, f_i = w_i f_v (seed-004 §2.6), so the total force is
  // unchanged (the weights sum to 1). The exact stiffness W^T K_v W couples the particles;
  // each particle takes |w_i| K_v instead (the row sums of W^T K_v W, made positive
  // semi-definite: the MLS weights of far corners are negative), which keeps the implicit
  // system symmetric positive definite.
  auto contact = physics::probe_contact(body.surface_positions, body.surface, body.fixed_vertices,
                                        vec(tool_.tip), vec(tool_.tail), tool_.radius,
                                        scene_.tool->stiffness);
  stats.contacts += contact.triangles_touched;
  const auto& embedding = *body.embedding;
  std::vector<int> slot(static_cast<std::size_t>(body.model->node_count()), -1);
  std::vector<physics::NodalSpring> springs;
  for (const auto& vertex_spring : contact.springs) {
    const std::size_t row = static_cast<std::size_t>(vertex_spring.node) * embedding.stride;
    for (int k = 0; k < embedding.row_lengths[vertex_spring.node]; ++k) {
      const int particle = embedding.particles[row + k];
      if (body.fixed[particle]) continue;
      const double weight = embedding.weights[row + k];
      if (slot[particle] < 0) {
        slot[particle] = static_cast<int>(springs.size());
        springs.push_back({particle, physics::Vec3::Zero(), physics::Mat3::Zero()});
      }
      auto& spring = springs[slot[particle]];
      spring.force += weight * vertex_spring.force;
      spring.stiffness += std::abs(weight) * vertex_spring.stiffness;
    }
  }
  return springs;
}

void World::rebuild_front_surface(Body& body, const physics::Vec3& dirty_lo, const physics::Vec3& dirty_hi,
                                  const std::vector<std::uint8_t>& changed, bool fixed_changed, StepStats& stats) {
  // What this costs follows the stroke, not the surface: FrontSurface keeps the base's
  // triangles in their slots and says which slots and base vertices the stroke changed, so
  // the triangles that can differ from the surface as last mapped are those the stroke
  // changed then and now (`before_slots`, `now_slots`); every other slot holds the same
  // triangle, its corners base vertices that keep their index and row.
  auto start = Clock::now();
  const physics::FrontSurface& front = *body.front_surface;
  const auto& vertices = front.vertices();
  const auto& triangles = front.triangles();
  const auto& planes = front.vertex_planes();
  physics::SurfaceEmbedding& embedding = *body.embedding;
  const int n = static_cast<int>(vertices.size());
  const int base_vertices = front.base_vertex_count();
  const std::size_t slots_now = triangles.size(), slots_before = body.surface.size();
  // The base's vertices keep their index and their row unless a trigger of seed 004 §2.6
  // names them (the base as the last mapping saw it: a stroke ended since then turned its
  // vertices into base ones, which are matched below like the stroke's).
  const int kept = std::min({base_vertices, body.front_mapped_base, embedding.vertex_count()});
  const int lowest = std::min(kept, body.front_identity.first);
  std::vector<int> now_slots = front.replaced_slots();
  for (std::size_t s = static_cast<std::size_t>(front.base_triangle_count()); s < slots_now; ++s) now_slots.push_back(static_cast<int>(s));
  const std::vector<int>& before_slots = body.front_changed_slots;
  // Per slot: 1 changed now, 8 looked at in the edge recount below.
  std::vector<std::uint8_t> slot_flags(std::max(slots_now, slots_before), 0);
  for (const int s : now_slots) slot_flags[static_cast<std::size_t>(s)] |= 1;
  // The triangles with a corner at or above `lowest` (the stroke's, and those of a stroke
  // ended since the last mapping, now base triangles around its vertices), increasing.
  std::vector<int> stroke_slots = now_slots;
  for (int v = lowest; v < base_vertices; ++v)
    for (const int s : front.base_triangles_around(v))
      if (!(slot_flags[static_cast<std::size_t>(s)] & 1)) stroke_slots.push_back(s);
  std::sort(stroke_slots.begin(), stroke_slots.end());
  stroke_slots.erase(std::unique(stroke_slots.begin(), stroke_slots.end()), stroke_slots.end());
  // The slots that can differ (changed then, or with a stroke's vertex now), increasing.
  std::vector<int> differing;
  std::set_union(stroke_slots.begin(), stroke_slots.end(), before_slots.begin(), before_slots.end(), std::back_inserter(differing));

  // The stroke's vertices are numbered anew at each sample, but those behind the front come
  // out the same: matched to the last mapping's (physics::front_vertex_identity), they keep
  // their row and flag, and only the new ones (and those the triggers below name) are mapped.
  physics::FrontVertexIdentity identity =
      physics::front_vertex_identity(vertices, triangles, planes, front.crack_front(), lowest, stroke_slots);
  std::vector<int> same_point;  // the same point, whatever its triangles: keeps its row
  const std::vector<int> same = physics::match_front_vertices(body.front_identity, identity, &same_point);
  const auto old_position = [&](int u) -> const physics::Vec3& {
    return u < body.front_identity.first ? vertices[static_cast<size_t>(u)]
                                         : body.front_stroke_rest[static_cast<size_t>(u - body.front_identity.first)];
  };
  // Where the surface changed: the triangles with a vertex that is new (or whose triangles
  // changed), now and at the last mapping (for those gone). Only a segment reaching into
  // this box can have changed side (the second trigger, below).
  // The same triangles' corners are where the edges' use can have changed: a triangle made
  // or gone changes the triangles of each of its corners, so each is a new (unmatched) vertex
  // or a base one. The surface's edge counts are kept by recounting the edges between two of
  // them, before and after (physics::surface_topology).
  physics::Vec3 changed_lo = physics::Vec3::Constant(1e300), changed_hi = physics::Vec3::Constant(-1e300);
  std::vector<std::uint8_t> touched_now(vertices.size(), 0), touched_before(static_cast<std::size_t>(embedding.vertex_count()), 0);
  std::vector<int> touched_base;  // touched vertices below kept (the same in both)
  {
    const auto grow = [&](const physics::Vec3& x) {
      changed_lo = changed_lo.cwiseMin(x);
      changed_hi = changed_hi.cwiseMax(x);
    };
    const auto is_new = [&](int v) { return v >= kept && same[static_cast<size_t>(v)] < 0; };
    for (const int s : stroke_slots) {
      const auto& tri = triangles[static_cast<std::size_t>(s)];
      if (is_new(tri[0]) || is_new(tri[1]) || is_new(tri[2]))
        for (const int v : tri) {
          grow(vertices[static_cast<size_t>(v)]);
          touched_now[static_cast<size_t>(v)] = 1;
          if (v < kept) touched_base.push_back(v);
        }
    }
    std::vector<std::uint8_t> still(static_cast<size_t>(embedding.vertex_count() - std::min(kept, embedding.vertex_count())), 0);
    for (int v = kept; v < n; ++v)
      if (const int u = same[static_cast<size_t>(v)]; u >= kept && u < embedding.vertex_count()) still[static_cast<size_t>(u - kept)] = 1;
    const auto is_gone = [&](int u) { return u >= kept && still[static_cast<size_t>(u - kept)] == 0; };
    // The last mapping's vertices at or above kept were its stroke's: their triangles were
    // in its changed slots.
    for (const int s : before_slots) {
      if (static_cast<std::size_t>(s) >= slots_before) continue;
      const auto& tri = body.surface[static_cast<std::size_t>(s)];
      if (is_gone(tri[0]) || is_gone(tri[1]) || is_gone(tri[2]))
        for (const int u : tri) {
          grow(old_position(u));
          touched_before[static_cast<size_t>(u)] = 1;
          if (u < kept) touched_base.push_back(u);
        }
    }
    std::sort(touched_base.begin(), touched_base.end());
    touched_base.erase(std::unique(touched_base.begin(), touched_base.end()), touched_base.end());
    for (const int v : touched_base) touched_now[static_cast<size_t>(v)] = touched_before[static_cast<size_t>(v)] = 1;
  }
  // The edges between two touched vertices lie on the differing triangles or on the unchanged
  // ones around a touched base vertex (the same before and after).
  std::vector<std::array<int, 3>> edges_before, edges_now;
  for (const int s : differing) {
    if (static_cast<std::size_t>(s) < slots_before) edges_before.push_back(body.surface[static_cast<std::size_t>(s)]);
    if (static_cast<std::size_t>(s) < slots_now) edges_now.push_back(triangles[static_cast<std::size_t>(s)]);
    slot_flags[static_cast<std::size_t>(s)] |= 8;
  }
  // The base's triangles away from the cut (all corners below kept, not all touched): the
  // unchanged ones are the same in both, so only the differing ones can make their counts
  // differ; if they do (a triangle lost or made away from the cut, which the stroke never
  // does), the surface is counted whole.
  const auto untouched_base = [&](const std::vector<std::array<int, 3>>& list, const std::vector<std::uint8_t>& touched) {
    long count = 0;
    for (const auto& tri : list)
      if (tri[0] < kept && tri[1] < kept && tri[2] < kept &&
          !(touched[static_cast<size_t>(tri[0])] && touched[static_cast<size_t>(tri[1])] && touched[static_cast<size_t>(tri[2])]))
        ++count;
    return count;
  };
  const bool recount = untouched_base(edges_before, touched_before) != untouched_base(edges_now, touched_now);
  for (const int v : touched_base) {
    if (v >= base_vertices) continue;
    for (const int s : front.base_triangles_around(v)) {
      if (slot_flags[static_cast<std::size_t>(s)] & 8) continue;
      slot_flags[static_cast<std::size_t>(s)] |= 8;
      edges_before.push_back(triangles[static_cast<std::size_t>(s)]);
      edges_now.push_back(triangles[static_cast<std::size_t>(s)]);
    }
  }
  const physics::SurfaceTopology touched_edges_before = physics::surface_topology(edges_before, touched_before);
  // The kept base rows whose planes or element changed (the first and third triggers): the
  // base vertices given planes by a stroke at the last mapping or since (the ends of cut
  // edges, corners of the split triangles, which hold a stroke's vertex), and those on a
  // re-selected element.
  // A kept vertex lies within front_reach (per axis) of its integration point (the rows below
  // kept are the last mapping's until the remapping below, which extends it again).
  const auto& centres = body.efg->element_centres();
  const auto reach_of = [&](int v) {
    return (centres[static_cast<std::size_t>(embedding.elements[static_cast<std::size_t>(v)])] - vertices[static_cast<std::size_t>(v)]).cwiseAbs().maxCoeff();
  };
  for (int v = body.front_reach_upto; v < kept; ++v) body.front_reach = std::max(body.front_reach, reach_of(v));
  body.front_reach_upto = std::max(body.front_reach_upto, kept);
  std::vector<int> remap;
  std::vector<int> planed = body.front_planed;
  {
    for (const int s : stroke_slots)
      for (const int v : triangles[static_cast<std::size_t>(s)])
        if (v < kept) planed.push_back(v);
    std::sort(planed.begin(), planed.end());
    planed.erase(std::unique(planed.begin(), planed.end()), planed.end());
    for (const int v : planed) {
      const auto index = static_cast<std::size_t>(v);
      if (v < kept && planes[index].size() != (index < body.front_plane_counts.size() ? body.front_plane_counts[index] : 0)) remap.push_back(v);
    }
    // Those on a re-selected element are among the base's vertices in the box of its points
    // grown by front_reach (the surface's own bins; not every vertex looked at).
    physics::Vec3 changed_centres_lo = physics::Vec3::Constant(1e300), changed_centres_hi = physics::Vec3::Constant(-1e300);
    for (std::size_t e = 0; e < changed.size(); ++e)
      if (changed[e] != 0) {
        changed_centres_lo = changed_centres_lo.cwiseMin(centres[e]);
        changed_centres_hi = changed_centres_hi.cwiseMax(centres[e]);
      }
    if ((changed_centres_lo.array() <= changed_centres_hi.array()).all()) {
      const physics::Vec3 grown = physics::Vec3::Constant(body.front_reach + 1e-3 * body.efg->spacing());
      std::vector<int> on_changed;
      front.base_vertices_in(changed_centres_lo - grown, changed_centres_hi + grown, on_changed);
      std::erase_if(on_changed, [&](int v) {
        return v >= kept || changed[static_cast<std::size_t>(embedding.elements[static_cast<std::size_t>(v)])] == 0;
      });
      std::vector<int> merged;
      std::set_union(remap.begin(), remap.end(), on_changed.begin(), on_changed.end(), std::back_inserter(merged));
      remap.swap(merged);
    }
  }
  // The matched stroke vertices take their rows along (from a copy: the numbers overlap),
  // and so do those at the same point whose triangles changed (the front's new vertices
  // joined to them): none of seed 004 §2.6's triggers names them. Their segment is tested
  // below with the others' (the second trigger), and the wrong-side count looks at them.
  std::vector<int> moved_from, moved_elements, moved_lengths, moved_particles;
  std::vector<double> moved_weights;
  std::vector<std::uint8_t> moved_wrong, moved_fixed;
  // Their positions too (the CPU's: those update_surface formed from the particles as they
  // still are, the same sums set_surface_position would do again).
  std::vector<physics::Vec3> moved_positions;
  const bool keep_positions = !body.gpu;
  const int stride = embedding.stride;
  for (int v = kept; v < n; ++v) {
    const int u = same_point[static_cast<std::size_t>(v)];
    if (u < 0 || u >= embedding.vertex_count() || changed[static_cast<std::size_t>(embedding.elements[static_cast<std::size_t>(u)])] != 0) continue;
    moved_from.push_back(v);
    moved_elements.push_back(embedding.elements[static_cast<size_t>(u)]);
    moved_lengths.push_back(embedding.row_lengths[static_cast<size_t>(u)]);
    const auto row = static_cast<std::ptrdiff_t>(u) * stride;
    moved_particles.insert(moved_particles.end(), embedding.particles.begin() + row, embedding.particles.begin() + row + stride);
    moved_weights.insert(moved_weights.end(), embedding.weights.begin() + row, embedding.weights.begin() + row + stride);
    moved_wrong.push_back(static_cast<size_t>(u) < body.front_wrong_side.size() ? body.front_wrong_side[static_cast<size_t>(u)] : 0);
    moved_fixed.push_back(static_cast<size_t>(u) < body.fixed_vertices.size() ? body.fixed_vertices[static_cast<size_t>(u)] : 0);
    if (keep_positions) moved_positions.push_back(3 * static_cast<Eigen::Index>(u) + 3 <= body.surface_positions.size()
                                                      ? physics::Vec3(body.surface_positions.segment<3>(3 * static_cast<Eigen::Index>(u)))
                                                      : physics::Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
  }
  physics::fit_rows(embedding, n, stride);
  body.front_wrong_side.resize(vertices.size(), 0);
  std::fill(body.front_wrong_side.begin() + kept, body.front_wrong_side.end(), 0);
  std::vector<std::uint8_t> has_row(static_cast<std::size_t>(n - kept), 0);  // per vertex from kept on
  std::vector<std::pair<std::size_t, std::uint8_t>> moved_fixed_at;  // set once the rows are all mapped
  for (std::size_t k = 0; k < moved_from.size(); ++k) {
    const auto v = static_cast<std::size_t>(moved_from[k]);
    embedding.elements[v] = moved_elements[k];
    embedding.row_lengths[v] = moved_lengths[k];
    std::copy_n(moved_particles.begin() + static_cast<std::ptrdiff_t>(k) * stride, stride, embedding.particles.begin() + static_cast<std::ptrdiff_t>(v) * stride);
    std::copy_n(moved_weights.begin() + static_cast<std::ptrdiff_t>(k) * stride, stride, embedding.weights.begin() + static_cast<std::ptrdiff_t>(v) * stride);
    body.front_wrong_side[v] = moved_wrong[k];
    moved_fixed_at.emplace_back(v, moved_fixed[k]);
    has_row[v - static_cast<std::size_t>(kept)] = 1;
  }
  // What is left of the stroke's vertices is mapped anew (after the trigger test below, which
  // looks at the rows kept).
  std::vector<int> fresh;
  for (int v = kept; v < n; ++v)
    if (!has_row[static_cast<std::size_t>(v - kept)]) fresh.push_back(v);
  body.front_stroke_rest.assign(vertices.begin() + identity.first, vertices.end());
  if (identity.first != kept) {
    identity = physics::front_vertex_identity(vertices, triangles, planes, front.crack_front(), kept, stroke_slots);
    body.front_stroke_rest.assign(vertices.begin() + kept, vertices.end());
  }
  body.front_identity = std::move(identity);
  // The triangles around each vertex, for the mapping's normals and one-rings: a base vertex's
  // unchanged base triangles and, for every vertex, the changed slots it is a corner of: for
  // the stroke's vertices in compressed rows (counted, then filled), for the base's (the
  // corners of split triangles: few) as sorted (vertex, slot) pairs.
  std::vector<int> stroke_around_start(static_cast<std::size_t>(std::max(0, n - base_vertices)) + 1, 0), stroke_around;
  std::vector<std::pair<int, int>> base_around;
  for (const int s : now_slots)
    for (const int v : triangles[static_cast<std::size_t>(s)])
      if (v >= base_vertices) ++stroke_around_start[static_cast<std::size_t>(v - base_vertices) + 1];
      else base_around.emplace_back(v, s);
  for (std::size_t k = 1; k < stroke_around_start.size(); ++k) stroke_around_start[k] += stroke_around_start[k - 1];
  stroke_around.resize(static_cast<std::size_t>(stroke_around_start.back()));
  {
    std::vector<int> fill(stroke_around_start.begin(), stroke_around_start.end() - 1);
    for (const int s : now_slots)
      for (const int v : triangles[static_cast<std::size_t>(s)])
        if (v >= base_vertices) stroke_around[static_cast<std::size_t>(fill[static_cast<std::size_t>(v - base_vertices)]++)] = s;
  }
  std::sort(base_around.begin(), base_around.end());
  const physics::TrianglesAround around = [&](int v, std::vector<int>& out) {
    const std::size_t first = out.size();
    if (v >= base_vertices) {
      const auto k = static_cast<std::size_t>(v - base_vertices);
      out.insert(out.end(), stroke_around.begin() + stroke_around_start[k], stroke_around.begin() + stroke_around_start[k + 1]);
    } else {
      for (const int s : front.base_triangles_around(v))
        if (!(slot_flags[static_cast<std::size_t>(s)] & 1)) out.push_back(s);
      for (auto it = std::lower_bound(base_around.begin(), base_around.end(), std::pair<int, int>(v, -1));
           it != base_around.end() && it->first == v; ++it)
        out.push_back(it->second);
    }
    std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
  };
  // The cut faces, each once (both sides' copies lie on it, with the same corners), and per
  // vertex whether it is on one (see physics::FrontVisibility): the base's that the stroke
  // left and the changed slots' (in slot order).
  std::vector<std::array<physics::Vec3, 3>> faces;
  std::vector<std::uint8_t> on_face(vertices.size(), 0);
  {
    std::vector<int> face_slots;
    for (const int s : front.base_cut_face_slots())
      if (!(slot_flags[static_cast<std::size_t>(s)] & 1)) face_slots.push_back(s);
    for (const int s : now_slots)
      if (front.on_cut_face()[static_cast<std::size_t>(s)]) face_slots.push_back(s);
    std::sort(face_slots.begin(), face_slots.end());
    // Each face's corners sorted, as its key; the first slot of each key is kept, in slot
    // order: a key is looked up among those met so far (open addressing on its bits, -0 as 0).
    std::vector<std::array<double, 9>> keys(face_slots.size());
    std::vector<int> table(std::bit_ceil(2 * face_slots.size() + 1), -1);
    const std::size_t mask = table.size() - 1;
    for (std::size_t k = 0; k < face_slots.size(); ++k) {
      const auto& tri = triangles[static_cast<std::size_t>(face_slots[k])];
      for (const int v : tri) on_face[static_cast<size_t>(v)] = 1;
      std::array<physics::Vec3, 3> corners{vertices[static_cast<size_t>(tri[0])], vertices[static_cast<size_t>(tri[1])], vertices[static_cast<size_t>(tri[2])]};
      std::sort(corners.begin(), corners.end(), [](const physics::Vec3& l, const physics::Vec3& r) {
        return std::lexicographical_compare(l.data(), l.data() + 3, r.data(), r.data() + 3);
      });
      auto& key = keys[k];
      // The nine coordinates' bits each times its own odd constant, summed, then mixed once:
      // independent products, not a chain of nine mixes (any hash gives the same faces).
      std::uint64_t sum = 0;
      for (int c = 0; c < 3; ++c)
        for (int d = 0; d < 3; ++d) {
          const double x = corners[static_cast<size_t>(c)][d] + 0.0;
          key[static_cast<size_t>(3 * c + d)] = x;
          std::uint64_t bits = 0;
          std::memcpy(&bits, &x, sizeof bits);
          sum += bits * (0x9e3779b97f4a7c15ULL + 2 * static_cast<std::uint64_t>(3 * c + d));
        }
      std::size_t at = physics::mix64(sum) & mask;
      bool met = false;
      for (; table[at] >= 0; at = (at + 1) & mask)
        if (keys[static_cast<std::size_t>(table[at])] == key) {
          met = true;
          break;
        }
      if (met) continue;
      table[at] = static_cast<int>(k);
      faces.push_back(corners);
    }
  }
  // The kept rows whose segment the cut crosses now (the second trigger, taken on the cut as
  // the surface shows it rather than on this step's sweep, which the stroke may have left out
  // in part: samples held, the front's transient part). Only a segment reaching into the box
  // of what the stroke made since the last mapping can have changed side: the other faces
  // were there when it was last tested. A base vertex's segment reaches at most front_reach
  // from it, so the base's vertices are taken from the box grown by that.
  const double inset = 0.1 * front.front_width() / 1.5;  // a tenth of a surface cell
  const physics::CutFaceIndex face_index(*body.efg, faces);
  std::vector<int> near;
  const auto segment_near = [&](int v) {
    const physics::Vec3& x = vertices[static_cast<size_t>(v)];
    const physics::Vec3& q = centres[static_cast<size_t>(embedding.elements[static_cast<size_t>(v)])];
    const physics::Vec3 lo = x.cwiseMin(q).array() - inset, hi = x.cwiseMax(q).array() + inset;
    return (lo.array() <= changed_hi.array()).all() && (hi.array() >= changed_lo.array()).all();
  };
  if ((changed_lo.array() <= changed_hi.array()).all()) {
    const physics::Vec3 grown = physics::Vec3::Constant(body.front_reach + inset);
    std::vector<int> candidates;
    front.base_vertices_in(changed_lo - grown, changed_hi + grown, candidates);
    for (const int v : candidates)
      if (v < kept && segment_near(v)) near.push_back(v);
    for (int v = kept; v < n; ++v)
      if (has_row[static_cast<std::size_t>(v - kept)] && segment_near(v)) near.push_back(v);
  }
  std::vector<int> crossed;
  // (An empty subset would count every vertex.)
  if (!near.empty())
    physics::count_wrong_side(*body.efg, vertices, triangles, embedding, face_index, inset, near, &crossed, on_face, &around);
  std::vector<int> merged;
  std::set_union(remap.begin(), remap.end(), crossed.begin(), crossed.end(), std::back_inserter(merged));
  remap.swap(merged);
  merged.clear();
  std::set_union(remap.begin(), remap.end(), fresh.begin(), fresh.end(), std::back_inserter(merged));
  remap.swap(merged);
  physics::FrontMappingReport mapping;
  // Each vertex sees its point through no cut face (what wrong_side below measures), the
  // crack front's vertices excepted.
  physics::FrontVisibility visibility{&face_index, inset, front.crack_front(), on_face};
  physics::map_front_surface(*body.efg, vertices, triangles, planes, remap, embedding, mapping, &visibility, &around, &body.front_cubes);
  for (const int v : remap)
    if (v < kept) body.front_reach = std::max(body.front_reach, reach_of(v));
  body.front_mapped_base = base_vertices;
  body.front_plane_counts.resize(planes.size());
  for (const int v : planed) body.front_plane_counts[static_cast<std::size_t>(v)] = planes[static_cast<std::size_t>(v)].size();
  for (std::size_t v = static_cast<std::size_t>(kept); v < planes.size(); ++v) body.front_plane_counts[v] = planes[v].size();
  body.front_planed = front.planed_base_vertices();
  // The body's and the render's triangles: the differing slots.
  body.surface.resize(slots_now);
  body.render_triangles.resize(3 * slots_now);
  body.render_cut_face.resize(slots_now, 0);
  for (const int s : differing) {
    const auto slot = static_cast<std::size_t>(s);
    if (slot >= slots_now) continue;
    body.surface[slot] = triangles[slot];
    for (std::size_t c = 0; c < 3; ++c) body.render_triangles[3 * slot + c] = static_cast<std::uint32_t>(triangles[slot][c]);
    body.render_cut_face[slot] = front.on_cut_face()[slot];
  }
  body.front_changed_slots = std::move(now_slots);
  // Which vertices only fixed particles carry: taken again for every row when the fixed
  // particles changed (orphans pinned), else for the rows mapped now, the others moved along.
  if (fixed_changed) {
    set_fixed_vertices(body);
  } else {
    body.fixed_vertices.resize(vertices.size(), 0);
    for (const auto& [v, flag] : moved_fixed_at) body.fixed_vertices[v] = flag;
    for (const int v : remap) body.fixed_vertices[static_cast<size_t>(v)] = fixed_vertex(body, v);
  }
  // Positions: on the CPU only the rows that changed (mapped, or moved with their vertex's
  // new number) are formed again, the others are those update_surface took from the same
  // particle positions; the GPU's are single precision, so all are taken again.
  if (body.gpu) {
    physics::CorotationalEfg::surface_positions(embedding, body.state.positions, body.surface_positions);
  } else {
    body.surface_positions.conservativeResize(3 * static_cast<Eigen::Index>(n));
    for (const int v : remap)
      if (v < kept) set_surface_position(body, v);
    // The stroke's vertices: the moved rows not mapped again take their position along.
    std::vector<std::uint8_t> taken(static_cast<std::size_t>(n - kept), 0);
    for (std::size_t k = 0; k < moved_from.size(); ++k) {
      const int v = moved_from[k];
      if (std::binary_search(remap.begin(), remap.end(), v) || !moved_positions[k].allFinite()) continue;
      body.surface_positions.segment<3>(3 * static_cast<Eigen::Index>(v)) = moved_positions[k];
      taken[static_cast<std::size_t>(v - kept)] = 1;
    }
    for (int v = kept; v < n; ++v)
      if (!taken[static_cast<std::size_t>(v - kept)]) set_surface_position(body, v);
  }
  stats.ms_mapping += ms_since(start);
  start = Clock::now();
  if (recount) {
    body.front_topology = physics::surface_topology(body.surface);
  } else {
    const physics::SurfaceTopology touched_edges_now = physics::surface_topology(edges_now, touched_now);
    body.front_topology.boundary_edges += touched_edges_now.boundary_edges - touched_edges_before.boundary_edges;
    body.front_topology.nonmanifold_edges += touched_edges_now.nonmanifold_edges - touched_edges_before.nonmanifold_edges;
  }
  const physics::SurfaceTopology topology = body.front_topology;
  cut_totals_.worst_boundary_edges = std::max(cut_totals_.worst_boundary_edges, topology.boundary_edges);
  cut_totals_.worst_nonmanifold_edges = std::max(cut_totals_.worst_nonmanifold_edges, topology.nonmanifold_edges);
  cut_totals_.vertices_remapped += mapping.mapped;
  cut_totals_.relaxed_fallbacks += mapping.relaxed_fallbacks;
  // Against the cut faces the surface shows: a vertex pulled a tenth of a cell inside, joined
  // to its integration point, must cross them an even number of times.
  // The crack front's vertices, where the two sides meet, belong to neither: not counted.
  // Kept per vertex and taken again where it can have changed: the remapped vertices (those
  // near what the stroke made and not remapped were just tested, their rows as they are).
  const auto& crack = front.crack_front();
  const auto counts = [&](int v) { return body.front_wrong_side[static_cast<std::size_t>(v)] != 0 && crack[static_cast<std::size_t>(v)] == 0 ? 1L : 0L; };
  for (int v = body.front_wrong_upto; v < kept; ++v) body.front_wrong_base += counts(v);
  body.front_wrong_upto = std::max(body.front_wrong_upto, kept);
  std::vector<int> across;
  if (!remap.empty()) physics::count_wrong_side(*body.efg, vertices, triangles, embedding, face_index, inset, remap, &across, on_face, &around);
  std::vector<int> tested;
  std::set_union(remap.begin(), remap.end(), near.begin(), near.end(), std::back_inserter(tested));
  for (const int v : tested) {
    if (v < kept) body.front_wrong_base -= counts(v);
    body.front_wrong_side[static_cast<std::size_t>(v)] = 0;
  }
  for (const int v : across) body.front_wrong_side[static_cast<std::size_t>(v)] = 1;
  for (const int v : crossed)
    if (!std::binary_search(remap.begin(), remap.end(), v)) body.front_wrong_side[static_cast<std::size_t>(v)] = 1;
  for (const int v : tested)
    if (v < kept) body.front_wrong_base += counts(v);
  long wrong = body.front_wrong_base;
  for (int v = kept; v < n; ++v) wrong += counts(v);
  cut_totals_.wrong_side = std::max(cut_totals_.wrong_side, wrong);
  cut_totals_.elements_linked_across = physics::update_elements_linked_across(
      *body.efg, *body.front_rest_cut, body.linked_across, dirty_lo, dirty_hi, &changed, &body.link_boxes, &body.linked_seen, &body.linked_index);
  stats.ms_checks += ms_since(start);
}

bool World::close_front_stroke(Body& body, double reach) {
  const bool carried = body.front_surface->end_stroke(reach);
  body.front_stroke_folds = 0;
  if (carried) cut_totals_.front_strokes_carried_through++;
  return carried;
}

void World::end_front_stroke(Body& body, StepStats& stats) {
  // The blade disengaged or left the body's box: the stroke ends now rather than when the
  // next one begins, its front carried through if it only stopped short at rest
  // (FrontSurface::end_stroke).
  body.front_engaged = false;
  physics::FrontSurface& front = *body.front_surface;
  if (front.stroke_samples() == 0) return;
  const auto start = Clock::now();
  // Not carried: the surface is the one shown (its stroke's vertices became base ones).
  if (!close_front_stroke(body, front.front_width())) return;
  const std::vector<std::uint8_t> unchanged(static_cast<std::size_t>(body.efg->element_count()), 0);
  rebuild_front_surface(body, body.surface_min, body.surface_max, unchanged, false, stats);
  stats.ms_topology += ms_since(start);
  stats.cut_event = true;
  cut_totals_.events++;
}

void World::cut_body(Body& body, StepStats& stats) {
  if (!body.cutter || !blade()) return;
  const auto& active = tool_.blade_active;
  if (std::find(active.begin(), active.end(), 1) == active.end()) {
    if (body.front_surface) end_front_stroke(body, stats);
    return;
  }
  // Nothing to test when the sweep's box misses the body's (with a particle spacing's margin).
  // The body's box is its particles': they lie at the corners of the particle cells that hold
  // the integration points, around the surface (which is mapped from them), and are fewer
  // than a fine surface's vertices (20k elements: 3.6k against 118k).
  physics::Vec3 lo = physics::Vec3::Constant(1e300), hi = physics::Vec3::Constant(-1e300);
  for (const auto& pose : tool_.blade_poses)
    for (const auto& p : pose) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  physics::Vec3 body_lo = physics::Vec3::Constant(1e300), body_hi = physics::Vec3::Constant(-1e300);
  for (Eigen::Index p = 0; p < body.state.positions.size() / 3; ++p) {
    body_lo = body_lo.cwiseMin(body.state.positions.segment<3>(3 * p));
    body_hi = body_hi.cwiseMax(body.state.positions.segment<3>(3 * p));
  }
  const double margin = 2 * body.efg->spacing();
  for (int axis = 0; axis < 3; ++axis)
    if (lo[axis] > body_hi[axis] + margin || hi[axis] < body_lo[axis] - margin) {
      if (body.front_surface) end_front_stroke(body, stats);
      return;
    }

  stats.cut_tested = true;
  auto topology_start = Clock::now();
  // The sweep in the rest configuration (seed 004 §2.3: topology edits are done at rest).
  // The edge is resampled every a / 2 and each point mapped through the body's local
  // deformation at its moment; moments are taken so that the blade moves at most about a / 2
  // relative to the body between two of them, and consecutive moments span quads, two
  // triangles each.
  const double a = body.efg->spacing();
  std::vector<physics::RestTriangle> triangles;
  // Front surface: the blade at rest at each mapped moment, and whether it starts a run of
  // engaged samples (a new stroke).
  std::vector<std::pair<std::vector<physics::Vec3>, bool>> moments;
  {
    const auto& edge0 = tool_.blade_poses.front();
    std::vector<int> pieces;
    for (std::size_t i = 0; i + 1 < edge0.size(); ++i)
      pieces.push_back(std::max(1, static_cast<int>(std::ceil((edge0[i + 1] - edge0[i]).norm() / (0.5 * a)))));
    // A front surface's strokes need the same points at every sample: the resampling is
    // fixed the first time (the count could flip where a segment is a multiple of a / 2).
    if (body.front_surface) {
      if (body.front_blade_pieces.size() != pieces.size()) body.front_blade_pieces = pieces;
      pieces = body.front_blade_pieces;
    }
    const auto resample = [&](const std::vector<physics::Vec3>& edge) {
      std::vector<physics::Vec3> points;
      for (std::size_t i = 0; i + 1 < edge.size(); ++i)
        for (int k = 0; k < pieces[i]; ++k) points.push_back(edge[i] + (static_cast<double>(k) / pieces[i]) * (edge[i + 1] - edge[i]));
      points.push_back(edge.back());
      return points;
    };
    // Moments of the step at which the sweep is mapped: every sample's, and more wherever
    // the blade or the body moved more than a / 2 between two of them (a static blade in a
    // falling body sweeps the body all the same).
    double body_motion = 0;
    for (Eigen::Index p = 0; p < body.state.positions.size() / 3; ++p)
      body_motion = std::max(body_motion, (body.state.positions.segment<3>(3 * p) - body.previous_positions.segment<3>(3 * p)).norm());
    physics::Vector at_fraction;
    const auto map_at = [&](std::size_t j, double f, std::vector<physics::Vec3>& rest, std::vector<double>& distance) {
      // The blade between samples j and j + 1, at the step's fraction f.
      const double f0 = tool_.blade_fractions[j], f1 = tool_.blade_fractions[j + 1];
      const double s = f1 > f0 ? std::clamp((f - f0) / (f1 - f0), 0.0, 1.0) : 0.0;
      std::vector<physics::Vec3> edge(tool_.blade_poses[j].size());
      for (std::size_t i = 0; i < edge.size(); ++i) edge[i] = tool_.blade_poses[j][i] + s * (tool_.blade_poses[j + 1][i] - tool_.blade_poses[j][i]);
      at_fraction = body.previous_positions + f * (body.state.positions - body.previous_positions);
      body.cutter->to_rest(at_fraction, resample(edge), rest, &distance);
    };
    const auto moved = [&](std::size_t j) {
      double most = 0;
      for (std::size_t i = 0; i < tool_.blade_poses[j].size(); ++i)
        most = std::max(most, (tool_.blade_poses[j + 1][i] - tool_.blade_poses[j][i]).norm());
      return most;
    };
    std::vector<physics::Vec3> rest_a, rest_b;
    std::vector<double> far_a, far_b;
    bool open = false;  // rest_a holds the sweep's last mapped moment
    for (std::size_t j = 0; j + 1 < tool_.blade_poses.size(); ++j) {
      if (!active[j]) {
        open = false;
        continue;
      }
      const double f0 = tool_.blade_fractions[j], f1 = tool_.blade_fractions[j + 1];
      if (!open) {
        map_at(j, f0, rest_a, far_a);
        open = true;
        // A stroke going on from the last step: this pose is its last sample already (the
        // same blade in the same body, only mapped to rest again after the step's topology
        // change, which moves it a little and would make the sheet waver); not sampled again.
        if (body.front_surface && (j > 0 || !body.front_engaged)) moments.emplace_back(rest_a, true);
      }
      const double relative = moved(j) + body_motion * (f1 - f0);
      const int pieces_in_time = std::max(1, static_cast<int>(std::ceil(relative / (0.5 * a))));
      // Consecutive samples that moved little are merged: only map where needed.
      const bool stretch_ends = j + 2 >= tool_.blade_poses.size() || !active[j + 1];
      if (pieces_in_time == 1 && !stretch_ends && relative < 0.25 * a) {
        // Accumulate nothing now: the next interval's quad starts from rest_a, whose moment is
        // earlier; its relative motion is bounded by the same test there.
        continue;
      }
      for (int piece = 1; piece <= pieces_in_time; ++piece) {
        map_at(j, f0 + (f1 - f0) * piece / pieces_in_time, rest_b, far_b);
        if (body.front_surface) moments.emplace_back(rest_b, false);
        for (std::size_t i = 0; i + 1 < rest_a.size(); ++i) {
          // Outside the body (every corner beyond 2a of the integration points) the mapping
          // only extrapolates: such quads are left out.
          if (std::min({far_a[i], far_a[i + 1], far_b[i], far_b[i + 1]}) > 2 * a) continue;
          triangles.push_back({rest_a[i], rest_a[i + 1], rest_b[i + 1]});
          triangles.push_back({rest_a[i], rest_b[i + 1], rest_b[i]});
        }
        rest_a.swap(rest_b);
        far_a.swap(far_b);
      }
    }
  }
  int faces = 0;
  // The thesis's surface cut: each moment is a blade sample of the stroke; a stroke ends when
  // the blade disengages or its front has left the body after cutting. It needs nothing the
  // volume's cut below makes, nor the volume anything it makes (the volume's agreement pass
  // reads the sweep at rest, front_rest_cut, filled here first), so with a helper thread
  // (Body::executor's side helper) the two run side by side.
  const auto cut_front = [&] {
    physics::FrontSurface& front = *body.front_surface;
    for (const auto& [blade_at_rest, starts_run] : moments) {
      if (starts_run && front.stroke_samples() > 1) {
        close_front_stroke(body, front.front_width());
        ++faces;
      }
      physics::FrontCutReport cut;
      try {
        cut = front.advance(blade_at_rest);
      } catch (const std::invalid_argument& error) {
        // A sample the stroke cannot take (its point count changed, a point not finite): the
        // stroke ends where it was, and this sample starts the next one.
        cut.problems.push_back(error.what());
        close_front_stroke(body, 0);
        if (std::all_of(blade_at_rest.begin(), blade_at_rest.end(), [](const physics::Vec3& p) { return p.allFinite(); }))
          front.advance(blade_at_rest);
      }
      cut_totals_.front_folded_edges += std::max(0, cut.folded_edges - body.front_stroke_folds);
      body.front_stroke_folds = cut.folded_edges;
      if (!cut.ok()) {
        cut_totals_.front_problems++;
        if (cut_totals_.first_front_problem.empty())
          cut_totals_.first_front_problem = "step " + std::to_string(steps_ + 1) + ": " + cut.problems.front();
      }
      if (cut.crossings + cut.tips > 0) ++faces;
      if (cut.ok() && cut.crossings > 0 && !cut.front_in_body) close_front_stroke(body, 0);
    }
  };
  for (const auto& t : triangles) body.front_rest_cut->add(t);
  double ms_rest = ms_since(topology_start);
  // The volume: CCD of the sweep against the links, re-selection kept consistent with the
  // rest cut around this sweep.
  physics::VolumeCutter::RestVisibility visibility;
  const physics::RestCut& rest_cut = *body.front_rest_cut;
  visibility.blocked = [&rest_cut](const physics::Vec3& a, const physics::Vec3& b) { return rest_cut.crosses(a, b); };
  visibility.lo = physics::Vec3::Constant(1e300);
  visibility.hi = physics::Vec3::Constant(-1e300);
  for (const auto& t : triangles)
    for (const auto* p : {&t.a, &t.b, &t.c}) visibility.lo = visibility.lo.cwiseMin(*p), visibility.hi = visibility.hi.cwiseMax(*p);
  visibility.lo -= physics::Vec3::Constant(2 * body.efg->spacing());
  visibility.hi += physics::Vec3::Constant(2 * body.efg->spacing());
  physics::VolumeCutReport report;
  const auto cut_volume = [&] {
    report = body.cutter->cut(tool_.blade_poses, tool_.blade_fractions, active, body.previous_positions, body.state.positions,
                              triangles.empty() ? nullptr : &visibility);
  };
  if (body.front_surface && !moments.empty()) {
    // The volume on this thread (a GPU body's context is current here), the surface on the
    // helper (or here, after the volume, if the helper has not begun it by then). The step
    // waits for the surface only when it takes longer than the volume: that wait is the
    // surface cut's share of the step (ms_rest_cut, ms_topology), its whole time ms_front_cut.
    const auto fork = Clock::now();
    double ms_volume = 0, ms_front = 0;
    const std::function<void()> volume_job = [&] {
      const auto start = Clock::now();
      cut_volume();
      ms_volume = ms_since(start);
    };
    const std::function<void()> front_job = [&] {
      const auto start = Clock::now();
      cut_front();
      ms_front = ms_since(start);
    };
    body.executor->run_beside(volume_job, front_job);
    const double wall = ms_since(fork);
    const double wait = std::max(0.0, wall - ms_volume);
    stats.ms_front_cut += ms_front;
    stats.ms_front_wait += wait;
    ms_rest += wait;
  } else {
    cut_volume();  // no surface sample to cut this step
  }
  if (body.front_surface) body.front_engaged = active.back() != 0;
  stats.ms_rest_cut += ms_rest;
  stats.ms_ccd += report.ms_ccd;
  stats.ms_reselect += report.ms_topology;
  topology_start = Clock::now();
  // Particles no element uses any more are pinned: they carry no stiffness.
  const auto& orphans = body.efg->orphaned_particles();
  for (std::size_t k = body.orphans_pinned; k < orphans.size(); ++k) {
    body.fixed[orphans[k]] = 1;
    body.state.velocities.segment<3>(3 * orphans[k]).setZero();
    body.velocity_change.segment<3>(3 * orphans[k]).setZero();
  }
  const bool pinned = orphans.size() > body.orphans_pinned;
  body.orphans_pinned = orphans.size();
  cut_totals_.orphaned_particles = static_cast<long>(orphans.size());
  cut_totals_.positive_mass_elements = body.efg->positive_mass_elements();
  cut_totals_.deactivated_elements = body.efg->deactivated_elements();
  cut_totals_.masses_floored = body.efg->masses_floored();
  const bool changed = report.any() || faces > 0;
  if (changed) {
    // The masses moved with the neighbourhoods: so does their weight.
    body.gravity = physics::gravity_forces(body.model->lumped_masses(), vec(scene_.solver.gravity));
    // Remap what the cut's new triangles hide and wherever an element was re-selected
    // (physics::remap_surface); the linked-across check takes the re-selected elements and
    // those with a link reaching into the box of this step's triangles (grown by 2 a).
    std::vector<std::uint8_t> element_changed(static_cast<std::size_t>(body.efg->element_count()), 0);
    for (int e : report.changed_elements) element_changed[e] = 1;
    rebuild_front_surface(body, visibility.lo, visibility.hi, element_changed, pinned, stats);
  }
  stats.ms_topology += ms_rest + report.ms_topology + ms_since(topology_start);
  stats.links_severed += report.particle_links_severed + report.element_links_severed + report.links_severed_at_rest;
  if (changed) {
    stats.cut_event = true;
    cut_totals_.events++;
    cut_totals_.links_severed += report.particle_links_severed + report.element_links_severed;
    cut_totals_.links_severed_at_rest += report.links_severed_at_rest;
    cut_totals_.elements_reselected += report.elements_reselected;
    cut_totals_.isolated_elements += report.elements_isolated;
    cut_totals_.nonlocal_reselections += report.elements_nonlocal;
    cut_totals_.reselection_failures += report.reselection_failures;
  }
}

void World::update_surface(Body& body) const {
  if (!body.embedding) return;  // the surface vertices are nodes
  if (body.gpu)
    body.gpu->surface_positions(*body.embedding, body.surface_positions);
  else
    physics::CorotationalEfg::surface_positions(*body.embedding, body.state.positions, body.surface_positions);
}

void World::make_gpu_backend(Body& body, std::size_t index) const {
  const std::string where = scene_.file.string() + ": solver.backend: 'gpu': ";
  if (!body.efg)
    throw std::runtime_error(where + "bodies[" + std::to_string(index) + "] ('" + body.name + "') has model '" +
                             body.model_name + "'; the GPU backend runs efg bodies only");
  physics::gpu::GpuSettings settings;
  settings.precision = scene_.solver.precision == "double" ? physics::gpu::Precision::double_precision
                                                           : physics::gpu::Precision::single;
  settings.batch_rows = scene_.solver.batch_rows;
  try {
    body.gpu = std::make_shared<physics::gpu::EfgStep>(*body.efg, settings);
    if (body.embedding) body.gpu->upload_surface(*body.embedding);
  } catch (const std::exception& e) {
    throw std::runtime_error(where + e.what());
  }
}

void World::solve_body(Body& body, const std::vector<physics::NodalSpring>& springs,
                       double end_time, StepStats& stats) {
  physics::Vector external = body.gravity;
  for (std::size_t k = 0; k < body.load_nodes.size(); ++k) {
    auto force = load_force_at(scene_.loads[body.load_index[k]], end_time);
    double total_mass = 0;
    for (int i : body.load_nodes[k]) total_mass += body.model->lumped_masses()[i];
    for (int i : body.load_nodes[k]) {
      double share = body.model->lumped_masses()[i] / total_mass;
      for (int c = 0; c < 3; ++c) external[3 * i + c] += share * force[c];
    }
  }
  const physics::Vector positions_before = body.state.positions;
  if (body.cutter) body.previous_positions = body.state.positions;
  // Non-finite guard: a step that produces a non-finite value leaves the state untouched
  // and is retried as 2, 4, ... sub-steps (dt halved each time) before giving up.
  for (int attempt = 0; attempt <= scene_.solver.max_retries; ++attempt) {
    int substeps = 1 << attempt;
    physics::ImplicitEulerSettings settings = body.integrator;
    settings.dt = body.integrator.dt / substeps;
    physics::State saved = body.state;
    physics::Vector saved_velocity_change = body.velocity_change;
    bool failed = false;
    physics::StepReport report;
    for (int s = 0; s < substeps && !failed; ++s) {
      report = body.gpu ? body.gpu->step(*body.efg, body.state, body.fixed, external, springs, settings,
                                         &body.velocity_change)
                        : physics::implicit_euler_step(*body.model, body.state, body.fixed, external, springs,
                                                       settings, &body.velocity_change);
      stats.cg_iterations += report.cg.iterations;
      stats.cg_residual = std::max(stats.cg_residual, report.cg.relative_residual);
      if (!report.cg.converged && !report.nonfinite) {
        stats.cg_converged = false;
        guard_counts_.cg_not_converged++;
        log_guard(body.name, "cg_not_converged",
                  "relative residual " + std::to_string(report.cg.relative_residual) + " after " +
                      std::to_string(report.cg.iterations) + " iterations (tolerance " +
                      std::to_string(settings.cg.tolerance) + ")");
      }
      failed = report.nonfinite;
    }
    if (!failed) {
      stats.elastic_energy += report.elastic_energy;
      stats.kinetic_energy += report.kinetic_energy;
      // Energy watchdog: implicit Euler dissipates, so the energy may grow only by the work
      // of the external and contact forces over the step. A clear excess is the signature
      // of an instability (or of a step far outside the linearisation) and is reported.
      double work = external.dot(body.state.positions - positions_before);
      for (const auto& spring : springs) {
        const physics::Vec3 moved = body.state.positions.segment<3>(3 * spring.node) -
                                    positions_before.segment<3>(3 * spring.node);
        work += spring.force.dot(moved);
        // The contact force the implicit step applied is the linearised one at the end of
        // the step, f - K dx: that is what the tissue pushes the tool with, not the larger
        // penetration force at the start of the step.
        const physics::Vec3 applied = spring.force - spring.stiffness * moved;
        for (int i = 0; i < 3; ++i) stats.tool_force[i] -= applied[i];
      }
      const double energy = report.elastic_energy + report.kinetic_energy;
      const double excess = energy - body.last_energy - std::max(work, 0.0);
      if (excess > 0.5 * body.last_energy + 1e-9) {
        stats.energy_growth_events++;
        guard_counts_.energy_growth++;
        log_guard(body.name, "energy_growth",
                  "energy " + std::to_string(body.last_energy) + " -> " + std::to_string(energy) +
                      " J with " + std::to_string(work) + " J of external work");
      }
      body.last_energy = energy;
      if (attempt > 0)
        log_guard(body.name, "nonfinite_retry",
                  "recovered with " + std::to_string(substeps) + " sub-steps of " +
                      std::to_string(settings.dt) + " s");
      return;
    }
    body.state = std::move(saved);
    body.velocity_change = std::move(saved_velocity_change);
    stats.nonfinite_events++;
    guard_counts_.nonfinite_retries++;
  }
  log_guard(body.name, "nonfinite_retry", "gave up after " + std::to_string(scene_.solver.max_retries) + " halvings");
  throw NonFiniteError("step " + std::to_string(steps_ + 1) + " (t = " + std::to_string(end_time) +
                       " s), body '" + body.name + "': non-finite values after " +
                       std::to_string(scene_.solver.max_retries) + " retries with halved dt");
}

void World::log_guard(const std::string& body, const std::string& kind, const std::string& detail) {
  if (guard_events_.size() >= kGuardLogLimit) return;
  guard_events_.push_back({steps_ + 1, static_cast<double>(steps_ + 1) * scene_.solver.dt, body, kind, detail});
}

StepStats World::step() {
  StepStats stats;
  const auto gpu_bytes = [this](bool rows) {
    long long bytes = 0;
    for (const auto& body : bodies_)
      if (body.gpu) bytes += rows ? body.gpu->counters().row_bytes : body.gpu->counters().bytes_uploaded();
    return bytes;
  };
  const long long gpu_bytes_before = gpu_bytes(false), gpu_row_bytes_before = gpu_bytes(true);
  auto start = Clock::now();
  auto phase = start;
  const double end_time = static_cast<double>(steps_ + 1) * scene_.solver.dt;
  take_tool_input(end_time);
  stats.ms_tool_input = ms_since(phase);
  // detect_cuts -> apply_topology (cuttable bodies and a blade only).
  for (auto& body : bodies_) cut_body(body, stats);
  std::vector<std::vector<physics::NodalSpring>> springs(bodies_.size());
  phase = Clock::now();
  for (std::size_t b = 0; b < bodies_.size(); ++b) springs[b] = contact(bodies_[b], stats);
  stats.ms_contact = ms_since(phase);
  phase = Clock::now();
  for (std::size_t b = 0; b < bodies_.size(); ++b) solve_body(bodies_[b], springs[b], end_time, stats);
  stats.ms_solve = ms_since(phase);
  phase = Clock::now();
  for (auto& body : bodies_) update_surface(body);
  stats.ms_surface = ms_since(phase);
  ++steps_;
  time_ = end_time;
  stats.ms_total = ms_since(start);
  stats.gpu_bytes = gpu_bytes(false) - gpu_bytes_before;
  stats.gpu_row_bytes = gpu_bytes(true) - gpu_row_bytes_before;
  return stats;
}

std::uint64_t World::state_hash() const {
  std::uint64_t hash = 1469598103934665603ull;
  auto mix = [&hash](const physics::Vector& v) {
    const auto* bytes = reinterpret_cast<const unsigned char*>(v.data());
    for (std::size_t i = 0; i < static_cast<std::size_t>(v.size()) * sizeof(double); ++i) {
      hash ^= bytes[i];
      hash *= 1099511628211ull;
    }
  };
  for (const auto& body : bodies_) {
    mix(body.state.positions);
    mix(body.state.velocities);
    mix(body.velocity_change);
  }
  return hash;
}

void World::fill_frame(render::Frame& frame, int width, int height) const {
  // The organ's capsule, and the parenchyma a cut exposes: darker and redder (sRGB).
  constexpr std::array<float, 3> skin_color{0.85f, 0.45f, 0.42f}, cut_color{0.62f, 0.17f, 0.16f};
  frame.meshes.resize(bodies_.size());
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const auto& body = bodies_[b];
    auto& mesh = frame.meshes[b];
    if (body.embedding) {
      const auto& x = body.surface_positions;
      mesh.positions.resize(static_cast<std::size_t>(x.size()));
      for (Eigen::Index i = 0; i < x.size(); ++i) mesh.positions[i] = static_cast<float>(x[i]);
    } else {
      mesh.positions.resize(body.surface_nodes.size() * 3);
      const auto& x = body.state.positions;
      for (std::size_t i = 0; i < body.surface_nodes.size(); ++i)
        for (int c = 0; c < 3; ++c)
          mesh.positions[3 * i + c] = static_cast<float>(x[3 * body.surface_nodes[i] + c]);
    }
    mesh.normals.clear();
    mesh.color = skin_color;
    // A cut surface changes its triangles, not always their count.
    if (body.front_surface || mesh.triangles.size() != body.render_triangles.size())
      mesh.triangles = body.render_triangles;
  }
  // The tissue a cut exposed, drawn apart in its own colour (after the bodies' meshes, which
  // keep their index): its triangles leave the body's mesh, its vertices are the body's.
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const auto& flags = bodies_[b].render_cut_face;
    if (std::find(flags.begin(), flags.end(), std::uint8_t{1}) == flags.end()) continue;
    render::SurfaceMesh cut;
    cut.color = cut_color;
    cut.positions = frame.meshes[b].positions;
    std::vector<std::uint32_t> skin;
    const auto& triangles = bodies_[b].render_triangles;
    for (std::size_t t = 0; t < flags.size() && 3 * t + 2 < triangles.size(); ++t) {
      auto& to = flags[t] ? cut.triangles : skin;
      const auto corner = triangles.begin() + static_cast<std::ptrdiff_t>(3 * t);
      to.insert(to.end(), corner, corner + 3);
    }
    frame.meshes[b].triangles = std::move(skin);
    frame.meshes.push_back(std::move(cut));
  }
  frame.tools.clear();
  if (blade()) {
    // The cutting edge as thin capsules, red while engaged.
    const auto& edge = tool_.blade_poses.empty() ? std::vector<physics::Vec3>{} : tool_.blade_poses.back();
    for (std::size_t i = 0; i + 1 < edge.size(); ++i) {
      render::ToolShape shape;
      shape.kind = render::ToolShape::Kind::capsule;
      for (int c = 0; c < 3; ++c) {
        shape.a[c] = static_cast<float>(edge[i][c]);
        shape.b[c] = static_cast<float>(edge[i + 1][c]);
      }
      shape.radius = static_cast<float>(tool_.radius);
      shape.engaged = (tool_.pose.buttons & 1u) != 0;
      frame.tools.push_back(shape);
    }
  } else if (tool_.present) {
    render::ToolShape shape;
    shape.kind = scene_.tool->shape == "capsule" ? render::ToolShape::Kind::capsule
                                                 : render::ToolShape::Kind::sphere;
    for (int i = 0; i < 3; ++i) {
      shape.a[i] = static_cast<float>(tool_.tip[i]);
      shape.b[i] = static_cast<float>(tool_.tail[i]);
    }
    shape.radius = static_cast<float>(tool_.radius);
    shape.engaged = (tool_.pose.buttons & 1u) != 0;
    frame.tools.push_back(shape);
  }
  const auto& r = scene_.render;
  frame.floor = r.floor;
  frame.floor_z = static_cast<float>(r.floor_z);
  if (r.camera) {
    for (int i = 0; i < 3; ++i) {
      frame.camera.eye[i] = static_cast<float>(r.camera->eye[i]);
      frame.camera.target[i] = static_cast<float>(r.camera->target[i]);
    }
    frame.camera.fov_y_deg = static_cast<float>(r.camera->fov_deg);
    float span = 0;
    for (int i = 0; i < 3; ++i)
      span = std::max(span, std::abs(frame.camera.eye[i] - frame.camera.target[i]));
    frame.camera.near_plane = span * 0.01f;
    frame.camera.far_plane = span * 20.0f;
  } else {
    std::array<float, 3> lo{}, hi{};
    for (int i = 0; i < 3; ++i) {
      lo[i] = static_cast<float>(bounds_min_[i]);
      hi[i] = static_cast<float>(bounds_max_[i]);
    }
    frame.camera = render::fit_camera(lo, hi, static_cast<float>(width) / static_cast<float>(height));
  }
}

}  // namespace incise::engine
