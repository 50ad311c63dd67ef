// Writing a CSV report (replay's steps.csv, the benchmarks' tables): a header line of column
// names, then rows of as many fields, comma separated. Each field is written with operator<<
// on a stream in its default state, so a number reads as the stream's default (6 significant
// digits); a report that wants another format passes the text of significant() or fixed().
#pragma once

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

namespace incise::common {

class CsvWriter {
 public:
  // Creates (truncates) `path` and writes the header; throws std::runtime_error if it cannot.
  CsvWriter(const std::filesystem::path& path, std::initializer_list<std::string_view> columns);

  // One row; throws std::logic_error when the field count is not the header's, so that a
  // column added to one and not the other cannot shift the rest.
  template <class... Fields>
  void row(const Fields&... fields) {
    check_width(sizeof...(Fields));
    std::size_t index = 0;
    ((out_ << (index++ > 0 ? "," : "") << fields), ...);
    out_ << '\n';
  }
  // Reports that may be interrupted flush each row, so that what is written stays readable.
  void flush() { out_.flush(); }

 private:
  void check_width(std::size_t fields) const;
  std::filesystem::path path_;
  std::vector<std::string> columns_;
  std::ofstream out_;
};

// `value` with `digits` significant digits, as printf's %g writes it (no trailing zeros).
std::string significant(double value, int digits);
// `value` with `decimals` digits after the point, as printf's %f writes it.
std::string fixed(double value, int decimals);

}  // namespace incise::common
