#include "report/frames_player.hpp"

#include "report/video.hpp"

#include <algorithm>
#include <cmath>

namespace incise::report {

namespace {

std::vector<std::filesystem::path> captured_frames(const std::filesystem::path& frames_dir) {
  std::vector<std::filesystem::path> frames;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(frames_dir, error)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("frame_", 0) == 0 && entry.path().extension() == ".png") frames.push_back(entry.path());
  }
  std::sort(frames.begin(), frames.end());
  return frames;
}

// Frames per simulated second: one frame every frames.every_steps steps of dt_s.
double capture_rate(const nlohmann::json& metrics) {
  if (!metrics.contains("frames") || !metrics.contains("dt_s")) return 0;
  const double every = metrics["frames"].value("every_steps", 0.0), dt = metrics.value("dt_s", 0.0);
  return every > 0 && dt > 0 ? 1.0 / (every * dt) : 0;
}

// The player steps through the frames at the capture rate (at most 50 per second of wall
// time: a browser timer does not go faster).
std::string player_html(const std::vector<std::filesystem::path>& frames, double fps) {
  std::string list;
  for (const auto& f : frames) list += (list.empty() ? "\"frames/" : ",\"frames/") + html_escaped(f.filename().string()) + "\"";
  const int interval_ms = static_cast<int>(std::lround(std::max(20.0, fps > 0 ? 1000.0 / fps : 100.0)));
  return "<div class=\"player\"><img id=\"player-frame\" alt=\"frame\" src=\"frames/" +
         html_escaped(frames.front().filename().string()) +
         "\"><div class=\"controls\"><button id=\"player-play\" type=\"button\">play</button> "
         "<input id=\"player-slider\" type=\"range\" min=\"0\" max=\"" + std::to_string(frames.size() - 1) +
         "\" value=\"0\"> <span id=\"player-label\"></span></div></div>\n<script>\n(function () {\n"
         "var frames = [" + list + "];\nvar img = document.getElementById('player-frame');\n"
         "var slider = document.getElementById('player-slider');\nvar button = document.getElementById('player-play');\n"
         "var label = document.getElementById('player-label');\nvar timer = null;\n"
         "function show(i) { slider.value = i; img.src = frames[i]; label.textContent = (+i + 1) + ' / ' + frames.length; }\n"
         "slider.addEventListener('input', function () { show(slider.value); });\n"
         "button.addEventListener('click', function () {\n"
         "  if (timer) { clearInterval(timer); timer = null; button.textContent = 'play'; return; }\n"
         "  button.textContent = 'pause';\n"
         "  timer = setInterval(function () { show((+slider.value + 1) % frames.length); }, " + std::to_string(interval_ms) + ");\n"
         "});\nshow(0);\n})();\n</script>";
}

// At most 24 thumbnails, evenly spaced, each captioned with its step.
std::string strip_html(const std::vector<std::filesystem::path>& frames) {
  std::string html = "<div class=\"strip\">";
  const std::size_t shown = std::min<std::size_t>(24, frames.size());
  for (std::size_t i = 0; i < shown; ++i) {
    const auto& f = frames[shown > 1 ? i * (frames.size() - 1) / (shown - 1) : 0];
    std::string step = f.stem().string().substr(6);
    step.erase(0, std::min(step.find_first_not_of('0'), step.size() - 1));
    html += "<figure><img src=\"frames/" + html_escaped(f.filename().string()) + "\" alt=\"step " + step +
            "\"><figcaption>step " + step + "</figcaption></figure>";
  }
  return html + "</div>";
}

}  // namespace

void frames_section(HtmlPage& page, const std::filesystem::path& run_dir, const nlohmann::json& metrics) {
  page.heading("Video and frames");
  const auto frames = captured_frames(run_dir / "frames");
  if (frames.empty()) {
    page.note("no frames were captured (run with --capture-every K to capture one every K steps)");
    return;
  }
  const double fps = capture_rate(metrics);
  const VideoOutcome video = encode_video(run_dir, frames, fps);
  // The video and the player side by side (one above the other on a narrow screen).
  page.raw("<div class=\"media\"><div>");
  page.heading("Video", 3);
  if (video.made) {
    page.raw("<video controls preload=\"metadata\" src=\"replay.mp4\"></video>");
    page.paragraph("replay.mp4: " + std::to_string(frames.size()) + " frames at " +
                   (fps > 0 ? std::to_string(static_cast<int>(std::lround(fps))) : std::string("25")) +
                   " frames per second (the capture rate: real time).");
  } else {
    page.note("no video: " + video.problem + ". The frames are in the frames/ folder beside this page.");
    page.raw("<p><a href=\"frames/\">frames/</a></p>");
  }
  page.raw("</div><div>");
  page.heading("Player", 3);
  page.raw(player_html(frames, fps));
  page.raw("</div></div>");
  page.heading("Strip", 3);
  page.raw(strip_html(frames));
}

}  // namespace incise::report
