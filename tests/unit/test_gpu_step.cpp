// The GPU backend (physics/gpu) against the CPU one on the corotated EFG model, on Mesa's
// llvmpipe here and in CI: the same implicit Euler steps agree (mean displacement within
// 1e-3 relative in float, 1e-9 in double), the rows a topology edit changes are the only ones
// uploaded again, and a missing compute capability is a clear error.
#include "physics/core/implicit_euler.hpp"
#include "physics/efg/corotational_efg.hpp"
#include "physics/gpu/efg_step.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <span>
#include <string>
#include <utility>
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
double beam_agreement(Precision precision, double tolerance, int steps, bool rotations_on_gpu = true) {
  Beam cpu(tolerance), gpu(tolerance);
  GpuSettings settings;
  settings.precision = precision;
  settings.rotations_on_gpu = rotations_on_gpu;
  EfgStep step(gpu.model, settings);
  // The GPU starts from the newest dv alone: the CPU too, to compare like with like.
  WarmStart cpu_start(1);
  Vector gpu_dv;
  double worst = 0;
  for (int s = 0; s < steps; ++s) {
    const StepReport a = implicit_euler_step(cpu.model, cpu.state, cpu.fixed, cpu.gravity, {}, cpu.settings, &cpu_start);
    const StepReport b = step.step(gpu.model, gpu.state, gpu.fixed, gpu.gravity, {}, gpu.settings, &gpu_dv);
    EXPECT_TRUE(a.cg.converged) << "cpu step " << s;
    EXPECT_TRUE(b.cg.converged) << "gpu step " << s << ": residual " << b.cg.relative_residual << " after "
                                << b.cg.iterations;
    EXPECT_FALSE(b.nonfinite);
    const double mc = mean_displacement(cpu.state.positions, cpu.model.rest_positions());
    const double mg = mean_displacement(gpu.state.positions, gpu.model.rest_positions());
    worst = std::max(worst, std::abs(mg - mc) / mc);
    if (s + 1 == steps)
      std::printf("[gpu %s, rotations on the %s] step %d: mean displacement cpu %.9e gpu %.9e m, relative %.3e; CG %d / %d iterations; "
                  "max node difference %.3e m\n",
                  gpu::precision_name(precision).c_str(), rotations_on_gpu ? "gpu" : "cpu", s + 1, mc, mg, std::abs(mg - mc) / mc, a.cg.iterations,
                  b.cg.iterations, (cpu.state.positions - gpu.state.positions).cwiseAbs().maxCoeff());
  }
  // Rotations go up only when the CPU computes them.
  if (rotations_on_gpu) {
    EXPECT_EQ(step.counters().rotation_bytes, 0);
  } else {
    EXPECT_EQ(step.counters().rotation_bytes, 9LL * steps * gpu.model.element_count() * step.real_bytes());
  }
  EXPECT_EQ(step.counters().rotation_fallbacks, 0);
  return worst;
}

TEST(GpuStep, DoublePrecisionAgreesWithTheCpuOnTheBeam) {
  EXPECT_LT(beam_agreement(Precision::double_precision, 1e-10, 12), 1e-9);
}

TEST(GpuStep, SinglePrecisionAgreesWithTheCpuOnTheBeam) {
  EXPECT_LT(beam_agreement(Precision::single, 1e-6, 12), 1e-3);
}

TEST(GpuStep, RotationsFromTheCpuAgreeToo) {
  EXPECT_LT(beam_agreement(Precision::double_precision, 1e-10, 6, false), 1e-9);
  EXPECT_LT(beam_agreement(Precision::single, 1e-6, 6, false), 1e-3);
}

// CG stopped after 3 iterations at every step (a real-time budget's minimum): the GPU starts
// from the same A-norm-scaled warm start as the CPU (cg.cpp's scale_initial_guess), so the
// truncated iterates, which depend on the start far more than converged ones, still agree.
TEST(GpuStep, ACgStoppedAtThreeIterationsStartsFromTheCpusScaledGuess) {
  Beam cpu(1e-12), gpu(1e-12);
  cpu.settings.cg.budget.stop_at = gpu.settings.cg.budget.stop_at = 3;
  GpuSettings settings;
  settings.precision = Precision::double_precision;
  EfgStep step(gpu.model, settings);
  // The GPU starts from the newest dv alone: the CPU too, to compare like with like.
  WarmStart cpu_start(1);
  Vector gpu_dv;
  double worst = 0;
  for (int s = 0; s < 20; ++s) {
    const StepReport a = implicit_euler_step(cpu.model, cpu.state, cpu.fixed, cpu.gravity, {}, cpu.settings, &cpu_start);
    const StepReport b = step.step(gpu.model, gpu.state, gpu.fixed, gpu.gravity, {}, gpu.settings, &gpu_dv);
    ASSERT_TRUE(a.cg.stopped_by_budget && b.cg.stopped_by_budget) << "step " << s;
    ASSERT_EQ(a.cg.iterations, 3);
    ASSERT_EQ(b.cg.iterations, 3);
    worst = std::max(worst, (cpu.state.positions - gpu.state.positions).cwiseAbs().maxCoeff());
  }
  const double reach = (cpu.state.positions - cpu.model.rest_positions()).cwiseAbs().maxCoeff();
  std::printf("[gpu double, CG stopped at 3] 20 steps: largest node difference %.3e m of a %.3e m displacement\n", worst,
              reach);
  EXPECT_GT(reach, 1e-4);
  EXPECT_LT(worst, 1e-9 * reach);
}

// CG's stops are decided on the GPU and the host reads them back only every few iterations:
// the iterations queued past a stop must leave the iterate alone. Checked after every
// iteration, every 3 and every 8, the same steps give the bitwise same states and iteration
// counts, converged (a count no batch divides) and stopped by a recorded stop at 5.
TEST(GpuStep, CgChecksReadBackEveryFewIterationsGiveTheSameIterate) {
  for (const int stop_at : {0, 5}) {
    std::vector<Vector> states;
    std::vector<std::vector<int>> counts;
    for (const int every : {1, 3, 8}) {
      Beam beam(1e-8);
      beam.settings.cg.budget.stop_at = stop_at;
      GpuSettings settings;
      settings.precision = Precision::double_precision;
      settings.cg_iterations_per_check = every;
      EfgStep step(beam.model, settings);
      std::vector<int> iterations;
      for (int s = 0; s < 4; ++s) {
        const StepReport report = step.step(beam.model, beam.state, beam.fixed, beam.gravity, {}, beam.settings);
        ASSERT_TRUE(stop_at > 0 ? report.cg.stopped_by_budget : report.cg.converged) << "every " << every;
        iterations.push_back(report.cg.iterations);
      }
      states.push_back(beam.state.positions);
      counts.push_back(iterations);
    }
    std::printf("[gpu double, stop_at %d] CG iterations per step %d %d %d %d (checked every 1, 3, 8)\n", stop_at,
                counts[0][0], counts[0][1], counts[0][2], counts[0][3]);
    if (stop_at == 0) {  // a count no batch divides: iterations were queued past the stop
      EXPECT_TRUE(std::any_of(counts[0].begin(), counts[0].end(), [](int n) { return n % 8 != 0 && n % 3 != 0; }));
    }
    for (size_t k = 1; k < states.size(); ++k) {
      EXPECT_EQ(counts[k], counts[0]);
      EXPECT_EQ((states[k] - states[0]).cwiseAbs().maxCoeff(), 0.0);
    }
  }
  Beam beam(1e-8);
  GpuSettings settings;
  settings.cg_iterations_per_check = 0;
  EXPECT_THROW(EfgStep(beam.model, settings), std::invalid_argument);
}

// A rigid rotation of 1 rad about a tilted axis, no load, nothing fixed: the corotated forces
// vanish only if every element's rotation is extracted right (from an identity warm start,
// as after a cut), so the beam must stay at rest; the CPU does the same step.
TEST(GpuStep, ARigidlyRotatedBeamStaysAtRest) {
  for (Precision precision : {Precision::double_precision, Precision::single}) {
    Beam cpu(1e-10), gpu(1e-10);
    const Eigen::Matrix3d rotation = Eigen::AngleAxisd(1.0, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    for (Beam* beam : {&cpu, &gpu}) {
      std::fill(beam->fixed.begin(), beam->fixed.end(), 0);
      for (int i = 0; i < beam->model.node_count(); ++i)
        beam->state.positions.segment<3>(3 * i) = rotation * beam->model.rest_positions().segment<3>(3 * i);
    }
    GpuSettings settings;
    settings.precision = precision;
    EfgStep step(gpu.model, settings);
    const Vector no_load = Vector::Zero(3 * gpu.model.node_count());
    implicit_euler_step(cpu.model, cpu.state, cpu.fixed, no_load, {}, cpu.settings);
    step.step(gpu.model, gpu.state, gpu.fixed, no_load, {}, gpu.settings);
    const double speed = gpu.state.velocities.cwiseAbs().maxCoeff();
    std::printf("[gpu %s] rigidly rotated beam: largest speed after a step %.3e m/s (cpu %.3e)\n",
                gpu::precision_name(precision).c_str(), speed, cpu.state.velocities.cwiseAbs().maxCoeff());
    // Against g dt = 0.05 m/s, the speed gravity would give in a step.
    EXPECT_LT(speed, precision == Precision::single ? 1e-5 : 1e-12);
    EXPECT_EQ(step.counters().rotation_fallbacks, 0);
  }
}

// Penalty springs (probe contact) enter the implicit system with their stiffness; two on one
// particle are summed.
TEST(GpuStep, SpringsAgreeWithTheCpu) {
  Beam cpu(1e-10), gpu(1e-10);
  GpuSettings settings;
  settings.precision = Precision::double_precision;
  EfgStep step(gpu.model, settings);
  const int tip = gpu.model.node_count() - 1;
  std::vector<NodalSpring> springs(3);
  springs[0].node = tip;
  springs[0].force = Vec3(0, 0, 0.5);
  springs[0].stiffness = 200 * Mat3::Identity();
  springs[1] = springs[0];
  springs[1].force = Vec3(0.1, -0.2, 0.3);
  springs[2].node = tip / 2;
  springs[2].force = Vec3(0, 0.4, 0);
  springs[2].stiffness << 300, 10, 0, 10, 100, 5, 0, 5, 50;
  // The GPU starts from the newest dv alone: the CPU too, to compare like with like.
  WarmStart cpu_start(1);
  Vector gpu_dv;
  for (int s = 0; s < 4; ++s) {
    // The last step has none: the GPU must drop the previous step's springs.
    const std::span<const NodalSpring> active(springs.data(), s < 3 ? springs.size() : 0);
    implicit_euler_step(cpu.model, cpu.state, cpu.fixed, cpu.gravity, active, cpu.settings, &cpu_start);
    step.step(gpu.model, gpu.state, gpu.fixed, gpu.gravity, active, gpu.settings, &gpu_dv);
    const double difference = (cpu.state.positions - gpu.state.positions).cwiseAbs().maxCoeff();
    const double moved = (cpu.state.positions - cpu.model.rest_positions()).cwiseAbs().maxCoeff();
    EXPECT_LT(difference, 1e-9 * moved) << "step " << s;
  }
}

// Why the scatter is a gather and not a colouring (efg_step.hpp): a greedy colouring of
// efg_beam's elements (a = 2.5 mm), two elements conflicting when they share a particle,
// needs as many colours as dispatches per product. Checked here: the colouring is valid and
// needs at least the 8 elements of one particle cell (which share all 8 corners).
TEST(GpuStep, AColouringOfTheBeamNeedsManyDispatches) {
  EfgSettings s;
  s.spacing = 0.0025;
  s.support_factor = 1.2;
  const CorotationalEfg model(Vec3(0, -0.01, -0.01), Vec3(0.2, 0.01, 0.01), Material{10e6, 0.3, 1000}, s);
  std::vector<std::vector<int>> elements_of(static_cast<size_t>(model.node_count()));
  const auto row = [&](int e) {
    const auto begin = model.neighbours().begin() + static_cast<std::ptrdiff_t>(e) * model.row_stride();
    return std::vector<int>(begin, begin + model.row_lengths()[e]);
  };
  for (int e = 0; e < model.element_count(); ++e)
    for (int n : row(e)) elements_of[n].push_back(e);
  std::vector<int> colour(static_cast<size_t>(model.element_count()), -1);
  int colours = 0;
  for (int e = 0; e < model.element_count(); ++e) {
    std::set<int> taken;
    for (int n : row(e))
      for (int other : elements_of[n])
        if (colour[other] >= 0) taken.insert(colour[other]);
    int c = 0;
    while (taken.count(c)) ++c;
    colour[e] = c;
    colours = std::max(colours, c + 1);
  }
  for (int n = 0; n < model.node_count(); ++n) {
    std::set<int> seen;
    for (int e : elements_of[n]) EXPECT_TRUE(seen.insert(colour[e]).second) << "particle " << n;
  }
  std::printf("greedy colouring of %d elements: %d colours (dispatches per K p), against 2 for the gather\n",
              model.element_count(), colours);
  EXPECT_GE(colours, 8);
}

// Each node's (element, slot) pairs in element order: the incidence rows, derived here from
// the model's rows independently of the backend.
std::vector<std::vector<std::pair<int, int>>> incidences(const CorotationalEfg& model) {
  std::vector<std::vector<std::pair<int, int>>> table(static_cast<size_t>(model.node_count()));
  for (int e = 0; e < model.element_count(); ++e)
    for (int k = 0; k < model.row_lengths()[e]; ++k)
      table[model.neighbours()[static_cast<size_t>(e) * model.row_stride() + k]].push_back({e, k});
  return table;
}

TEST(GpuStep, AfterATopologyEditOnlyTheChangedBatchesAreUploaded) {
  Beam beam(1e-10), reference(1e-10);
  GpuSettings settings;
  settings.precision = Precision::double_precision;
  settings.batch_rows = 16;
  EfgStep step(beam.model, settings);
  Vector dv;
  WarmStart reference_start(1);  // the GPU's start: the newest dv alone
  step.step(beam.model, beam.state, beam.fixed, beam.gravity, {}, beam.settings, &dv);
  implicit_euler_step(reference.model, reference.state, reference.fixed, reference.gravity, {}, reference.settings,
                      &reference_start);
  const gpu::GpuCounters before = step.counters();

  // What a cut does to an element (set_neighbourhood, seed 004 §2.4): new rows for three
  // elements, two in the first batch and one in batch 18; here each row is reversed, which
  // changes its slots, phi and grad phi order and every incidence that names it.
  const auto old_incidences = incidences(beam.model);
  const std::vector<int> edited{5, 6, 300};
  for (CorotationalEfg* model : {&beam.model, &reference.model}) {
    for (int e : edited) {
      const size_t base = static_cast<size_t>(e) * model->row_stride();
      std::vector<int> row(model->neighbours().begin() + base,
                           model->neighbours().begin() + base + model->row_lengths()[e]);
      std::reverse(row.begin(), row.end());
      model->set_neighbourhood(e, row);
    }
  }
  const auto new_incidences = incidences(beam.model);
  beam.gravity = gravity_forces(beam.model.lumped_masses(), Vec3(0, 0, -9.81));
  reference.gravity = gravity_forces(reference.model.lumped_masses(), Vec3(0, 0, -9.81));
  step.step(beam.model, beam.state, beam.fixed, beam.gravity, {}, beam.settings, &dv);
  implicit_euler_step(reference.model, reference.state, reference.fixed, reference.gravity, {}, reference.settings,
                      &reference_start);
  const gpu::GpuCounters& after = step.counters();

  // The expected batches and bytes, from the layout in efg_step.hpp: an element row is
  // capacity x (int + 4 reals) + int + 10 reals, an incidence row capacity ints + int.
  const long long real = step.real_bytes();
  const long long element_row = step.row_capacity() * (4 + 4 * real) + 4 + 10 * real;
  const long long incidence_row = step.incidence_capacity() * 4LL + 4;
  std::set<int> element_batches, node_batches;
  for (int e : edited) element_batches.insert(e / settings.batch_rows);
  for (int n = 0; n < beam.model.node_count(); ++n)
    if (old_incidences[n] != new_incidences[n]) node_batches.insert(n / settings.batch_rows);
  long long expected_bytes = 0;
  for (int b : element_batches)
    expected_bytes += std::min(settings.batch_rows, beam.model.element_count() - b * settings.batch_rows) * element_row;
  for (int b : node_batches)
    expected_bytes += std::min(settings.batch_rows, beam.model.node_count() - b * settings.batch_rows) * incidence_row;
  EXPECT_EQ(element_batches.size(), 2u);
  EXPECT_EQ(after.element_batches - before.element_batches, static_cast<long long>(element_batches.size()));
  EXPECT_EQ(after.incidence_batches - before.incidence_batches, static_cast<long long>(node_batches.size()));
  EXPECT_EQ(after.row_bytes - before.row_bytes, expected_bytes);
  EXPECT_EQ(after.reallocations, 0);
  std::printf("edit of %zu elements: %lld row bytes uploaded in %lld batches (%zu element, %zu incidence), a full "
              "re-upload is %lld\n",
              edited.size(), after.row_bytes - before.row_bytes, after.row_batches - before.row_batches,
              element_batches.size(), node_batches.size(), step.full_row_bytes());
  EXPECT_LT(after.row_bytes - before.row_bytes, step.full_row_bytes() / 4);

  // And the GPU solved the edited model: it still agrees with the CPU.
  const double mc = mean_displacement(reference.state.positions, reference.model.rest_positions());
  const double mg = mean_displacement(beam.state.positions, beam.model.rest_positions());
  EXPECT_LT(std::abs(mg - mc) / mc, 1e-9);

  // A step with no edit uploads no rows.
  const long long rows_before = step.counters().row_bytes;
  step.step(beam.model, beam.state, beam.fixed, beam.gravity, {}, beam.settings, &dv);
  EXPECT_EQ(step.counters().row_bytes, rows_before);
}

TEST(GpuStep, SurfaceAndIntegrationPointsFollowTheMappingWeights) {
  Beam beam(1e-8);
  GpuSettings settings;
  settings.precision = Precision::double_precision;
  EfgStep step(beam.model, settings);
  Vector dv;
  for (int s = 0; s < 3; ++s) step.step(beam.model, beam.state, beam.fixed, beam.gravity, {}, beam.settings, &dv);
  // Vertices on the beam's faces, mapped by the model's own embedding (CPU reference).
  Vector vertices(3 * 40);
  for (int v = 0; v < 40; ++v) vertices.segment<3>(3 * v) = Vec3(0.005 * v, v % 2 ? 0.01 : -0.01, 0.003 * (v % 5) - 0.006);
  const SurfaceEmbedding embedding = beam.model.embed_surface(vertices);
  Vector cpu, gpu_positions;
  CorotationalEfg::surface_positions(embedding, beam.state.positions, cpu);
  step.surface_positions(embedding, gpu_positions);
  ASSERT_EQ(gpu_positions.size(), cpu.size());
  EXPECT_LT((gpu_positions - cpu).cwiseAbs().maxCoeff(), 1e-12);
  // Integration points: x_e = sum_n phi_n x_n.
  Vector points;
  step.integration_points(beam.model, points);
  ASSERT_EQ(points.size(), 3 * beam.model.element_count());
  double worst = 0;
  for (int e = 0; e < beam.model.element_count(); ++e) {
    Vec3 expected = Vec3::Zero();
    const size_t base = static_cast<size_t>(e) * beam.model.row_stride();
    for (int k = 0; k < beam.model.row_lengths()[e]; ++k)
      expected += beam.model.shape_values()[base + k] * beam.state.positions.segment<3>(3 * beam.model.neighbours()[base + k]);
    worst = std::max(worst, (points.segment<3>(3 * e) - expected).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-12);
}

TEST(GpuStep, BadSettingsNameTheField) {
  Beam beam(1e-6);
  GpuSettings settings;
  settings.batch_rows = 0;
  try {
    EfgStep step(beam.model, settings);
    FAIL() << "batch_rows 0 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("batch_rows"), std::string::npos) << e.what();
  }
}

TEST(GpuStep, DoubleWithoutFp64IsAClearError) {
  Beam beam(1e-6);
  setenv("INCISE_GPU_DISABLE_FP64", "1", 1);
  GpuSettings settings;
  settings.precision = Precision::double_precision;
  try {
    EfgStep step(beam.model, settings);
    unsetenv("INCISE_GPU_DISABLE_FP64");
    FAIL() << "double precision accepted with fp64 hidden";
  } catch (const gpu::ComputeUnavailable& e) {
    unsetenv("INCISE_GPU_DISABLE_FP64");
    EXPECT_NE(std::string(e.what()).find("GL_ARB_gpu_shader_fp64"), std::string::npos) << e.what();
  }
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
