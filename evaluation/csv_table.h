#pragma once
// The benches' CSV files: a header row of column names, then one row per measurement; fields
// with a comma or a quote are double-quoted ("" for a quote). The charts are drawn from these
// files, so a chart can be redrawn from its CSV alone.
#include <filesystem>
#include <string>
#include <vector>

namespace ls::evaluation {

struct CsvTable {
  std::filesystem::path path;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  // Each as long as the header.

  // InputError naming the file when it cannot be read, is empty or a row's length differs.
  static CsvTable read(const std::filesystem::path& path);

  bool has(const std::string& name) const;
  // The column's index; InputError naming the file and the column (and those there are).
  size_t column(const std::string& name) const;
  // The column's values, each once, in the order they first appear.
  std::vector<std::string> distinct(const std::string& name) const;
  // The column's numbers, in row order (an empty or unparsable field is NaN).
  std::vector<double> numbers(const std::string& name) const;
};

// A value as a CSV field: quoted when it holds a comma, a quote or a line break.
std::string csv_field(const std::string& value);

}  // namespace ls::evaluation
