// Headless rendering checks: what ends up in the pixels, not just that calls succeed.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <stdexcept>
#include <thread>
#include <utility>

#include "render/error.hpp"
#include "render/frame.hpp"
#include "render/image.hpp"
#include "render/offscreen.hpp"

namespace {

using render::Camera;
using render::Frame;
using render::Image;
using render::OffscreenTarget;
using render::SurfaceMesh;
using render::ToolShape;
using Point = std::array<float, 3>;

std::filesystem::path output_directory() {
    std::filesystem::path directory = INCISE_RENDER_TEST_OUTPUT;
    std::filesystem::create_directories(directory);
    return directory;
}

// Subdivided icosahedron: a closed, evenly tessellated surface whose vertex normals
// the renderer must compute itself (normals are left empty on purpose).
SurfaceMesh icosphere(Point center, float radius, int subdivisions) {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    std::vector<Point> points = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                 {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    std::vector<std::array<uint32_t, 3>> faces = {
        {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
        {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
        {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    auto unit = [](Point p) {
        float l = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        return Point{p[0] / l, p[1] / l, p[2] / l};
    };
    for (Point& p : points) p = unit(p);
    for (int level = 0; level < subdivisions; ++level) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoints;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            auto key = std::minmax(a, b);
            auto found = midpoints.find(key);
            if (found != midpoints.end()) return found->second;
            Point m{(points[a][0] + points[b][0]) / 2, (points[a][1] + points[b][1]) / 2,
                    (points[a][2] + points[b][2]) / 2};
            points.push_back(unit(m));
            uint32_t index = uint32_t(points.size() - 1);
            midpoints.emplace(key, index);
            return index;
        };
        std::vector<std::array<uint32_t, 3>> finer;
        for (auto [a, b, c] : faces) {
            uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
            finer.push_back({a, ab, ca});
            finer.push_back({b, bc, ab});
            finer.push_back({c, ca, bc});
            finer.push_back({ab, bc, ca});
        }
        faces = std::move(finer);
    }
    SurfaceMesh mesh;
    for (const Point& p : points)
        for (int k = 0; k < 3; ++k) mesh.positions.push_back(center[k] + radius * p[k]);
    for (const auto& f : faces) mesh.triangles.insert(mesh.triangles.end(), f.begin(), f.end());
    return mesh;
}

// A block of tissue: 6 faces with their own vertices so the computed normals stay flat.
SurfaceMesh box(Point low, Point high) {
    SurfaceMesh mesh;
    auto corner = [&](int i) { return Point{i & 1 ? high[0] : low[0], i & 2 ? high[1] : low[1], i & 4 ? high[2] : low[2]}; };
    // Corner indices per face, counter-clockwise seen from outside.
    const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& face : faces) {
        uint32_t base = uint32_t(mesh.positions.size() / 3);
        for (int i : face) {
            Point p = corner(i);
            mesh.positions.insert(mesh.positions.end(), p.begin(), p.end());
        }
        mesh.triangles.insert(mesh.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    }
    return mesh;
}

std::pair<Point, Point> bounds(const SurfaceMesh& mesh) {
    Point low{1e30f, 1e30f, 1e30f}, high{-1e30f, -1e30f, -1e30f};
    for (size_t i = 0; i < mesh.positions.size(); i += 3)
        for (int k = 0; k < 3; ++k) {
            low[k] = std::min(low[k], mesh.positions[i + k]);
            high[k] = std::max(high[k], mesh.positions[i + k]);
        }
    return {low, high};
}

bool differs(const Image& a, const Image& b, int x, int y) {
    const uint8_t* p = a.pixel(x, y);
    const uint8_t* q = b.pixel(x, y);
    int difference = 0;
    for (int k = 0; k < 3; ++k) difference += std::abs(int(p[k]) - int(q[k]));
    return difference > 6;
}

bool uniform(const Image& image) {
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            if (!std::equal(image.pixel(x, y), image.pixel(x, y) + 4, image.pixel(0, 0))) return false;
    return true;
}

TEST(RenderCapture, MeshPixelsLieInsideProjectedBoundingBox) {
    const int width = 320, height = 240;
    Frame frame;
    frame.floor = false;
    frame.meshes.push_back(icosphere({0.01f, -0.02f, 0.05f}, 0.04f, 3));
    auto [low, high] = bounds(frame.meshes[0]);
    frame.camera = render::fit_camera(low, high, float(width) / height);

    OffscreenTarget target = OffscreenTarget::create(width, height, 4);
    Frame empty = frame;
    empty.meshes.clear();
    Image background = target.render(empty);
    Image image = target.render(frame);
    ASSERT_EQ(image.width, width);
    ASSERT_EQ(image.height, height);
    ASSERT_EQ(image.rgba.size(), size_t(width * height * 4));
    EXPECT_FALSE(uniform(image));

    float left = 1e9f, right = -1e9f, top = 1e9f, bottom = -1e9f;
    for (int i = 0; i < 8; ++i) {
        Point corner{i & 1 ? high[0] : low[0], i & 2 ? high[1] : low[1], i & 4 ? high[2] : low[2]};
        auto pixel = render::project_to_pixel(frame.camera, width, height, corner);
        left = std::min(left, pixel[0]);
        right = std::max(right, pixel[0]);
        top = std::min(top, pixel[1]);
        bottom = std::max(bottom, pixel[1]);
    }
    const float margin = 2;
    int covered = 0, outside = 0;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            if (!differs(image, background, x, y)) continue;
            ++covered;
            float cx = x + 0.5f, cy = y + 0.5f;
            if (cx < left - margin || cx > right + margin || cy < top - margin || cy > bottom + margin) ++outside;
        }
    EXPECT_EQ(outside, 0) << "pixels drawn outside the projected bounding box [" << left << ", " << right << "] x ["
                          << top << ", " << bottom << "]";
    float rectangle = (std::min(right, float(width)) - std::max(left, 0.0f)) *
                      (std::min(bottom, float(height)) - std::max(top, 0.0f));
    ASSERT_GT(rectangle, 0);
    EXPECT_GE(covered, 0.05f * rectangle) << covered << " of " << rectangle << " pixels covered";
    // fit_camera keeps the whole box in view.
    EXPECT_GE(left, 0);
    EXPECT_LE(right, width);
    EXPECT_GE(top, 0);
    EXPECT_LE(bottom, height);
}

TEST(RenderCapture, PngWithFloorHasRightSize) {
    const int width = 640, height = 480;
    Frame frame;
    frame.floor = true;
    frame.floor_z = 0;
    frame.meshes.push_back(box({-0.04f, -0.03f, 0.0f}, {0.04f, 0.03f, 0.025f}));
    frame.meshes.push_back(icosphere({0.0f, 0.0f, 0.025f}, 0.012f, 3));
    frame.meshes.back().color = {0.80f, 0.62f, 0.48f};
    ToolShape probe;
    probe.kind = ToolShape::Kind::capsule;
    probe.a = {0.02f, -0.005f, 0.03f};
    probe.b = {0.05f, -0.03f, 0.075f};
    probe.radius = 0.003f;
    probe.engaged = true;
    frame.tools.push_back(probe);
    frame.overlay_text = "incise render test\nt = 0.000 s";
    frame.camera = render::fit_camera({-0.05f, -0.04f, 0.0f}, {0.05f, 0.04f, 0.06f}, float(width) / height);

    OffscreenTarget target = OffscreenTarget::create(width, height, 4);
    std::cout << "renderer: " << target.renderer_string() << ", MSAA samples: " << target.samples() << "\n";
    Image image = target.render(frame);
    EXPECT_FALSE(uniform(image));

    // The floor shows below the object: the bottom-centre pixel changes when it is turned off.
    Frame no_floor = frame;
    no_floor.floor = false;
    Image without = target.render(no_floor);
    EXPECT_TRUE(differs(image, without, width / 2, height - 5));

    std::filesystem::path path = output_directory() / "render_floor_scene.png";
    render::write_png(path, image);
    std::ifstream file(path, std::ios::binary);
    ASSERT_TRUE(file) << path;
    unsigned char header[24] = {};
    file.read(reinterpret_cast<char*>(header), sizeof header);
    ASSERT_EQ(file.gcount(), 24);
    const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    EXPECT_TRUE(std::equal(signature, signature + 8, header));
    EXPECT_EQ(std::string(reinterpret_cast<char*>(header + 12), 4), "IHDR");
    auto big_endian = [&](int offset) {
        return (uint32_t(header[offset]) << 24) | (uint32_t(header[offset + 1]) << 16) |
               (uint32_t(header[offset + 2]) << 8) | uint32_t(header[offset + 3]);
    };
    EXPECT_EQ(big_endian(16), uint32_t(width));
    EXPECT_EQ(big_endian(20), uint32_t(height));
}

TEST(RenderCapture, ToolAppearsAtItsProjectedCentre) {
    const int width = 320, height = 240;
    Frame frame;
    frame.floor = false;
    ToolShape tool;
    tool.kind = ToolShape::Kind::sphere;
    tool.a = tool.b = {0.0f, 0.0f, 0.04f};
    tool.radius = 0.004f;
    frame.tools.push_back(tool);
    frame.camera = render::fit_camera({-0.03f, -0.03f, 0.0f}, {0.03f, 0.03f, 0.06f}, float(width) / height);

    OffscreenTarget target = OffscreenTarget::create(width, height, 4);
    Frame empty = frame;
    empty.tools.clear();
    Image background = target.render(empty);
    Image image = target.render(frame);

    auto centre = render::project_to_pixel(frame.camera, width, height, tool.a);
    int cx = int(centre[0]), cy = int(centre[1]);
    ASSERT_TRUE(cx >= 2 && cx < width - 2 && cy >= 2 && cy < height - 2);
    for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx) EXPECT_TRUE(differs(image, background, cx + dx, cy + dy)) << dx << "," << dy;

    // Engaged tools are tinted red.
    frame.tools[0].engaged = true;
    Image engaged = target.render(frame);
    auto redness = [&](const Image& im) { return int(im.pixel(cx, cy)[0]) - int(im.pixel(cx, cy)[2]); };
    EXPECT_GT(redness(engaged), redness(image) + 40);
}

TEST(RenderCapture, BackFacesAreLit) {
    // A square facing away from the camera stands in for the inside of a cut: it must
    // be shaded, not black, and drawn in the darker interior colour.
    const int size = 64;
    Frame frame;
    frame.floor = false;
    SurfaceMesh square;
    square.positions = {-0.02f, 0, -0.02f, 0.02f, 0, -0.02f, 0.02f, 0, 0.02f, -0.02f, 0, 0.02f};
    square.triangles = {0, 1, 2, 0, 2, 3};  // counter-clockwise seen from -y
    frame.meshes.push_back(square);
    frame.camera.eye = {0, 0.1f, 0};
    frame.camera.target = {0, 0, 0};
    OffscreenTarget target = OffscreenTarget::create(size, size, 0);
    Image back = target.render(frame);
    frame.camera.eye = {0, -0.1f, 0};
    Image front = target.render(frame);
    const uint8_t* inside = back.pixel(size / 2, size / 2);
    const uint8_t* outside = front.pixel(size / 2, size / 2);
    EXPECT_GT(std::max({inside[0], inside[1], inside[2]}), 60);
    EXPECT_GT(int(outside[1]) - int(inside[1]), 10) << "interior should be darker and redder";
}

TEST(RenderCapture, SeveralTargetsShareTheDisplay) {
    Frame frame;
    frame.meshes.push_back(icosphere({0, 0, 0.05f}, 0.04f, 1));
    frame.camera = render::fit_camera({-0.04f, -0.04f, 0.01f}, {0.04f, 0.04f, 0.09f}, 1.0f);
    auto first = std::make_unique<OffscreenTarget>(OffscreenTarget::create(64, 64, 0));
    OffscreenTarget second = OffscreenTarget::create(48, 32, 4);
    Image before = second.render(frame);
    first.reset();  // must not terminate the display under the second target
    Image after = second.render(frame);
    EXPECT_EQ(after.width, 48);
    EXPECT_EQ(after.height, 32);
    EXPECT_EQ(before.rgba, after.rgba);
}

TEST(RenderCapture, RenderFromAnotherThreadIsRefused) {
    OffscreenTarget target = OffscreenTarget::create(32, 32, 0);
    bool refused = false;
    std::thread other([&] {
        try {
            target.render(Frame{});
        } catch (const render::RenderError&) {
            refused = true;
        }
    });
    other.join();
    EXPECT_TRUE(refused);
}

TEST(RenderCapture, MalformedMeshIsRejected) {
    OffscreenTarget target = OffscreenTarget::create(32, 32, 0);
    Frame frame;
    SurfaceMesh mesh;
    mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    mesh.triangles = {0, 1, 3};
    frame.meshes.push_back(mesh);
    EXPECT_THROW(target.render(frame), std::invalid_argument);
    frame.meshes[0].triangles = {0, 1, 2};
    frame.meshes[0].normals = {0, 0, 1};
    EXPECT_THROW(target.render(frame), std::invalid_argument);
    // The target is still usable after a rejected frame.
    frame.meshes[0].normals.clear();
    EXPECT_NO_THROW(target.render(frame));
}

TEST(RenderMath, ProjectionCentresTheTarget) {
    Camera camera;
    camera.eye = {0.3f, -0.4f, 0.2f};
    camera.target = {0.01f, 0.02f, 0.03f};
    auto pixel = render::project_to_pixel(camera, 200, 100, camera.target);
    EXPECT_NEAR(pixel[0], 100, 1e-3);
    EXPECT_NEAR(pixel[1], 50, 1e-3);
    // Up in the world is up in the picture: smaller row numbers.
    auto above = render::project_to_pixel(camera, 200, 100, {0.01f, 0.02f, 0.05f});
    EXPECT_LT(above[1], pixel[1]);
    // Behind the eye there is no pixel.
    auto behind = render::project_to_pixel(camera, 200, 100, {0.6f, -0.8f, 0.4f});
    EXPECT_TRUE(std::isnan(behind[0]));
}

TEST(RenderMath, AreaWeightedNormals) {
    // Two triangles sharing an edge at a right angle; the big one dominates the shared vertices.
    std::vector<float> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0.1f};
    std::vector<uint32_t> triangles = {0, 1, 2, 0, 3, 1};
    auto normals = render::vertex_normals(positions, triangles);
    ASSERT_EQ(normals.size(), positions.size());
    EXPECT_NEAR(normals[8], 1.0f, 1e-6f);    // vertex 2: only the z-facing triangle
    EXPECT_NEAR(normals[10], 1.0f, 1e-6f);   // vertex 3: only the y-facing triangle
    EXPECT_GT(normals[2], 0.95f);            // vertex 0: area 0.5 vs 0.05
    EXPECT_GT(normals[1], 0.05f);
}

TEST(RenderImage, WritePngNamesThePathOnFailure) {
    Image image;
    image.width = 2;
    image.height = 2;
    image.rgba.assign(16, 255);
    std::filesystem::path path = output_directory() / "no such directory" / "image.png";
    try {
        render::write_png(path, image);
        FAIL() << "expected an exception";
    } catch (const std::runtime_error& error) {
        EXPECT_NE(std::string(error.what()).find("image.png"), std::string::npos) << error.what();
    }
    image.rgba.resize(3);
    EXPECT_THROW(render::write_png(output_directory() / "bad.png", image), std::runtime_error);
}

}  // namespace

TEST(RenderMath, CreaseShadingKeepsABoxsEdgesSharpAndASmoothSurfaceAsItWas) {
    // A unit cube, two triangles per face, outward: each corner meets three faces at 90 degrees.
    const std::vector<float> cube = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    const std::vector<uint32_t> faces = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                         2, 3, 7, 2, 7, 6, 1, 2, 6, 1, 6, 5, 0, 4, 7, 0, 7, 3};
    render::ShadedSurface shaded;
    render::crease_shading(cube, faces, 50.0f, shaded);
    ASSERT_EQ(shaded.positions.size(), 3u * 24u);  // each corner once per face
    ASSERT_EQ(shaded.normals.size(), shaded.positions.size());
    ASSERT_EQ(shaded.triangles.size(), faces.size());
    for (size_t t = 0; t < faces.size() / 3; ++t) {
        // Every corner of a face carries that face's own normal, and the corner's position.
        const uint32_t* c = &shaded.triangles[3 * t];
        const auto p = [&](uint32_t i, int k) { return shaded.positions[3 * i + k]; };
        const float e1[3] = {p(c[1], 0) - p(c[0], 0), p(c[1], 1) - p(c[0], 1), p(c[1], 2) - p(c[0], 2)};
        const float e2[3] = {p(c[2], 0) - p(c[0], 0), p(c[2], 1) - p(c[0], 1), p(c[2], 2) - p(c[0], 2)};
        const float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; ++k) {
            for (int d = 0; d < 3; ++d) {
                EXPECT_EQ(shaded.positions[3 * c[k] + d], cube[3 * faces[3 * t + k] + d]);
                EXPECT_NEAR(shaded.normals[3 * c[k] + d], n[d], 1e-6f) << "triangle " << t;
            }
        }
    }
    // A smooth bowl z = (x^2 + y^2) / 4 over [-1, 1]^2: no vertex split, the normals those of
    // vertex_normals.
    std::vector<float> positions;
    std::vector<uint32_t> triangles;
    const int m = 12;
    for (int j = 0; j <= m; ++j)
        for (int i = 0; i <= m; ++i) {
            const float x = -1 + 2.0f * i / m, y = -1 + 2.0f * j / m;
            positions.insert(positions.end(), {x, y, 0.25f * (x * x + y * y)});
        }
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i) {
            const uint32_t a = static_cast<uint32_t>(j * (m + 1) + i), b = a + 1, c = a + m + 1, d = c + 1;
            triangles.insert(triangles.end(), {a, b, d, a, d, c});
        }
    render::crease_shading(positions, triangles, 50.0f, shaded);
    EXPECT_EQ(shaded.positions, positions);
    EXPECT_EQ(shaded.triangles, triangles);
    const auto smooth = render::vertex_normals(positions, triangles);
    ASSERT_EQ(shaded.normals.size(), smooth.size());
    for (size_t i = 0; i < smooth.size(); ++i) EXPECT_NEAR(shaded.normals[i], smooth[i], 1e-6f);
}
