#include "physics/promayon/truth_cube.hpp"

#include "physics/fem/static_solve.hpp"
#include "physics/fem/tet_mesh.hpp"
#include "physics/promayon/lattice.hpp"
#include "physics/promayon/seed_step.hpp"
#include "physics/promayon/shape_memory.hpp"
#include "physics/promayon/spring_network.hpp"

#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

namespace incise::physics {

TruthCube::TruthCube()
    : mesh_(make_box_hexes(Vec3::Zero(), Vec3::Constant(kCells), {kCells, kCells, kCells})) {
  const int n = static_cast<int>(mesh_.rest.size() / 3);
  fixed_.assign(static_cast<std::size_t>(n), 0);
  start_ = mesh_.rest;
  for (int i = 0; i < n; ++i) {
    const double z = mesh_.rest[3 * i + 2];
    if (z < 0.5) fixed_[static_cast<std::size_t>(i)] = 1;
    if (z > kCells - 0.5) {
      fixed_[static_cast<std::size_t>(i)] = 1;
      start_[3 * i + 2] -= kCompression * kCells;
    }
  }
  surface_ = hex_boundary_triangles(mesh_.hexes);
  rest_volume_ = closed_volume(mesh_.rest, surface_);
}

bool TruthCube::interior(int i) const {
  for (int c = 0; c < 3; ++c)
    if (mesh_.rest[3 * i + c] < 0.5 || mesh_.rest[3 * i + c] > kCells - 0.5) return false;
  return true;
}

Vector TruthCube::fem_reference(int fem_cells, double poisson_ratio) const {
  if (fem_cells < 4 || fem_cells % 4 != 0)
    throw std::invalid_argument("TruthCube: the FEM needs a multiple of 4 cells (got " + std::to_string(fem_cells) + ")");
  const QuadraticTetMesh fem =
      make_box_quadratic_tets(Vec3::Zero(), Vec3::Constant(kCells), {fem_cells, fem_cells, fem_cells});
  const double nodes_per_unit = 2.0 * fem_cells / kCells;  // quadratic: two node spacings per cell
  const int side = 2 * fem_cells + 1;
  const double half_spacing = 0.5 / nodes_per_unit;
  const auto index = [&](const Vec3& p) {
    const auto c = [&](int k) { return std::lround(nodes_per_unit * p[k]); };
    return static_cast<int>(c(0) + side * (c(1) + side * c(2)));
  };
  const auto nodes = static_cast<std::size_t>(fem.rest.size() / 3);
  std::vector<std::uint8_t> fixed(nodes, 0);
  Vector prescribed = Vector::Zero(fem.rest.size());
  for (std::size_t i = 0; i < nodes; ++i) {
    const double z = fem.rest[static_cast<Eigen::Index>(3 * i + 2)];
    if (z < half_spacing) fixed[i] = 1;
    if (z > kCells - half_spacing) {
      fixed[i] = 1;
      prescribed[static_cast<Eigen::Index>(3 * i + 2)] = -kCompression * kCells;
    }
  }
  const Material material{1.0, poisson_ratio, 1.0};
  const Vector u = solve_static_quadratic(fem, material, fixed, prescribed, Vec3::Zero(), Vector());
  Vector out = mesh_.rest;
  for (Eigen::Index i = 0; i < out.size() / 3; ++i) {
    const int f = index(mesh_.rest.segment<3>(3 * i));
    if ((fem.rest.segment<3>(3 * f) - mesh_.rest.segment<3>(3 * i)).norm() > 1e-9)
      throw std::logic_error("TruthCube: atom " + std::to_string(i) + " is not an FEM node");
    out.segment<3>(3 * i) += u.segment<3>(3 * f);
  }
  return out;
}

CompressionResult truth_cube_error(const TruthCube& cube, const Vector& positions, const Vector& reference) {
  CompressionResult r;
  std::vector<double> e;
  const Vector& rest = cube.mesh().rest;
  for (int i = 0; i < static_cast<int>(rest.size() / 3); ++i)
    if (cube.interior(i))
      e.push_back((positions.segment<3>(3 * i) - reference.segment<3>(3 * i)).norm() /
                  (rest.segment<3>(3 * i) - reference.segment<3>(3 * i)).norm());
  for (double v : e) r.error += v / static_cast<double>(e.size());
  for (double v : e) r.spread += (v - r.error) * (v - r.error) / static_cast<double>(e.size());
  r.spread = std::sqrt(r.spread);
  r.volume_change = closed_volume(positions, cube.surface()) / cube.rest_volume() - 1;
  r.positions = positions;
  return r;
}

CompressionResult relax_truth_cube(const TruthCube& cube, const Vector& reference, const TruthCubeModel& spec) {
  const HexMesh& mesh = cube.mesh();
  const Vector masses = Vector::Ones(mesh.rest.size() / 3);
  const auto neighbours = lattice_neighbours(mesh, spec.neighbourhood);
  std::unique_ptr<DeformableModel> model;
  long long elements = 0;
  if (spec.kind == PromayonKind::shape_memory) {
    auto sm = std::make_unique<ShapeMemory>(mesh.rest, neighbours, masses, 1, 1, spec.selection);
    elements = static_cast<long long>(sm->triplet_count());
    model = std::move(sm);
  } else {
    auto network = std::make_unique<SpringNetwork>(mesh.rest, neighbours, masses, 1, 0, 1);
    elements = static_cast<long long>(network->springs().size());
    model = std::move(network);
  }
  const double damping = spec.kind == PromayonKind::shape_memory ? 0.1 : 0.3;
  VolumeControl volume;
  volume.triangles = cube.surface();
  volume.rest_volume = cube.rest_volume();
  State state{cube.start(), Vector::Zero(cube.start().size())};
  const Vector zero = Vector::Zero(cube.start().size());
  const SeedStepSettings settings{0.2, damping, 0, SeedScheme::symplectic_euler};
  if (spec.volume_control)  // start on the constraint: the plates' move changed the volume
    project_volume(state.positions, volume.triangles, cube.fixed(), volume.rest_volume);
  int steps = 1;
  bool settled = false;
  for (; steps <= 200000; ++steps) {
    seed_explicit_step(*model, state, cube.fixed(), zero, {}, settings, spec.volume_control ? &volume : nullptr, 0);
    if (state.velocities.cwiseAbs().maxCoeff() < 1e-9) {
      settled = true;
      break;
    }
  }
  CompressionResult r = truth_cube_error(cube, state.positions, reference);
  r.steps = steps;
  r.settled = settled;
  r.elements = elements;
  return r;
}

}  // namespace incise::physics
