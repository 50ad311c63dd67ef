// The terminal progress bar of long runs (a replay, the benchmark sweeps): one line redrawn in
// place after a carriage return,
//   [#########.....................] 12/40 what
// padded with spaces to the last line's length so that a shorter text leaves nothing behind.
#pragma once

#include <cstddef>
#include <ostream>
#include <string>

namespace incise::common {

class ProgressBar {
 public:
  ProgressBar(std::ostream& stream, long total) : stream_(stream), total_(total) {}

  // Redraws the bar at the current count with `what` after it.
  void draw(const std::string& what);
  void advance() { ++done_; }
  void set_done(long done) { done_ = done; }
  // advance(), then draw(what).
  void step(const std::string& what) {
    advance();
    draw(what);
  }
  // A full line printed over the bar (which the next draw() puts back below it).
  void note(const std::string& text);
  // Ends the bar's line.
  void finish();

 private:
  std::ostream& stream_;
  long total_;
  long done_ = 0;
  std::size_t last_length_ = 0;
};

}  // namespace incise::common
