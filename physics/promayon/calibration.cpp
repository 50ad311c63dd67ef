#include "physics/promayon/calibration.hpp"

#include "physics/promayon/seed_step.hpp"
#include "physics/promayon/shape_memory.hpp"
#include "physics/promayon/spring_network.hpp"

#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>
#include <stdexcept>
#include <utility>

namespace incise::physics {

double apparent_modulus(PromayonKind kind, Neighbourhood neighbourhood, int cells, TripletSelection selection) {
  const HexMesh mesh = make_box_hexes(Vec3::Zero(), Vec3::Constant(cells), {cells, cells, cells});
  const auto neighbours = lattice_neighbours(mesh, neighbourhood);
  const Vector masses = Vector::Ones(static_cast<Eigen::Index>(mesh.rest.size() / 3));
  std::unique_ptr<DeformableModel> model;
  if (kind == PromayonKind::shape_memory)
    model = std::make_unique<ShapeMemory>(mesh.rest, neighbours, masses, 1.0, 1.0, selection);
  else
    model = std::make_unique<SpringNetwork>(mesh.rest, neighbours, masses, 1.0, 0.0, 1.0);
  const double strain = 1e-3;
  const int n = model->node_count();
  std::vector<std::uint8_t> fixed(static_cast<std::size_t>(n), 0);
  State state{mesh.rest, Vector::Zero(mesh.rest.size())};
  std::vector<int> top;
  for (int i = 0; i < n; ++i) {
    const double z = mesh.rest[3 * i + 2];
    if (z < 1e-9) fixed[static_cast<std::size_t>(i)] = 1;
    if (z > cells - 1e-9) {
      fixed[static_cast<std::size_t>(i)] = 1;
      top.push_back(i);
      state.positions[3 * i + 2] -= strain * cells;
    }
  }
  // Dynamic relaxation: unit masses, a step well inside the explicit limit, damping near the
  // lowest mode's critical value.
  SeedStepSettings settings{0.1, 0.5, 0, SeedScheme::symplectic_euler};
  const Vector zero = Vector::Zero(state.positions.size());
  for (int it = 0; it < 200000; ++it) {
    seed_explicit_step(*model, state, fixed, zero, {}, settings, nullptr, 0);
    if (it % 200 != 199) continue;
    Vector f = Vector::Zero(state.positions.size());
    model->add_elastic_forces(state.positions, f);
    double residual = 0;
    for (int i = 0; i < n; ++i)
      if (!fixed[static_cast<std::size_t>(i)]) residual = std::max(residual, f.segment<3>(3 * i).norm());
    if (residual < 1e-13 && state.velocities.norm() < 1e-12) {
      double force = 0;  // the plate's push: minus the elastic forces on the top atoms
      for (int i : top) force -= f[3 * i + 2];
      return -force / (static_cast<double>(cells) * cells * strain);
    }
  }
  throw std::runtime_error("calibration: the block did not settle");
}

double calibration_constant(PromayonKind kind, Neighbourhood neighbourhood, TripletSelection selection) {
  static std::mutex mutex;
  static std::map<std::tuple<int, int, int>, double> cache;
  const std::lock_guard lock(mutex);
  if (kind == PromayonKind::spring_network) selection = TripletSelection::all;
  const auto key = std::make_tuple(static_cast<int>(kind), static_cast<int>(neighbourhood), static_cast<int>(selection));
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  const double c = apparent_modulus(kind, neighbourhood, 4, selection);
  if (!(c > 0)) throw std::runtime_error("calibration: non-positive apparent modulus");
  cache[key] = c;
  return c;
}

double stiffness_from_youngs_modulus(PromayonKind kind, Neighbourhood neighbourhood, double youngs_modulus,
                                     double spacing, TripletSelection selection) {
  return youngs_modulus * spacing / calibration_constant(kind, neighbourhood, selection);
}

}  // namespace incise::physics
