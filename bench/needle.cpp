#include "bench/needle.hpp"

#include "bench/plot.hpp"
#include "bench/repo_files.hpp"
#include "engine/needle_summary.hpp"
#include "engine/scene.hpp"
#include "engine/world.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace incise::bench {

namespace {

// The scene's trajectory with its times scaled by 1 / speed_factor (the same path, faster).
engine::Trajectory scaled(const engine::Trajectory& trajectory, double speed_factor) {
  engine::Trajectory out = trajectory;
  for (auto& sample : out.samples) sample.time /= speed_factor;
  return out;
}

struct Run {
  std::vector<engine::StepStats> stats;
  std::vector<double> times;
};

Run run_once(const engine::Scene& scene, const engine::Trajectory& trajectory, double duration) {
  engine::World world(scene, trajectory);
  Run run;
  const auto steps = static_cast<long>(std::lround(duration / scene.solver.dt));
  for (long k = 0; k < steps; ++k) {
    run.stats.push_back(world.step());
    run.times.push_back(world.time());
  }
  return run;
}

std::string plot_script(const std::string& csv_rows, int runs) {
  std::ostringstream s;
  s << "set terminal pngcairo size 900,560\nset output 'needle.png'\nset datafile separator ','\n"
    << "set title 'Needle into the shape-memory cube: resistance against depth'\n"
    << "set xlabel 'depth past the first contact (mm)'\nset ylabel 'axial force (N)'\nset key top left\n"
    << "$d << EOD\n" << csv_rows << "EOD\nplot ";
  for (int r = 0; r < runs; ++r)
    s << (r ? ", " : "") << "$d using ($1 == " << r << " ? 1000 * $3 : 1/0):4 with lines title 'run " << r << "'";
  s << "\n";
  return s.str();
}

}  // namespace

int run_needle_bench(const NeedleBenchOptions& options, std::ostream& progress) {
  try {
    const auto scene_file = options.scene.empty() ? find_repo_file("assets/scenes/needle_cube.json", "needle") : options.scene;
    const engine::Scene scene = engine::load_scene(scene_file);
    if (!scene.tool || scene.tool->shape != "needle" || !scene.tool->trajectory)
      throw std::runtime_error(scene_file.string() + ": tool: the needle bench needs a needle tool with a trajectory");
    const engine::Trajectory trajectory = engine::read_trajectory(*scene.tool->trajectory);
    std::filesystem::create_directories(options.out_dir);
    std::ofstream csv(options.out_dir / "needle.csv");
    csv << "run,time_s,depth_m,force_axial_N,force_lateral_N,phase\n";
    std::ostringstream rows;
    const std::vector<double> speeds{0.5, 1.0, 2.0};  // of the scene's insertion speed
    bool holds = true;
    for (std::size_t r = 0; r < speeds.size(); ++r) {
      const Run run = run_once(scene, scaled(trajectory, speeds[r]), scene.solver.duration / speeds[r]);
      for (std::size_t k = 0; k < run.stats.size(); ++k) {
        const engine::NeedleStepStats& n = run.stats[k].needle;
        char line[256];
        std::snprintf(line, sizeof line, "%zu,%.6f,%.9g,%.9g,%.9g,%s\n", r, run.times[k], n.depth, -n.axial, n.lateral,
                      n.phase.c_str());
        csv << line;
        rows << line;
      }
      const engine::NeedleSummary s = engine::summarise_needle(run.stats);
      char line[512];
      std::snprintf(line, sizeof line,
                    "run %zu (x%.1f speed): puncture peak %.4f N, insertion early %.4f N -> late %.4f N, retraction max %.4f N "
                    "(cutting %.1g N), depth %.2f mm, stick->slip %ld, slip->stick %ld\n",
                    r, speeds[r], s.puncture_peak, s.insert_early_mean, s.insert_late_mean, s.retract_max, s.retract_cutting_max,
                    1e3 * s.max_depth, s.stick_to_slip, s.slip_to_stick);
      progress << line;
      holds = holds && s.puncture_peak > s.insert_early_mean && s.insert_late_mean > s.insert_early_mean &&
              s.retract_cutting_max == 0;
    }
    csv.close();
    draw_with_gnuplot(options.out_dir, "needle.gp", plot_script(rows.str(), static_cast<int>(speeds.size())), "needle.png",
                      progress);
    progress << "wrote " << (options.out_dir / "needle.csv").string() << "\n";
    if (!holds) progress << "needle bench: the seed's qualitative results do not all hold (see above)\n";
    return holds ? 0 : 1;
  } catch (const std::exception& e) {
    progress << "needle bench: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace incise::bench
