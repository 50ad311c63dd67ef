#include "render/window.hpp"

#include "render/gl.hpp"  // before GLFW, which then must not pull in its own GL header

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <string>

#include "render/error.hpp"
#include "render/framebuffer.hpp"
#include "render/gl_renderer.hpp"

namespace render {
namespace {

// GLFW reports failures through a callback only; keep the latest message so the
// exception can say why (e.g. "The DISPLAY environment variable is missing").
thread_local std::string last_glfw_error;

void remember_glfw_error(int code, const char* description) {
    last_glfw_error = "GLFW error " + std::to_string(code) + ": " + (description ? description : "");
}

}  // namespace

struct Window::State {
    GLFWwindow* window = nullptr;
    ImGuiContext* imgui = nullptr;
    bool imgui_platform_ready = false;
    bool imgui_renderer_ready = false;
    int samples = 0;
    std::unique_ptr<GlRenderer> renderer;
    Framebuffer framebuffer;
    std::string renderer_string;
    std::array<double, 2> scroll{};
    std::array<double, 2> scroll_pending{};

    ~State() {
        if (window) {
            glfwMakeContextCurrent(window);
            renderer.reset();
            framebuffer.release();
        }
        if (imgui) ImGui::SetCurrentContext(imgui);
        if (imgui_renderer_ready) ImGui_ImplOpenGL3_Shutdown();
        if (imgui_platform_ready) ImGui_ImplGlfw_Shutdown();
        if (imgui) ImGui::DestroyContext(imgui);
        if (window) glfwDestroyWindow(window);
    }

    void use_imgui() const { ImGui::SetCurrentContext(imgui); }
};

Window::Window(int width, int height, const std::string& title, int samples) : state_(std::make_unique<State>()) {
    State& s = *state_;
    s.samples = samples;
    glfwSetErrorCallback(remember_glfw_error);
    last_glfw_error.clear();
    // GLFW stays initialised for the rest of the process (a repeated glfwInit is a
    // no-op): glfwTerminate closes the X connection, which makes Mesa unload its
    // driver and strand the driver's static allocations, so LeakSanitizer reports
    // them. Windows themselves are destroyed with their Window.
    if (!glfwInit()) throw RenderError("cannot open a window: glfwInit failed (" + last_glfw_error + ")");

    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    // The scene is drawn into our own (multisampled) framebuffer and copied over,
    // so the window's own buffer needs neither depth nor samples.
    glfwWindowHint(GLFW_DEPTH_BITS, 0);
    glfwWindowHint(GLFW_STENCIL_BITS, 0);
    glfwWindowHint(GLFW_SAMPLES, 0);
    s.window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
    if (!s.window)
        throw RenderError("cannot open a window with an OpenGL 4.5 core context (" + last_glfw_error + ")");
    glfwMakeContextCurrent(s.window);
    glfwSwapInterval(1);
    if (!gl::has_core_45())
        throw RenderError("the window's context is " + gl::version_string() + ", not OpenGL 4.5 core");
    s.renderer_string = gl::version_string();

    // Registered before ImGui's backend, which chains to callbacks already installed.
    glfwSetWindowUserPointer(s.window, &s);
    glfwSetScrollCallback(s.window, [](GLFWwindow* window, double x, double y) {
        auto* state = static_cast<State*>(glfwGetWindowUserPointer(window));
        state->scroll_pending[0] += x;
        state->scroll_pending[1] += y;
    });

    IMGUI_CHECKVERSION();
    s.imgui = ImGui::CreateContext();
    ImGui::SetCurrentContext(s.imgui);
    // No imgui.ini in whatever directory the simulator was started from.
    ImGui::GetIO().IniFilename = nullptr;
    ImGui::StyleColorsDark();
    if (!ImGui_ImplGlfw_InitForOpenGL(s.window, true)) throw RenderError("ImGui GLFW backend failed to start");
    s.imgui_platform_ready = true;
    if (!ImGui_ImplOpenGL3_Init("#version 450")) throw RenderError("ImGui OpenGL3 backend failed to start");
    s.imgui_renderer_ready = true;

    s.renderer = std::make_unique<GlRenderer>();
}

Window::~Window() = default;

bool Window::should_close() const { return glfwWindowShouldClose(state_->window) != 0; }

void Window::draw(const Frame& frame, const std::function<void()>& imgui_panels) {
    State& s = *state_;
    glfwMakeContextCurrent(s.window);
    int width = 0, height = 0;
    glfwGetFramebufferSize(s.window, &width, &height);
    // A minimised window has no pixels; keep polling so it can be restored.
    if (width > 0 && height > 0) {
        s.framebuffer.resize(width, height, s.samples);
        s.framebuffer.bind_for_drawing();
        s.renderer->draw(frame, width, height);
        s.framebuffer.resolve();
        s.framebuffer.bind_resolved_for_drawing();

        s.use_imgui();
        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
        try {
            if (imgui_panels) imgui_panels();
        } catch (...) {
            ImGui::EndFrame();  // leaves ImGui ready for the next frame
            throw;
        }
        ImGui::Render();
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());

        s.framebuffer.blit_to(0, width, height);
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        gl::check_error("Window::draw");
        glfwSwapBuffers(s.window);
    }
    s.scroll_pending = {0, 0};
    glfwPollEvents();
    s.scroll = s.scroll_pending;
}

Image Window::save_screenshot() const {
    const State& s = *state_;
    if (s.framebuffer.width() == 0) throw RenderError("Window::save_screenshot: nothing has been drawn yet");
    glfwMakeContextCurrent(s.window);
    return s.framebuffer.read();
}

std::string Window::renderer_string() const { return state_->renderer_string; }

int Window::framebuffer_width() const {
    int width = 0, height = 0;
    glfwGetFramebufferSize(state_->window, &width, &height);
    return width;
}

int Window::framebuffer_height() const {
    int width = 0, height = 0;
    glfwGetFramebufferSize(state_->window, &width, &height);
    return height;
}

std::array<double, 2> Window::cursor_position() const {
    GLFWwindow* window = state_->window;
    double x = 0, y = 0;
    glfwGetCursorPos(window, &x, &y);
    // GLFW gives window coordinates, which differ from pixels on high-DPI screens.
    int window_width = 0, window_height = 0, pixel_width = 0, pixel_height = 0;
    glfwGetWindowSize(window, &window_width, &window_height);
    glfwGetFramebufferSize(window, &pixel_width, &pixel_height);
    if (window_width > 0) x *= double(pixel_width) / window_width;
    if (window_height > 0) y *= double(pixel_height) / window_height;
    return {x, y};
}

bool Window::mouse_button_down(MouseButton button) const {
    return glfwGetMouseButton(state_->window, int(button)) == GLFW_PRESS;
}

std::array<double, 2> Window::scroll_delta() const { return state_->scroll; }

bool Window::key_down(int key) const {
    if (key < GLFW_KEY_SPACE || key > GLFW_KEY_LAST) return false;
    return glfwGetKey(state_->window, key) == GLFW_PRESS;
}

bool Window::gui_wants_mouse() const {
    state_->use_imgui();
    return ImGui::GetIO().WantCaptureMouse;
}

bool Window::gui_wants_keyboard() const {
    state_->use_imgui();
    return ImGui::GetIO().WantCaptureKeyboard;
}

}  // namespace render
