#include "report/csv_table.hpp"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace incise::report {

namespace {

std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (c == '"' && quoted && i + 1 < line.size() && line[i + 1] == '"') {
      fields.back() += '"';
      ++i;
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

double number_or_nan(const std::string& field) {
  char* end = nullptr;
  const double value = std::strtod(field.c_str(), &end);
  return end != field.c_str() && *end == '\0' ? value : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

std::optional<std::size_t> CsvTable::index(const std::string& column) const {
  for (std::size_t i = 0; i < columns.size(); ++i)
    if (columns[i] == column) return i;
  return std::nullopt;
}

std::vector<double> CsvTable::column(const std::string& name) const {
  std::vector<double> values;
  const auto i = index(name);
  if (!i) return values;
  values.reserve(rows.size());
  for (const auto& row : rows) values.push_back(*i < row.size() ? row[*i] : std::numeric_limits<double>::quiet_NaN());
  return values;
}

CsvTable read_csv_table(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot read");
  CsvTable table;
  std::string line;
  if (!std::getline(in, line) || line.empty()) throw std::runtime_error(file.string() + ": no header line");
  if (line.back() == '\r') line.pop_back();
  table.columns = split_fields(line);
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    std::vector<std::string> fields = split_fields(line);
    std::vector<double> row;
    for (const auto& field : fields) row.push_back(number_or_nan(field));
    table.rows.push_back(std::move(row));
    table.text.push_back(std::move(fields));
  }
  return table;
}

}  // namespace incise::report
