#include "common/csv.hpp"

#include <cstdio>
#include <stdexcept>

namespace incise::common {

CsvWriter::CsvWriter(const std::filesystem::path& path, std::initializer_list<std::string_view> columns)
    : path_(path), columns_(columns.begin(), columns.end()), out_(path) {
  if (!out_) throw std::runtime_error("cannot write " + path.string());
  for (std::size_t i = 0; i < columns_.size(); ++i) out_ << (i > 0 ? "," : "") << columns_[i];
  out_ << '\n';
}

void CsvWriter::check_width(std::size_t fields) const {
  if (fields != columns_.size()) {
    throw std::logic_error(path_.string() + ": a row of " + std::to_string(fields) + " fields under a header of " +
                           std::to_string(columns_.size()) + " columns");
  }
}

std::string significant(double value, int digits) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*g", digits, value);
  return buffer;
}

std::string fixed(double value, int decimals) {
  char buffer[400];  // %f of the largest double: 309 digits before the point
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, value);
  return buffer;
}

}  // namespace incise::common
