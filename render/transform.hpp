#pragma once

// Minimal column-major 4x4 matrix maths shared by the GL renderer and by
// project_to_pixel, so that the tests' projection is exactly what the GPU draws.

#include <array>
#include <cmath>

#include "render/frame.hpp"

namespace render {

using Vec3 = std::array<float, 3>;
using Vec4 = std::array<float, 4>;
using Mat4 = std::array<float, 16>;  // column-major, as glProgramUniformMatrix4fv expects with transpose = false

inline Vec3 operator+(Vec3 a, Vec3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 operator*(Vec3 a, float s) { return {a[0] * s, a[1] * s, a[2] * s}; }
inline float dot(Vec3 a, Vec3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross(Vec3 a, Vec3 b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline float length(Vec3 a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalized(Vec3 a, Vec3 fallback = {0, 0, 1}) {
    float l = length(a);
    return l > 1e-20f ? a * (1.0f / l) : fallback;
}

inline Mat4 multiply(const Mat4& a, const Mat4& b) {
    Mat4 r{};
    for (int column = 0; column < 4; ++column)
        for (int row = 0; row < 4; ++row) {
            float sum = 0;
            for (int k = 0; k < 4; ++k) sum += a[k * 4 + row] * b[column * 4 + k];
            r[column * 4 + row] = sum;
        }
    return r;
}

inline Vec4 transform(const Mat4& m, Vec4 v) {
    Vec4 r{};
    for (int row = 0; row < 4; ++row)
        r[row] = m[row] * v[0] + m[4 + row] * v[1] + m[8 + row] * v[2] + m[12 + row] * v[3];
    return r;
}

// Orthonormal camera basis; copes with an up vector parallel to the view direction
// (a camera looking straight down) by borrowing another axis.
struct CameraBasis {
    Vec3 forward, right, up;
};

inline CameraBasis camera_basis(const Camera& camera) {
    Vec3 forward = normalized(camera.target - camera.eye, {0, 1, 0});
    Vec3 up_hint = normalized(camera.up);
    if (std::abs(dot(forward, up_hint)) > 0.999f)
        up_hint = std::abs(forward[1]) < 0.9f ? Vec3{0, 1, 0} : Vec3{1, 0, 0};
    Vec3 right = normalized(cross(forward, up_hint));
    Vec3 up = cross(right, forward);
    return {forward, right, up};
}

inline Mat4 view_matrix(const Camera& camera) {
    CameraBasis basis = camera_basis(camera);
    const Vec3& s = basis.right;
    const Vec3& u = basis.up;
    const Vec3& f = basis.forward;
    const Vec3& e = camera.eye;
    return {s[0], u[0], -f[0], 0,
            s[1], u[1], -f[1], 0,
            s[2], u[2], -f[2], 0,
            -dot(s, e), -dot(u, e), dot(f, e), 1};
}

inline Mat4 projection_matrix(const Camera& camera, float aspect) {
    constexpr float pi = 3.14159265358979f;
    float near_plane = camera.near_plane > 0 ? camera.near_plane : 1e-4f;
    float far_plane = camera.far_plane > near_plane ? camera.far_plane : near_plane * 1000;
    float f = 1.0f / std::tan(camera.fov_y_deg * pi / 360.0f);
    float depth = near_plane - far_plane;
    if (!(aspect > 0)) aspect = 1;
    return {f / aspect, 0, 0, 0,
            0, f, 0, 0,
            0, 0, (far_plane + near_plane) / depth, -1,
            0, 0, 2 * far_plane * near_plane / depth, 0};
}

inline Mat4 view_projection_matrix(const Camera& camera, int width, int height) {
    float aspect = height > 0 ? float(width) / float(height) : 1.0f;
    return multiply(projection_matrix(camera, aspect), view_matrix(camera));
}

}  // namespace render
