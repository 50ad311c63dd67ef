// The shape memory's explicit limits in the stability summary (issue 30): the seed's 3-atom
// figure (physics/promayon/three_atom.hpp: shape memory against mass-spring, the seed's ratio 2)
// and an explicit dt sweep of the seed's symplectic step around each body's bound 2 / omega_max
// (seed_step_limit: K at rest with the normals frozen, by power iteration), so that the grid's
// fixed steps, which are all beyond it, are read against where it lies.
#include "bench/stability_sweep.hpp"

#include "physics/promayon/three_atom.hpp"

#include <algorithm>
#include <sstream>
#include <string>

namespace incise::bench::sweep {

std::string shape_memory_limits_report(bool quick, std::ostream& progress) {
  std::ostringstream out;
  progress << "shape memory: the 3-atom test and the explicit dt sweep around its bound\n";
  const physics::ThreeAtomLimits three = physics::three_atom_limits();
  out << "Shape memory, explicit limits:\n  3-atom test (seed 002 §5.2; k 0.05, k_a 1, unit masses, explicit Euler, "
         "bisection): largest stable dt " << format(three.shape_memory, 4) << " (shape memory) against "
      << format(three.mass_spring, 4) << " (mass-spring), ratio " << format(three.shape_memory / three.mass_spring, 3)
      << " (seed: 2)\n";
  const Integrator symplectic{"seed_symplectic_euler", false, ExplicitScheme::explicit_euler,
                              physics::SeedScheme::symplectic_euler};
  const std::vector<double> factors{0.5, 0.9, 1.1, 2};
  const std::vector<double> moduli = quick ? std::vector<double>{10e3, 10e6} : std::vector<double>{10e3, 10e6, 1e9};
  out << "  seed symplectic step at f x the bound 2 / omega_max (nu 0.3, at most 2000 steps):\n";
  for (const std::string case_name : {"beam_gravity", "compression_release"}) {
    for (double youngs_modulus : moduli) {
      Body body = make_body("shape_memory", case_name, {youngs_modulus, 0.3, density});
      const double bound = physics::seed_step_limit(*body.model, body.fixed);
      out << "    " << case_name << " E " << short_modulus(youngs_modulus) << ": bound " << format(1e3 * bound, 4)
          << " ms;";
      for (double f : factors) {
        const double dt = f * bound;
        const double duration = std::min(is_beam(case_name) ? 1.0 : 0.5, 2000 * dt);
        const Run run = simulate(body, symplectic, dt, duration);
        out << " " << format(f, 2) << "x " << outcome_name(run.outcome);
      }
      out << "\n";
    }
  }
  return out.str();
}

}  // namespace incise::bench::sweep
