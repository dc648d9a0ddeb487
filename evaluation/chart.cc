#include "evaluation/chart.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "lightstage/image.h"

namespace ls::evaluation {

namespace {

const cv::Scalar kColours[] = {{200, 90, 30},  {40, 140, 230}, {60, 170, 60},   {40, 40, 200},
                               {160, 80, 160}, {30, 160, 180}, {120, 120, 120}, {0, 0, 0}};

std::string format_tick(double v) {
  char buf[32];
  if (std::abs(v) >= 1000 || (std::abs(v) < 0.01 && v != 0)) {
    std::snprintf(buf, sizeof buf, "%.0e", v);
  } else {
    std::snprintf(buf, sizeof buf, "%g", std::round(v * 1000) / 1000);
  }
  return buf;
}

}  // namespace

void write_chart(const std::filesystem::path& png, const ChartAxes& axes,
                 const std::vector<ChartSeries>& series) {
  constexpr int W = 960, H = 620, L = 90, R = 200, T = 70, B = 70;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  auto tx = [&](double x) { return axes.log_x ? std::log10(std::max(x, 1e-12)) : x; };
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (const auto& s : series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = std::min(x0, tx(s.x[i]));
      x1 = std::max(x1, tx(s.x[i]));
      y0 = std::min(y0, s.y[i]);
      y1 = std::max(y1, s.y[i]);
    }
  }
  if (!std::isfinite(x0)) return;
  const double px = (x1 - x0) * 0.08 + 1e-9, py = (y1 - y0) * 0.1 + 1e-9;
  x0 -= px, x1 += px, y0 -= py, y1 += py;
  auto to_px = [&](double x, double y) {
    return cv::Point(L + int((tx(x) - x0) / (x1 - x0) * (W - L - R)),
                     H - B - int((y - y0) / (y1 - y0) * (H - T - B)));
  };
  const cv::Scalar grey(200, 200, 200), black(0, 0, 0);
  for (int i = 0; i <= 5; ++i) {
    const double gx = x0 + (x1 - x0) * i / 5, gy = y0 + (y1 - y0) * i / 5;
    const int X = L + (W - L - R) * i / 5, Y = H - B - (H - T - B) * i / 5;
    cv::line(img, {X, T}, {X, H - B}, grey, 1);
    cv::line(img, {L, Y}, {W - R, Y}, grey, 1);
    cv::putText(img, format_tick(axes.log_x ? std::pow(10, gx) : gx), {X - 20, H - B + 20},
                cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1, cv::LINE_AA);
    cv::putText(img, format_tick(gy), {8, Y + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1,
                cv::LINE_AA);
  }
  cv::rectangle(img, {L, T}, {W - R, H - B}, black, 1);
  cv::putText(img, axes.title, {12, 26}, cv::FONT_HERSHEY_SIMPLEX, 0.6, black, 1, cv::LINE_AA);
  cv::putText(img, axes.x_label + (axes.log_x ? " (log)" : ""), {L + 150, H - 20},
              cv::FONT_HERSHEY_SIMPLEX, 0.55, black, 1, cv::LINE_AA);
  cv::putText(img, axes.y_label, {8, T - 10}, cv::FONT_HERSHEY_SIMPLEX, 0.5, black, 1, cv::LINE_AA);
  for (size_t k = 0; k < series.size(); ++k) {
    const auto& s = series[k];
    const cv::Scalar colour = kColours[k % std::size(kColours)];
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      const cv::Point p = to_px(s.x[i], s.y[i]);
      if (s.connect && i > 0 && std::isfinite(s.x[i - 1]) && std::isfinite(s.y[i - 1])) {
        cv::line(img, to_px(s.x[i - 1], s.y[i - 1]), p, colour, 2, cv::LINE_AA);
      }
      cv::circle(img, p, 5, colour, cv::FILLED, cv::LINE_AA);
      if (i < s.point_labels.size()) {
        cv::putText(img, s.point_labels[i], p + cv::Point(6, -6), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                    colour, 1, cv::LINE_AA);
      }
    }
    const int ly = T + 20 + int(k) * 22;
    cv::circle(img, {W - R + 20, ly - 5}, 5, colour, cv::FILLED, cv::LINE_AA);
    cv::putText(img, s.name, {W - R + 32, ly}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1,
                cv::LINE_AA);
  }
  // Drawn in OpenCV's BGR order (kColours), written in RGB order.
  cv::Mat rgb;
  cv::cvtColor(img, rgb, cv::COLOR_BGR2RGB);
  write_rgb8(png, rgb.cols, rgb.rows, rgb.ptr<uint8_t>());
}

}  // namespace ls::evaluation
