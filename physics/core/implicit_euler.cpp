#include "physics/core/implicit_euler.hpp"

#include "physics/core/extra_stiffness.hpp"
#include "physics/core/stopwatch.hpp"
#include "physics/solve/bicgstab.hpp"
#include "physics/solve/current_system.hpp"
#include "physics/solve/current_vcycle.hpp"
#include "physics/solve/multigrid.hpp"
#include "physics/solve/rest_vcycle.hpp"
#include "physics/solve/warped_preconditioner.hpp"

#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace incise::physics {

namespace {

using Index = Eigen::Index;

// out = M p with M the lumped (diagonal) mass, 3 entries per node.
void multiply_mass(const Vector& masses, const Vector& p, Vector& out) {
  for (Index node = 0; node < masses.size(); ++node) {
    out.segment<3>(3 * node) = masses[node] * p.segment<3>(3 * node);
  }
}

// out += K_springs p.
void add_spring_product(std::span<const NodalSpring> springs, const Vector& p, Vector& out) {
  for (const NodalSpring& spring : springs) {
    out.segment<3>(3 * spring.node) += spring.stiffness * p.segment<3>(3 * spring.node);
  }
}

void check_inputs(const DeformableModel& model, const State& state,
                  const std::vector<uint8_t>& fixed_nodes, const Vector& external_forces,
                  std::span<const NodalSpring> springs, const ImplicitEulerSettings& settings) {
  const int nodes = model.node_count();
  const Index size = 3 * static_cast<Index>(nodes);
  auto fail = [](const std::string& what) {
    throw std::invalid_argument("implicit_euler_step: " + what);
  };
  if (state.positions.size() != size || state.velocities.size() != size) {
    fail("state has " + std::to_string(state.positions.size()) + " positions and " +
         std::to_string(state.velocities.size()) + " velocities, the model needs " +
         std::to_string(size));
  }
  if (external_forces.size() != size) {
    fail("external_forces has " + std::to_string(external_forces.size()) + " entries, expected " +
         std::to_string(size));
  }
  if (!fixed_nodes.empty() && static_cast<int>(fixed_nodes.size()) != nodes) {
    fail("fixed_nodes has " + std::to_string(fixed_nodes.size()) + " entries, expected " +
         std::to_string(nodes));
  }
  for (const NodalSpring& spring : springs) {
    if (spring.node < 0 || spring.node >= nodes) {
      fail("spring node " + std::to_string(spring.node) + " outside [0, " + std::to_string(nodes) +
           ")");
    }
  }
  if (!(settings.dt > 0.0)) fail("dt must be positive");
}

// The diagonal of A = m_coefficient M + k_coefficient K (the springs' included) + d_coefficient D
// (a model's own dashpots, where it has them) + d_coefficient^2 K_extra (where it has one: the
// step's d_coefficient is dt).
Vector jacobi_diagonal(const DeformableModel& model, std::span<const NodalSpring> springs, const Vector& masses,
                       double mass_coefficient, double stiffness_coefficient, double damping_coefficient) {
  Vector stiffness_diagonal = Vector::Zero(3 * masses.size());
  model.add_stiffness_diagonal(stiffness_diagonal);
  for (const NodalSpring& spring : springs) {
    stiffness_diagonal.segment<3>(3 * spring.node) += spring.stiffness.diagonal();
  }
  Vector diagonal(3 * masses.size());
  for (Index node = 0; node < masses.size(); ++node) {
    diagonal.segment<3>(3 * node) = mass_coefficient * masses[node] * Vec3::Ones() +
                                    stiffness_coefficient * stiffness_diagonal.segment<3>(3 * node);
  }
  if (model.has_damping() && damping_coefficient != 0) {
    Vector damping_diagonal = Vector::Zero(diagonal.size());
    model.add_damping_diagonal(damping_diagonal);
    diagonal += damping_coefficient * damping_diagonal;
  }
  if (const ExtraStiffness* extra_part = extra_stiffness(model)) {
    Vector extra = Vector::Zero(diagonal.size());
    extra_part->add_extra_stiffness_diagonal(extra);
    diagonal += damping_coefficient * damping_coefficient * extra;
  }
  return diagonal;
}

// Jacobi-preconditioned BiCGSTAB, for a model whose extra stiffness is not symmetric.
CgResult nonsymmetric_solve(const DeformableModel& model, std::span<const NodalSpring> springs, const Vector& masses,
                            double mass_coefficient, double stiffness_coefficient, double dt,
                            const LinearOperator& apply,
                            const Vector& right_hand_side, const std::vector<uint8_t>& fixed_nodes,
                            Vector& velocity_change, const CgSettings& settings) {
  const Vector inverse =
      jacobi_inverse(jacobi_diagonal(model, springs, masses, mass_coefficient, stiffness_coefficient, dt));
  const Preconditioner jacobi = [&](const Vector& r, Vector& out) { out = inverse.cwiseProduct(r); };
  return bicgstab(apply, right_hand_side, jacobi, fixed_nodes, velocity_change, settings);
}

// CG preconditioned with that diagonal.
CgResult jacobi_solve(const DeformableModel& model, std::span<const NodalSpring> springs, const Vector& masses,
                      double mass_coefficient, double stiffness_coefficient, double damping_coefficient,
                      const LinearOperator& apply,
                      const Vector& right_hand_side, const std::vector<uint8_t>& fixed_nodes, Vector& velocity_change,
                      const CgSettings& settings) {
  const Vector diagonal =
      jacobi_diagonal(model, springs, masses, mass_coefficient, stiffness_coefficient, damping_coefficient);
  return conjugate_gradient(apply, right_hand_side, diagonal, fixed_nodes, velocity_change, settings);
}

// CG preconditioned with a rest factor warped by the node rotations: the whole factor, the
// additive two-level (a coarse factor plus Jacobi, which takes what the coarse grid cannot
// represent), or the rest system's V-cycle (physics/solve/multigrid.hpp) warped likewise.
CgResult rest_factor_solve(const DeformableModel& model, const RestFactor& factor, const LinearOperator& apply,
                           const Vector& inverse_diagonal, const Vector& right_hand_side,
                           const std::vector<uint8_t>& fixed_nodes, Vector& velocity_change, const CgSettings& settings) {
  std::vector<Eigen::Quaterniond> rotations;
  model.node_rotations(rotations);
  if (factor.smoothing_degree() > 0) {
    // M^-1 = R V0 R^T, V0 the V-cycle of the rest system A0 = R^T A R's approximation: its
    // smoother multiplies by the assembled A0 (block CSR, several times cheaper than the
    // matrix-free A), and V0 is a fixed SPD operator, so M^-1 is SPD whatever the rotations.
    // The Chebyshev interval's top is over the Lanczos estimate of A0's own D0^-1 A0, which
    // approaches it from below.
    // RestVcycle fuses the warps and the Chebyshev recurrences into the cycle's passes.
    ChebyshevSmoother smoother;
    smoother.degree = factor.smoothing_degree();
    smoother.upper = 1.05 * factor.smoothing_eigenvalue();
    RestVcycle vcycle(factor, rotations, smoother, model.executor());
    const Preconditioner cycle = [&](const Vector& r, Vector& z) { vcycle(r, z); };
    return preconditioned_conjugate_gradient(apply, right_hand_side, cycle, fixed_nodes, velocity_change, settings);
  }
  Vector coarse(right_hand_side.size());
  const Preconditioner warped = [&](const Vector& r, Vector& z) {
    if (!factor.coarse()) return warped_solve(factor, rotations, r, z);
    warped_solve(factor, rotations, r, coarse);
    z = inverse_diagonal.cwiseProduct(r) + coarse;
  };
  return preconditioned_conjugate_gradient(apply, right_hand_side, warped, fixed_nodes, velocity_change, settings);
}

// CG on the assembled current system A, preconditioned with the V-cycle of A itself: its
// Chebyshev smoother on D^-1 A and the rest factor's coarse correction warped by the node
// rotations, C = R P (P^T A0 P)^-1 P^T R^T. D is A's 3x3 node blocks where the factor
// estimated B0^-1 A0's top (a multigrid_current factor, jacobi_scaling.hpp), else A's
// diagonal, whose interval ends at 1.2 x the rest build's largest eigenvalue of D0^-1 A0:
// turning the nodes' blocks moves D's entries and with them the top of D^-1 A (+9 % on a ball
// bent by 0.6 rad, test_current_vcycle), and the Chebyshev step contracts only up to
// (1 + 1/ratio) x its interval's top. S and C symmetric
// make M^-1 symmetric, and SPD while the smoother contracts (multigrid.hpp). The cycle's
// products are float products on K's paired float copy (paired_blocks.hpp: half the
// instructions of a double product): M^-1 is then symmetric to float round-off, as good a
// preconditioner (the iterations did not move). CG's own product is the same float product,
// its convergence confirmed on the double system (preconditioned_conjugate_gradient's
// `exact`): a residual above the tolerance on the double system restarts CG from it (2 of the
// quick performance bench's 400 solves).
constexpr double current_smoothing_margin = 1.2;
// With the node blocks' scaling (jacobi_scaling.hpp) the rest estimate bounds the current top
// closely: over every shipped scene's replay the current top (100 power steps, every tenth
// solve) stayed within 0.993-1.0012 of it, the bent, turned test ball 1.0004. The Chebyshev
// step contracts up to upper (1 + 1 / ratio), so 1.05 covers 1.085 of the estimate. Less
// margin, fewer iterations: `bench performance --quick`, the 20248 lobe's mean 6.20 at 1.1, 6.12
// at 1.05.
constexpr double node_block_smoothing_margin = 1.05;
// Above this size of K's single-precision copy the smoother reads its halves
// (CycleEntries::half_smoother): the products are bound by memory there (a copy several times
// the second-level caches: 16 MB at 75k EFG elements), and the iterations do not move with the
// smoother's entries rounded to 11 bits. CG's product keeps the single-precision entries.
constexpr std::size_t half_smoother_bytes = std::size_t{8} << 20;

CgResult current_vcycle_solve(const DeformableModel& model, const RestFactor& factor, const LinearOperator& apply,
                              const CurrentSystem& system, const Vector& right_hand_side,
                              const std::vector<uint8_t>& fixed_nodes, Vector& velocity_change, const CgSettings& settings) {
  std::vector<Eigen::Quaterniond> rotations;
  model.node_rotations(rotations);
  ChebyshevSmoother smoother;
  smoother.degree = factor.smoothing_degree();
  smoother.upper = current_smoothing_margin * factor.smoothing_eigenvalue();
  if (factor.node_block_eigenvalue() > 0) {
    smoother.node_blocks = true;
    smoother.upper = node_block_smoothing_margin * factor.node_block_eigenvalue();
  }
  // The paired copy's storage stays with the stepping thread from step to step
  // (PairedBlocks::build).
  thread_local PairedBlocks workspace;
  const CycleEntries entries = PairedBlocks::single_bytes(system.rows(), system.nodes()) > half_smoother_bytes
                                   ? CycleEntries::half_smoother
                                   : CycleEntries::single;
  CurrentVcycle vcycle(system, factor, rotations, smoother, model.executor(), entries, &workspace);
  const Preconditioner cycle = [&](const Vector& r, Vector& z) { vcycle(r, z); };
  if (!vcycle.single_precision())
    return preconditioned_conjugate_gradient(apply, right_hand_side, cycle, fixed_nodes, velocity_change, settings);
  const LinearOperator rounded = [&](const Vector& p, Vector& out) { vcycle.multiply(p, out); };
  return preconditioned_conjugate_gradient(rounded, right_hand_side, cycle, fixed_nodes, velocity_change, settings, &apply);
}

// v' = v + dv and x' = x + dt v', the fixed nodes at rest where they are; false when either is
// not finite.
bool advance(const State& state, const Vector& velocity_change, const std::vector<uint8_t>& fixed_nodes, double dt,
             Vector& velocities, Vector& positions) {
  velocities = state.velocities + velocity_change;
  for (size_t node = 0; node < fixed_nodes.size(); ++node) {
    if (fixed_nodes[node] != 0) velocities.segment<3>(3 * static_cast<Index>(node)).setZero();
  }
  positions = state.positions + dt * velocities;
  if (!velocities.allFinite() || !positions.allFinite()) return false;
  // Fixed nodes keep their position bitwise (x + dt * 0 already equals x, kept explicit).
  for (size_t node = 0; node < fixed_nodes.size(); ++node) {
    if (fixed_nodes[node] != 0) {
      const Index offset = 3 * static_cast<Index>(node);
      positions.segment<3>(offset) = state.positions.segment<3>(offset);
    }
  }
  return true;
}

}  // namespace

bool assembles_current_stiffness(const DeformableModel& model) {
  return model.has_current_stiffness() && !model.has_damping() && !extra_stiffness(model);
}

Vector gravity_forces(const Vector& lumped_masses, const Vec3& g) {
  Vector forces(3 * lumped_masses.size());
  for (Index node = 0; node < lumped_masses.size(); ++node) {
    forces.segment<3>(3 * node) = lumped_masses[node] * g;
  }
  return forces;
}

double kinetic_energy(const Vector& lumped_masses, const Vector& velocities) {
  double energy = 0;
  for (Index node = 0; node < lumped_masses.size(); ++node) {
    energy += 0.5 * lumped_masses[node] * velocities.segment<3>(3 * node).squaredNorm();
  }
  return energy;
}

StepReport implicit_euler_step(DeformableModel& model, State& state,
                               const std::vector<uint8_t>& fixed_nodes,
                               const Vector& external_forces, std::span<const NodalSpring> springs,
                               const ImplicitEulerSettings& settings,
                               WarmStart* warm_start, const RestFactor* rest_factor) {
  check_inputs(model, state, fixed_nodes, external_forces, springs, settings);
  StepReport report;
  const Index size = state.positions.size();
  const Vector& masses = model.lumped_masses();
  const double dt = settings.dt;
  const double alpha = settings.rayleigh_mass;
  const double beta = settings.rayleigh_stiffness;

  model.update_rotations(state.positions);

  const bool damped = model.has_damping();
  const ExtraStiffness* extra = extra_stiffness(model);
  // The assembled current stiffness K(x) (settings.assembled_system; it holds K only), read by
  // the right-hand side's K v and by every product of the solve.
  const BlockMatrix* current = nullptr;
  if (settings.assembled_system && assembles_current_stiffness(model)) {
    const Stopwatch assembly;
    current = model.current_stiffness();
    report.assembly_ms = assembly.ms();
  }
  Executor& executor = model.executor();

  // Right-hand side: dt [f(x) - (dt + beta) K v - alpha M v]. With K assembled, K v is one
  // product on it and the model gives the forces alone: its matrix-free K v would visit every
  // integration point's neighbourhood a second time.
  Vector forces = external_forces;
  Vector stiffness_velocity = Vector::Zero(size);
  if (current) {
    model.add_elastic_forces(state.positions, forces);
    const std::vector<uint8_t> nothing_fixed;  // (CurrentSystem keeps a reference)
    const CurrentSystem stiffness_alone(*current, masses, nothing_fixed, {}, 0.0, 1.0);
    stiffness_alone.multiply(state.velocities, stiffness_velocity, executor);
  } else {
    model.add_forces_and_stiffness_product(state.positions, forces, state.velocities, stiffness_velocity);
  }
  for (const NodalSpring& spring : springs) forces.segment<3>(3 * spring.node) += spring.force;
  add_spring_product(springs, state.velocities, stiffness_velocity);
  Vector mass_velocity(size);
  multiply_mass(masses, state.velocities, mass_velocity);

  Vector right_hand_side =
      dt * (forces - (dt + beta) * stiffness_velocity - alpha * mass_velocity);
  // The model's own dashpots, -D v, implicit like the rest: A gains dt D.
  Vector damping_p;
  if (damped) {
    Vector damping_velocity = Vector::Zero(size);
    model.add_damping_product(state.velocities, damping_velocity);
    right_hand_side -= dt * damping_velocity;
    damping_p.resize(size);
  }
  // The model's extra stiffness (has_extra_stiffness), in the force's linearisation only:
  // f(x + dt v') ~ f(x) - dt K_extra v', so A gains dt^2 K_extra and the right -dt^2 K_extra v
  // (Rayleigh's beta K stays on K).
  Vector extra_p;
  if (extra) {
    Vector extra_velocity = Vector::Zero(size);
    extra->add_extra_stiffness_product(state.velocities, extra_velocity);
    right_hand_side -= dt * dt * extra_velocity;
    extra_p.resize(size);
  }
  if (!right_hand_side.allFinite()) {
    report.nonfinite = true;
    return report;
  }

  // System matrix A = m_coefficient M + k_coefficient K.
  const double mass_coefficient = 1.0 + dt * alpha;
  const double stiffness_coefficient = dt * beta + dt * dt;
  Vector stiffness_p(size);
  const LinearOperator apply = [&](const Vector& p, Vector& out) {
    multiply_mass(masses, p, out);
    out *= mass_coefficient;
    stiffness_p.setZero();
    model.add_stiffness_product(p, stiffness_p);
    add_spring_product(springs, p, stiffness_p);
    out += stiffness_coefficient * stiffness_p;
    if (damped) {
      damping_p.setZero();
      model.add_damping_product(p, damping_p);
      out += dt * damping_p;
    }
    if (extra) {
      extra_p.setZero();
      extra->add_extra_stiffness_product(p, extra_p);
      out += dt * dt * extra_p;
    }
  };

  // The assembled current system, which then replaces `apply`.
  std::optional<CurrentSystem> system;
  if (current) system.emplace(*current, masses, fixed_nodes, springs, mass_coefficient, stiffness_coefficient);
  const LinearOperator assembled_apply = [&](const Vector& p, Vector& out) { system->multiply(p, out, executor); };
  const LinearOperator& product = system ? assembled_apply : apply;

  // CG starts from the last steps' solutions (warm_start.hpp); BiCGSTAB's non-symmetric
  // system, with no A-norm to combine them in, from the newest alone.
  const bool symmetric = !(extra && !extra->extra_stiffness_symmetric());
  Vector velocity_change = warm_start ? warm_start->newest(size) : Vector::Zero(size);
  CgSettings cg_settings = settings.cg;
  if (warm_start && symmetric) cg_settings.start_space = warm_start->older(size);
  // The start's products on the assembled system in one pass (every path below that has the
  // system starts CG with its product).
  if (system && !cg_settings.start_space.empty())
    cg_settings.start_products = [&](std::span<const Vector> p, std::span<Vector> out) { system->multiply_several(p, out, executor); };
  if (!symmetric) {
    // No rest factor here: its warped preconditioners are built for CG's SPD systems.
    report.cg = nonsymmetric_solve(model, springs, masses, mass_coefficient, stiffness_coefficient, dt, apply,
                                   right_hand_side, fixed_nodes, velocity_change, cg_settings);
  } else if (system && rest_factor && rest_factor->size() == size && rest_factor->smoothing_degree() > 0) {
    report.cg = current_vcycle_solve(model, *rest_factor, product, *system, right_hand_side, fixed_nodes, velocity_change,
                                     cg_settings);
  } else if (rest_factor && rest_factor->size() == size && rest_factor->serves_rest_cycles()) {
    // The additive two-level's fine part (the V-cycle smooths with the rest system's own).
    const Vector inverse_diagonal =
        rest_factor->coarse() && rest_factor->smoothing_degree() == 0
            ? jacobi_inverse(jacobi_diagonal(model, springs, masses, mass_coefficient, stiffness_coefficient, dt))
            : Vector();
    report.cg = rest_factor_solve(model, *rest_factor, product, inverse_diagonal, right_hand_side, fixed_nodes,
                                  velocity_change, cg_settings);
  } else {
    report.cg = jacobi_solve(model, springs, masses, mass_coefficient, stiffness_coefficient, dt, product, right_hand_side,
                             fixed_nodes, velocity_change, cg_settings);
  }
  if (report.cg.nonfinite) {
    report.nonfinite = true;
    return report;
  }

  Vector velocities, positions;
  if (!advance(state, velocity_change, fixed_nodes, dt, velocities, positions)) {
    report.nonfinite = true;
    return report;
  }
  if (warm_start) warm_start->record(velocity_change);
  state.positions.swap(positions);
  state.velocities.swap(velocities);
  report.elastic_energy = model.elastic_energy(state.positions);
  report.kinetic_energy = kinetic_energy(masses, state.velocities);
  return report;
}

}  // namespace incise::physics
