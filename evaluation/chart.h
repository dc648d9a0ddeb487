#pragma once
// Minimal scatter/line charts as PNG (OpenCV drawing), for speed-versus-accuracy results.
#include <filesystem>
#include <string>
#include <vector>

namespace ls::evaluation {

struct ChartSeries {
  std::string name;
  std::vector<double> x, y;
  std::vector<std::string> point_labels;  // Optional, one per point.
  bool connect = true;  // Lines between consecutive points; false: a scatter of unordered points.
};

struct ChartAxes {
  std::string title, x_label, y_label;
  bool log_x = false;
};

void write_chart(const std::filesystem::path& png, const ChartAxes& axes,
                 const std::vector<ChartSeries>& series);

}  // namespace ls::evaluation
