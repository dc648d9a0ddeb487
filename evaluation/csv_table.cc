#include "evaluation/csv_table.h"

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <limits>

#include "lightstage/errors.h"

namespace ls::evaluation {

namespace {

std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted && c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
      fields.back() += '"';
      ++i;
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      fields.emplace_back();
    } else if (c != '\r') {
      fields.back() += c;
    }
  }
  return fields;
}

}  // namespace

CsvTable CsvTable::read(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot read");
  CsvTable table;
  table.path = path;
  std::string line;
  if (!std::getline(in, line) || line.empty()) {
    throw InputError(path.string() + ": empty, expected a header row of column names");
  }
  table.header = split_fields(line);
  for (int number = 2; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    table.rows.push_back(split_fields(line));
    if (table.rows.back().size() != table.header.size()) {
      throw InputError(path.string() + ": line " + std::to_string(number) + " has " +
                       std::to_string(table.rows.back().size()) + " fields, the header " +
                       std::to_string(table.header.size()));
    }
  }
  return table;
}

bool CsvTable::has(const std::string& name) const {
  return std::find(header.begin(), header.end(), name) != header.end();
}

size_t CsvTable::column(const std::string& name) const {
  const auto it = std::find(header.begin(), header.end(), name);
  if (it != header.end()) return size_t(it - header.begin());
  std::string names;
  for (const std::string& h : header) names += (names.empty() ? "" : ", ") + h;
  throw InputError(path.string() + ": no column '" + name + "' (its columns: " + names + ")");
}

std::vector<std::string> CsvTable::distinct(const std::string& name) const {
  const size_t c = column(name);
  std::vector<std::string> values;
  for (const auto& row : rows) {
    if (std::find(values.begin(), values.end(), row[c]) == values.end()) values.push_back(row[c]);
  }
  return values;
}

std::vector<double> CsvTable::numbers(const std::string& name) const {
  const size_t c = column(name);
  std::vector<double> values;
  values.reserve(rows.size());
  for (const auto& row : rows) {
    char* end = nullptr;
    const double v = std::strtod(row[c].c_str(), &end);
    const bool whole = !row[c].empty() && end == row[c].c_str() + row[c].size();
    values.push_back(whole ? v : std::numeric_limits<double>::quiet_NaN());
  }
  return values;
}

std::string csv_field(const std::string& value) {
  if (value.find_first_of(",\"\n\r") == std::string::npos) return value;
  std::string quoted = "\"";
  for (const char c : value) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + '"';
}

}  // namespace ls::evaluation
