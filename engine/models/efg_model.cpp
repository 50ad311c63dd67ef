// The meshless corotational EFG model (physics/efg/corotational_efg.hpp, seed 004): particles
// on a grid, integration cubes over the shape, a render surface embedded in it. Its settings
// block is `efg` (BodySpec::efg); it can be cut (the cut's state is made here for a cuttable
// body) and runs on the GPU backend (physics/gpu/efg_step.hpp steps its CorotationalEfg).
#include "engine/body_builder.hpp"
#include "engine/mesh_import.hpp"
#include "engine/models/efg_settings.hpp"
#include "engine/model_registry.hpp"
#include "physics/core/contact.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/cut/voxel_boundary.hpp"
#include "physics/efg/efg_static.hpp"
#include "physics/fem/static_solve.hpp"

#include <stdexcept>
#include <string>
#include <vector>

namespace incise::engine {

namespace {

// The render surface of a meshless body: the imported mesh itself, or (generated bodies) the
// boundary of a voxel fill at surface_resolution (default a / 2, finer than the integration
// grid as seed-004 §2.6 requires), snapped onto the true surface.
void make_render_surface(physics::BodyModel& model, physics::BodyData& body, const BodySpec& spec, const BodyShape& shape,
                         physics::Vector& rest_vertices) {
  if (spec.mesh) {
    // The surface body_shape read (the file is read once per build).
    if (!shape.surface) throw std::logic_error("a mesh body's shape carries no surface");
    const TriangleSoup& soup = *shape.surface;
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
    physics::fair_surface_onto_shape(faired, body.surface, shape.inside, resolution, 3, shape.along);
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

// The mesh's own triangles as a cut surface, and their mean edge length (the cut face's
// triangles are made about as wide: CutModel::surface_cell). They are counter-clockwise seen
// from outside, as the front wants: a file wound inward has a winding number of -1 inside and
// was refused by the shape as having no interior.
physics::TriangleSurface mesh_surface(const TriangleSoup& soup, double& mean_edge) {
  physics::TriangleSurface surface;
  surface.vertices.reserve(soup.vertices.size());
  for (const auto& v : soup.vertices) surface.vertices.push_back(physics::Vec3(v[0], v[1], v[2]));
  surface.triangles = soup.triangles;
  double sum = 0;
  for (const auto& t : surface.triangles)
    for (int k = 0; k < 3; ++k) sum += (surface.vertices[t[k]] - surface.vertices[t[(k + 1) % 3]]).norm();
  mean_edge = surface.triangles.empty() ? 0 : sum / (3.0 * static_cast<double>(surface.triangles.size()));
  return surface;
}

// A cuttable body's cut state. Its first surface is the voxel boundary at the surface
// resolution put onto the shape (no element carries this surface, so its vertices go onto the
// shape and even out along it; the voxel snap stops short where its tetrahedra would flatten),
// or with `base_surface: mesh` the mesh's own triangles: an edge thinner than a surface cell
// keeps the mesh's shape rather than a voxel boundary faired onto it (serrated).
void make_cut(Body& result, const physics::BodyModel& model, const BodySpec& spec, const BodyShape& shape) {
  auto cut_model = std::make_shared<physics::CutModel>();
  cut_model->spacing = spec.resolution;
  cut_model->surface_cell = spec.efg.surface_resolution.value_or(0.5 * spec.resolution);
  physics::Stopwatch watch;
  physics::TriangleSurface initial;
  if (spec.efg.base_surface_mesh) {
    if (!shape.surface) throw std::logic_error("a mesh body's shape carries no surface");
    double mean_edge = 0;
    initial = mesh_surface(*shape.surface, mean_edge);
    if (!spec.efg.surface_resolution) cut_model->surface_cell = mean_edge;
  } else {
    initial = physics::voxel_boundary(shape.inside, shape.lo, shape.hi, cut_model->surface_cell);
    physics::fair_surface_onto_shape(initial.vertices, initial.triangles, shape.inside, cut_model->surface_cell, 3,
                                     shape.along);
  }
  result.build_ms.surface = watch.ms();
  watch.restart();
  result.cut = std::make_unique<physics::CutData>(
      physics::make_cut_data(model, result.data, *cut_model, std::move(initial.vertices), std::move(initial.triangles),
                             &shape.inside));
  result.cut_model = std::move(cut_model);
  result.build_ms.cut = watch.ms();
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
    physics::Stopwatch watch;
    auto efg = std::make_unique<physics::CorotationalEfg>(shape.inside, shape.lo, shape.hi, material, efg_settings(spec),
                                                          result.executor.get());
    body.efg = efg.get();
    body.mechanics = std::move(efg);
    result.build_ms.volume = watch.ms();
    watch.restart();
    if (spec.cuttable) {
      make_cut(result, *model, spec, shape);
    } else {
      make_render_surface(*model, body, spec, shape, rest_vertices);
      result.build_ms.surface = watch.ms();
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  const physics::CorotationalEfg& efg = *body.efg;
  model->elements = static_cast<std::size_t>(efg.element_count());
  // Each vertex follows a point it sees through the body: a thin fin's vertex beside another
  // part across a narrow gap takes no point on that part (CorotationalEfg::embed_surface).
  if (!body.embedding) body.embedding = efg.embed_surface(rest_vertices, &shape.inside);
  start_at_rest(body);
  fix_nodes(body, spec, efg.rest_positions());
  body.gravity = physics::gravity_forces(efg.lumped_masses(), model->gravity);
  settle_if_asked(result, solver, where, [&] {
    return physics::solve_static(physics::assemble_stiffness(efg), body.gravity, body.fixed);
  });
  physics::set_fixed_vertices(body);
  physics::CorotationalEfg::surface_positions(*body.embedding, body.state.positions, body.surface_positions);
  if (result.cut) result.cut->previous_positions = body.state.positions;
  result.model = std::move(model);
  return result;
}

}  // namespace

void register_efg_model(ModelRegistry& registry) {
  registry.add({.name = "efg",
                .summary = "meshless corotational element-free Galerkin",
                .cuttable = true,
                .gpu = true,
                .node_name = "particle",
                .read_settings = read_efg_settings,
                .build = build_efg_body});
}

}  // namespace incise::engine
