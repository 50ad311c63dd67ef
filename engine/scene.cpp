#include "engine/scene.hpp"

#include "common/missing_reason.hpp"
#include "engine/model_registry.hpp"
#include "engine/scene_reader.hpp"
#include "engine/tet_mesh_import.hpp"
#include "physics/cut/cutting_resistance.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>

#include <unistd.h>

namespace incise::engine {

using Json = nlohmann::json;

namespace {

std::string join_errors(const std::string& file, const std::vector<std::string>& errors) {
  std::ostringstream out;
  out << file << ": " << errors.size() << (errors.size() == 1 ? " error" : " errors");
  for (const auto& e : errors) out << "\n  " << file << ": " << e;
  return out.str();
}

Box read_box(const Json& node, const std::string& path, std::vector<std::string>& errors) {
  Reader r(node, path, errors);
  Box b;
  b.min = r.point("min", true, {});
  b.max = r.point("max", true, {});
  for (int i = 0; i < 3; ++i) {
    if (b.min[i] > b.max[i]) {
      r.error(path, "min[" + std::to_string(i) + "] " + number_text(b.min[i]) +
                        " is greater than max[" + std::to_string(i) + "] " + number_text(b.max[i]));
      break;
    }
  }
  return b;
}

std::filesystem::path resolve(const std::filesystem::path& scene_file, const std::string& p) {
  std::filesystem::path path(p);
  if (path.is_absolute()) return path;
  return scene_file.parent_path() / path;
}

GeneratorSpec read_generator(const Json& node, const std::string& path,
                             std::vector<std::string>& errors) {
  Reader r(node, path, errors);
  GeneratorSpec g;
  g.type = r.text("type", true, "", {"box", "ellipsoid", "organ", "cylinder", "torus"});
  if (g.type == "box") {
    g.box.min = r.point("min", true, {});
    g.box.max = r.point("max", true, {});
    for (int i = 0; i < 3; ++i)
      if (!(g.box.min[i] < g.box.max[i])) {
        r.error(r.child("max"), "must be greater than min on every axis");
        break;
      }
  } else if (g.type == "ellipsoid" || g.type == "organ") {
    g.center = r.point("center", true, {});
    g.radii = r.point("radii", true, {1, 1, 1}, 1e-6, 100);
  } else if (g.type == "cylinder" || g.type == "torus") {
    g.center = r.point("center", true, {});
    const std::string axis = r.text("axis", false, "z", {"x", "y", "z"});
    g.axis = axis == "x" ? 0 : axis == "y" ? 1 : 2;
    g.radius = r.number("radius", true, 0.01, 0, 100, true);
    if (g.type == "cylinder") g.length = r.number("length", true, 0.05, 0, 100, true);
    if (g.type == "torus") {
      g.major_radius = r.number("major_radius", true, 0.03, 0, 100, true);
      if (r.has("major_radius") && r.has("radius") && !(g.major_radius > g.radius))
        r.error(r.child("major_radius"), "must be greater than radius (the tube would cross the axis)");
    }
  }
  return g;
}

// A model's settings block is the body's key named after it, read by its registry entry; an
// absent block reads as an empty one, so the model fills its defaults and names what it
// requires. The block of another model is refused by name rather than as an unknown key.
void read_model_settings(Reader& r, BodySpec& b, std::vector<std::string>& errors) {
  static const Json empty = Json::object();
  for (const ModelEntry& entry : models().entries()) {
    if (!entry.read_settings) continue;
    const Json* block = r.get(entry.name, false);
    if (entry.name != b.model) {
      if (block) r.error(r.child(entry.name), "only bodies with model '" + entry.name + "' take " + entry.name + " settings");
      continue;
    }
    Reader settings(block ? *block : empty, r.child(entry.name), errors);
    entry.read_settings(settings, b);
  }
}

// A tetrahedral mesh is the body's discretisation; its resolution (the contact's reach and
// stiffness, an efg body's particle spacing) is its mean edge length. Reading the mesh here
// also refuses a bad one before any other work, naming the file and the element.
void tet_mesh_resolution(Reader& r, BodySpec& b) {
  if (!common::missing_reason(*b.mesh).empty() || !(b.mesh_scale > 0)) return;  // refused above
  try {
    b.tets = std::make_shared<const physics::TetMesh>(import_tet_mesh(*b.mesh, b.mesh_scale, b.mesh_up));
    b.resolution = mean_edge_length(*b.tets);
  } catch (const MeshError& e) {
    r.error(r.child("mesh"), e.what());
  }
}

BodySpec read_body(const Json& node, const std::string& path, const std::filesystem::path& file,
                   std::vector<std::string>& errors) {
  Reader r(node, path, errors);
  BodySpec b;
  b.name = r.text("name", true, "");
  if (r.has("name") && b.name.empty()) r.error(r.child("name"), "must not be empty");
  b.model = r.text("model", true, "fem", models().names());
  const ModelEntry* model = models().find(b.model);
  if (const Json* mesh = r.get("mesh", false)) {
    if (!mesh->is_string()) {
      r.error(r.child("mesh"), "must be a file path (string)");
    } else {
      b.mesh = resolve(file, mesh->get<std::string>());
      if (const std::string why = common::missing_reason(*b.mesh); !why.empty())
        r.error(r.child("mesh"), "file '" + b.mesh->string() + "' " + why);
    }
  }
  b.mesh_scale = r.number("mesh_scale", false, 1.0, 0, 1e6, true);
  b.mesh_up = r.text("mesh_up", false, "z", {"x", "y", "z", "-x", "-y", "-z"});
  if (!b.mesh && r.has("mesh_up")) r.error(r.child("mesh_up"), "only a body with a 'mesh' takes mesh_up");
  if (const Json* g = r.get("generator", false)) b.generator = read_generator(*g, r.child("generator"), errors);
  if (b.mesh && b.generator) r.error(path, "give either 'mesh' or 'generator', not both");
  if (!b.mesh && !b.generator && !r.has("mesh")) r.error(path, "needs a 'mesh' or a 'generator'");
  const bool tetrahedra = b.mesh && is_tet_mesh_file(*b.mesh);
  b.resolution = r.number("resolution", !tetrahedra, 0.01, 1e-4, 10, false);
  if (tetrahedra && !r.has("resolution")) tet_mesh_resolution(r, b);
  if (const Json* m = r.get("material", true)) {
    Reader mr(*m, r.child("material"), errors);
    b.material.youngs_modulus = mr.number("E", true, 1e4, 0, 1e12, true);
    b.material.poisson_ratio = mr.number("nu", true, 0.3, 0, 0.5, false, true);
    b.material.density = mr.number("rho", true, 1000, 0, 1e5, true);
    // Fracture toughness, J/m^2 (Mahvash and Hayward 2004's cutting model; liver: 100-300).
    b.material.toughness = mr.number("toughness", false, physics::kLiverToughness, 0, 1e7, true);
  }
  if (const Json* fixed = r.get("fixed", false)) {
    if (!fixed->is_array()) {
      r.error(r.child("fixed"), "must be an array of boxes {\"min\": [...], \"max\": [...]}");
    } else {
      for (std::size_t i = 0; i < fixed->size(); ++i)
        b.fixed.push_back(read_box((*fixed)[i], r.child("fixed") + "[" + std::to_string(i) + "]", errors));
    }
  }
  b.cuttable = r.boolean("cuttable", false);
  if (b.cuttable && model && !model->cuttable) {
    const auto cuttable = models().names_where(&ModelEntry::cuttable);
    r.error(r.child("cuttable"), cuttable.empty() ? "no registered model can be cut"
                                                  : "only " + alternatives(cuttable) + " bodies can be cut");
  }
  read_model_settings(r, b, errors);
  if (const Json* d = r.get("damping", false)) {
    Reader dr(*d, r.child("damping"), errors);
    b.damping_mass = dr.number("mass", false, 0, 0, 1e4);
    b.damping_stiffness = dr.number("stiffness", false, 0, 0, 10);
  }
  return b;
}

// `bodies`: a non-empty array of bodies (read_body), no name used twice.
void read_bodies(Reader& r, const Json& bodies, const std::filesystem::path& file, std::vector<BodySpec>& out,
                 std::vector<std::string>& errors) {
  if (!bodies.is_array() || bodies.empty()) {
    r.error("bodies", "must be a non-empty array");
    return;
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    std::string path = "bodies[" + std::to_string(i) + "]";
    out.push_back(read_body(bodies[i], path, file, errors));
    const auto& n = out.back().name;
    if (!n.empty() && !names.insert(n).second) r.error(path + ".name", "'" + n + "' is used twice");
  }
}

// `tool.edge`: a blade's cutting edge, 2 to 64 distinct consecutive points in the tool's frame.
void read_edge(Reader& tr, const Json& edge, bool blade, std::vector<Point>& out) {
  if (!blade) {
    tr.error("tool.edge", "only a blade has a cutting edge");
    return;
  }
  if (!edge.is_array() || edge.size() < 2 || edge.size() > 64) {
    tr.error("tool.edge", "must be an array of 2 to 64 points [x, y, z] (the cutting edge in the tool's frame)");
    return;
  }
  for (std::size_t i = 0; i < edge.size(); ++i) {
    const Json& point = edge[i];
    const std::string where = "tool.edge[" + std::to_string(i) + "]";
    bool ok = point.is_array() && point.size() == 3;
    for (std::size_t c = 0; ok && c < 3; ++c)
      ok = point[c].is_number() && std::isfinite(point[c].get<double>()) && std::abs(point[c].get<double>()) <= 1;
    if (!ok) {
      tr.error(where, "must be an array of 3 finite numbers within [-1, 1] m");
      continue;
    }
    out.push_back({point[0].get<double>(), point[1].get<double>(), point[2].get<double>()});
  }
  for (std::size_t i = 1; i < out.size(); ++i) {
    double length = 0;
    for (int c = 0; c < 3; ++c) length += (out[i][c] - out[i - 1][c]) * (out[i][c] - out[i - 1][c]);
    if (!(length > 1e-12)) tr.error("tool.edge[" + std::to_string(i) + "]", "repeats the point before it");
  }
}

// `tool.needles`: 1 to 64 needles driven by the one trajectory, each an `offset` (m, the tool's
// frame) and a `delay` (s); without it, one needle at the origin.
void read_needle_template(Reader& tr, std::vector<NeedleEntry>& out) {
  const Json* needles = tr.get("needles", false);
  if (!needles) {
    out.assign(1, NeedleEntry{});
    return;
  }
  if (!needles->is_array() || needles->empty() || needles->size() > 64) {
    tr.error(tr.child("needles"), "must be an array of 1 to 64 needles {\"offset\": [x, y, z], \"delay\": s}");
    return;
  }
  for (std::size_t i = 0; i < needles->size(); ++i) {
    Reader nr((*needles)[i], tr.child("needles") + "[" + std::to_string(i) + "]", tr.errors());
    NeedleEntry e;
    if (const Json* offset = nr.get("offset", false)) {
      bool ok = offset->is_array() && offset->size() == 3;
      for (std::size_t c = 0; ok && c < 3; ++c)
        ok = (*offset)[c].is_number() && std::isfinite((*offset)[c].get<double>()) && std::abs((*offset)[c].get<double>()) <= 1;
      if (ok) e.offset = {(*offset)[0].get<double>(), (*offset)[1].get<double>(), (*offset)[2].get<double>()};
      else nr.error(nr.child("offset"), "must be an array of 3 finite numbers within [-1, 1] m (the tip in the tool's frame)");
    }
    e.delay = nr.number("delay", false, 0, 0, 1e4);
    out.push_back(e);
  }
}

// The needle's own keys (seed 002 §2.3; physics/needle/needle_settings.hpp), refused on other tools.
void read_needle(Reader& tr, bool needle, ToolSpec& t) {
  physics::NeedleSettings& n = t.needle;
  const physics::NeedleSettings d;
  n.nodes = tr.integer("nodes", false, d.nodes, 2, 10000);
  n.cutting_radius = tr.number("cutting_radius", false, d.cutting_radius, 0, 1, true);
  n.friction_radius = tr.number("friction_radius", false, d.friction_radius, 0, 1, true);
  n.cutting_force = tr.number("cutting_force", false, d.cutting_force, 0, 1e4);
  n.puncture_force = tr.number("puncture_force", false, d.puncture_force, 0, 1e4);
  n.friction_force = tr.number("friction_force", false, d.friction_force, 0, 1e4);
  n.stick_stiffness = tr.number("stick_stiffness", false, d.stick_stiffness, 0, 1e9, true);
  n.length = t.length;
  if (needle) {
    read_needle_template(tr, t.needles);
    return;
  }
  if (tr.has("needles")) tr.error(tr.child("needles"), "only a needle tool has it");
  for (const char* key : {"nodes", "cutting_radius", "friction_radius", "cutting_force", "puncture_force", "friction_force",
                          "stick_stiffness"})
    if (tr.has(key)) tr.error(tr.child(key), "only a needle has it");
}

ToolSpec read_tool(const Json& tool, const std::filesystem::path& file, std::vector<std::string>& errors) {
  Reader tr(tool, "tool", errors);
  ToolSpec t;
  t.shape = tr.text("shape", true, "sphere", {"sphere", "capsule", "blade", "needle"});
  const bool blade = t.shape == "blade";
  const bool needle = t.shape == "needle";
  t.radius = tr.number("radius", !blade && !needle, blade || needle ? 0.0005 : 0.005, 0, 1, true);
  t.length = tr.number("length", t.shape == "capsule" || needle, 0, 0, 10, needle);
  t.stiffness = tr.number("stiffness", false, 500, 0, 1e9, true);
  if (needle && tr.has("stiffness")) tr.error(tr.child("stiffness"), "a needle has no penalty contact (its forces are its zones', docs/scenes.md \"Needle\")");
  read_needle(tr, needle, t);
  t.flank_friction = tr.number("flank_friction", false, physics::kDefaultFlankFriction, 0, 1e7);
  if (!blade && tr.has("flank_friction")) tr.error(tr.child("flank_friction"), "only a blade has flanks");
  t.onset = tr.boolean("onset", blade);  // a blade presses until the crack's onset unless told not to
  if (!blade && tr.has("onset")) tr.error(tr.child("onset"), "only a blade cuts");
  if (const Json* edge = tr.get("edge", blade)) read_edge(tr, *edge, blade, t.edge);
  // Optional: a replay needs one (or --trajectory); a live session's device drives the tool.
  if (const Json* traj = tr.get("trajectory", false)) {
    if (!traj->is_string()) {
      tr.error("tool.trajectory", "must be a file path (string)");
    } else {
      t.trajectory = resolve(file, traj->get<std::string>());
      if (const std::string why = common::missing_reason(*t.trajectory); !why.empty())
        tr.error("tool.trajectory", "file '" + t.trajectory->string() + "' " + why);
    }
  }
  return t;
}

void read_solver(const Json& solver, SolverSpec& s, std::vector<std::string>& errors) {
  Reader sr(solver, "solver", errors);
  s.dt = sr.number("dt", true, 0.01, 0, 0.1, true);
  s.tolerance = sr.number("tolerance", false, 1e-6, 0, 1, true, true);
  s.max_iterations = sr.integer("max_iterations", false, 200, 1, 100000);
  s.backend = sr.text("backend", false, "cpu", {"cpu", "gpu"});
  s.precision = sr.text("precision", false, "single", {"single", "double"});
  s.batch_rows = sr.integer("batch_rows", false, 256, 1, 1000000);
  s.gravity = sr.point("gravity", false, {0, 0, -9.81}, -1e4, 1e4);
  s.duration = sr.number("duration", true, 1, 0, 1e5, true);
  s.max_retries = sr.integer("max_retries", false, 3, 0, 20);
  s.preconditioner = sr.text("preconditioner", false, "multigrid_current", {"jacobi", "warped_cholesky", "two_level", "multigrid", "multigrid_current"});
  s.multigrid_smoothing = sr.integer("multigrid_smoothing", false, 0, 1, 8);
  s.multigrid_precision = sr.text("multigrid_precision", false, "double", {"double", "float"});
  s.preconditioner_latency = sr.integer("preconditioner_latency", false, -1, 0, 1000);
  s.start = sr.text("start", false, "rest", {"rest", "settled"});
  s.realtime = sr.boolean("realtime", true);
  s.realtime_min_iterations = sr.integer("realtime_min_iterations", false, 3, 1, 100000);
}

// One load: a body named in `bodies`, a region, and force events at increasing times.
LoadSpec read_load(const Json& node, const std::string& path, const std::vector<BodySpec>& bodies,
                   std::vector<std::string>& errors) {
  Reader lr(node, path, errors);
  LoadSpec l;
  l.body = lr.text("body", true, "");
  bool known = false;
  for (const auto& b : bodies) known = known || b.name == l.body;
  if (lr.has("body") && !l.body.empty() && !known)
    lr.error(path + ".body", "no body is named '" + l.body + "'");
  if (const Json* region = lr.get("region", true)) l.region = read_box(*region, path + ".region", errors);
  if (const Json* events = lr.get("events", true)) {
    if (!events->is_array() || events->empty()) {
      lr.error(path + ".events", "must be a non-empty array of {\"t\": s, \"force\": [N, N, N]}");
    } else {
      for (std::size_t k = 0; k < events->size(); ++k) {
        std::string epath = path + ".events[" + std::to_string(k) + "]";
        Reader er((*events)[k], epath, errors);
        LoadEvent e;
        e.time = er.number("t", true, 0, 0, 1e6);
        e.force = er.point("force", true, {}, -1e6, 1e6);
        if (!l.events.empty() && !(e.time > l.events.back().time))
          er.error(epath + ".t", "times must increase (" + number_text(e.time) +
                                     " follows " + number_text(l.events.back().time) + ")");
        l.events.push_back(e);
      }
    }
  }
  return l;
}

void read_loads(Reader& r, const Json& loads, const std::vector<BodySpec>& bodies, std::vector<LoadSpec>& out,
                std::vector<std::string>& errors) {
  if (!loads.is_array()) {
    r.error("loads", "must be an array");
    return;
  }
  for (std::size_t i = 0; i < loads.size(); ++i)
    out.push_back(read_load(loads[i], "loads[" + std::to_string(i) + "]", bodies, errors));
}

void read_render(const Json& render, RenderSpec& s, std::vector<std::string>& errors) {
  Reader rr(render, "render", errors);
  s.capture_every = rr.integer("capture_every", false, 0, 0, 1000000);
  if (const Json* size = rr.get("size", false)) {
    if (!size->is_array() || size->size() != 2 || !(*size)[0].is_number_integer() ||
        !(*size)[1].is_number_integer() || (*size)[0].get<long long>() < 16 ||
        (*size)[1].get<long long>() < 16 || (*size)[0].get<long long>() > 8192 ||
        (*size)[1].get<long long>() > 8192) {
      rr.error("render.size", "must be [width, height], integers in [16, 8192]");
    } else {
      s.width = (*size)[0].get<int>();
      s.height = (*size)[1].get<int>();
    }
  }
  if (const Json* cam = rr.get("camera", false)) {
    Reader cr(*cam, "render.camera", errors);
    CameraSpec c;
    c.eye = cr.point("eye", true, {});
    c.target = cr.point("target", true, {});
    c.fov_deg = cr.number("fov_deg", false, 40, 1, 170);
    if (c.eye == c.target) cr.error("render.camera.eye", "must differ from target");
    s.camera = c;
  }
  s.floor = rr.boolean("floor", true);
  s.floor_z = rr.number("floor_z", false, 0, -1e6, 1e6);
}

// `plan`: the planned incision (PlanSpec).
PlanSpec read_plan(const Json& node, const std::vector<BodySpec>& bodies, std::vector<std::string>& errors) {
  Reader r(node, "plan", errors);
  PlanSpec plan;
  const auto cuttable = std::find_if(bodies.begin(), bodies.end(), [](const BodySpec& b) { return b.cuttable; });
  plan.body = r.text("body", false, cuttable != bodies.end() ? cuttable->name : "");
  const auto named = std::find_if(bodies.begin(), bodies.end(), [&](const BodySpec& b) { return b.name == plan.body; });
  if (named == bodies.end())
    r.error("plan.body", plan.body.empty() ? "no body is cuttable: a plan needs one" : "no body is named '" + plan.body + "'");
  else if (!named->cuttable)
    r.error("plan.body", "'" + plan.body + "' is not cuttable");
  if (const Json* path = r.get("path", true)) {
    if (!path->is_array() || path->size() < 2 || path->size() > 1000) {
      r.error("plan.path", "must be an array of 2 to 1000 points [x, y, z] (m, at rest), not " + kind_of(*path));
    } else {
      for (std::size_t i = 0; i < path->size(); ++i) {
        const Json& p = (*path)[i];
        bool ok = p.is_array() && p.size() == 3;
        for (std::size_t c = 0; ok && c < 3; ++c)
          ok = p[c].is_number() && std::isfinite(p[c].get<double>()) && std::abs(p[c].get<double>()) <= 10;
        if (!ok) {
          r.error("plan.path[" + std::to_string(i) + "]", "must be an array of 3 finite numbers within [-10, 10] m");
          continue;
        }
        plan.path.push_back({p[0].get<double>(), p[1].get<double>(), p[2].get<double>()});
      }
    }
  }
  plan.depth = r.number("depth", true, 0, 0, 1, true);
  plan.band = r.number("band", true, 0, 0, 1, true);
  plan.direction = r.point("direction", false, plan.direction, -1e6, 1e6);
  const double norm = std::sqrt(plan.direction[0] * plan.direction[0] + plan.direction[1] * plan.direction[1] +
                                plan.direction[2] * plan.direction[2]);
  if (!(norm > 1e-9)) {
    r.error("plan.direction", "must not be the zero vector");
  } else {
    for (double& c : plan.direction) c /= norm;
  }
  // Lengths across the direction: a path along it has none to follow.
  for (std::size_t i = 1; i < plan.path.size(); ++i) {
    double along = 0, length = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = plan.path[i][c] - plan.path[i - 1][c];
      along += d * plan.direction[c];
      length += d * d;
    }
    if (!(length - along * along > 1e-12))
      r.error("plan.path[" + std::to_string(i) + "]", "repeats the point before it, seen along plan.direction");
  }
  return plan;
}

// `expect`: per metric path, a min, a max or both.
void read_expect(Reader& r, const Json& expect, std::vector<Expectation>& out, std::vector<std::string>& errors) {
  if (!expect.is_object()) {
    r.error("expect", "must be an object {\"metric.path\": {\"min\": x, \"max\": y}}");
    return;
  }
  for (const auto& [key, value] : expect.items()) {
    std::string path = "expect." + key;
    Reader er(value, path, errors);
    Expectation e;
    e.metric = key;
    if (er.has("min")) e.min = er.number("min", true, 0, -1e300, 1e300);
    if (er.has("max")) e.max = er.number("max", true, 0, -1e300, 1e300);
    if (value.is_object() && !e.min && !e.max) er.error(path, "needs 'min' or 'max'");
    if (e.min && e.max && *e.min > *e.max) er.error(path, "min is greater than max");
    out.push_back(e);
  }
}

// Memory a body takes per cell of its bounding box at its resolution, measured with
// `incise check` on an ellipsoid (fem 3.2 kB, efg 4.2 kB with its render surface at a / 2),
// and per cell at an efg body's own surface_resolution.
constexpr double kBytesPerCell = 4096;
constexpr double kBytesPerSurfaceCell = 512;

double cells(const Point& lo, const Point& hi, double resolution) {
  double n = 1;
  for (int i = 0; i < 3; ++i) n *= std::max(1.0, std::round((hi[i] - lo[i]) / resolution));
  return n;
}

std::string bytes_text(double bytes) {
  const char* units[] = {"B", "kB", "MB", "GB", "TB", "PB", "EB"};
  int unit = 0;
  while (bytes >= 1000 && unit < 6) {
    bytes /= 1000;
    ++unit;
  }
  std::ostringstream out;
  out.precision(bytes < 10 ? 2 : 3);
  out << bytes << " " << units[unit];
  return out.str();
}

double physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : 0;
}

}  // namespace

int multigrid_smoothing_degree(const SolverSpec& solver) {
  if (solver.multigrid_smoothing > 0) return solver.multigrid_smoothing;
  return solver.preconditioner == "multigrid_current" ? 4 : 2;
}

int preconditioner_latency(const SolverSpec& solver, const std::string& model) {
  if (solver.preconditioner_latency >= 0) return solver.preconditioner_latency;
  return solver.preconditioner == "multigrid_current" && model == "efg" ? 12 : 4;
}

Box generator_bounds(const GeneratorSpec& g) {
  if (g.type == "box") return g.box;
  Point half = g.radii;
  if (g.type == "cylinder" || g.type == "torus") {
    half.fill(g.type == "torus" ? g.major_radius + g.radius : g.radius);
    half[g.axis] = g.type == "torus" ? g.radius : 0.5 * g.length;
  }
  Box b;
  for (int i = 0; i < 3; ++i) {
    b.min[i] = g.center[i] - half[i];
    b.max[i] = g.center[i] + half[i];
  }
  return b;
}

double estimated_bytes(const BodySpec& body, const Point& lo, const Point& hi) {
  double bytes = kBytesPerCell * cells(lo, hi, body.resolution);
  if (body.efg.surface_resolution) bytes += kBytesPerSurfaceCell * cells(lo, hi, *body.efg.surface_resolution);
  return bytes;
}

std::optional<std::string> size_problem(const BodySpec& body, const Point& lo, const Point& hi,
                                        std::optional<double> memory_bytes) {
  const double available = memory_bytes.value_or(physical_memory_bytes());
  const double bytes = estimated_bytes(body, lo, hi);
  if (available <= 0 || bytes <= available) return std::nullopt;
  std::ostringstream out;
  out.precision(3);
  out << number_text(body.resolution) << " m over the body's " << (hi[0] - lo[0]) << " x " << (hi[1] - lo[1])
      << " x " << (hi[2] - lo[2]) << " m bounding box is " << cells(lo, hi, body.resolution)
      << " cells, about " << bytes_text(bytes) << " to build; this machine has " << bytes_text(available)
      << " (coarsen the resolution)";
  return out.str();
}

SceneError::SceneError(const std::string& file, std::vector<std::string> errors)
    : std::runtime_error(join_errors(file, errors)), errors_(std::move(errors)) {}

bool Box::contains(const Point& p, double tolerance) const {
  for (int i = 0; i < 3; ++i)
    if (p[i] < min[i] - tolerance || p[i] > max[i] + tolerance) return false;
  return true;
}

Scene parse_scene(const std::string& text, const std::filesystem::path& file) {
  const std::string name = file.string();
  std::vector<std::string> errors;
  const Json root = parse_scene_json(text, errors);
  if (!errors.empty()) throw SceneError(name, errors);
  Scene scene;
  scene.file = file;
  {
    // Its unknown keys are reported when it goes out of scope, after every section's errors.
    Reader r(root, "", errors);
    scene.name = r.text("name", true, "");
    scene.description = r.text("description", false, "");
    if (const Json* bodies = r.get("bodies", true)) read_bodies(r, *bodies, file, scene.bodies, errors);
    for (std::size_t i = 0; i < scene.bodies.size(); ++i) {
      const BodySpec& b = scene.bodies[i];
      if (!b.generator) continue;  // a mesh's extent is known once it is read (build_body)
      const Box bounds = generator_bounds(*b.generator);
      if (auto problem = size_problem(b, bounds.min, bounds.max))
        r.error("bodies[" + std::to_string(i) + "].resolution", *problem);
    }
    if (const Json* tool = r.get("tool", false)) scene.tool = read_tool(*tool, file, errors);
    if (const Json* solver = r.get("solver", true)) read_solver(*solver, scene.solver, errors);
    if (const Json* loads = r.get("loads", false)) read_loads(r, *loads, scene.bodies, scene.loads, errors);
    if (const Json* render = r.get("render", false)) read_render(*render, scene.render, errors);
    if (const Json* expect = r.get("expect", false)) read_expect(r, *expect, scene.expect, errors);
    if (const Json* plan = r.get("plan", false)) scene.plan = read_plan(*plan, scene.bodies, errors);
  }
  if (!errors.empty()) throw SceneError(name, errors);
  return scene;
}

Scene load_scene(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SceneError(file.string(), {"cannot open the file"});
  // A scene is a few kilobytes; a file this large is not one, and parsing it would take
  // several times its size in memory.
  constexpr std::uintmax_t kMaximumBytes = 16u << 20;
  std::error_code size_error;
  if (const auto bytes = std::filesystem::file_size(file, size_error); !size_error && bytes > kMaximumBytes)
    throw SceneError(file.string(), {"the file has " + std::to_string(bytes) + " bytes; a scene may have at most " +
                                     std::to_string(kMaximumBytes)});
  std::stringstream buffer;
  buffer << in.rdbuf();
  if (buffer.str().empty()) throw SceneError(file.string(), {"the file is empty"});
  return parse_scene(buffer.str(), file);
}

}  // namespace incise::engine
