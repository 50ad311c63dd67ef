// `incise report RUN_DIR`: RUN_DIR/report.html, the page a reviewer opens after a replay or
// a session: the scene, the video and the frames, the plots of steps.csv, the incision's
// score, the `expect` results and every metric. Whatever the run did not write (frames,
// steps.csv, score.json) or the machine lacks (gnuplot, ffmpeg) is said on the page.
#pragma once

#include <filesystem>
#include <ostream>

namespace incise::report {

// Writes RUN_DIR/report.html (plots and their scripts in RUN_DIR/report/, the video as
// RUN_DIR/replay.mp4) and returns the page's path. Throws std::runtime_error naming the path
// when RUN_DIR has neither metrics.json (a replay) nor session.json (a session).
std::filesystem::path write_run_report(const std::filesystem::path& run_dir, std::ostream& progress);

}  // namespace incise::report
