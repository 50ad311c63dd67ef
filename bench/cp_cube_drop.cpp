// cp_cube_drop [out_dir] [key=value ...]: Dionne's falling cube (digest D3,
// physics/cp/cube_drop.hpp) for distance only, + area, + volume, + the stretch limiter; prints
// the volume ratio every 50 frames and the inverted tets, writes cp_cube_drop.csv (a column per
// variant) and draws cp_cube_drop.png with gnuplot. Keys override CubeDrop's parameters: side,
// density, stiffness, drop, gravity, damping, dt, steps_per_frame, frames.
#include "bench/plot.hpp"
#include "physics/cp/cube_drop.hpp"

#include <algorithm>
#include <cmath>
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

}  // namespace

int main(int argc, char** argv) {
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
