#include "render/frame.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/transform.hpp"

namespace render {

Camera fit_camera(std::array<float, 3> box_min, std::array<float, 3> box_max, float aspect) {
    constexpr float pi = 3.14159265358979f;
    if (!(aspect > 0)) aspect = 1;
    Vec3 center = (box_min + box_max) * 0.5f;
    float radius = 0.5f * length(box_max - box_min);
    if (!(radius > 1e-6f)) radius = 1e-3f;

    Camera camera;
    // The bounding sphere has to fit in the narrower of the two view angles.
    float half_y = camera.fov_y_deg * pi / 360.0f;
    float half_x = std::atan(std::tan(half_y) * aspect);
    float half = std::min(half_y, half_x);
    float distance = 1.08f * radius / std::sin(half);

    // Three-quarter view: turned 35 degrees from the -y side, 32 degrees above the horizon,
    // which shows the top and two sides of a block of tissue at once.
    float azimuth = 35 * pi / 180;
    float elevation = 32 * pi / 180;
    Vec3 direction{std::sin(azimuth) * std::cos(elevation), -std::cos(azimuth) * std::cos(elevation),
                   std::sin(elevation)};
    camera.target = center;
    camera.eye = center + direction * distance;
    camera.up = {0, 0, 1};
    // Near as far out as possible for depth precision, far enough to keep the floor
    // (which reaches several scene radii around the scene) mostly unclipped.
    camera.near_plane = std::max((distance - radius) * 0.5f, distance * 1e-3f);
    camera.far_plane = distance + 8 * radius;
    return camera;
}

std::array<float, 2> project_to_pixel(const Camera& camera, int width, int height, std::array<float, 3> point) {
    Mat4 view_projection = view_projection_matrix(camera, width, height);
    Vec4 clip = transform(view_projection, {point[0], point[1], point[2], 1});
    if (!(clip[3] > 0)) {
        float nan = std::numeric_limits<float>::quiet_NaN();
        return {nan, nan};
    }
    float x = clip[0] / clip[3];
    float y = clip[1] / clip[3];
    return {(x * 0.5f + 0.5f) * float(width), (0.5f - y * 0.5f) * float(height)};
}

std::vector<float> vertex_normals(const std::vector<float>& positions, const std::vector<uint32_t>& triangles) {
    std::vector<float> normals(positions.size(), 0.0f);
    size_t vertex_count = positions.size() / 3;
    auto vertex = [&](uint32_t i) { return Vec3{positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]}; };
    for (size_t t = 0; t + 2 < triangles.size(); t += 3) {
        uint32_t i0 = triangles[t], i1 = triangles[t + 1], i2 = triangles[t + 2];
        if (i0 >= vertex_count || i1 >= vertex_count || i2 >= vertex_count) continue;
        // The unnormalised cross product is twice the triangle area along the face
        // normal, which is exactly the area weighting.
        Vec3 face = cross(vertex(i1) - vertex(i0), vertex(i2) - vertex(i0));
        for (uint32_t i : {i0, i1, i2})
            for (int k = 0; k < 3; ++k) normals[3 * i + k] += face[k];
    }
    for (size_t i = 0; i < vertex_count; ++i) {
        Vec3 n{normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]};
        n = normalized(n, {0, 0, 0});
        for (int k = 0; k < 3; ++k) normals[3 * i + k] = n[k];
    }
    return normals;
}

void crease_shading(const std::vector<float>& positions, const std::vector<uint32_t>& triangles, float crease_degrees,
                    ShadedSurface& out) {
    const size_t vertex_count = positions.size() / 3;
    const float cos_crease = std::cos(crease_degrees * 3.14159265f / 180.0f);
    out.positions.assign(positions.begin(), positions.begin() + static_cast<std::ptrdiff_t>(3 * vertex_count));
    out.triangles = triangles;
    auto vertex = [&](uint32_t i) { return Vec3{positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]}; };
    // Per triangle its area vector (twice the area along the normal) and unit normal; per
    // vertex its corners, in triangle order (compressed rows).
    const size_t triangle_count = triangles.size() / 3;
    std::vector<Vec3> area(triangle_count, Vec3{0, 0, 0}), unit(triangle_count, Vec3{0, 0, 0});
    std::vector<uint32_t> start(vertex_count + 1, 0);
    for (size_t t = 0; t < triangle_count; ++t) {
        const uint32_t i0 = triangles[3 * t], i1 = triangles[3 * t + 1], i2 = triangles[3 * t + 2];
        if (i0 >= vertex_count || i1 >= vertex_count || i2 >= vertex_count) continue;
        area[t] = cross(vertex(i1) - vertex(i0), vertex(i2) - vertex(i0));
        unit[t] = normalized(area[t], {0, 0, 0});
        for (uint32_t i : {i0, i1, i2}) ++start[i + 1];
    }
    for (size_t v = 0; v < vertex_count; ++v) start[v + 1] += start[v];
    std::vector<uint32_t> corners(start.back()), fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < triangle_count; ++t) {
        const uint32_t i0 = triangles[3 * t], i1 = triangles[3 * t + 1], i2 = triangles[3 * t + 2];
        if (i0 >= vertex_count || i1 >= vertex_count || i2 >= vertex_count) continue;
        for (uint32_t c = 0; c < 3; ++c) corners[fill[triangles[3 * t + c]]++] = static_cast<uint32_t>(3 * t + c);
    }
    std::vector<Vec3> sums(vertex_count, Vec3{0, 0, 0});
    struct Group {
        Vec3 facing;
        uint32_t index;
    };
    std::vector<Group> groups;
    for (size_t v = 0; v < vertex_count; ++v) {
        groups.clear();
        for (uint32_t k = start[v]; k < start[v + 1]; ++k) {
            const uint32_t corner = corners[k];
            const size_t t = corner / 3;
            const bool degenerate = unit[t][0] == 0 && unit[t][1] == 0 && unit[t][2] == 0;
            size_t g = 0;
            if (!degenerate) {
                // A first group holding only degenerate triangles takes this one's facing.
                if (!groups.empty() && groups[0].facing[0] == 0 && groups[0].facing[1] == 0 && groups[0].facing[2] == 0)
                    groups[0].facing = unit[t];
                while (g < groups.size() && dot(groups[g].facing, unit[t]) < cos_crease) ++g;
                if (g == groups.size()) {
                    uint32_t index = static_cast<uint32_t>(v);
                    if (!groups.empty()) {
                        index = static_cast<uint32_t>(out.positions.size() / 3);
                        for (int c = 0; c < 3; ++c) out.positions.push_back(positions[3 * v + c]);
                        sums.push_back(Vec3{0, 0, 0});
                    }
                    groups.push_back({unit[t], index});
                }
            } else if (groups.empty()) {
                groups.push_back({Vec3{0, 0, 0}, static_cast<uint32_t>(v)});
            }
            const uint32_t index = groups[g].index;
            out.triangles[corner] = index;
            sums[index] = sums[index] + area[t];
        }
    }
    out.normals.resize(out.positions.size());
    for (size_t i = 0; i < sums.size(); ++i) {
        const Vec3 n = normalized(sums[i], {0, 0, 0});
        for (int c = 0; c < 3; ++c) out.normals[3 * i + c] = n[c];
    }
}

}  // namespace render
