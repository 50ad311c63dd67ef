#include "report/run_plots.hpp"

#include "bench/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace incise::report {

namespace {

using Columns = std::vector<std::vector<double>>;

// White background, labelled axes and a grid: the page must read printed.
std::string script_head(const std::string& png, const std::string& title, const std::string& xlabel,
                        const std::string& ylabel) {
  return "set terminal pngcairo size 960,340 font ',10' background rgb '#ffffff'\n"
         "set output '" + png + "'\nset title '" + title + "'\nset xlabel '" + xlabel + "'\nset ylabel '" + ylabel +
         "'\nset grid lc rgb '#dddddd'\nset key outside right top\nset border lw 1.2\n"
         "set autoscale xfix\n";  // every time axis spans the run exactly, so the plots line up
}

// A gnuplot datablock (`$data` unless named) with one row per step, the columns given (NaN where unknown).
std::string inline_data(const Columns& columns, const std::string& name = "$data") {
  std::ostringstream data;
  data.precision(9);
  data << name << " << EOD\n";
  const std::size_t rows = columns.empty() ? 0 : columns.front().size();
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const double v = r < columns[c].size() ? columns[c][r] : NAN;
      data << (c ? " " : "") << (std::isfinite(v) ? std::to_string(v) : "NaN");
    }
    data << "\n";
  }
  data << "EOD\n";
  return data.str();
}

// The steps that severed links, merged into time intervals and shaded behind the curves:
// the cut events on the time axis.
std::string cut_shading(const std::vector<double>& time, const std::vector<double>& severed) {
  std::string objects;
  const double half_step = time.size() > 1 ? 0.5 * (time[1] - time[0]) : 0.0;
  std::size_t k = 0;
  while (k < severed.size()) {
    if (!(severed[k] > 0)) {
      ++k;
      continue;
    }
    std::size_t end = k;
    while (end + 1 < severed.size() && severed[end + 1] > 0) ++end;
    objects += "set object rectangle from " + std::to_string(time[k] - half_step) + ", graph 0 to " +
               std::to_string(time[end] + half_step) +
               ", graph 1 fc rgb '#ffcccc' fs solid 0.6 noborder behind\n";
    k = end + 1;
  }
  return objects;
}

// 1 for each step that cut (changed the topology, or severed links in an older steps.csv
// without cut_event), else 0.
std::vector<double> cut_steps(const CsvTable& steps) {
  const auto events = steps.column("cut_event"), severed = steps.column("links_severed");
  std::vector<double> cut(steps.rows.size(), 0.0);
  for (std::size_t k = 0; k < cut.size(); ++k)
    cut[k] = (k < events.size() && events[k] > 0) || (k < severed.size() && severed[k] > 0) ? 1.0 : 0.0;
  return cut;
}

struct Context {
  const CsvTable& steps;
  std::filesystem::path out_dir;
  std::ostream& progress;
  std::vector<double> time;
  std::string shading;
  RunPlots result;

  void draw(const std::string& id, const std::string& title, const std::string& script) {
    bench::draw_with_gnuplot(out_dir, id + ".gp", script, id + ".png", progress);
    result.plots.push_back({out_dir / (id + ".png"), title, id});
  }
  bool need(const std::vector<std::string>& names, const std::string& what) {
    for (const auto& n : names)
      if (!steps.has(n)) {
        result.notes.push_back(what + ": not drawn (steps.csv has no " + n + " column)");
        return false;
      }
    return true;
  }
};

void forces_plot(Context& c) {
  if (!c.need({"tool_force_x", "tool_force_y", "tool_force_z"}, "Tool force")) return;
  const auto fx = c.steps.column("tool_force_x"), fy = c.steps.column("tool_force_y"), fz = c.steps.column("tool_force_z");
  std::vector<double> magnitude(fx.size());
  for (std::size_t k = 0; k < fx.size(); ++k) magnitude[k] = std::sqrt(fx[k] * fx[k] + fy[k] * fy[k] + fz[k] * fz[k]);
  c.draw("forces", "Tool force",
         script_head("forces.png", "Tool force (shaded: steps that cut)", "time (s)", "force (N)") + c.shading +
             inline_data({c.time, fx, fy, fz, magnitude}) +
             "plot $data using 1:2 with lines lw 1.5 title 'F_x', '' using 1:3 with lines lw 1.5 title 'F_y', "
             "'' using 1:4 with lines lw 1.5 title 'F_z', '' using 1:5 with lines lw 2.5 lc rgb '#000000' title '|F|'\n");
}

// Stacked: each band is a phase, the top curve the step's total.
void phases_plot(Context& c) {
  static const std::vector<std::string> phases = {"ms_tool_input", "ms_contact", "ms_ccd", "ms_topology", "ms_solve", "ms_surface"};
  Columns columns = {c.time};
  std::vector<std::string> names;
  std::vector<double> sum(c.time.size(), 0.0);
  for (const auto& p : phases) {
    if (!c.steps.has(p)) continue;
    const auto v = c.steps.column(p);
    for (std::size_t k = 0; k < sum.size(); ++k) sum[k] += std::isfinite(v[k]) ? v[k] : 0.0;
    columns.push_back(sum);
    std::string name = p.substr(3);
    std::replace(name.begin(), name.end(), '_', ' ');  // gnuplot would read _ as a subscript
    names.push_back(name);
  }
  if (names.empty()) {
    c.result.notes.push_back("Step time per phase: not drawn (steps.csv has no ms_* phase column)");
    return;
  }
  if (c.steps.has("ms_total")) {
    auto total = c.steps.column("ms_total");
    for (std::size_t k = 0; k < total.size(); ++k) total[k] = std::max(total[k], sum[k]);
    columns.push_back(total);
    names.push_back("other");
  }
  std::string plot = "plot ";
  for (std::size_t i = names.size(); i-- > 0;)
    plot += "$data using 1:" + std::to_string(i + 2) + " with filledcurves x1 title '" + names[i] + "'" + (i ? ", " : "\n");
  c.draw("phases", "Step time per phase",
         script_head("phases.png", "Step time per phase, stacked (shaded: steps that cut)", "time (s)", "ms per step") +
             c.shading + "set style fill solid 0.85 noborder\n" + inline_data(columns) + plot);
}

void single_series_plot(Context& c, const std::string& id, const std::string& title, const std::string& ylabel,
                        const std::vector<std::pair<std::string, std::string>>& series) {
  std::vector<std::string> names;
  for (const auto& s : series) names.push_back(s.first);
  if (!c.need(names, title)) return;
  Columns columns = {c.time};
  std::string plot = "plot ";
  for (std::size_t i = 0; i < series.size(); ++i) {
    columns.push_back(c.steps.column(series[i].first));
    plot += "$data using 1:" + std::to_string(i + 2) + " with lines lw 1.8 title '" + series[i].second + "'" +
            (i + 1 < series.size() ? ", " : "\n");
  }
  c.draw(id, title, script_head(id + ".png", title + " (shaded: steps that cut)", "time (s)", ylabel) + c.shading +
                        inline_data(columns) + plot);
}

// One bar per step that changed the topology; links severed (EFG volume cuts) beside them.
void cuts_plot(Context& c) {
  if (!c.steps.has("cut_event") && !c.steps.has("links_severed")) {
    c.result.notes.push_back("Cut events: not drawn (steps.csv has neither cut_event nor links_severed)");
    return;
  }
  const auto events = c.steps.has("cut_event") ? c.steps.column("cut_event") : std::vector<double>(c.time.size(), NAN);
  const auto severed = c.steps.has("links_severed") ? c.steps.column("links_severed") : std::vector<double>(c.time.size(), NAN);
  c.draw("cuts", "Cut events",
         script_head("cuts.png", "Cut events: steps that changed the topology, links severed", "time (s)",
                     "cut event (1: yes)") +
             "set yrange [0:1.2]\nset y2range [0:*]\nset y2label 'links severed'\nset y2tics\nset ytics nomirror\n" +
             inline_data({c.time, events, severed}) +
             "plot $data using 1:2 with impulses lw 3 lc rgb '#cc0000' title 'cut event', "
             "'' using 1:3 axes x1y2 with points pt 7 ps 0.5 lc rgb '#404040' title 'links severed'\n");
}

// Millimetres of a column (m).
std::vector<double> millimetres(const CsvTable& table, const char* column) {
  auto v = table.column(column);
  for (auto& x : v) x *= 1000.0;
  return v;
}

// The planned incision (a blue line) and the cut path at rest (the wound's mouth, black
// segments), when the run has them.
void add_plan_and_cut(const TopView& top, std::string& data, std::string& plot) {
  if (top.plan && top.plan->has("x") && top.plan->has("y") && !top.plan->rows.empty()) {
    data += inline_data({millimetres(*top.plan, "x"), millimetres(*top.plan, "y")}, "$plan");
    plot += std::string(plot.empty() ? "" : ", ") + "$plan using 1:2 with lines lw 3 lc rgb '#3060d0' title 'plan'";
  }
  const CsvTable* cut = top.cut_path;
  if (cut && cut->has("x0") && cut->has("y0") && cut->has("x1") && cut->has("y1") && !cut->rows.empty()) {
    const auto x0 = millimetres(*cut, "x0"), y0 = millimetres(*cut, "y0"), x1 = millimetres(*cut, "x1"),
               y1 = millimetres(*cut, "y1");
    std::vector<double> dx(x0.size()), dy(y0.size());
    for (std::size_t k = 0; k < x0.size(); ++k) dx[k] = x1[k] - x0[k], dy[k] = y1[k] - y0[k];
    data += inline_data({x0, y0, dx, dy}, "$cut");
    plot += std::string(plot.empty() ? "" : ", ") + "$cut using 1:2:3:4 with vectors nohead lw 2 lc rgb '#000000' title 'cut path (at rest)'";
  }
}

// The organ at rest from above (its surface, grey) under the tool tip's path (x-y, mm),
// coloured by time, the steps that cut in red; with a plan, the plan and the cut path at rest.
void top_view_plot(Context& c, const TopView& top) {
  const bool path = c.steps.has("tool_x") && c.steps.has("tool_y");
  const CsvTable* rest_top = top.rest_top;
  const bool organ = rest_top && rest_top->has("x") && rest_top->has("y") && !rest_top->rows.empty();
  if (!path) c.result.notes.push_back("Cut path from above: not drawn (steps.csv has no tool_x, tool_y columns)");
  if (!organ && !path) return;
  std::string data, plot;
  if (organ) {
    data += inline_data({millimetres(*rest_top, "x"), millimetres(*rest_top, "y")}, "$rest");
    plot += "$rest using 1:2 with points pt 7 ps 0.35 lc rgb '#c8c8c8' title 'organ at rest'";
  }
  if (path) {
    const auto x = millimetres(c.steps, "tool_x"), y = millimetres(c.steps, "tool_y");
    std::vector<double> cut_x(x.size(), NAN), cut_y(y.size(), NAN);
    const auto cutting = cut_steps(c.steps);
    for (std::size_t k = 0; k < cutting.size() && k < x.size(); ++k)
      if (cutting[k] > 0) cut_x[k] = x[k], cut_y[k] = y[k];
    data += inline_data({c.time, x, y, cut_x, cut_y});
    plot += std::string(organ ? ", " : "") + "$data using 2:3:1 with lines lw 2 lc palette title 'tool tip', "
            "'' using 4:5 with points pt 7 ps 0.6 lc rgb '#cc0000' title 'cutting'";
  }
  add_plan_and_cut(top, data, plot);
  c.draw("top_view", "From above: the organ at rest and the cut path",
         "set terminal pngcairo size 960,520 font ',10' background rgb '#ffffff'\nset output 'top_view.png'\n"
         "set title 'From above: the organ at rest" + std::string(path ? ", the tool tip (colour: time; red: steps that cut)" : "") +
             "'\nset xlabel 'x (mm)'\nset ylabel 'y (mm)'\nset size ratio -1\nset grid lc rgb '#dddddd'\n"
             "set key outside right top\nset cblabel 'time (s)'\n"
             "set palette defined (0 '#2040a0', 1 '#20a0a0', 2 '#a0a020')\n" +
             data + "plot " + plot + "\n");
}

}  // namespace

bool gnuplot_installed() { return std::system("command -v gnuplot > /dev/null 2>&1") == 0; }

RunPlots draw_run_plots(const CsvTable& steps, const TopView& top, const std::filesystem::path& out_dir,
                        std::ostream& progress) {
  std::filesystem::create_directories(out_dir);
  Context c{steps, out_dir, progress, {}, {}, {}};
  c.time = steps.has("time_s") ? steps.column("time_s") : steps.column("step");
  if (c.time.empty()) {
    for (std::size_t k = 0; k < steps.rows.size(); ++k) c.time.push_back(static_cast<double>(k + 1));
  }
  c.shading = cut_shading(c.time, cut_steps(steps));
  forces_plot(c);
  phases_plot(c);
  single_series_plot(c, "cg", "CG iterations", "iterations per step", {{"cg_iterations", "CG iterations"}});
  single_series_plot(c, "energy", "Energy", "energy (J)",
                     {{"elastic_energy_J", "elastic"}, {"kinetic_energy_J", "kinetic"}});
  cuts_plot(c);
  top_view_plot(c, top);
  return std::move(c.result);
}

}  // namespace incise::report
