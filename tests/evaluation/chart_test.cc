// Charts drawn by gnuplot from a CSV file: the PNG, its script naming every series, the CSV's
// columns checked first, the script alone without gnuplot, and a bench's charts redrawn from its
// CSV alone.
#include "evaluation/chart.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <set>
#include <tuple>

#include "evaluation/bench_charts.h"
#include "evaluation/csv_table.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "tests/support/test_support.h"

namespace ls::evaluation {
namespace {

namespace fs = std::filesystem;

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Two maps' errors against LEDs, rows interleaved, one error missing.
fs::path write_small_csv(const fs::path& dir) {
  const fs::path csv = dir / "small.csv";
  std::ofstream(csv) << "leds,map,method,relative_rmse\n"
                        "20,sky_sun,cells,0.25\n20,\"studio, soft\",cells,0.12\n"
                        "40,sky_sun,cells,0.2\n40,\"studio, soft\",cells,\n"
                        "80,sky_sun,cells,0.15\n80,\"studio, soft\",cells,0.08\n";
  return csv;
}

Chart small_chart(const fs::path& csv) {
  Chart chart{.csv = csv,
              .x = "leds",
              .y = "relative_rmse",
              .series = series_by("map", {"sky_sun"}),
              .title = "Error vs LEDs",
              .x_label = "LEDs",
              .y_label = "relative RMSE",
              .log_x = true};
  chart.series.push_back({.title = "studio", .where = {{"method", "cells"}, {"leds", "80"}}});
  chart.series[0].labels.column = "leds";
  return chart;
}

// PATH set to an empty folder while it lives: no gnuplot.
class NoGnuplot {
 public:
  explicit NoGnuplot(const fs::path& empty) : saved_(std::getenv("PATH")) {
    setenv("PATH", empty.c_str(), 1);
  }
  ~NoGnuplot() { setenv("PATH", saved_.c_str(), 1); }

 private:
  std::string saved_;
};

TEST(CsvTable, ReadsQuotedFieldsBackAsWritten) {
  testing::TempDir dir;
  std::ofstream(dir / "t.csv") << "name,value\n" << csv_field("a, \"b\"") << ",1\nplain,x\n";
  const CsvTable table = CsvTable::read(dir / "t.csv");
  EXPECT_EQ(table.distinct("name"), (std::vector<std::string>{"a, \"b\"", "plain"}));
  const std::vector<double> values = table.numbers("value");
  EXPECT_EQ(values[0], 1);
  EXPECT_TRUE(std::isnan(values[1]));
}

TEST(Chart, DrawsAPngAndAScriptNamingEverySeries) {
  if (const auto missing = chart_tool_missing()) GTEST_SKIP() << *missing;
  testing::TempDir dir;
  const fs::path png = dir / "error.png";
  ASSERT_TRUE(write_chart(png, small_chart(write_small_csv(dir.path()))));
  const Image image = read_image(png);
  EXPECT_EQ(image.width, kChartWidth);
  EXPECT_EQ(image.height, kChartHeight);
  std::set<std::tuple<float, float, float>> colours;
  for (size_t i = 0; i < image.num_pixels() && colours.size() < 3; ++i) {
    colours.insert({image.pixels[i * 3], image.pixels[i * 3 + 1], image.pixels[i * 3 + 2]});
  }
  EXPECT_GE(colours.size(), 3u);  // Not blank: white, black and a series' colour at least.
  const std::string script = read_text(dir / "error.gp");
  EXPECT_NE(script.find("title 'sky_sun'"), std::string::npos) << script;
  EXPECT_NE(script.find("title 'studio'"), std::string::npos) << script;
  EXPECT_NE(script.find("'small.csv'"), std::string::npos) << "plots from the CSV: " << script;
  EXPECT_FALSE(fs::exists(dir / "error.gnuplot.log"));
}

TEST(Chart, RefusesACsvWithoutTheColumnNamingFileAndColumn) {
  testing::TempDir dir;
  Chart chart = small_chart(write_small_csv(dir.path()));
  chart.y = "psnr_db";
  try {
    write_chart(dir / "error.png", chart);
    FAIL() << "a missing column was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("small.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'psnr_db'"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "error.gp"));
}

TEST(Chart, RefusesToSelectByATextWithAComma) {
  testing::TempDir dir;
  Chart chart = small_chart(write_small_csv(dir.path()));
  chart.series = series_by("map", {"studio, soft"});
  EXPECT_THROW(write_chart(dir / "error.png", chart), InputError);
}

TEST(Chart, WithoutGnuplotWritesTheScriptAlone) {
  testing::TempDir dir;
  fs::create_directories(dir / "empty");
  const NoGnuplot no_gnuplot(dir / "empty");
  ASSERT_TRUE(chart_tool_missing().has_value());
  EXPECT_NE(chart_tool_missing()->find("gnuplot"), std::string::npos);
  EXPECT_FALSE(write_chart(dir / "error.png", small_chart(write_small_csv(dir.path()))));
  EXPECT_TRUE(fs::exists(dir / "error.gp"));
  EXPECT_FALSE(fs::exists(dir / "error.png"));
  EXPECT_THROW(redraw_bench_charts(dir.path()), InputError);
}

TEST(BenchCharts, RedrawsABenchsChartsFromItsCsvAlone) {
  if (const auto missing = chart_tool_missing()) GTEST_SKIP() << *missing;
  testing::TempDir dir;
  EXPECT_THROW(redraw_bench_charts(dir.path()), InputError);  // No bench CSV there.
  std::ofstream(dir / "leds.csv")
      << "leds,map,method,turns,relative_rmse,psnr_db,relight_ms,relight_gb_per_s,"
         "light_weights_ms,uncovered_fraction\n"
         "20,sky_sun,cells,0,0.25,29.6,0.14,28,2.3,0.07\n"
         "20,sky_sun,cells + sources,0,0.13,35.4,63.5,0.06,146.9,0.07\n"
         "20,sky_sun,cells,8,0.25,29.6,0,0,0,0.07\n"
         "40,sky_sun,cells,0,0.2,31.2,0.2,27,2.5,0.05\n"
         "40,sky_sun,cells + sources,0,0.1,37.1,64.1,0.06,150.2,0.05\n"
         "40,sky_sun,cells,8,0.21,31,0,0,0,0.05\n";
  std::ofstream(dir / "fit.csv") << "method,map,relative_rmse\nfield,sky_sun,0.1\n";
  const RedrawnCharts charts = redraw_bench_charts(dir.path());
  EXPECT_EQ(charts.drawn, std::vector<fs::path>{dir / "leds.csv"});
  ASSERT_EQ(charts.errors.size(), 1u);  // fit.csv lacks its times: the others drawn still.
  EXPECT_NE(charts.errors[0].find("fit.csv"), std::string::npos) << charts.errors[0];
  for (const char* name :
       {"leds_psnr_vs_time", "leds_error_vs_count", "leds_error_vs_count_turned"}) {
    EXPECT_TRUE(fs::exists(dir / (std::string(name) + ".png"))) << name;
    EXPECT_TRUE(fs::exists(dir / (std::string(name) + ".gp"))) << name;
  }
}

}  // namespace
}  // namespace ls::evaluation
