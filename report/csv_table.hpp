// A CSV report read back by column name (a run's steps.csv, a benchmark's table): the report
// plots whichever columns were written, so a column added or missing (tool positions, a newer
// phase) changes a plot, not whether the page is made. Fields may be double-quoted (a GPU's
// name holds commas).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace incise::report {

struct CsvTable {
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;  // a field that is not a number reads as NaN
  std::vector<std::vector<std::string>> text;  // the same fields as written, quotes removed

  std::optional<std::size_t> index(const std::string& column) const;
  bool has(const std::string& column) const { return index(column).has_value(); }
  // The column's values, one per row; empty when the column is absent.
  std::vector<double> column(const std::string& name) const;
};

// Throws std::runtime_error naming the file if it cannot be read or has no header.
CsvTable read_csv_table(const std::filesystem::path& file);

}  // namespace incise::report
