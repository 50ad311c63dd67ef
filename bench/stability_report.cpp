// The stability sweep's output: stability.csv (and resuming from it), the outcome map's
// gnuplot script and the summary's tables.
#include "bench/stability_sweep.hpp"
#include "bench/plot.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace incise::bench::sweep {

const char* outcome_name(Outcome outcome) {
  switch (outcome) {
    case Outcome::stable: return "stable";
    case Outcome::diverged: return "diverged";
    case Outcome::nonfinite: return "nonfinite";
    case Outcome::cg_not_converged: return "cg_not_converged";
    case Outcome::refused: return "refused";
  }
  return "unknown";
}

// Colours of the outcome map (RGB).
int outcome_colour(Outcome outcome) {
  switch (outcome) {
    case Outcome::stable: return 0x2ca02c;
    case Outcome::diverged: return 0xd62728;
    case Outcome::nonfinite: return 0x222222;
    case Outcome::cg_not_converged: return 0xf0b400;
    case Outcome::refused: return 0x9e9e9e;
  }
  return 0xffffff;
}

// ---- Output ------------------------------------------------------------------------------

// One row of stability.csv, flushed: an interrupted sweep leaves whole rows to resume from.
void write_row(common::CsvWriter& csv, const Run& run) {
  csv.row(run.model, run.integrator, run.case_name, format(run.youngs_modulus), format(run.poisson_ratio),
          format(run.dt), outcome_name(run.outcome), format(run.max_energy_ratio, 4), format(run.max_displacement, 4),
          run.steps, run.guard_events);
  csv.flush();
}

// The key of a run in the sweep: what identifies it, as the CSV writes it.
std::string run_key(const std::string& model, const std::string& integrator, const std::string& case_name,
                    double youngs_modulus, double poisson_ratio, double dt) {
  return model + "," + integrator + "," + case_name + "," + format(youngs_modulus) + "," + format(poisson_ratio) +
         "," + format(dt);
}

// The runs of an earlier (interrupted) sweep in `path`, by key. A row that does not parse
// (a line cut short when the sweep was killed) ends the list: it and what follows are run
// again. The CSV does not keep the inverted-element counts, so kept runs are left out of the
// summary's inverted_start table.
std::map<std::string, Run> read_previous_runs(const std::filesystem::path& path, std::ostream& progress) {
  std::map<std::string, Run> runs;
  std::ifstream in(path);
  if (!in) return runs;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (number == 1) {
      if (line.rfind("model,integrator,case,E,nu,dt,outcome", 0) != 0) {
        throw std::runtime_error(path.string() + ": line 1 is not a stability.csv header; not resuming from it");
      }
      continue;
    }
    std::vector<std::string> fields;
    std::stringstream stream(line);
    for (std::string field; std::getline(stream, field, ',');) fields.push_back(field);
    if (!line.empty() && line.back() == ',') fields.emplace_back();  // an empty last field
    Run run;
    bool ok = fields.size() == 11;
    try {
      if (ok) {
        run.model = fields[0], run.integrator = fields[1], run.case_name = fields[2];
        run.youngs_modulus = std::stod(fields[3]);
        run.poisson_ratio = std::stod(fields[4]);
        run.dt = std::stod(fields[5]);
        ok = false;
        for (Outcome outcome : all_outcomes)
          if (fields[6] == outcome_name(outcome)) run.outcome = outcome, ok = true;
        run.max_energy_ratio = std::stod(fields[7]);
        run.max_displacement = std::stod(fields[8]);
        run.steps = std::stoi(fields[9]);
        run.guard_events = std::stoi(fields[10]);
      }
    } catch (const std::exception&) {
      ok = false;
    }
    if (!ok) {
      progress << path.string() << ": line " << number << " is incomplete or malformed; it and any later lines are run again\n";
      break;
    }
    runs[run_key(run.model, run.integrator, run.case_name, run.youngs_modulus, run.poisson_ratio, run.dt)] = run;
  }
  return runs;
}

std::string short_modulus(double pascals) {
  if (pascals >= 1e9) return format(pascals / 1e9) + " GPa";
  if (pascals >= 1e6) return format(pascals / 1e6) + " MPa";
  if (pascals >= 1e3) return format(pascals / 1e3) + " kPa";
  return format(pascals) + " Pa";
}

size_t index_of(const std::vector<double>& values, double value) {
  return static_cast<size_t>(std::find(values.begin(), values.end(), value) - values.begin());
}

// gnuplot wants underscores escaped in enhanced-text strings (inside double quotes: "\\_").
std::string gnuplot_text(const std::string& text) {
  std::string escaped;
  for (char c : text) {
    if (c == '_') escaped += "\\\\";
    escaped += c;
  }
  return escaped;
}

// One panel per model + integrator (rows) and case (columns); inside a panel, E upwards and
// dt to the right, one block of dt columns per nu; each cell coloured by its outcome. The
// panels are placed in pixels (multiplot margins and spacing), so that the three-line title,
// the panel titles and the rotated dt labels never overlap whatever the sweep's size.
std::string plot_script(const std::string& png, bool quick, const Sweep& sweep, const std::vector<ModelKind>& kinds,
                        const std::vector<Run>& runs) {
  std::ostringstream script;
  const size_t block = sweep.time_steps.size() + 1;  // dt columns and a gap per nu
  const size_t columns = block * sweep.poisson_ratios.size() - 1;
  int rows = 0;
  for (const ModelKind& kind : kinds) rows += static_cast<int>(kind.integrators.size());
  const int cases = static_cast<int>(sweep.cases.size());
  // Pixels: the plot area of a panel, and the room around it.
  const int area_width = std::max(260, 24 * static_cast<int>(columns));
  const int area_height = std::max(90, 24 * static_cast<int>(sweep.youngs_moduli.size()));
  constexpr int left = 70, right = 20, header = 80, above = 40, below = 75, between = 80;
  const int width = left + cases * area_width + (cases - 1) * between + right;
  const int height = header + above + rows * area_height + (rows - 1) * (above + below) + below;
  auto fraction_x = [&](int pixels) { return format(static_cast<double>(pixels) / width, 5); };
  auto fraction_y = [&](int pixels) { return format(static_cast<double>(pixels) / height, 5); };

  script << "# Written by incise bench stability: the outcome map of stability.csv.\n"
         << "set terminal pngcairo size " << width << "," << height << " font ',9'\n"
         << "set output '" << png << "'\n"
         << "unset key\nset tics scale 0\nset border 0\n"
         << "set xrange [-0.6:" << columns - 0.4 << "]\n"
         << "set yrange [-0.6:" << sweep.youngs_moduli.size() - 0.4 << "]\n";
  script << "set ytics (";
  for (size_t e = 0; e < sweep.youngs_moduli.size(); ++e) {
    script << (e ? ", " : "") << "'" << short_modulus(sweep.youngs_moduli[e]) << "' " << e;
  }
  script << ")\nset xtics rotate by 90 right font ',8' (";
  bool first = true;
  for (size_t p = 0; p < sweep.poisson_ratios.size(); ++p) {
    for (size_t d = 0; d < sweep.time_steps.size(); ++d) {
      script << (first ? "" : ", ") << "'" << format(1e3 * sweep.time_steps[d], 3) << "' "
             << p * block + d;
      first = false;
    }
  }
  script << ")\n";
  for (size_t p = 0; p < sweep.poisson_ratios.size(); ++p) {
    const double centre = static_cast<double>(p * block) + 0.5 * (sweep.time_steps.size() - 1);
    script << "set label " << p + 1 << " 'nu " << format(sweep.poisson_ratios[p]) << "' at "
           << centre << ", graph 1.06 center font ',8'\n";
  }
  script << "set xlabel 'dt (ms), a block per Poisson ratio' font ',8' offset 0,0.2\n";
  int panel = 0;
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      for (const std::string& case_name : sweep.cases) {
        script << "$panel" << panel << " << EOD\n";
        for (const Run& run : runs) {
          if (run.model != kind.name || run.integrator != integrator.name || run.case_name != case_name)
            continue;
          const size_t column = index_of(sweep.poisson_ratios, run.poisson_ratio) * block +
                                index_of(sweep.time_steps, run.dt);
          script << column << " " << index_of(sweep.youngs_moduli, run.youngs_modulus) << " "
                 << outcome_colour(run.outcome) << "\n";
        }
        // A model that does not run the case (fem on the cutting cases): one point outside the
        // ranges, so the panel stays white and gnuplot has something to plot.
        if (!model_runs_case(kind.name, case_name)) script << "-10 -10 16777215\n";
        script << "EOD\n";
        ++panel;
      }
    }
  }
  const std::string title =
      std::string("incise stability sweep") + (quick ? " (quick)" : "") +
      "\\ngreen stable, red diverged, black nonfinite, gold cg_not_converged, white not run" +
      "\\ndiverged: energy > " + format(energy_bound) + " x E_ref or displacement > " +
      format(displacement_bound) + " x body size (stability_summary.txt)";
  script << "set multiplot layout " << rows << "," << cases << " margins " << fraction_x(left)
         << "," << fraction_x(width - right) << "," << fraction_y(below) << ","
         << fraction_y(height - header - above) << " spacing " << fraction_x(between) << ","
         << fraction_y(above + below) << " title \"" << gnuplot_text(title) << "\" font ',11'\n";
  panel = 0;
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      for (const std::string& case_name : sweep.cases) {
        script << "set title \"" << gnuplot_text(kind.name + " " + integrator.name + ", " + case_name)
               << "\" font ',10' offset 0,0.9\n"
               << "plot $panel" << panel
               << " using 1:2:(0.46):(0.46):3 with boxxyerror fill solid 1.0 noborder lc rgb variable\n";
        ++panel;
      }
    }
  }
  script << "unset multiplot\n";
  return script.str();
}

std::string counts_table(const std::vector<ModelKind>& kinds, const std::vector<Run>& runs) {
  std::ostringstream table;
  char line[160];
  std::snprintf(line, sizeof line, "%-36s %8s %9s %10s %17s %8s\n", "model/integrator", "stable",
                "diverged", "nonfinite", "cg_not_converged", "refused");
  table << line;
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      std::map<Outcome, int> counts;
      for (const Run& run : runs) {
        if (run.model == kind.name && run.integrator == integrator.name) ++counts[run.outcome];
      }
      const std::string name = kind.name + "/" + integrator.name;
      std::snprintf(line, sizeof line, "%-36s %8d %9d %10d %17d %8d\n", name.c_str(),
                    counts[Outcome::stable], counts[Outcome::diverged], counts[Outcome::nonfinite],
                    counts[Outcome::cg_not_converged], counts[Outcome::refused]);
      table << line;
    }
  }
  return table.str();
}

// inverted_start: of the runs that ended stable, how many still had inverted elements (a
// corotational model can settle into an inverted equilibrium instead of recovering).
std::string inverted_table(const std::vector<ModelKind>& kinds, const std::vector<Run>& runs) {
  std::ostringstream table;
  char line[160];
  for (const ModelKind& kind : kinds) {
    for (const Integrator& integrator : kind.integrators) {
      int stable = 0;
      int still_inverted = 0;
      for (const Run& run : runs) {
        if (run.model != kind.name || run.integrator != integrator.name || run.inverted_at_end < 0 ||
            run.outcome != Outcome::stable)
          continue;
        ++stable;
        still_inverted += run.inverted_at_end > 0 ? 1 : 0;
      }
      if (stable == 0) continue;
      const std::string name = kind.name + "/" + integrator.name;
      std::snprintf(line, sizeof line, "%-36s %d of %d stable inverted_start runs ended with inverted elements\n",
                    name.c_str(), still_inverted, stable);
      table << line;
    }
  }
  return table.str();
}

std::string bounds_text(const Sweep& sweep) {
  std::ostringstream text;
  text << "Outcomes (the first that applies): nonfinite = a step stayed non-finite after "
       << max_halvings << " halvings of dt; diverged = elastic + kinetic energy > " << energy_bound
       << " x E_ref (E_ref = max(initial elastic + kinetic energy, M g^2 T^2 / 2, the work of "
          "gravity on the body falling freely for the run's duration T)) or a node displacement > "
       << displacement_bound << " x the body size (largest side of its rest bounding box); "
       << "cg_not_converged = implicit Euler's CG hit its " << cg_max_iterations
       << "-iteration cap (tolerance " << format(cg_tolerance) << ") in more than "
       << 100 * cg_capped_fraction << " % of the run's steps (the run stops when it has); stable otherwise.\n"
       << "guard_events = steps that produced a non-finite value and were retried with dt "
          "halved (2, 4, 8 sub-steps).\n"
       << "Runs: T = " << format(sweep.beam_duration) << " s (beam_gravity), "
       << format(sweep.cube_duration)
       << " s (cubes) of simulated time, stopped at the first divergence; Rayleigh mass damping "
       << format(rayleigh_mass) << "/s; gravity 9.81 m/s^2 along -z; rho " << format(density)
       << " kg/m^3.\n"
       << "refused = the model refused the run: an explicit dt beyond its stability bound (the "
          "mass-spring's 2 sqrt(m_min / k_node_max), the constraint particles' min 2 sqrt(m_i / k_i)), or a brick "
          "its formulas give a non-positive stiffness.\n"
       << "fast_blade and thin_slice cut, which only the efg model does: the others are not run on them.\n";
  return text.str();
}


}  // namespace incise::bench::sweep
