#include "report/video.hpp"

#include "common/shell_quoted.hpp"

#include <cstdio>
#include <cstdlib>

namespace incise::report {

using common::shell_quoted;

VideoOutcome encode_video(const std::filesystem::path& run_dir, const std::vector<std::filesystem::path>& frames,
                          double fps) {
  VideoOutcome outcome;
  if (frames.empty()) {
    outcome.problem = "no frames were captured";
    return outcome;
  }
  if (std::system("command -v ffmpeg > /dev/null 2>&1") != 0) {
    outcome.problem = "ffmpeg is not installed (scripts/setup installs it)";
    return outcome;
  }
  if (!(fps > 0)) fps = 25;
  const std::filesystem::path dir = std::filesystem::absolute(run_dir);
  std::filesystem::create_directories(dir / "report");
  char rate[64];
  std::snprintf(rate, sizeof rate, "%.6g", fps);
  const std::string command = "cd " + shell_quoted(dir.string()) + " && ffmpeg -y -nostdin -loglevel error -framerate " + rate +
                              // A glob, not a %06d pattern: frames are numbered by step, not consecutively.
                              " -pattern_type glob -i 'frames/frame_*.png' -vf 'scale=trunc(iw/2)*2:trunc(ih/2)*2' -r " + rate +
                              " -c:v libx264 -pix_fmt yuv420p -movflags +faststart " +
                              shell_quoted((dir / "replay.mp4").string()) + " > " +
                              shell_quoted((dir / "report" / "ffmpeg.log").string()) + " 2>&1";
  if (std::system(command.c_str()) != 0) {
    outcome.problem = "ffmpeg failed (see report/ffmpeg.log)";
    return outcome;
  }
  outcome.made = true;
  return outcome;
}

}  // namespace incise::report
