// publish: the state as a render frame (the haptic contact model is published by the session).
#include "engine/world.hpp"

#include <algorithm>
#include <cmath>

namespace incise::engine {

void World::fill_frame(render::Frame& frame, int width, int height) const {
  // The organ's capsule, and the parenchyma a cut exposes: darker and redder (sRGB).
  constexpr std::array<float, 3> skin_color{0.85f, 0.45f, 0.42f}, cut_color{0.62f, 0.17f, 0.16f};
  frame.meshes.resize(bodies_.size());
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const auto& body = bodies_[b];
    auto& mesh = frame.meshes[b];
    if (body.data.embedding) {
      const auto& x = body.data.surface_positions;
      mesh.positions.resize(static_cast<std::size_t>(x.size()));
      for (Eigen::Index i = 0; i < x.size(); ++i) mesh.positions[i] = static_cast<float>(x[i]);
    } else {
      mesh.positions.resize(body.model->surface_nodes.size() * 3);
      const auto& x = body.data.state.positions;
      for (std::size_t i = 0; i < body.model->surface_nodes.size(); ++i)
        for (int c = 0; c < 3; ++c)
          mesh.positions[3 * i + c] = static_cast<float>(x[3 * body.model->surface_nodes[i] + c]);
    }
    mesh.normals.clear();
    mesh.color = skin_color;
    // A cut surface changes its triangles, not always their count.
    if (body.cut || mesh.triangles.size() != body.data.render_triangles.size())
      mesh.triangles = body.data.render_triangles;
  }
  // The tissue a cut exposed, drawn apart in its own colour (after the bodies' meshes, which
  // keep their index): its triangles leave the body's mesh, its vertices are the body's.
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const auto& flags = bodies_[b].data.render_cut_face;
    if (std::find(flags.begin(), flags.end(), std::uint8_t{1}) == flags.end()) continue;
    render::SurfaceMesh cut;
    cut.color = cut_color;
    cut.positions = frame.meshes[b].positions;
    std::vector<std::uint32_t> skin;
    const auto& triangles = bodies_[b].data.render_triangles;
    for (std::size_t t = 0; t < flags.size() && 3 * t + 2 < triangles.size(); ++t) {
      auto& to = flags[t] ? cut.triangles : skin;
      const auto corner = triangles.begin() + static_cast<std::ptrdiff_t>(3 * t);
      to.insert(to.end(), corner, corner + 3);
    }
    frame.meshes[b].triangles = std::move(skin);
    frame.meshes.push_back(std::move(cut));
  }
  frame.tools.clear();
  if (blade()) {
    // The cutting edge as thin capsules, red while engaged.
    const auto& edge = tool_.blade_poses.empty() ? std::vector<physics::Vec3>{} : tool_.blade_poses.back();
    for (std::size_t i = 0; i + 1 < edge.size(); ++i) {
      render::ToolShape shape;
      shape.kind = render::ToolShape::Kind::capsule;
      for (int c = 0; c < 3; ++c) {
        shape.a[c] = static_cast<float>(edge[i][c]);
        shape.b[c] = static_cast<float>(edge[i + 1][c]);
      }
      shape.radius = static_cast<float>(tool_.radius);
      shape.engaged = (tool_.pose.buttons & 1u) != 0;
      frame.tools.push_back(shape);
    }
  } else if (tool_.present) {
    render::ToolShape shape;
    shape.kind = scene_.tool->shape == "capsule" || scene_.tool->shape == "needle" ? render::ToolShape::Kind::capsule
                                                 : render::ToolShape::Kind::sphere;
    for (int i = 0; i < 3; ++i) {
      shape.a[i] = static_cast<float>(tool_.tip[i]);
      shape.b[i] = static_cast<float>(tool_.tail[i]);
    }
    shape.radius = static_cast<float>(tool_.radius);
    shape.engaged = (tool_.pose.buttons & 1u) != 0;
    frame.tools.push_back(shape);
  }
  const auto& r = scene_.render;
  frame.floor = r.floor;
  frame.floor_z = static_cast<float>(r.floor_z);
  if (r.camera) {
    for (int i = 0; i < 3; ++i) {
      frame.camera.eye[i] = static_cast<float>(r.camera->eye[i]);
      frame.camera.target[i] = static_cast<float>(r.camera->target[i]);
    }
    frame.camera.fov_y_deg = static_cast<float>(r.camera->fov_deg);
    float span = 0;
    for (int i = 0; i < 3; ++i)
      span = std::max(span, std::abs(frame.camera.eye[i] - frame.camera.target[i]));
    frame.camera.near_plane = span * 0.01f;
    frame.camera.far_plane = span * 20.0f;
  } else {
    std::array<float, 3> lo{}, hi{};
    for (int i = 0; i < 3; ++i) {
      lo[i] = static_cast<float>(bounds_min_[i]);
      hi[i] = static_cast<float>(bounds_max_[i]);
    }
    frame.camera = render::fit_camera(lo, hi, static_cast<float>(width) / static_cast<float>(height));
  }
}

}  // namespace incise::engine
