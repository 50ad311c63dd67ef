#pragma once

#include <array>
#include <functional>
#include <memory>
#include <string>

#include "render/frame.hpp"
#include "render/image.hpp"

namespace render {

// Key codes accepted by Window::key_down. They are GLFW's codes: printable keys
// use their upper-case ASCII value ('A', '1', ' '), so only the others are named here.
namespace keys {
inline constexpr int space = 32;
inline constexpr int escape = 256;
inline constexpr int enter = 257;
inline constexpr int tab = 258;
inline constexpr int right = 262;
inline constexpr int left = 263;
inline constexpr int down = 264;
inline constexpr int up = 265;
inline constexpr int left_shift = 340;
inline constexpr int left_control = 341;
inline constexpr int left_alt = 342;
}  // namespace keys

enum class MouseButton { left = 0, right = 1, middle = 2 };

// An on-screen window with an OpenGL 4.5 core context, the same scene drawing as
// OffscreenTarget, and Dear ImGui panels on top. Like any GL context it must be
// created, used and destroyed on one thread, and GLFW requires that thread to be the
// main thread. One Window at a time.
class Window {
public:
    // samples: MSAA of the scene (not of the panels). Throws RenderError when there
    // is no display or no 4.5 core context.
    Window(int width, int height, const std::string& title, int samples = 4);
    ~Window();
    Window(const Window&) = delete;
    Window& operator=(const Window&) = delete;

    bool should_close() const;

    // Renders the frame, then the panels (any ImGui calls), shows the result and
    // polls input, so the input accessors afterwards describe what happened while
    // this frame was on screen.
    void draw(const Frame& frame, const std::function<void()>& imgui_panels = {});

    // The last drawn frame including panels, top row first.
    Image save_screenshot() const;

    std::string renderer_string() const;
    int framebuffer_width() const;   // pixels; the size project_to_pixel should be given
    int framebuffer_height() const;

    // Input for the virtual haptic device. Cursor positions are framebuffer pixels,
    // y down, matching project_to_pixel.
    std::array<double, 2> cursor_position() const;
    bool mouse_button_down(MouseButton button) const;
    std::array<double, 2> scroll_delta() const;  // wheel movement during the last draw's poll
    bool key_down(int key) const;
    // True while the pointer or keyboard is used by an ImGui panel; scene input should
    // then be ignored.
    bool gui_wants_mouse() const;
    bool gui_wants_keyboard() const;

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace render
