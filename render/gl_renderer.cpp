#include "render/gl_renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "render/error.hpp"
#include "render/gl.hpp"
#include "render/transform.hpp"

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#endif
#include <stb_easy_font.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

namespace render {
namespace {

// Neighbouring triangles facing further apart than this meet at a sharp edge (crease_shading):
// a fairly meshed organ's meet at a few degrees, a cut's lip at about 90.
constexpr float crease_degrees = 50.0f;

// Lighting is computed in linear space and gamma-encoded at the end, so colours given
// in sRGB (as in SurfaceMesh::color) come out as picked and highlights do not wash out.
// Material colours are linearised on the CPU: per fragment it costs llvmpipe measurably.
constexpr const char* surface_vertex_source = R"(#version 450 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 0) uniform mat4 view_projection;
out vec3 world_position;
out vec3 world_normal;
void main() {
    world_position = position;
    world_normal = normal;
    gl_Position = view_projection * vec4(position, 1.0);
}
)";

constexpr const char* surface_fragment_source = R"(#version 450 core
in vec3 world_position;
in vec3 world_normal;
layout(location = 1) uniform vec3 eye_position;
layout(location = 2) uniform vec3 key_direction;
layout(location = 3) uniform vec3 fill_direction;
layout(location = 4) uniform vec3 base_color;  // linear
layout(location = 5) uniform vec3 back_color;  // linear
layout(location = 6) uniform float specular_strength;
layout(location = 7) uniform float shininess;
out vec4 fragment_color;

vec3 shade_light(vec3 n, vec3 v, vec3 l, vec3 radiance, vec3 albedo) {
    float diffuse = max(dot(n, l), 0.0);
    vec3 h = normalize(l + v);
    float specular = diffuse > 0.0 ? pow(max(dot(n, h), 0.0), shininess) * specular_strength : 0.0;
    return radiance * (albedo * diffuse + vec3(specular));
}

void main() {
    // Two-sided: a face seen from behind (the inside of a cut) is lit as if its normal
    // pointed at the viewer, and gets its own colour so interiors read as interiors.
    float normal_length = length(world_normal);
    vec3 n;
    if (normal_length > 1e-6) {
        n = (gl_FrontFacing ? world_normal : -world_normal) / normal_length;
    } else {
        n = normalize(cross(dFdx(world_position), dFdy(world_position)));
    }
    vec3 v = normalize(eye_position - world_position);
    vec3 albedo = gl_FrontFacing ? base_color : back_color;
    float sky = 0.5 + 0.5 * n.z;
    vec3 color = albedo * mix(vec3(0.05, 0.045, 0.045), vec3(0.17, 0.18, 0.20), sky);
    color += shade_light(n, v, key_direction, vec3(1.0, 0.96, 0.90), albedo);
    color += shade_light(n, v, fill_direction, vec3(0.30, 0.33, 0.38), albedo);
    fragment_color = vec4(pow(color, vec3(1.0 / 2.2)), 1.0);
}
)";

constexpr const char* background_vertex_source = R"(#version 450 core
out float height;
void main() {
    vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
    height = p.y * 0.5 + 0.5;
    gl_Position = vec4(p, 1.0, 1.0);
}
)";

constexpr const char* background_fragment_source = R"(#version 450 core
in float height;
layout(location = 0) uniform vec3 top_color;
layout(location = 1) uniform vec3 bottom_color;
out vec4 fragment_color;
void main() {
    fragment_color = vec4(mix(bottom_color, top_color, smoothstep(0.0, 1.0, height)), 1.0);
}
)";

constexpr const char* floor_vertex_source = R"(#version 450 core
layout(location = 0) uniform mat4 view_projection;
layout(location = 1) uniform vec3 floor_center;
layout(location = 2) uniform float half_extent;
out vec3 world_position;
void main() {
    vec2 corner = vec2((gl_VertexID & 1) == 0 ? -1.0 : 1.0, (gl_VertexID & 2) == 0 ? -1.0 : 1.0);
    world_position = floor_center + vec3(corner * half_extent, 0.0);
    gl_Position = view_projection * vec4(world_position, 1.0);
}
)";

constexpr const char* floor_fragment_source = R"(#version 450 core
in vec3 world_position;
layout(location = 1) uniform vec3 floor_center;
layout(location = 2) uniform float half_extent;
layout(location = 3) uniform float grid_spacing;
layout(location = 4) uniform vec3 shadow_disc;
layout(location = 5) uniform float shadow_strength;
out vec4 fragment_color;

// Anti-aliased grid lines of `width` pixels; lines closer together than a few pixels
// fade out instead of turning into moire at grazing angles.
float line_coverage(vec2 p, float spacing, float width) {
    vec2 cell = p / spacing;
    vec2 footprint = max(fwidth(cell), vec2(1e-6));
    vec2 distance_pixels = abs(fract(cell - 0.5) - 0.5) / footprint;
    float d = min(distance_pixels.x, distance_pixels.y);
    float coverage = 1.0 - smoothstep(0.5 * width - 0.5, 0.5 * width + 0.5, d);
    float density = max(footprint.x, footprint.y);
    return coverage * (1.0 - smoothstep(0.15, 0.45, density));
}

void main() {
    vec2 p = world_position.xy;
    float r = length(p - floor_center.xy) / half_extent;
    float fade = 1.0 - smoothstep(0.45, 1.0, r);
    vec3 color = vec3(0.47, 0.49, 0.52);
    color = mix(color, vec3(0.36, 0.38, 0.41), line_coverage(p, grid_spacing, 1.0));
    color = mix(color, vec3(0.27, 0.29, 0.32), line_coverage(p, grid_spacing * 5.0, 1.7));
    // A soft contact shadow under the scene grounds it without a shadow pass.
    float s = length(p - shadow_disc.xy) / shadow_disc.z;
    color *= 1.0 - shadow_strength * exp(-1.6 * s * s);
    fragment_color = vec4(color, fade);
}
)";

constexpr const char* text_vertex_source = R"(#version 450 core
layout(location = 0) in vec2 pixel;
layout(location = 0) uniform vec2 viewport_size;
layout(location = 1) uniform vec2 offset;
void main() {
    vec2 p = (pixel + offset) / viewport_size;
    gl_Position = vec4(p.x * 2.0 - 1.0, 1.0 - p.y * 2.0, 0.0, 1.0);
}
)";

constexpr const char* text_fragment_source = R"(#version 450 core
layout(location = 2) uniform vec4 color;
out vec4 fragment_color;
void main() {
    fragment_color = color;
}
)";

GLuint compile_shader(GLenum type, const char* source, const char* name) {
    GLuint shader = glCreateShader(type);
    glShaderSource(shader, 1, &source, nullptr);
    glCompileShader(shader);
    GLint ok = GL_FALSE;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (ok != GL_TRUE) {
        GLint size = 0;
        glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &size);
        std::string log(size_t(std::max(size, 1)), '\0');
        glGetShaderInfoLog(shader, GLsizei(log.size()), nullptr, log.data());
        glDeleteShader(shader);
        throw RenderError(std::string("compiling the ") + name +
                          (type == GL_VERTEX_SHADER ? " vertex" : " fragment") + " shader failed:\n" + log.c_str());
    }
    return shader;
}

GLuint link_program(const char* vertex_source, const char* fragment_source, const char* name) {
    GLuint vertex = compile_shader(GL_VERTEX_SHADER, vertex_source, name);
    GLuint fragment = 0;
    try {
        fragment = compile_shader(GL_FRAGMENT_SHADER, fragment_source, name);
    } catch (...) {
        glDeleteShader(vertex);
        throw;
    }
    GLuint program = glCreateProgram();
    glAttachShader(program, vertex);
    glAttachShader(program, fragment);
    glLinkProgram(program);
    glDetachShader(program, vertex);
    glDetachShader(program, fragment);
    glDeleteShader(vertex);
    glDeleteShader(fragment);
    GLint ok = GL_FALSE;
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    if (ok != GL_TRUE) {
        GLint size = 0;
        glGetProgramiv(program, GL_INFO_LOG_LENGTH, &size);
        std::string log(size_t(std::max(size, 1)), '\0');
        glGetProgramInfoLog(program, GLsizei(log.size()), nullptr, log.data());
        glDeleteProgram(program);
        throw RenderError(std::string("linking the ") + name + " shader program failed:\n" + log.c_str());
    }
    return program;
}

struct MeshBuffers {
    GLuint vertex_array = 0;
    GLuint positions = 0;
    GLuint normals = 0;
    GLuint indices = 0;
};

MeshBuffers create_mesh_buffers() {
    MeshBuffers b;
    glCreateVertexArrays(1, &b.vertex_array);
    GLuint buffers[3];
    glCreateBuffers(3, buffers);
    b.positions = buffers[0];
    b.normals = buffers[1];
    b.indices = buffers[2];
    glVertexArrayVertexBuffer(b.vertex_array, 0, b.positions, 0, 3 * sizeof(float));
    glVertexArrayAttribFormat(b.vertex_array, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(b.vertex_array, 0, 0);
    glEnableVertexArrayAttrib(b.vertex_array, 0);
    glVertexArrayVertexBuffer(b.vertex_array, 1, b.normals, 0, 3 * sizeof(float));
    glVertexArrayAttribFormat(b.vertex_array, 1, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(b.vertex_array, 1, 1);
    glEnableVertexArrayAttrib(b.vertex_array, 1);
    glVertexArrayElementBuffer(b.vertex_array, b.indices);
    return b;
}

void destroy_mesh_buffers(MeshBuffers& b) {
    GLuint buffers[3] = {b.positions, b.normals, b.indices};
    glDeleteBuffers(3, buffers);
    glDeleteVertexArrays(1, &b.vertex_array);
    b = {};
}

void validate(const SurfaceMesh& mesh, size_t index) {
    auto fail = [&](const std::string& why) {
        throw std::invalid_argument("render: mesh " + std::to_string(index) + ": " + why);
    };
    if (mesh.positions.size() % 3 != 0) fail("positions size is not a multiple of 3");
    if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
        fail("normals must be empty or have one normal per vertex");
    if (mesh.triangles.size() % 3 != 0) fail("triangles size is not a multiple of 3");
    size_t vertex_count = mesh.positions.size() / 3;
    for (uint32_t i : mesh.triangles)
        if (i >= vertex_count)
            fail("triangle index " + std::to_string(i) + " out of range for " + std::to_string(vertex_count) +
                 " vertices");
}

// A capsule around the segment a-b as two hemispheres joined by a cylinder; with
// a == b it is a sphere. Normals are exact, so no normal computation is needed.
void build_capsule(const ToolShape& tool, SurfaceMesh& out) {
    constexpr int segments = 28;
    constexpr int rings = 8;  // per hemisphere
    constexpr float pi = 3.14159265358979f;
    Vec3 a = tool.a;
    Vec3 b = tool.kind == ToolShape::Kind::capsule ? tool.b : tool.a;
    float radius = std::max(tool.radius, 1e-6f);
    Vec3 axis = b - a;
    Vec3 direction = normalized(axis, {0, 0, 1});
    Vec3 helper = std::abs(direction[2]) < 0.9f ? Vec3{0, 0, 1} : Vec3{1, 0, 0};
    Vec3 p = normalized(cross(direction, helper));
    Vec3 q = cross(direction, p);

    out.positions.clear();
    out.normals.clear();
    out.triangles.clear();
    constexpr int ring_count = 2 * (rings + 1);
    for (int ring = 0; ring < ring_count; ++ring) {
        bool upper = ring > rings;
        int step = upper ? ring - (rings + 1) : ring;
        float latitude = upper ? 0.5f * pi * float(step) / rings : -0.5f * pi + 0.5f * pi * float(step) / rings;
        Vec3 center = upper ? b : a;
        for (int s = 0; s < segments; ++s) {
            float longitude = 2 * pi * float(s) / segments;
            Vec3 around = p * std::cos(longitude) + q * std::sin(longitude);
            Vec3 normal = around * std::cos(latitude) + direction * std::sin(latitude);
            Vec3 position = center + normal * radius;
            out.positions.insert(out.positions.end(), position.begin(), position.end());
            out.normals.insert(out.normals.end(), normal.begin(), normal.end());
        }
    }
    for (int ring = 0; ring + 1 < ring_count; ++ring)
        for (int s = 0; s < segments; ++s) {
            uint32_t v00 = uint32_t(ring * segments + s);
            uint32_t v01 = uint32_t(ring * segments + (s + 1) % segments);
            uint32_t v10 = v00 + segments;
            uint32_t v11 = v01 + segments;
            out.triangles.insert(out.triangles.end(), {v00, v01, v11, v00, v11, v10});
        }
}

struct SceneBounds {
    Vec3 min{std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
             std::numeric_limits<float>::max()};
    Vec3 max{-std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
             -std::numeric_limits<float>::max()};
    bool empty = true;

    void add(Vec3 point, float margin = 0) {
        for (int k = 0; k < 3; ++k) {
            min[k] = std::min(min[k], point[k] - margin);
            max[k] = std::max(max[k], point[k] + margin);
        }
        empty = false;
    }
};

Vec3 to_linear(Vec3 srgb) {
    return {std::pow(srgb[0], 2.2f), std::pow(srgb[1], 2.2f), std::pow(srgb[2], 2.2f)};
}

void set_material(GLuint program, Vec3 front_srgb, Vec3 back_srgb, float specular_strength, float shininess) {
    Vec3 front = to_linear(front_srgb);
    Vec3 back = to_linear(back_srgb);
    glProgramUniform3fv(program, 4, 1, front.data());
    glProgramUniform3fv(program, 5, 1, back.data());
    glProgramUniform1f(program, 6, specular_strength);
    glProgramUniform1f(program, 7, shininess);
}

// Rounds to 1, 2 or 5 times a power of ten, so grid cells have readable sizes.
float nice_spacing(float rough) {
    float magnitude = std::pow(10.0f, std::floor(std::log10(rough)));
    float fraction = rough / magnitude;
    float nice = fraction < 1.5f ? 1 : fraction < 3.5f ? 2 : fraction < 7.5f ? 5 : 10;
    return nice * magnitude;
}

}  // namespace

struct GlRenderer::State {
    GLuint surface_program = 0;
    GLuint background_program = 0;
    GLuint floor_program = 0;
    GLuint text_program = 0;
    GLuint empty_vertex_array = 0;  // core profile refuses to draw without a bound vertex array
    GLuint text_vertex_array = 0;
    GLuint text_buffer = 0;
    std::vector<MeshBuffers> mesh_buffers;
    SurfaceMesh tool_mesh;                 // reused to avoid reallocating every frame
    ShadedSurface shaded;                  // likewise
    std::vector<char> text_scratch;
    std::vector<char> text_quads;
    std::vector<float> text_vertices;

    MeshBuffers& buffers(size_t slot) {
        while (mesh_buffers.size() <= slot) mesh_buffers.push_back(create_mesh_buffers());
        return mesh_buffers[slot];
    }

    void draw_surface(size_t slot, const std::vector<float>& positions, const std::vector<float>& normals,
                      const std::vector<uint32_t>& triangles) {
        MeshBuffers& b = buffers(slot);
        // Full re-specification lets the driver hand out fresh storage (orphaning)
        // instead of stalling on a buffer the previous frame may still read.
        glNamedBufferData(b.positions, GLsizeiptr(positions.size() * sizeof(float)), positions.data(),
                          GL_STREAM_DRAW);
        glNamedBufferData(b.normals, GLsizeiptr(normals.size() * sizeof(float)), normals.data(), GL_STREAM_DRAW);
        glNamedBufferData(b.indices, GLsizeiptr(triangles.size() * sizeof(uint32_t)), triangles.data(),
                          GL_STREAM_DRAW);
        glBindVertexArray(b.vertex_array);
        glDrawElements(GL_TRIANGLES, GLsizei(triangles.size()), GL_UNSIGNED_INT, nullptr);
    }

    void draw_text(const std::string& text, int width, int height);
};

GlRenderer::GlRenderer() : state_(std::make_unique<State>()) {
    State& s = *state_;
    try {
        s.surface_program = link_program(surface_vertex_source, surface_fragment_source, "surface");
        s.background_program = link_program(background_vertex_source, background_fragment_source, "background");
        s.floor_program = link_program(floor_vertex_source, floor_fragment_source, "floor");
        s.text_program = link_program(text_vertex_source, text_fragment_source, "text");
    } catch (...) {
        for (GLuint program : {s.surface_program, s.background_program, s.floor_program, s.text_program})
            if (program) glDeleteProgram(program);
        throw;
    }
    glCreateVertexArrays(1, &s.empty_vertex_array);
    glCreateVertexArrays(1, &s.text_vertex_array);
    glCreateBuffers(1, &s.text_buffer);
    glVertexArrayVertexBuffer(s.text_vertex_array, 0, s.text_buffer, 0, 2 * sizeof(float));
    glVertexArrayAttribFormat(s.text_vertex_array, 0, 2, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(s.text_vertex_array, 0, 0);
    glEnableVertexArrayAttrib(s.text_vertex_array, 0);
    gl::check_error("GlRenderer setup");
}

GlRenderer::~GlRenderer() {
    State& s = *state_;
    for (MeshBuffers& b : s.mesh_buffers) destroy_mesh_buffers(b);
    glDeleteBuffers(1, &s.text_buffer);
    GLuint arrays[2] = {s.empty_vertex_array, s.text_vertex_array};
    glDeleteVertexArrays(2, arrays);
    for (GLuint program : {s.surface_program, s.background_program, s.floor_program, s.text_program})
        glDeleteProgram(program);
}

void GlRenderer::State::draw_text(const std::string& text, int width, int height) {
    // stb_easy_font builds glyphs from quads in a 1-pixel design grid; scaled up on
    // large targets so it stays readable.
    float scale = height >= 700 ? 3.0f : height >= 360 ? 2.0f : 1.0f;
    text_scratch.assign(text.begin(), text.end());
    text_scratch.push_back('\0');
    text_quads.resize(text.size() * 300 + 1024);  // stb's documented worst case is ~270 bytes a character
    int quad_count =
        stb_easy_font_print(0, 0, text_scratch.data(), nullptr, text_quads.data(), int(text_quads.size()));
    if (quad_count <= 0) return;
    text_vertices.clear();
    constexpr size_t stride = 16;  // x, y, z as float and 4 colour bytes
    for (int quad = 0; quad < quad_count; ++quad) {
        float corner[4][2];
        for (int v = 0; v < 4; ++v) {
            const char* vertex = text_quads.data() + (size_t(quad) * 4 + size_t(v)) * stride;
            std::memcpy(corner[v], vertex, 2 * sizeof(float));
        }
        for (int v : {0, 1, 2, 0, 2, 3}) {
            text_vertices.push_back(corner[v][0] * scale);
            text_vertices.push_back(corner[v][1] * scale);
        }
    }
    glNamedBufferData(text_buffer, GLsizeiptr(text_vertices.size() * sizeof(float)), text_vertices.data(),
                      GL_STREAM_DRAW);
    glUseProgram(text_program);
    glBindVertexArray(text_vertex_array);
    glProgramUniform2f(text_program, 0, float(width), float(height));
    GLsizei vertex_count = GLsizei(text_vertices.size() / 2);
    float margin = 6 * scale;
    // A dark offset copy keeps the text legible on both the light floor and dark background.
    glProgramUniform2f(text_program, 1, margin + scale, margin + scale);
    glProgramUniform4f(text_program, 2, 0.0f, 0.0f, 0.0f, 0.7f);
    glDrawArrays(GL_TRIANGLES, 0, vertex_count);
    glProgramUniform2f(text_program, 1, margin, margin);
    glProgramUniform4f(text_program, 2, 0.95f, 0.95f, 0.95f, 1.0f);
    glDrawArrays(GL_TRIANGLES, 0, vertex_count);
}

void GlRenderer::draw(const Frame& frame, int width, int height) {
    if (width <= 0 || height <= 0) return;
    State& s = *state_;
    for (size_t i = 0; i < frame.meshes.size(); ++i) validate(frame.meshes[i], i);

    const Camera& camera = frame.camera;
    Mat4 view_projection = view_projection_matrix(camera, width, height);
    CameraBasis basis = camera_basis(camera);
    // Lights ride with the camera, so whatever the surgeon looks at is lit from
    // above-left like a headlamp, with a cool fill from the right softening the shadows.
    Vec3 back = basis.forward * -1.0f;
    Vec3 key = normalized(back * 0.8f + basis.up * 1.0f - basis.right * 0.6f);
    Vec3 fill = normalized(back * 1.0f + basis.right * 0.9f - basis.up * 0.2f);

    glViewport(0, 0, width, height);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_CULL_FACE);
    glDisable(GL_STENCIL_TEST);
    glDisable(GL_BLEND);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glClearDepth(1.0);
    glClear(GL_DEPTH_BUFFER_BIT);

    // Background: fills every pixel, so no colour clear is needed.
    glDisable(GL_DEPTH_TEST);
    glUseProgram(s.background_program);
    glProgramUniform3f(s.background_program, 0, 0.30f, 0.34f, 0.40f);
    glProgramUniform3f(s.background_program, 1, 0.09f, 0.10f, 0.12f);
    glBindVertexArray(s.empty_vertex_array);
    glDrawArrays(GL_TRIANGLES, 0, 3);

    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glUseProgram(s.surface_program);
    glProgramUniformMatrix4fv(s.surface_program, 0, 1, GL_FALSE, view_projection.data());
    glProgramUniform3fv(s.surface_program, 1, 1, camera.eye.data());
    glProgramUniform3fv(s.surface_program, 2, 1, key.data());
    glProgramUniform3fv(s.surface_program, 3, 1, fill.data());

    SceneBounds bounds;
    SceneBounds mesh_bounds;
    size_t slot = 0;
    for (const SurfaceMesh& mesh : frame.meshes) {
        for (size_t i = 0; i + 2 < mesh.positions.size(); i += 3) {
            Vec3 p{mesh.positions[i], mesh.positions[i + 1], mesh.positions[i + 2]};
            bounds.add(p);
            mesh_bounds.add(p);
        }
        if (mesh.triangles.empty()) continue;
        // Tissue is moist: a moderately tight highlight. The inside of a cut is
        // darker and redder than the surface.
        Vec3 back_color{mesh.color[0] * 0.78f, mesh.color[1] * 0.42f, mesh.color[2] * 0.42f};
        set_material(s.surface_program, mesh.color, back_color, 0.22f, 48.0f);
        if (mesh.normals.empty()) {
            // Smooth, but a cut's lips and a box's edges kept sharp (crease_shading).
            crease_shading(mesh.positions, mesh.triangles, crease_degrees, s.shaded);
            s.draw_surface(slot++, s.shaded.positions, s.shaded.normals, s.shaded.triangles);
        } else {
            s.draw_surface(slot++, mesh.positions, mesh.normals, mesh.triangles);
        }
    }

    for (const ToolShape& tool : frame.tools) {
        build_capsule(tool, s.tool_mesh);
        bounds.add(tool.a, tool.radius);
        if (tool.kind == ToolShape::Kind::capsule) bounds.add(tool.b, tool.radius);
        Vec3 steel{0.60f, 0.62f, 0.66f};
        Vec3 engaged{0.90f, 0.18f, 0.14f};
        Vec3 color = tool.engaged ? steel * 0.45f + engaged * 0.55f : steel;
        set_material(s.surface_program, color, color, 0.85f, 90.0f);
        s.draw_surface(slot++, s.tool_mesh.positions, s.tool_mesh.normals, s.tool_mesh.triangles);
    }

    if (frame.floor) {
        // Sized to the tissue alone when there is any, so the floor does not shift
        // about as the tool moves.
        const SceneBounds& extent = mesh_bounds.empty ? bounds : mesh_bounds;
        Vec3 center;
        float radius;
        if (extent.empty) {
            center = camera.target;
            radius = std::max(0.25f * length(camera.eye - camera.target), 1e-3f);
        } else {
            center = (extent.min + extent.max) * 0.5f;
            radius = std::max(0.5f * length(extent.max - extent.min), 1e-3f);
        }
        float half_extent = 4.0f * radius;
        float spacing = nice_spacing(radius / 4.0f);
        // The contact shadow is strongest when the scene rests on the floor and fades as it rises.
        Vec3 shadow_disc{center[0], center[1], radius};
        float shadow_strength = 0;
        if (!mesh_bounds.empty) {
            float half_x = 0.5f * (mesh_bounds.max[0] - mesh_bounds.min[0]);
            float half_y = 0.5f * (mesh_bounds.max[1] - mesh_bounds.min[1]);
            float footprint = std::max(std::sqrt(half_x * half_x + half_y * half_y), 1e-4f);
            shadow_disc = {0.5f * (mesh_bounds.min[0] + mesh_bounds.max[0]),
                           0.5f * (mesh_bounds.min[1] + mesh_bounds.max[1]), footprint};
            float gap = std::max(mesh_bounds.min[2] - frame.floor_z, 0.0f);
            shadow_strength = 0.45f * std::exp(-gap / footprint);
        }
        glEnable(GL_BLEND);
        glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
        glDepthMask(GL_FALSE);
        glUseProgram(s.floor_program);
        glProgramUniformMatrix4fv(s.floor_program, 0, 1, GL_FALSE, view_projection.data());
        glProgramUniform3f(s.floor_program, 1, center[0], center[1], frame.floor_z);
        glProgramUniform1f(s.floor_program, 2, half_extent);
        glProgramUniform1f(s.floor_program, 3, spacing);
        glProgramUniform3fv(s.floor_program, 4, 1, shadow_disc.data());
        glProgramUniform1f(s.floor_program, 5, shadow_strength);
        glBindVertexArray(s.empty_vertex_array);
        glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
        glDepthMask(GL_TRUE);
        glDisable(GL_BLEND);
    }

    if (!frame.overlay_text.empty()) {
        glDisable(GL_DEPTH_TEST);
        glEnable(GL_BLEND);
        glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
        s.draw_text(frame.overlay_text, width, height);
        glDisable(GL_BLEND);
    }

    glBindVertexArray(0);
    glUseProgram(0);
    gl::check_error("GlRenderer::draw");
}

}  // namespace render
