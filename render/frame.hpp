#pragma once

// Plain data the renderer consumes. The engine fills a Frame from its own state;
// nothing here knows about OpenGL, physics or the engine, so the data can be built
// on any thread and handed to the render thread by value.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace render {

struct SurfaceMesh {
    std::vector<float> positions;       // 3 floats per vertex, world space, metres
    std::vector<float> normals;         // 3 per vertex, or empty: the renderer computes area-weighted vertex normals
    std::vector<uint32_t> triangles;    // 3 vertex indices per triangle, counter-clockwise seen from outside
    std::array<float, 3> color{0.85f, 0.45f, 0.42f};  // sRGB, 0..1
};

struct ToolShape {
    enum class Kind { sphere, capsule };
    Kind kind = Kind::sphere;
    std::array<float, 3> a{};
    std::array<float, 3> b{};  // capsule end; equal to a for a sphere
    float radius = 0.005f;
    bool engaged = false;      // in contact with tissue: drawn with a red tint
};

struct Camera {
    std::array<float, 3> eye{0.3f, -0.3f, 0.25f};
    std::array<float, 3> target{0, 0, 0};
    std::array<float, 3> up{0, 0, 1};
    float fov_y_deg = 40;
    float near_plane = 0.01f;
    float far_plane = 10;
};

struct Frame {
    std::vector<SurfaceMesh> meshes;
    std::vector<ToolShape> tools;
    Camera camera;
    bool floor = true;
    float floor_z = 0;
    std::string overlay_text;  // ASCII, '\n' starts a new line; drawn at the top-left corner
};

// A camera looking at the box from a three-quarter view above (z up), far enough
// that the whole box fits in the view for the given width/height aspect ratio.
Camera fit_camera(std::array<float, 3> box_min, std::array<float, 3> box_max, float aspect);

// Where a world point lands in an image of width x height rendered with this camera.
// Continuous pixel coordinates: x to the right, y DOWN from the top-left corner
// (pixel (i, j) covers [i, i+1) x [j, j+1)), i.e. the row order of Image and PNG.
// Points at or behind the eye plane give NaN.
std::array<float, 2> project_to_pixel(const Camera& camera, int width, int height, std::array<float, 3> point);

// Area-weighted vertex normals (unit length; zero for vertices of degenerate triangles only).
std::vector<float> vertex_normals(const std::vector<float>& positions, const std::vector<uint32_t>& triangles);

// Smooth shading that keeps sharp edges sharp, what the renderer draws when
// SurfaceMesh::normals is empty. At each vertex its triangles are grouped by facing, in
// triangle order: a triangle joins the first group whose first triangle faces within
// `crease_degrees` of it, else starts one. The first group keeps the vertex; each other gets
// a copy appended to the positions, and the triangles' corners in it point at the copy. Each
// group's normal is the area-weighted sum of its triangles' (unit length; zero for degenerate
// triangles only, which join the first group). A cut's lip, where the skin meets the cut face
// at about 90 degrees, and a box's edges stay sharp instead of darkening the faces beside
// them; a smooth surface (every vertex one group) is shaded exactly as by vertex_normals.
struct ShadedSurface {
    std::vector<float> positions;
    std::vector<float> normals;
    std::vector<uint32_t> triangles;
};
void crease_shading(const std::vector<float>& positions, const std::vector<uint32_t>& triangles, float crease_degrees,
                    ShadedSurface& out);

}  // namespace render
