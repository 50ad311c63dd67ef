// A run's steps.csv read back by column name: the report plots whichever columns the run
// wrote, so a column added or missing (tool positions, a newer phase) changes a plot, not
// whether the page is made.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace incise::report {

struct StepsTable {
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;  // a field that is not a number reads as NaN

  std::optional<std::size_t> index(const std::string& column) const;
  bool has(const std::string& column) const { return index(column).has_value(); }
  // The column's values, one per row; empty when the column is absent.
  std::vector<double> column(const std::string& name) const;
};

// Throws std::runtime_error naming the file if it cannot be read or has no header.
StepsTable read_steps_csv(const std::filesystem::path& file);

}  // namespace incise::report
