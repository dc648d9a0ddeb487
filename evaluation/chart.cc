#include "evaluation/chart.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>

#include "evaluation/bench_support.h"
#include "evaluation/csv_table.h"
#include "lightstage/errors.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

namespace {

// Okabe and Ito's colours (told apart with the common colour-vision deficiencies; brown for
// their yellow, faint on white), then grey.
constexpr const char* kColours[] = {"#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00",
                                    "#56B4E9", "#000000", "#8C564B", "#777777"};
// Filled circle, square, triangle, diamond, inverted triangle, then their outlines, +, x, *.
constexpr int kPoints[] = {7, 5, 9, 13, 11, 6, 4, 8, 12, 10, 1, 2, 3};
constexpr int kDashes = 5;  // gnuplot's solid, dashed, dotted, dash-dot, dash-dot-dot.

// A gnuplot string literal: single-quoted, a quote doubled.
std::string gp_string(const std::string& text) {
  std::string out = "'";
  for (const char c : text) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}

// One series' rows to plot (finite x and y, `where` met) and the labels drawn beside them.
struct SeriesRows {
  size_t k = 0;                   // The series' index in the chart.
  std::vector<size_t> rows;       // In the CSV.
  std::vector<double> x, y;       // Their values.
  std::vector<std::string> text;  // Their labels ("" where none).
  std::vector<size_t> labelled;   // The rows whose label is drawn.
};

// A label's text as gnuplot's `sprintf(format, scale * value)` or the field itself.
std::string label_text(const ChartLabels& labels, const std::string& field) {
  if (labels.format.empty()) return field;
  char text[128];
  std::snprintf(text, sizeof text, labels.format.c_str(),
                labels.scale * std::strtod(field.c_str(), nullptr));
  return text;
}

SeriesRows rows_of(const CsvTable& table, const Chart& chart, size_t k) {
  const ChartSeries& s = chart.series[k];
  std::vector<size_t> where;
  for (const auto& [column, text] : s.where) where.push_back(table.column(column));
  const std::vector<double> x = table.numbers(s.x.empty() ? chart.x : s.x);
  const std::vector<double> y = table.numbers(s.y.empty() ? chart.y : s.y);
  const bool labelled = !s.labels.column.empty();
  const size_t label = labelled ? table.column(s.labels.column) : 0;
  const bool only = !s.labels.where.first.empty();
  const size_t only_column = only ? table.column(s.labels.where.first) : 0;
  SeriesRows out;
  out.k = k;
  for (size_t r = 0; r < table.rows.size(); ++r) {
    bool match = std::isfinite(x[r]) && std::isfinite(y[r]);
    for (size_t i = 0; i < where.size() && match; ++i) {
      match = table.rows[r][where[i]] == s.where[i].second;
    }
    if (!match) continue;
    out.rows.push_back(r);
    out.x.push_back(x[r]);
    out.y.push_back(y[r]);
    const bool shown = labelled && (!only || table.rows[r][only_column] == s.labels.where.second);
    out.text.push_back(shown ? label_text(s.labels, table.rows[r][label]) : "");
  }
  return out;
}

// An axis' data range, in log10 on a log axis (whose non-positive values are not drawn).
struct Range {
  double lo = INFINITY, hi = -INFINITY;
  void add(double v, bool log) {
    if (log && !(v > 0)) return;
    const double t = log ? std::log10(v) : v;
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
};

// Where gnuplot draws a chart's points, in pixels: the plot area estimated from the PNG's size
// less the title, the axes' numbers and titles, and the legend's rows below.
class PixelMap {
 public:
  PixelMap(const Chart& chart, const Range& x, const Range& y, double right_offset,
           const std::vector<SeriesRows>& plotted)
      : chart_(chart),
        x_lo_(x.lo - 0.04 * (x.hi - x.lo)),
        x_span_((x.hi - x.lo) * (1.04 + right_offset)),
        y_lo_(y.lo - 0.06 * (y.hi - y.lo)),
        y_span_((y.hi - y.lo) * 1.12) {
    size_t longest = 0;
    for (const SeriesRows& s : plotted) longest = std::max(longest, chart.series[s.k].title.size());
    // A legend column: its title, the line sample and gaps, at about 8.5 px a character.
    const size_t columns = std::max<size_t>(1, size_t(920 / (8.5 * double(longest + 8))));
    const size_t rows = (plotted.size() + columns - 1) / columns;
    height_ = kChartHeight - 55 - 60 - 21.0 * double(rows);
  }
  bool shown(double x, double y) const {
    return (!chart_.log_x || x > 0) && (!chart_.log_y || y > 0);
  }
  double px(double x) const {
    const double t = chart_.log_x ? std::log10(x) : x;
    return 60 + (kChartWidth - 90) * (t - x_lo_) / (x_span_ > 0 ? x_span_ : 1);
  }
  double py(double y) const {
    const double t = chart_.log_y ? std::log10(y) : y;
    return 55 + height_ * (1 - (t - y_lo_) / (y_span_ > 0 ? y_span_ : 1));
  }

 private:
  const Chart& chart_;
  double x_lo_, x_span_, y_lo_, y_span_, height_ = 0;
};

// Labels kept where they cover neither a label kept before them (series by series, row by row)
// nor another point; each placed as gnuplot places it (offset char 0.8, 0.5; ~6.5 px a character).
void thin_labels(std::vector<SeriesRows>& all, const PixelMap& map) {
  struct Box {
    double x0, x1, y0, y1;
    bool covers(const Box& b) const { return x0 < b.x1 && b.x0 < x1 && y0 < b.y1 && b.y0 < y1; }
  };
  std::vector<Box> taken;  // The points (7 px about each), then the labels kept.
  for (const SeriesRows& s : all) {
    for (size_t i = 0; i < s.rows.size(); ++i) {
      if (!map.shown(s.x[i], s.y[i])) continue;
      const double px = map.px(s.x[i]), py = map.py(s.y[i]);
      taken.push_back({px - 7, px + 7, py - 7, py + 7});
    }
  }
  for (SeriesRows& s : all) {
    for (size_t i = 0; i < s.rows.size(); ++i) {
      if (s.text[i].empty() || !map.shown(s.x[i], s.y[i])) continue;
      const double px = map.px(s.x[i]) + 7, py = map.py(s.y[i]) - 8;
      const Box box{px, px + 6.5 * double(s.text[i].size()), py - 6, py + 6};
      if (std::any_of(taken.begin(), taken.end(), [&](const Box& b) { return box.covers(b); })) {
        continue;
      }
      taken.push_back(box);
      s.labelled.push_back(s.rows[i]);
    }
  }
}

// A log axis over less than three decades gets tics at 1, 2 and 5 times the powers of ten (a
// decade's tics alone may leave it one number, or none).
void write_log_tics(std::ostream& gp, const char* axis, double lo, double hi) {
  if (!(lo > 0) || !(hi >= lo) || std::log10(hi / lo) >= 3) return;
  gp << "set " << axis << "tics (";
  const char* separator = "";
  for (int e = int(std::floor(std::log10(lo))) - 1; e <= int(std::ceil(std::log10(hi))); ++e) {
    for (const double m : {1.0, 2.0, 5.0}) {
      const double tic = m * std::pow(10.0, e);
      if (tic < lo / 2 || tic > hi * 2) continue;
      gp << separator << tic;
      separator = ", ";
    }
  }
  gp << ")\n";
}

// The series' rows, filtered from the CSV into the datablock $sK (x, y, label).
void write_table(std::ostream& gp, const Chart& chart, const SeriesRows& rows,
                 const std::string& data) {
  const ChartSeries& s = chart.series[rows.k];
  gp << "set table $s" << rows.k << " separator comma\n";
  gp << "plot " << data << " using (column(" << gp_string(s.x.empty() ? chart.x : s.x)
     << ")):(column(" << gp_string(s.y.empty() ? chart.y : s.y) << "))";
  if (!s.labels.column.empty()) {
    // Only the rows thin_labels kept (column 0: the row's index in the CSV).
    std::string kept = ",";
    for (const size_t r : rows.labelled) kept += std::to_string(r) + ",";
    gp << ":(strstrt(" << gp_string(kept) << ", sprintf(',%d,', column(0))) == 0 ? '' : ";
    if (s.labels.format.empty()) {
      gp << "strcol(" << gp_string(s.labels.column) << "))";
    } else {
      gp << "sprintf(" << gp_string(s.labels.format) << ", " << s.labels.scale << " * column("
         << gp_string(s.labels.column) << ")))";
    }
  }
  gp << " with table";
  for (size_t i = 0; i < s.where.size(); ++i) {
    gp << (i == 0 ? " if (" : " && ") << "strcol(" << gp_string(s.where[i].first) << ") eq "
       << gp_string(s.where[i].second);
  }
  gp << (s.where.empty() ? "\n" : ")\n") << "unset table\n";
}

void write_style(std::ostream& gp, const Chart& chart, const Range& x, const Range& y,
                 double right_offset, const fs::path& png) {
  gp << "set terminal pngcairo size " << kChartWidth << "," << kChartHeight
     << " noenhanced font 'Sans,11'\n"
     << "set output " << gp_string(png.filename().string()) << "\n"
     << "set title " << gp_string(chart.title) << " font 'Sans,13'\n"
     << "set xlabel " << gp_string(chart.x_label) << "\nset ylabel " << gp_string(chart.y_label)
     << "\n"
     << "set format x '%g'\nset format y '%g'\n"
     << "set grid xtics ytics mxtics mytics lc rgb '#dddddd'\n"
     << "set key below left Left reverse horizontal spacing 1.2 width 2 height 1\n"
     << "set autoscale fix\n"
     << "set offsets graph 0.04, graph " << right_offset << ", graph 0.06, graph 0.06\n";
  if (chart.log_x) {
    gp << "set logscale x\n";
    write_log_tics(gp, "x", std::pow(10.0, x.lo), std::pow(10.0, x.hi));
  }
  if (chart.log_y) {
    gp << "set logscale y\n";
    write_log_tics(gp, "y", std::pow(10.0, y.lo), std::pow(10.0, y.hi));
  }
  for (size_t k = 0; k < std::size(kPoints); ++k) {
    gp << "set linetype " << k + 1 << " lc rgb '" << kColours[k % std::size(kColours)]
       << "' lw 2 pt " << kPoints[k] << " ps 1.4 dt " << k % kDashes + 1 << "\n";
  }
  gp << "set linetype cycle " << std::size(kPoints) << "\n";
}

void run_gnuplot(const fs::path& script) {
  const fs::path log = fs::path(script).replace_extension(".gnuplot.log");
  try {
    run_process(
        {"gnuplot", "-e", "cd " + gp_string(script.parent_path().string()), script.string()}, log);
  } catch (const InputError&) {
    std::ifstream in(log);
    const std::string said{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    throw InputError(script.string() + ": gnuplot failed: " + said);
  }
  fs::remove(log);
}

}  // namespace

std::vector<ChartSeries> series_by(const std::string& column,
                                   const std::vector<std::string>& values) {
  std::vector<ChartSeries> series;
  series.reserve(values.size());
  for (const std::string& value : values) {
    series.push_back({.title = value, .where = {{column, value}}});
  }
  return series;
}

std::optional<std::string> chart_tool_missing() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    if (!dir.empty() && access((fs::path(dir) / "gnuplot").c_str(), X_OK) == 0) return {};
  }
  return "gnuplot is not on PATH (Debian: apt-get install gnuplot-nox)";
}

bool write_chart(const fs::path& png, const Chart& chart) {
  const CsvTable table = CsvTable::read(chart.csv);
  const fs::path dir = fs::absolute(png).parent_path();
  const fs::path csv = fs::absolute(chart.csv);
  const std::string data =
      gp_string(csv.parent_path() == dir ? csv.filename().string() : csv.string());
  std::ostringstream gp;
  gp << "# " << png.filename().string() << " from " << csv.filename().string()
     << ", written by lightstage. Re-plot in this folder: gnuplot "
     << fs::path(png).replace_extension(".gp").filename().string() << "\n"
     << "set datafile separator comma\n";
  std::vector<SeriesRows> plotted;  // Series without a row to plot are left out.
  Range x, y;
  bool labelled = false;
  for (size_t k = 0; k < chart.series.size(); ++k) {
    const ChartSeries& s = chart.series[k];
    for (const auto& [column, text] : s.where) {
      if (text.find(',') != std::string::npos) {
        throw InputError(chart.csv.string() + ": series '" + s.title + "' selects " + column +
                         " = '" + text + "': gnuplot cannot match a text holding a comma");
      }
    }
    SeriesRows rows = rows_of(table, chart, k);
    if (rows.rows.empty()) continue;
    for (size_t i = 0; i < rows.rows.size(); ++i) {
      x.add(rows.x[i], chart.log_x);
      y.add(rows.y[i], chart.log_y);
    }
    labelled = labelled || !s.labels.column.empty();
    plotted.push_back(std::move(rows));
  }
  if (plotted.empty() || !(x.hi >= x.lo) || !(y.hi >= y.lo)) {
    throw InputError(chart.csv.string() + ": no row to plot in " + png.filename().string());
  }
  const double right_offset = labelled ? 0.14 : 0.04;  // Room for labels right of the points.
  thin_labels(plotted, PixelMap(chart, x, y, right_offset, plotted));
  for (const SeriesRows& rows : plotted) write_table(gp, chart, rows, data);
  write_style(gp, chart, x, y, right_offset, png);
  gp << "plot";
  for (size_t i = 0; i < plotted.size(); ++i) {
    const size_t k = plotted[i].k;
    const ChartSeries& s = chart.series[k];
    gp << (i ? ", \\\n     " : " ") << "$s" << k << " using 1:2 with "
       << (chart.lines ? "linespoints" : "points") << " lt " << i + 1 << " title "
       << gp_string(s.title);
    if (!s.labels.column.empty()) {
      gp << ", \\\n     $s" << k << " using 1:2:3 with labels left offset char 0.8,0.5"
         << " font 'Sans,9' textcolor lt " << i + 1 << " notitle";
    }
  }
  gp << "\n";
  const fs::path script = fs::path(dir / png.filename()).replace_extension(".gp");
  {
    std::ofstream out(script);
    out << gp.str();
    if (!out) throw InputError(script.string() + ": cannot write");
  }
  if (chart_tool_missing()) return false;
  run_gnuplot(script);
  return true;
}

}  // namespace ls::evaluation
