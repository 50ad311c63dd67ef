// Needs an X display (Xvfb is enough); skipped without one.

#include <gtest/gtest.h>
#include <imgui.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "render/frame.hpp"
#include "render/image.hpp"
#include "render/window.hpp"

namespace {

TEST(RenderWindow, DrawsFrameAndPanels) {
    const char* display = std::getenv("DISPLAY");
    if (!display || !*display) GTEST_SKIP() << "DISPLAY is not set";

    render::Window window(400, 300, "incise window test");
    std::cout << "window renderer: " << window.renderer_string() << "\n";
    render::Frame frame;
    render::ToolShape tool;
    tool.a = tool.b = {0, 0, 0.02f};
    tool.radius = 0.01f;
    frame.tools.push_back(tool);
    frame.camera = render::fit_camera({-0.03f, -0.03f, 0}, {0.03f, 0.03f, 0.04f},
                                      float(window.framebuffer_width()) / float(window.framebuffer_height()));
    int panel_runs = 0;
    auto panels = [&] {
        ++panel_runs;
        ImGui::SetNextWindowPos(ImVec2(10, 10));
        ImGui::SetNextWindowSize(ImVec2(160, 60));
        ImGui::Begin("Tissue");
        ImGui::Text("stiffness %.1f kPa", 3.0);
        ImGui::End();
    };
    // ImGui keeps a new window hidden on its first frame while it lays it out.
    window.draw(frame, panels);
    window.draw(frame, panels);
    EXPECT_EQ(panel_runs, 2);
    EXPECT_FALSE(window.should_close());

    render::Image shot = window.save_screenshot();
    EXPECT_EQ(shot.width, window.framebuffer_width());
    EXPECT_EQ(shot.height, window.framebuffer_height());
    ASSERT_EQ(shot.rgba.size(), size_t(shot.width) * size_t(shot.height) * 4);
    bool varied = false;
    for (size_t i = 4; i < shot.rgba.size() && !varied; i += 4)
        varied = !std::equal(shot.rgba.begin() + long(i), shot.rgba.begin() + long(i) + 3, shot.rgba.begin());
    EXPECT_TRUE(varied);
    std::filesystem::create_directories(INCISE_RENDER_TEST_OUTPUT);
    render::write_png(std::filesystem::path(INCISE_RENDER_TEST_OUTPUT) / "render_window.png", shot);

    // The panel is drawn over the scene.
    window.draw(frame);
    render::Image bare = window.save_screenshot();
    int changed = 0;
    for (int y = 10; y < 70; ++y)
        for (int x = 10; x < 170; ++x)
            changed += !std::equal(shot.pixel(x, y), shot.pixel(x, y) + 3, bare.pixel(x, y));
    EXPECT_GT(changed, 160 * 60 / 2);

    // Input accessors answer without events having happened.
    EXPECT_FALSE(window.key_down(render::keys::space));
    EXPECT_FALSE(window.mouse_button_down(render::MouseButton::left));
    EXPECT_EQ(window.scroll_delta()[1], 0.0);
    EXPECT_FALSE(window.key_down(-5));
}

}  // namespace
