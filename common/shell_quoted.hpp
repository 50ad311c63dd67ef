// A string as one word for the shell (the benches' gnuplot and the report's ffmpeg commands).
#pragma once

#include <string>

namespace incise::common {

// `text` inside single quotes: each ' becomes '\'' (close, escaped quote, reopen).
inline std::string shell_quoted(const std::string& text) {
  std::string quoted = "'";
  for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

}  // namespace incise::common
