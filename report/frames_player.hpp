// The captured frames on the page: the video (RUN_DIR/replay.mp4, made here), a strip of
// thumbnails and a small player (play, pause, a slider). Frames are referenced beside the
// page (frames/...), not embedded: a long run captures hundreds.
#pragma once

#include "report/html_page.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>

namespace incise::report {

void frames_section(HtmlPage& page, const std::filesystem::path& run_dir, const nlohmann::json& metrics);

}  // namespace incise::report
