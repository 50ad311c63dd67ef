#include "common/progress_bar.hpp"

namespace incise::common {

void ProgressBar::draw(const std::string& what) {
  constexpr long width = 30;
  const long filled = total_ > 0 ? width * done_ / total_ : width;
  std::string line = "\r[" + std::string(static_cast<std::size_t>(filled), '#') +
                     std::string(static_cast<std::size_t>(width - filled), '.') + "] " + std::to_string(done_) +
                     "/" + std::to_string(total_) + " " + what;
  if (line.size() < last_length_) line += std::string(last_length_ - line.size(), ' ');
  last_length_ = line.size();
  stream_ << line << std::flush;
}

void ProgressBar::note(const std::string& text) {
  stream_ << "\r" << text;
  if (text.size() + 1 < last_length_) stream_ << std::string(last_length_ - text.size() - 1, ' ');
  stream_ << "\n";
  last_length_ = 0;
}

void ProgressBar::finish() {
  stream_ << "\n";
  last_length_ = 0;
}

}  // namespace incise::common
