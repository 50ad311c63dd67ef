// The window end to end (issue 5), under a display (Xvfb is enough; skipped without one):
// `incise run` on the haptics block with a scripted mouse drag (--script-drag moves the
// virtual device's cursor frame by frame with the blade engaged: scripted cursor positions,
// not X events) must cut the body (cut events, more triangles), and its screenshot must show
// the body and the ImGui panel; the session it recorded (--record) replays headless to the
// state hash its summary names.
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>

#include "engine/scene.hpp"
#include "render/frame.hpp"
#include "tests/unit/temp_dir.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <string>

namespace {

std::string run_command(const std::string& command, int& status) {
  std::string out;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) {
    status = -1;
    return out;
  }
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe)) out += buffer;
  status = pclose(pipe);
  return out;
}

}  // namespace

TEST(WindowSession, AScriptedDragCutsTheBodyAndTheScreenshotShowsBodyAndPanel) {
  const char* display = std::getenv("DISPLAY");
  if (!display || !*display) GTEST_SKIP() << "DISPLAY is not set";
  incise::testing::TempDir dir("incise_window_session");
  const std::string scene = std::string(INCISE_SOURCE_DIR) + "/assets/scenes/haptics_block.json";
  const std::string shot = (dir.path / "window.png").string();
  const std::string record = (dir.path / "window.traj").string();
  int status = 0;
  const std::string out = run_command(std::string(INCISE_BINARY) + " run " + scene +
                                          " --frames 60 --script-drag 380,300,640,300,0.008 --screenshot " + shot +
                                          " --record " + record + " 2>&1",
                                      status);
  std::printf("%s", out.c_str());
  ASSERT_EQ(status, 0) << out;
  long frames = 0, cuts = 0;
  double time = 0;
  std::size_t before = 0, after = 0;
  const auto at = out.find("window: ");
  ASSERT_NE(at, std::string::npos) << out;
  ASSERT_EQ(std::sscanf(out.c_str() + at, "window: %ld frames, physics t = %lf s, %ld cut events, triangles %zu -> %zu",
                        &frames, &time, &cuts, &before, &after),
            5)
      << out;
  EXPECT_GE(frames, 60);
  EXPECT_GT(cuts, 0) << "the drag with the blade engaged should cut";
  EXPECT_GT(after, before);

  int width = 0, height = 0, channels = 0;
  std::unique_ptr<unsigned char, void (*)(void*)> pixels(stbi_load(shot.c_str(), &width, &height, &channels, 3),
                                                         stbi_image_free);
  ASSERT_TRUE(pixels) << shot;
  const incise::engine::Scene parsed = incise::engine::load_scene(scene);
  ASSERT_EQ(width, parsed.render.width);
  const auto pixel = [&](int x, int y) { return pixels.get() + (static_cast<std::size_t>(y) * width + x) * 3; };
  // The body: the block's top centre, projected with the scene's camera, is the tissue's red.
  render::Camera camera;
  for (int i = 0; i < 3; ++i) {
    camera.eye[i] = static_cast<float>(parsed.render.camera->eye[i]);
    camera.target[i] = static_cast<float>(parsed.render.camera->target[i]);
  }
  camera.fov_y_deg = static_cast<float>(parsed.render.camera->fov_deg);
  const auto centre = render::project_to_pixel(camera, width, height, {0.02f, 0.0f, 0.02f});
  const unsigned char* body = pixel(static_cast<int>(centre[0]), static_cast<int>(centre[1]));
  EXPECT_GT(body[0], body[1] + 40) << "body pixel " << int(body[0]) << "," << int(body[1]) << "," << int(body[2]);
  // The panel: its title bar (top left) is ImGui's blue, its body dark and grey.
  const unsigned char* title = pixel(100, 17);
  EXPECT_GT(title[2], title[0] + 30) << "title pixel " << int(title[0]) << "," << int(title[1]) << "," << int(title[2]);
  int dark = 0;
  for (int y = 40; y < 120; ++y)
    for (int x = 12; x < 300; ++x) {
      const unsigned char* p = pixel(x, y);
      dark += p[0] < 40 && p[1] < 40 && p[2] < 40;
    }
  EXPECT_GT(dark, 288 * 80 / 2) << "the panel's background should cover its area";

  // The recording the window made replays headless to the state its summary names.
  std::ifstream summary_file(record + ".json");
  ASSERT_TRUE(summary_file) << "no summary beside the recording";
  const nlohmann::json summary = nlohmann::json::parse(summary_file);
  const std::string replay_out = (dir.path / "replay").string();
  run_command(std::string(INCISE_BINARY) + " replay " + scene + " --trajectory " + record + " --steps " +
                  summary["steps"].dump() + " --out " + replay_out + " --quiet 2>&1",
              status);
  ASSERT_EQ(status, 0);
  std::ifstream metrics_file(replay_out + "/metrics.json");
  const nlohmann::json metrics = nlohmann::json::parse(metrics_file);
  std::printf("window recording: %s steps, state hash %s; headless replay %s\n", summary["steps"].dump().c_str(),
              summary["state_hash"].get<std::string>().c_str(), metrics["state_hash"].get<std::string>().c_str());
  EXPECT_EQ(metrics["state_hash"], summary["state_hash"]);
  EXPECT_EQ(metrics["surface"]["triangles"], summary["surface_triangles"]);
  EXPECT_GT(summary["cut_events"].get<long>(), 0);
}
