// RUN_DIR/replay.mp4 from the captured frames, through Debian's ffmpeg (H.264, yuv420p so
// that browsers play it, even dimensions as yuv420p needs).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace incise::report {

struct VideoOutcome {
  bool made = false;
  std::string problem;  // why not, for the page (ffmpeg missing, no frames, ffmpeg failed)
};

// `frames` are the PNG files (frames/frame_NNNNNN.png, in step order); `fps` the scene's capture rate (frames per simulated
// second). Writes run_dir/replay.mp4 (ffmpeg's messages to run_dir/report/ffmpeg.log).
VideoOutcome encode_video(const std::filesystem::path& run_dir, const std::vector<std::filesystem::path>& frames,
                          double fps);

}  // namespace incise::report
