#pragma once
// Charts of the benches' CSV files, drawn by gnuplot (Debian: gnuplot-nox, its pngcairo
// terminal). A chart names a CSV file and its columns; write_chart writes a gnuplot script,
// NAME.gp beside NAME.png, that plots straight from the CSV (re-plot or restyle it with
// `gnuplot NAME.gp` in that folder), then runs it. Series differ in colour, point type and dash
// type; the legend sits below the plot.
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace ls::evaluation {

// Text beside each point of a series.
struct ChartLabels {
  std::string column;  // Empty: no labels.
  // printf format of the column's number times `scale` ("%.0f%% flagged"); empty: the text as
  // the CSV holds it.
  std::string format;
  double scale = 1;
  std::pair<std::string, std::string> where;  // Only rows whose column holds this text; empty: all.
};

// One series: the CSV rows whose columns hold the given texts (all of them; every row when
// `where` is empty), their x against their y. gnuplot cuts a quoted field at its first comma, so
// a text to match holds none (write_chart refuses one that does).
struct ChartSeries {
  std::string title;                                       // In the legend.
  std::vector<std::pair<std::string, std::string>> where;  // {column, text as written}.
  std::string x, y;                                        // Columns; empty: the chart's.
  ChartLabels labels;
};

// One series per value of `column`, titled by the value.
std::vector<ChartSeries> series_by(const std::string& column,
                                   const std::vector<std::string>& values);

struct Chart {
  std::filesystem::path csv;
  std::string x, y;  // Columns (a series may name its own).
  std::vector<ChartSeries> series;
  std::string title, x_label, y_label;
  bool log_x = false, log_y = false;
  bool lines = true;  // Points joined in the CSV's row order; false: points alone.
};

inline constexpr int kChartWidth = 1000, kChartHeight = 700;  // Pixels of the PNG.

// Why charts cannot be drawn on this machine (gnuplot is not on PATH), or nothing.
std::optional<std::string> chart_tool_missing();

// Writes `png` and its script (png with .gp) from the chart's CSV. InputError naming the file and
// the column when the CSV lacks a column the chart names, and with gnuplot's message when it
// fails. Without gnuplot, the script alone is written and the result is false.
bool write_chart(const std::filesystem::path& png, const Chart& chart);

}  // namespace ls::evaluation
