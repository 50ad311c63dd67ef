// cp_cube_drop [out_dir] [key=value ...]: Dionne's falling cube (digest D3,
// physics/cp/cube_drop.hpp) for distance only, + area, + volume, + the stretch limiter; prints
// the volume ratio every 50 frames and the inverted tets, writes cp_cube_drop.csv (a column per
// variant) and draws cp_cube_drop.png with gnuplot. Keys override CubeDrop's parameters: side,
// density, stiffness, drop, gravity, damping, dt, steps_per_frame, frames.
//
// cp_cube_drop throughput [cells=34] [steps=20]: digest D11, the thesis's 42,671-particle body
// stepped at 20 frames/s of two 15 ms velocity Verlet steps (2009, C#, one core). Our stand-in:
// the falling cube's split at cells^3 cells ((cells + 1)^3 particles: 42,875 at 34), every
// constraint (area on the surface triangles, as on the patient's skin) and the stretch limiter,
// timed over `steps` steps of the full Alg. 3.2 step (integrator, limiter, floor, inverted-tet
// count) after two warm-up steps; prints ms/step and steps/s in wall-clock and process CPU time
// (the second holds on a loaded machine). A figure to read, asserted nowhere.
#include "bench/plot.hpp"
#include "physics/core/implicit_euler.hpp"  // gravity_forces
#include "physics/cp/cube_drop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace {

using incise::physics::CubeDrop;

bool set(CubeDrop& drop, const std::string& argument) {
  const auto equals = argument.find('=');
  if (equals == std::string::npos) return false;
  const std::string key = argument.substr(0, equals);
  const double value = std::atof(argument.c_str() + equals + 1);
  if (key == "side") drop.side = value;
  else if (key == "density") drop.density = value;
  else if (key == "stiffness") drop.stiffness = value;
  else if (key == "drop") drop.drop = value;
  else if (key == "gravity") drop.gravity = value;
  else if (key == "damping") drop.damping = value;
  else if (key == "dt") drop.dt = value;
  else if (key == "steps_per_frame") drop.steps_per_frame = static_cast<int>(value);
  else if (key == "frames") drop.frames = static_cast<int>(value);
  else return false;
  return true;
}

int throughput(int argc, char** argv) {
  int cells = 34, steps = 20;
  for (int i = 2; i < argc; ++i) {
    const std::string argument = argv[i];
    if (argument.rfind("cells=", 0) == 0) cells = std::atoi(argument.c_str() + 6);
    else if (argument.rfind("steps=", 0) == 0) steps = std::atoi(argument.c_str() + 6);
    else {
      std::cerr << "cp_cube_drop throughput: unknown parameter '" << argument << "' (cells=, steps=)\n";
      return 2;
    }
  }
  if (cells < 1 || steps < 1) {
    std::cerr << "cp_cube_drop throughput: cells and steps must be >= 1\n";
    return 2;
  }
  namespace physics = incise::physics;
  const CubeDrop drop;
  const double h = drop.side / drop.cells;  // the D3 cube's cell, so its k and dt hold
  const physics::Vec3 lo(0, 0, drop.drop);
  const physics::TetMesh mesh = physics::make_box_tets5(lo, lo + physics::Vec3::Constant(h * cells), {cells, cells, cells});
  physics::ConstraintParticleSettings settings;
  settings.density = drop.density;
  settings.distance_stiffness = settings.area_stiffness = settings.volume_stiffness = drop.stiffness;
  physics::ConstraintParticles model(mesh, settings);
  physics::CpStepSettings step;
  step.dt = drop.dt;
  step.floor_z = 0.0;
  physics::State state{mesh.rest, physics::Vector::Zero(mesh.rest.size())};
  const physics::Vector gravity = physics::gravity_forces(model.lumped_masses(), physics::Vec3(0, 0, -drop.gravity));
  int counts[3] = {0, 0, 0};
  for (const auto& c : model.constraints()) ++counts[static_cast<int>(c.kind)];
  for (int k = 0; k < 2; ++k) physics::constraint_particles_step(model, state, {}, gravity, step, model.verlet_history());
  const auto wall_start = std::chrono::steady_clock::now();
  const std::clock_t cpu_start = std::clock();
  bool finite = true;
  for (int k = 0; k < steps; ++k)
    finite = finite && !physics::constraint_particles_step(model, state, {}, gravity, step, model.verlet_history()).nonfinite;
  const double cpu_ms = 1e3 * static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC / steps;
  const double wall_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall_start).count() / steps;
  std::cout << "D11 throughput: " << model.node_count() << " particles, " << model.tets().size() << " tets, "
            << model.constraints().size() << " constraints (" << counts[0] << " distance, " << counts[1] << " area, "
            << counts[2] << " volume), velocity Verlet + stretch limiter, " << steps << " steps"
            << (finite ? "" : " (non-finite!)") << ":\n  wall " << wall_ms << " ms/step = " << 1e3 / wall_ms
            << " steps/s; process CPU " << cpu_ms << " ms/step = " << 1e3 / cpu_ms << " steps/s (one thread)\n"
            << "  thesis (2009, C#, one Core 2 Duo core): 42,671 particles, 245,804 constraints, 20 frames/s of 2 steps "
               "= 40 steps/s, 25 ms/step\n";
  return finite ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::string(argv[1]) == "throughput") return throughput(argc, argv);
  std::filesystem::path out = ".";
  CubeDrop base;
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    if (argument.find('=') == std::string::npos) out = argument;
    else if (!set(base, argument)) {
      std::cerr << "cp_cube_drop: unknown parameter '" << argument << "'\n";
      return 2;
    }
  }
  std::filesystem::create_directories(out);
  struct Variant {
    const char* name;
    bool area, volume, limiter;
  };
  const std::vector<Variant> variants{{"distance", false, false, false},
                                      {"+area", true, false, false},
                                      {"+volume", true, true, false},
                                      {"+limiter", true, true, true}};
  std::vector<incise::physics::CubeDropResult> results;
  for (const Variant& v : variants) {
    CubeDrop drop = base;
    drop.area = v.area;
    drop.volume = v.volume;
    drop.limiter = v.limiter;
    results.push_back(incise::physics::run_cube_drop(drop));
    const auto& r = results.back();
    std::cout << v.name << (r.finite ? "" : " (non-finite, stopped)") << ":";
    for (std::size_t f = 0; f < r.volume_ratio.size(); f += 50) std::cout << " f" << f << "=" << r.volume_ratio[f];
    double worst = 0;
    for (std::size_t f = 0; f < r.volume_ratio.size(); ++f) worst = std::max(worst, std::abs(r.volume_ratio[f] - 1));
    std::cout << "  last=" << r.volume_ratio.back() << " max|V/V0-1|=" << worst
              << " inverted(max)=" << *std::max_element(r.inverted.begin(), r.inverted.end())
              << " inverted(last)=" << r.inverted.back() << "\n";
  }
  std::ofstream csv(out / "cp_cube_drop.csv");
  csv << "frame";
  for (const Variant& v : variants) csv << "," << v.name;
  csv << "\n";
  std::ostringstream data;
  for (int f = 0; f <= base.frames; ++f) {
    csv << f;
    data << f;
    for (const auto& r : results) {
      const double value = f < static_cast<int>(r.volume_ratio.size()) ? r.volume_ratio[f] : NAN;
      csv << "," << value;
      data << " " << value;
    }
    csv << "\n";
    data << "\n";
  }
  std::ostringstream script;
  script << "set terminal pngcairo size 900,500\nset output 'cp_cube_drop.png'\n"
         << "set title \"Dionne's falling cube (D3): volume / rest volume per frame\"\n"
         << "set xlabel 'frame (" << base.steps_per_frame << " steps of " << base.dt << " s)'\nset ylabel 'V / V0'\n"
         << "set key bottom right\nset datafile missing 'nan'\n$data << EOD\n" << data.str() << "EOD\n"
         << "plot $data using 1:2 with lines title 'distance only', $data using 1:3 with lines title '+ area', "
         << "$data using 1:4 with lines title '+ volume', $data using 1:5 with lines lw 2 title '+ stretch limiter'\n";
  incise::bench::draw_with_gnuplot(out, "cp_cube_drop.gp", script.str(), "cp_cube_drop.png", std::cout);
  return 0;
}
