// The numerical stability sweep (issue 7): where each model and integrator breaks on stiff
// and extreme settings, as a map anyone can rerun.
//
// Cases (all under gravity, 9.81 m/s^2 along -z, rho = 1000 kg/m^3):
// - beam_gravity: B1, the beam 0.2 x 0.02 x 0.02 m along +x clamped at x = 0, from rest;
// - compression_release: a 0.04 m cube on a clamped base (z = 0), its nodes starting at 10 %
//   of their height (z -> 0.1 z, a prescribed squeezed state) and at rest, then released;
// - inverted_start: the same cube at rest with three top nodes flipped, so that some elements
//   start inverted (FEM: each node reflected through the face opposite it in its first
//   tetrahedron; EFG: each particle reflected through the plane of the particle layer below).
// - fast_blade (efg only): the cube clamped at z = 0, at rest; a straight vertical blade edge
//   (y = 21.5 mm, z from 60 mm down to 15.5 mm) crosses it along +x at 5 m/s from x = -10 mm
//   at t = 0, cutting the upper part in two (both halves stay attached below z = 15.5 mm),
//   and the run goes on. The blade goes through physics::VolumeCutter every step, before the
//   solve, with the particles' motion over the previous step (positions before the last
//   solve to after it), as the engine does (continuous collision: at dt = 33 ms the whole
//   crossing is one step); gravity is recomputed from the masses the re-selection moves;
// - thin_slice (efg only): the cube clamped on its face x = 0, cut at rest by VolumeCutter
//   with two horizontal blade sweeps across its width, from beyond the free face x = 40 mm
//   back to x = 11.5 mm: at z = 34 mm (a slice one integration element thick on top: one
//   integration layer, one particle layer) and at z = 11 mm (a slice two elements thick at the
//   bottom: two integration and two particle layers); the slices hang from the block under
//   gravity. One element is too thin for the discretisation (thesis §4.3.3, ch. 5: about 2
//   elements is the thinnest separable part): the top slice's elements find no neighbourhood
//   spanning 3 dimensions on their side, the cutter counts them as re-selection failures
//   (32 of them) and they keep their old rows, so the top slice stays partly tied across its
//   cut (stability_summary.txt, Set-up).
// After the sweep, the thin-slice study runs thin_slice under gravity for 3 s (6 s in the full
// sweep) at dt = 16.7 ms with each rotation of the corotation (EfgSettings::rotation), E 10 kPa,
// 100 kPa and 1 MPa, nu 0.45, and prints for each slice the rms particle speed and the
// centroid drift over the last second and the sag, and the energy the run gained (sum of the
// per-step rises of elastic + kinetic + gravitational energy) over its net change: a damped
// conservative model never gains any. What it shows and why the corotation takes its rotation
// from the deformation gradient: docs/physics-choices.md, "`rotation` = deformation_gradient"
// (corotational_efg.hpp, "Rotation").
//
// Models: `fem`, CorotationalTetFem (beam 10 x 2 x 2 cells, cube 4 x 4 x 4 cells, 6 tets per
// cell) with implicit Euler and the five explicit integrators; `efg`, CorotationalEfg (grid
// spacing a = 5 mm, particles 10 mm apart) with implicit Euler; `mass_spring`, Baudet's
// HexMassSpring (cubic bricks: beam 20 x 2 x 2, cube 4 x 4 x 4; critical dashpots, no
// corrections) with implicit Euler and the five explicit integrators, an explicit run whose dt
// is beyond its bound 2 sqrt(m_min / k_node_max) counted as `refused` (as is a body whose bricks
// the formulas give a non-positive stiffness; the cubic bricks never do); `constraint_particles`,
// Dionne's ConstraintParticles (beam 20 x 2 x 2, cube 4 x 4 x 4 cubic cells of 5 tets; k_D = k_A =
// E h^3 and k_V = E h^3 / (15 (1 - 2 nu)), make_constraint_particles_body says why) with implicit
// Euler and the five explicit integrators, each explicit step followed by the stretch limiter
// (Alg. 3.2), an explicit dt beyond its bound min 2 sqrt(m_i / k_i) refused. Damping: Rayleigh mass
// damping alpha = 1/s for every integrator; implicit Euler's CG: tolerance 1e-6, at most 1000
// iterations, warm started from the previous step's velocity change, as in the engine.
//
// Each run, at the nominal dt, applies the engine's non-finite guard: a step that produces a
// non-finite value is rolled back and retried as 2, 4, 8 sub-steps; guard_events counts the
// steps that needed it. Outcomes, the first that applies:
// - nonfinite: a step stayed non-finite after 3 halvings (the run stops there);
// - diverged: the elastic + kinetic energy exceeded 100 x E_ref, E_ref the larger of the
//   initial elastic + kinetic energy and the work gravity would do on the whole body falling
//   freely for the run's duration T (M g^2 T^2 / 2), or a node moved more than 10 x the body
//   size (the largest side of its rest bounding box); the run stops at the first such step;
// - cg_not_converged: implicit Euler's CG hit its 1000-iteration cap in more than 10 % of the
//   run's steps; the run stops as soon as that count is reached (its steps are then not
//   implicit Euler's solution, and the stiff runs that never converge would otherwise take
//   most of the sweep's time);
// - stable otherwise.
// Runs are T = 1 s (beam) or 0.5 s (cubes) of simulated time; 0.25 s in quick mode.
// Quick sweep: 3 E x 3 nu x 2 dt, 1062 runs. The sweeps' outcomes: docs/status.md, "Benchmarks".
#include "bench/stability.hpp"
#include "bench/stability_sweep.hpp"
#include "bench/bench_page.hpp"
#include "bench/plot.hpp"

#include "common/csv.hpp"
#include "common/progress_bar.hpp"
#include "engine/model_registry.hpp"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <fstream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::bench::sweep {

Sweep make_sweep(bool quick) {
  if (quick) {
    // Soft, stiff and beyond; compressible, nearly and almost incompressible; a haptic-rate
    // and a frame-rate step; every case.
    return {{10e3, 10e6, 1e9}, {0.3, 0.49, 0.499}, {1e-3, 33e-3},
            {"beam_gravity", "compression_release", "inverted_start", "fast_blade", "thin_slice"},
            0.25, 0.25};
  }
  return {{1e3, 10e3, 100e3, 1e6, 10e6, 100e6, 1e9},
          {0.3, 0.45, 0.49, 0.499},
          {0.5e-3, 1e-3, 4e-3, 16.7e-3, 33e-3},
          {"beam_gravity", "compression_release", "inverted_start", "fast_blade", "thin_slice"},
          1.0,
          0.5};
}

// The models this bench sets up bodies for (make_body, below the engine's builder: the cases
// need the bare DeformableModel), with the integrators each offers.
const std::set<std::string>& bench_models() {
  static const std::set<std::string> names{"fem", "efg", "mass_spring", "constraint_particles", "shape_memory"};
  return names;
}

Integrator implicit_euler() { return {"implicit_euler", true, ExplicitScheme::explicit_euler, std::nullopt}; }

// The sweep's models: the registry's (engine/model_registry.hpp), in its order, those this bench
// can set up; `left_out` receives the others.
std::vector<ModelKind> model_kinds(std::vector<std::string>* left_out) {
  std::vector<Integrator> fem{implicit_euler()};
  for (ExplicitScheme scheme : {ExplicitScheme::explicit_euler, ExplicitScheme::midpoint,
                                ExplicitScheme::runge_kutta4, ExplicitScheme::verlet,
                                ExplicitScheme::velocity_verlet}) {
    fem.push_back({std::string(physics::explicit_scheme_name(scheme)), false, scheme, std::nullopt});
  }
  std::vector<ModelKind> kinds;
  for (const std::string& name : engine::models().names()) {
    if (!bench_models().count(name)) {
      if (left_out) left_out->push_back(name);
      continue;
    }
    // The EFG model offers implicit Euler only (issue 7: explicit integrators "where a model
    // offers them"); any DeformableModel would take the explicit steps as well. The mass-spring
    // and the constraint particles take them all, up to their explicit bound (beyond it the run
    // is refused).
    // The shape memory: implicit Euler and the seed's own explicit step in its two schemes.
    if (name == "shape_memory") {
      kinds.push_back({name,
                       {implicit_euler(),
                        {"seed_explicit_euler", false, ExplicitScheme::explicit_euler, physics::SeedScheme::explicit_euler},
                        {"seed_symplectic_euler", false, ExplicitScheme::explicit_euler, physics::SeedScheme::symplectic_euler}}});
      continue;
    }
    kinds.push_back({name, name != "efg" ? fem : std::vector<Integrator>{implicit_euler()}});
  }
  return kinds;
}

std::string format(double value, int digits) { return common::significant(value, digits); }

}  // namespace incise::bench::sweep

namespace incise::bench {

using namespace sweep;


// The summary's line on a body as built: its nodes, the elements inverted at the start of
// inverted_start, and the body's own note.
std::string set_up_note(const std::string& model, const std::string& case_name, const Body& body) {
  return model + " " + case_name + ": " + std::to_string(body.model->node_count()) + " nodes" +
         (case_name == "inverted_start" ? ", " + std::to_string(body.inverted) + " elements inverted at the start" : "") +
         (body.note.empty() ? "" : ", " + body.note);
}

// Resuming: every run of a body (a model, case and material) from the earlier sweep, or none
// when one is missing (the body is then built and the missing runs made).
std::vector<Run> all_kept(const std::map<std::string, Run>& previous, const ModelKind& kind, const std::string& case_name,
                          double youngs_modulus, double poisson_ratio, const std::vector<double>& time_steps) {
  std::vector<Run> kept;
  for (const Integrator& integrator : kind.integrators)
    for (double dt : time_steps) {
      const auto run = previous.find(run_key(kind.name, integrator.name, case_name, youngs_modulus, poisson_ratio, dt));
      if (run == previous.end()) return {};
      kept.push_back(run->second);
    }
  return kept;
}

// The runs of a set-up the model refused (a mass-spring brick of non-positive stiffness): one
// per integrator and dt, each counted as refused.
std::vector<Run> refused_runs(const ModelKind& kind, const std::string& case_name, double youngs_modulus,
                              double poisson_ratio, const std::vector<double>& time_steps) {
  std::vector<Run> runs;
  for (const Integrator& integrator : kind.integrators)
    for (double dt : time_steps) {
      Run run;
      run.model = kind.name, run.integrator = integrator.name, run.case_name = case_name;
      run.youngs_modulus = youngs_modulus, run.poisson_ratio = poisson_ratio, run.dt = dt;
      run.outcome = Outcome::refused;
      runs.push_back(std::move(run));
    }
  return runs;
}

// Adds the process's CPU time over its life to `total` (the summary's seconds per model: a
// model's bodies and runs, set-up included).
struct CpuClock {
  double& total;
  std::clock_t start = std::clock();
  ~CpuClock() { total += static_cast<double>(std::clock() - start) / CLOCKS_PER_SEC; }
};

std::string cpu_line(const std::vector<ModelKind>& kinds, const std::map<std::string, double>& seconds) {
  std::string line = "CPU seconds per model:";
  for (const ModelKind& kind : kinds) {
    const auto it = seconds.find(kind.name);
    line += " " + kind.name + " " + format(it == seconds.end() ? 0.0 : it->second, 3);
  }
  return line + "\n";
}

// The runs of the part: every run of the bodies (a model, a case and a material, in the sweep's
// order) whose index `in_part` takes.
template <class InPart>
int runs_in_part(const Sweep& sweep, const std::vector<ModelKind>& kinds, const InPart& in_part) {
  int total = 0, body_index = 0;
  for (const std::string& case_name : sweep.cases)
    for (const ModelKind& kind : kinds) {
      if (!model_runs_case(kind.name, case_name)) continue;
      for (std::size_t m = 0; m < sweep.youngs_moduli.size() * sweep.poisson_ratios.size(); ++m)
        if (in_part(body_index++)) total += static_cast<int>(kind.integrators.size() * sweep.time_steps.size());
    }
  return total;
}

namespace {

// The summary (stability_summary.txt), the plot and the report page of a finished sweep.
void write_stability_reports(const std::filesystem::path& out_dir, bool quick, const Sweep& sweep,
                             const std::vector<ModelKind>& kinds, const std::vector<Run>& runs,
                             const std::vector<std::string>& set_up_notes, const std::string& cpu,
                             const std::string& slices, const std::string& limits, double seconds,
                             std::ostream& progress_stream) {
  const std::string counts = counts_table(kinds, runs);
  progress_stream << "outcome counts (" << runs.size() << " runs, " << format(seconds, 3)
                  << " s):\n"
                  << counts << cpu << inverted_table(kinds, runs) << slices << limits;
  std::ofstream summary(out_dir / "stability_summary.txt");
  summary << "incise bench stability" << (quick ? " --quick" : "") << "\n\n"
          << bounds_text(sweep) << "\nSet-up:\n";
  for (const std::string& note : set_up_notes) summary << "  " << note << "\n";
  summary << "\nOutcome counts (" << runs.size() << " runs, " << format(seconds, 3) << " s):\n"
          << counts << cpu << "\nInverted elements at the end of the stable inverted_start runs:\n"
          << inverted_table(kinds, runs) << "\n" << slices << "\n" << limits;

  draw_with_gnuplot(out_dir, "stability.gnuplot", plot_script("stability.png", quick, sweep, kinds, runs),
                    "stability.png", progress_stream);
  progress_stream << "wrote " << (out_dir / "stability.csv").string() << "\n";
  progress_stream << "report: "
                  << write_bench_page(out_dir, {"incise bench stability" + std::string(quick ? " --quick" : ""),
                                                "Stiff and extreme cases: the outcome of each model, integrator, "
                                                "case, E, nu and dt (bench/stability.cpp says what each case is).",
                                                {{"stability.png", "Outcome map"}}, "stability_summary.txt",
                                                "stability.csv"})
                         .string()
                  << "\n";
}

}  // namespace

int run_stability_bench(const StabilityOptions& options, const std::filesystem::path& out_dir,
                        std::ostream& progress_stream) {
  const bool quick = options.quick, resume = options.resume;
  if (options.parts < 1 || options.part < 0 || options.part >= options.parts) {
    progress_stream << "stability bench: part " << options.part << " of " << options.parts << " does not exist\n";
    return 1;
  }
  // A part runs every parts-th body of the sweep (a model, case and material, in the order
  // below) with all its runs: a body serves its runs in turn and keeps its rotations' warm
  // starts from one to the next, so its runs are only reproduced bit for bit in that order.
  const auto in_part = [&](int body_index) { return body_index % options.parts == options.part; };
  try {
    std::filesystem::create_directories(out_dir);
    const Sweep sweep = make_sweep(quick);
    std::vector<std::string> left_out;
    const std::vector<ModelKind> kinds = model_kinds(&left_out);
    for (const std::string& name : left_out)
      progress_stream << "model '" << name << "' is registered but left out: this bench sets up "
                      << engine::alternatives({bench_models().begin(), bench_models().end()}) << " bodies only\n";
    const std::map<std::string, Run> previous =
        resume ? read_previous_runs(out_dir / "stability.csv", progress_stream) : std::map<std::string, Run>{};
    common::CsvWriter csv(out_dir / "stability.csv",
                          {"model", "integrator", "case", "E", "nu", "dt", "outcome", "max_energy_ratio",
                           "max_displacement", "steps", "guard_events"});
    if (resume) progress_stream << "resuming: " << previous.size() << " runs kept from the earlier sweep\n";

    const int total = runs_in_part(sweep, kinds, in_part);
    progress_stream << "stability sweep" << (quick ? " (quick)" : "") << ": " << total << " runs";
    if (options.parts > 1) progress_stream << " (part " << options.part << " of " << options.parts << ")";
    progress_stream << "\n" << bounds_text(sweep);
    const auto start = std::chrono::steady_clock::now();
    common::ProgressBar progress(progress_stream, total);
    std::vector<Run> runs;
    std::vector<std::string> set_up_notes;
    std::map<std::string, double> cpu_seconds;
    int body_index = 0;
    for (const std::string& case_name : sweep.cases) {
      const double duration = is_beam(case_name) ? sweep.beam_duration : sweep.cube_duration;
      for (const ModelKind& kind : kinds) {
        if (!model_runs_case(kind.name, case_name)) continue;
        for (double youngs_modulus : sweep.youngs_moduli) {
          for (double poisson_ratio : sweep.poisson_ratios) {
            if (!in_part(body_index++)) continue;
            const CpuClock clock{cpu_seconds[kind.name]};
            const Material material{youngs_modulus, poisson_ratio, density};
            const bool first_material = youngs_modulus == sweep.youngs_moduli.front() &&
                                        poisson_ratio == sweep.poisson_ratios.front();
            // Resuming: the runs of this material already done are kept as they were; the
            // body is only built when a run is missing (or for the set-up note).
            if (!first_material) {
              const std::vector<Run> kept = all_kept(previous, kind, case_name, youngs_modulus, poisson_ratio,
                                                     sweep.time_steps);
              for (const Run& run : kept) {
                write_row(csv, run);
                runs.push_back(run);
                progress.advance();
              }
              if (!kept.empty()) continue;
            }
            Body body;
            try {
              body = make_body(kind.name, case_name, material);
            } catch (const std::invalid_argument& refusal) {
              // The model refused the set-up (a mass-spring brick with a non-positive stiffness):
              // each of its runs is counted as refused, and the sweep goes on.
              if (first_material) set_up_notes.push_back(kind.name + " " + case_name + ": refused: " + refusal.what());
              for (Run& run : refused_runs(kind, case_name, youngs_modulus, poisson_ratio, sweep.time_steps)) {
                write_row(csv, run);
                runs.push_back(std::move(run));
                progress.advance();
              }
              continue;
            }
            if (first_material) set_up_notes.push_back(set_up_note(kind.name, case_name, body));
            bool used = false;
            for (const Integrator& integrator : kind.integrators) {
              for (double dt : sweep.time_steps) {
                if (used && body.single_use) {
                  body.cutter.reset();  // before the model it refers to
                  body = make_body(kind.name, case_name, material);
                }
                const auto kept = previous.find(run_key(kind.name, integrator.name, case_name, youngs_modulus,
                                                        poisson_ratio, dt));
                if (kept != previous.end()) {
                  write_row(csv, kept->second);
                  runs.push_back(kept->second);
                  progress.advance();
                  continue;
                }
                used = true;
                progress.draw(kind.name + " " + integrator.name + " " + case_name + " E " +
                              short_modulus(youngs_modulus) + " nu " + format(poisson_ratio) +
                              " dt " + format(1e3 * dt, 3) + " ms");
                Run run = simulate(body, integrator, dt, duration);
                if (first_material && body.single_use && dt == sweep.time_steps.front()) {
                  set_up_notes.push_back(kind.name + " " + case_name + " after the run at dt " +
                                         format(1e3 * dt, 3) + " ms: " + body.note);
                }
                run.model = kind.name;
                run.integrator = integrator.name;
                run.case_name = case_name;
                run.youngs_modulus = youngs_modulus;
                run.poisson_ratio = poisson_ratio;
                write_row(csv, run);
                runs.push_back(std::move(run));
                progress.advance();
              }
            }
          }
        }
      }
    }
    progress.draw("done");
    progress.finish();
    const std::string slices = options.parts > 1 ? "Thin-slice study: run by the merge of the parts.\n"
                                                 : thin_slice_report(quick, progress_stream);
    const bool shape_memory = std::any_of(kinds.begin(), kinds.end(), [](const ModelKind& k) { return k.name == "shape_memory"; });
    std::string limits;
    if (options.parts == 1 && shape_memory) {
      const CpuClock clock{cpu_seconds["shape memory limits"]};
      limits = shape_memory_limits_report(quick, progress_stream);
    }
    const std::string cpu = cpu_line(kinds, cpu_seconds) + (limits.empty() ? "" : "  and the shape memory's limits " +
                                                             format(cpu_seconds["shape memory limits"], 3) + "\n");
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    write_stability_reports(out_dir, quick, sweep, kinds, runs, set_up_notes, cpu, slices, limits, seconds,
                            progress_stream);
    return 0;
  } catch (const std::exception& error) {
    progress_stream << "\nstability bench failed: " << error.what() << "\n";
    return 1;
  }
}

}  // namespace incise::bench
