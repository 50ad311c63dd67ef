#include "engine/haptic_session.hpp"

#include "haptics/clock.hpp"
#include "physics/core/contact.hpp"
#include "physics/core/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace incise::engine {

namespace {

using physics::Vec3;

Vec3 vec(const std::array<double, 3>& p) { return {p[0], p[1], p[2]}; }

// The tool's contact points in the world after the step.
std::vector<Vec3> tool_points(const World& world) {
  const ToolState& tool = world.tool();
  std::vector<Vec3> points;
  const int capacity = haptics::ContactModel::kCapacity;
  if (world.blade()) {
    if (tool.blade_poses.empty()) return points;
    const auto& edge = tool.blade_poses.back();
    double length = 0;
    for (std::size_t i = 0; i + 1 < edge.size(); ++i) length += (edge[i + 1] - edge[i]).norm();
    if (edge.size() < 2 || length <= 0) return {edge.front()};
    // Evenly along the polyline, ends included.
    for (int k = 0; k < capacity; ++k) {
      double along = length * k / (capacity - 1);
      std::size_t i = 0;
      for (; i + 2 < edge.size(); ++i) {
        const double piece = (edge[i + 1] - edge[i]).norm();
        if (along <= piece) break;
        along -= piece;
      }
      const double piece = (edge[i + 1] - edge[i]).norm();
      points.push_back(piece > 0 ? Vec3(edge[i] + std::min(1.0, along / piece) * (edge[i + 1] - edge[i])) : edge[i]);
    }
    return points;
  }
  const Vec3 tip = vec(tool.tip), tail = vec(tool.tail);
  if ((tail - tip).norm() == 0) return {tip};
  const int count = std::max(2, std::min(capacity, 1 + static_cast<int>(std::ceil((tail - tip).norm() / std::max(tool.radius, 1e-4)))));
  for (int k = 0; k < count; ++k) points.push_back(tip + (static_cast<double>(k) / (count - 1)) * (tail - tip));
  return points;
}

// N/s: how fast the rendered cutting resistance may rise or fall (HapticSession::publish).
constexpr double kCuttingForceRamp = 10;
// N/s: how fast the needle's levels may fall (HapticSession::publish).
constexpr double kNeedleForceRamp = 10;

}  // namespace

haptics::ContactModel build_contact_model(const World& world, const ContactBuild& build) {
  haptics::ContactModel model;
  model.step = build.step;
  model.time_ns = build.time_ns;
  const ToolState& tool = world.tool();
  if (!tool.present) return model;
  // The engine's tools have no dynamics of their own: physics places the blade or the probe
  // exactly where the device was (the ideal blade applies no force, a probe's penalty springs
  // act on the tissue only), so the proxy is the device itself, delayed by a physics step.
  // Coupling the hand to it would render only that delay, as a drag of K v dt (0.3 N at
  // 10 cm/s here) and a pull when the hand stops. The proxy is published for the record
  // (has_proxy false: the loop renders the contact half-spaces alone, at 1 kHz, against the
  // device's current position); a tool that physics constrains would set it.
  model.has_proxy = false;
  model.proxy_position = tool.pose.position;
  model.linearised_at = tool.pose.position;
  model.valid_radius = build.valid_radius;
  model.proxy_velocity = build.proxy_velocity;

  const Scene& scene = world.scene();
  double search = build.search_radius;
  if (search <= 0)
    for (const auto& spec : scene.bodies) search = std::max(search, 3 * spec.resolution);
  if (model.valid_radius <= 0) model.valid_radius = search;
  if (world.needle()) {
    model.needle = needle_resistance(world);
    haptics::validate(model);
    return model;
  }
  const std::vector<Vec3> points = tool_points(world);
  if (points.empty()) return model;
  Vec3 lo = points.front(), hi = points.front();
  for (const auto& p : points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  lo.array() -= search;
  hi.array() += search;

  struct Nearest {
    double distance = 1e300;
    Vec3 point = Vec3::Zero(), normal = Vec3::UnitZ();
    double compliance = 0;
  };
  std::vector<Nearest> nearest(points.size());
  const auto& bodies = world.bodies();
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const Body& body = bodies[b];
    const BodySpec& spec = scene.bodies[b];
    const physics::Vector& x = body.data.embedding ? body.data.surface_positions : body.data.state.positions;
    const double nu = spec.material.poisson_ratio;
    const double compliance = (1 - nu * nu) / (2 * spec.material.youngs_modulus * spec.resolution);
    for (const auto& t : body.data.surface) {
      const Vec3 a = x.segment<3>(3 * t[0]), c1 = x.segment<3>(3 * t[1]), c2 = x.segment<3>(3 * t[2]);
      // Cheap rejection first: most triangles are nowhere near the tool.
      const Vec3 tmin = a.cwiseMin(c1).cwiseMin(c2), tmax = a.cwiseMax(c1).cwiseMax(c2);
      if ((tmin.array() > hi.array()).any() || (tmax.array() < lo.array()).any()) continue;
      const Vec3 face = (c1 - a).cross(c2 - a);
      const double area2 = face.norm();
      if (!(area2 > 0)) continue;
      for (std::size_t i = 0; i < points.size(); ++i) {
        const Vec3& p = points[i];
        if ((p.array() < tmin.array() - search).any() || (p.array() > tmax.array() + search).any()) continue;
        const Vec3 q = physics::closest_point_on_triangle(p, a, c1, c2);
        const double d = (p - q).norm();
        if (d < nearest[i].distance && d <= search) nearest[i] = {d, q, face / area2, compliance};
      }
    }
  }
  double stiffness = scene.tool->stiffness;
  if (!(stiffness > 0)) stiffness = kDefaultBladeStiffness;
  const Vec3 reference = vec(tool.pose.position);
  int found = 0;
  for (const auto& n : nearest) found += n.distance < 1e300 ? 1 : 0;
  // An engaged blade cuts what it enters (seed 004 §2.2: the ideal blade has no volume and
  // applies no force): a point of its edge inside the tissue is where it is cutting, and no
  // surface pushes it out. Without this the blade would be pushed back by the surface it is
  // cutting until the cut surface opens there (it advances by surface cells), and the force
  // would drop at that cut event. What stays is the contact of edge points outside the
  // tissue: the lips beside the blade's flanks. A surface the moving edge runs into (its
  // normal against the blade's velocity) is about to be cut, not pushed against: it would push
  // the hand back over the step and let go at the next publication, once the edge is inside.
  // Before the crack's onset (tool.onset) the engaged blade presses like a probe: every surface
  // pushes it.
  const bool cutting = world.blade() && (tool.pose.buttons & kToolButtonEngaged) != 0 &&
                       (!world.scene().tool->onset || tool.cutting.cutting);
  const Vec3 velocity = vec(build.proxy_velocity);
  const double speed = velocity.norm();
  const Vec3 heading = speed > 1e-3 ? Vec3(velocity / speed) : Vec3::Zero();
  for (std::size_t i = 0; i < points.size() && model.count < haptics::ContactModel::kCapacity; ++i) {
    const Nearest& n = nearest[i];
    if (!(n.distance < 1e300)) continue;
    if (cutting && ((points[i] - n.point).dot(n.normal) < 0 || n.normal.dot(heading) < -0.5)) continue;
    haptics::ContactPoint& c = model.contacts[model.count++];
    const Vec3 shifted = n.point - (points[i] - reference);
    for (int k = 0; k < 3; ++k) c.point[k] = shifted[k], c.normal[k] = n.normal[k];
    c.reach = tool.radius;
    c.stiffness = stiffness / found;
    c.compliance = n.compliance * found;  // the patch is shared too: each point's spring is softer
  }
  // The tissue's resistance to the blade (engine/cutting_resistance.cpp) as the level at which
  // the loop's spring lets the crack front advance (haptics/cutting_proxy.hpp): the toughness
  // times the engaged edge across its motion plus the flanks' friction, whether or not the
  // blade advanced over this step. The hand moves between steps (a window's cursor in jumps a
  // frame apart): it meets the same crack front, and the loop decides when it ruptures. Its
  // direction: the blade's motion over the step, else its last one.
  const double resisting = tool.cutting_force.norm();
  const Vec3 direction = resisting > 0 ? Vec3(-tool.cutting_force / resisting) : vec(build.cutting_direction);
  if (cutting && tool.cutting.cutting && tool.engaged_length > 0 && direction.norm() > 0.5) {
    for (int k = 0; k < 3; ++k) model.cutting.direction[k] = direction[k];
    model.cutting.force =
        world.toughness() * tool.onset_width + world.scene().tool->flank_friction * tool.engaged_length;
  }
  haptics::validate(model);  // non-finite numbers are caught here, where they arise
  return model;
}

ToolSample to_tool_sample(const haptics::TickSample& tick, std::int64_t t0_ns) {
  ToolSample s;
  s.time = 1e-9 * static_cast<double>(tick.time_ns - t0_ns);
  s.position = tick.pose.position;
  s.orientation = tick.pose.orientation;
  s.buttons = (tick.pose.buttons & 0xffu) | (static_cast<std::uint32_t>(tick.state) << kButtonsDeviceStateShift) |
              (tick.clamped ? kButtonClamped : 0u);
  for (int i = 0; i < 3; ++i) s.force[i] = static_cast<float>(tick.force[i]);
  return s;
}

HapticSession::HapticSession(const Scene& scene, haptics::Device& device, SessionOptions options)
    : options_(std::move(options)), device_(device) {
  if (!scene.tool) throw std::runtime_error(scene.file.string() + ": a haptic session needs a `tool`");
  device_.open();
  try {
    loop_ = std::make_unique<haptics::HapticLoop>(device_, channel_, options_.loop);
    if (options_.record) writer_.emplace(*options_.record, options_.record_chunk);
    // The first tick, on this thread: t = 0 and the tool's first sample.
    const bool simulated = options_.clock == SessionOptions::Clock::simulated;
    t0_ns_ = simulated ? 0 : haptics::monotonic_now_ns();
    if (simulated && options_.script) options_.script(0.0);
    const haptics::TickSample first = loop_->tick(t0_ns_);
    next_tick_ns_ = t0_ns_ + static_cast<std::int64_t>(std::llround(1e9 / options_.loop.rate_hz));
    haptics::TickSample popped;
    while (loop_->samples().try_pop(popped)) {
    }
    if (options_.keep_ticks) ticks_.push_back(first);
    const ToolSample sample = to_tool_sample(first, t0_ns_);
    if (writer_) writer_->append(sample), ++samples_recorded_;
    Trajectory start;
    start.samples.push_back(sample);
    world_ = std::make_unique<World>(scene, std::move(start));
    previous_proxy_ = world_->tool().pose.position;
    publish(0);
    if (!simulated) loop_->start();
  } catch (...) {
    if (loop_) loop_->stop();
    device_.close();
    throw;
  }
}

HapticSession::~HapticSession() {
  try {
    stop();
  } catch (...) {
    // A destructor never throws; call stop() to see the error.
  }
}

void HapticSession::take(const haptics::TickSample& tick) {
  const ToolSample sample = to_tool_sample(tick, t0_ns_);
  if (writer_) writer_->append(sample), ++samples_recorded_;
  if (options_.keep_ticks) ticks_.push_back(tick);
  pending_.push_back(sample);
}

void HapticSession::drain() {
  loop_->samples().drain([this](const haptics::TickSample& tick) { take(tick); });
  if (!pending_.empty()) {
    world_->append_tool_samples(pending_);
    pending_.clear();
  }
}

StepStats HapticSession::step() {
  if (stopped_) throw std::logic_error("HapticSession::step after stop()");
  const double end = static_cast<double>(world_->steps_taken() + 1) * world_->dt();
  const bool simulated = options_.clock == SessionOptions::Clock::simulated;
  auto waiting_since = std::chrono::steady_clock::now();
  drain();
  while (!(world_->last_tool_sample_time() > end)) {
    if (simulated) {
      if (options_.script) options_.script(1e-9 * static_cast<double>(next_tick_ns_ - t0_ns_));
      loop_->tick(next_tick_ns_);
      next_tick_ns_ += static_cast<std::int64_t>(std::llround(1e9 / options_.loop.rate_hz));
    } else {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      if (std::chrono::duration<double>(std::chrono::steady_clock::now() - waiting_since).count() > options_.realtime_stall_s)
        throw std::runtime_error("haptic loop: no tick for " + std::to_string(options_.realtime_stall_s) + " s");
    }
    const double before = world_->last_tool_sample_time();
    drain();
    if (world_->last_tool_sample_time() > before) waiting_since = std::chrono::steady_clock::now();
  }
  const StepStats stats = world_->step(step_deadline_ns(end));
  if (stats.cg_budget_stops > 0) {
    ++steps_over_budget_;
    residual_max_over_budget_ = std::max(residual_max_over_budget_, stats.cg_residual);
  }
  const std::vector<CgStop> stops = world_->take_cg_stops();
  if (writer_) writer_->append_cg_stops(stops);
  cut_steps_.push_back(stats.cut_event ? 1 : 0);
  publish(world_->steps_taken());
  return stats;
}

std::int64_t HapticSession::step_deadline_ns(double end) const {
  if (!options_.budget) return 0;
  const double allowed = options_.budget_share * world_->dt();
  if (options_.clock == SessionOptions::Clock::simulated)
    return physics::steady_now_ns() + static_cast<std::int64_t>(std::llround(allowed * 1e9));
  // The hand reaches the next step's end then: physics is a step behind it at most.
  return t0_ns_ + static_cast<std::int64_t>(std::llround((end + allowed) * 1e9));
}

void HapticSession::publish(std::uint64_t step) {
  ContactBuild build;
  build.step = step;
  build.time_ns = t0_ns_ + static_cast<std::int64_t>(std::llround(world_->time() * 1e9));
  const auto& now = world_->tool().pose.position;
  if (step > 0)
    for (int i = 0; i < 3; ++i) build.proxy_velocity[i] = (now[i] - previous_proxy_[i]) / world_->dt();
  previous_proxy_ = now;
  // The cutting resistance's level changes at most kCuttingForceRamp N/s from one model to the
  // next. Rising: an edge that enters the tissue along its whole length (engaged from nothing to
  // all of it in a step) is felt building up over a few steps. Falling: a blade that stops
  // cutting or leaves the tissue lets the load ahead of its edge go over a few steps (the
  // previous direction kept), where the loop's spring would otherwise drop it in a tick.
  const haptics::CuttingResistance previous = last_model_.cutting;
  const haptics::NeedleResistance previous_needle = last_model_.needle;
  if (previous.force > 0) build.cutting_direction = previous.direction;
  last_model_ = build_contact_model(*world_, build);
  haptics::CuttingResistance& cutting = last_model_.cutting;
  const double most = kCuttingForceRamp * world_->dt();
  if (cutting.force > previous.force + most) cutting.force = previous.force + most;
  if (cutting.force < previous.force - most) {
    const double level = previous.force - most;
    if (cutting.force == 0) cutting = previous;  // no blade cutting now: the last one's direction
    cutting.force = level;
  }
  // The needle's levels fall at most kNeedleForceRamp N/s while it stays in the tissue (they
  // rise through the loop's friction spring anyway): the puncture giving way is felt over a few
  // steps rather than in the one tick the loop's fade takes at a short physics step. Leaving the
  // tissue, the last node's friction goes with the fade.
  haptics::NeedleResistance& needle = last_model_.needle;
  const double fall = kNeedleForceRamp * world_->dt();
  if (needle.stiffness > 0 && previous_needle.stiffness > 0) {
    needle.insert_force = std::max(needle.insert_force, previous_needle.insert_force - fall);
    needle.retract_force = std::max(needle.retract_force, previous_needle.retract_force - fall);
  }
  channel_.write(last_model_);
}

void HapticSession::stop() {
  if (stopped_) return;
  stopped_ = true;
  loop_->stop();
  // What the loop produced after the last step is recorded too (the world no longer steps).
  loop_->samples().drain([this](const haptics::TickSample& tick) { take(tick); });
  pending_.clear();
  device_.close();
  if (writer_) writer_->close();
}

ForceJumps force_jumps(const std::vector<haptics::TickSample>& ticks, const std::vector<std::uint8_t>& cut_steps,
                       double period_ms) {
  ForceJumps j;
  j.ticks = ticks.size();
  for (std::size_t i = 1; i < ticks.size(); ++i) {
    const auto& a = ticks[i - 1];
    const auto& b = ticks[i];
    if (!(b.time_ns > a.time_ns)) continue;
    const double ms = std::max(1e-6 * static_cast<double>(b.time_ns - a.time_ns), period_ms);
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += (b.force[k] - a.force[k]) * (b.force[k] - a.force[k]);
    const double rate = std::sqrt(d2) / ms;
    if (b.contact_step != a.contact_step) {
      // Any cut among the steps this tick's model jumped over (a slow tick may skip one).
      bool cut = false;
      for (std::uint64_t k = a.contact_step + 1; k <= b.contact_step && k < cut_steps.size(); ++k) cut = cut || cut_steps[k];
      if (cut) {
        if (rate > j.at_cut_max) j.at_cut_max = rate, j.at_cut_max_ns = b.time_ns;
        ++j.cut_ticks;
      } else {
        if (rate > j.at_publication_max) j.at_publication_max = rate, j.at_publication_max_ns = b.time_ns;
        ++j.publication_ticks;
      }
    } else if (rate > j.between_max) {
      j.between_max = rate;
      j.between_max_ns = b.time_ns;
    }
  }
  return j;
}

nlohmann::json session_summary(const HapticSession& session) {
  const World& world = session.world();
  std::size_t triangles = 0;
  for (const auto& body : world.bodies()) triangles += body.data.surface.size();
  std::ostringstream hash;
  hash << "0x" << std::hex << std::setw(16) << std::setfill('0') << world.state_hash();
  nlohmann::json j = {{"scene", world.scene().name},
                      {"scene_file", world.scene().file.string()},
                      {"steps", world.steps_taken()},
                      {"sim_time_s", world.time()},
                      {"samples_recorded", session.samples_recorded()},
                      {"state_hash", hash.str()},
                      {"surface_triangles", triangles},
                      {"cut_events", world.cut_totals().events},
                      {"real_time",
                       {{"budget", session.budget()},
                        {"steps_over_budget", session.steps_over_budget()},
                        {"cg_stops", world.real_time_budget().deadline_stops()},
                        {"residual_max_over_budget", session.residual_max_over_budget()}}}};
  if (!session.ticks().empty()) {
    const ForceJumps jumps = force_jumps(session.ticks(), session.cut_steps());
    double max_force = 0;
    for (const auto& t : session.ticks()) max_force = std::max(max_force, std::hypot(t.force[0], t.force[1], t.force[2]));
    j["ticks"] = session.ticks().size();
    j["max_force_N"] = max_force;
    j["force_jump_at_cut_N_per_ms"] = {{"max", jumps.at_cut_max}, {"ticks", jumps.cut_ticks}};
    j["force_jump_at_other_publications_N_per_ms"] = {{"max", jumps.at_publication_max}, {"ticks", jumps.publication_ticks}};
    j["force_jump_between_publications_N_per_ms"] = {{"max", jumps.between_max}};
  }
  return j;
}

void write_session_summary(const HapticSession& session, const std::filesystem::path& file) {
  std::ofstream out(file);
  out << session_summary(session).dump(2) << "\n";
  if (!out) throw std::runtime_error(file.string() + ": cannot write the session summary");
}

}  // namespace incise::engine
