// `lightstage fit --time` in bands of rows: the time-step fields read a band at a time
// within --memory, the curves learnt from every band's sample, the maps written a band at a time,
// the same maps as the fit of the whole fields; a run killed halfway resumes from its checkpoints.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "app/jobs/fit_job.h"
#include "app/jobs/relight_job.h"
#include "capture/field_file.h"
#include "lightstage/image.h"
#include "relight/time/temporal_fit.h"
#include "sim/scene.h"
#include "tests/relight/time/time_fixtures.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

struct Killed {};

// A progress callback that stops the job (as a kill would) once `phase` is half done.
jobs::ProgressFn killed_halfway_through(const std::string& phase) {
  return [phase](const std::string& p, long done, long total, const std::string&) {
    if (p == phase && 2 * done >= total) throw Killed{};
  };
}

// The simulator's time-varying scene (paint, dust, rust: every process, a few pixels the curves
// explain and a few whose process runs away) at 6 times on a 40-LED dome, one field per file.
class TemporalBands : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir;
    Stage stage = stage_with_directions(fibonacci_dome_directions(40, -11.5));
    stage.camera.width = 36;
    stage.camera.height = 30;
    const sim::Scene scene = sim::time_varying_scene();
    int i = 0;
    for (const double t : {0.0, 120.0, 300.0, 500.0, 800.0, 1200.0}) {
      char name[32];
      std::snprintf(name, sizeof name, "field_t%03d.exr", i);
      capture::write_field(fields() / name, relight::time_testing::field_at(
                                                stage, scene, t, relight::NoiseModel{}, 7 + i));
      ++i;
    }
    jobs::FitJobOptions whole = options(*dir_ / "whole.exr", 0);
    whole_ = new jobs::TemporalFitJobSummary(jobs::fit_over_time(whole));
  }
  static void TearDownTestSuite() {
    delete whole_;
    delete dir_;
  }
  static fs::path fields() {
    fs::create_directories(*dir_ / "fields");
    return *dir_ / "fields";
  }
  static jobs::FitJobOptions options(const fs::path& out, std::size_t memory_bytes) {
    jobs::FitJobOptions o;
    o.time_inputs = {fields()};
    o.out = out;
    o.memory = MemoryBudget(memory_bytes);
    return o;
  }
  // A budget of about 4 rows of every step's fits: 8 bands.
  static std::size_t four_rows() { return 4 * 36 * 3 * 40 * 4 * 2 + 4 * 36 * 4 * 120; }

  static testing::TempDir* dir_;
  static jobs::TemporalFitJobSummary* whole_;
};
testing::TempDir* TemporalBands::dir_ = nullptr;
jobs::TemporalFitJobSummary* TemporalBands::whole_ = nullptr;

TEST_F(TemporalBands, BandsGiveTheMapsOfTheWholeSeries) {
  ASSERT_EQ(whole_->band_rows, 30) << "the series fits in memory by default";
  EXPECT_GT(whole_->fit.curve_families, 0) << "the scene's curves are learnt (and offered)";
  EXPECT_GT(whole_->fit.per_model[int(relight::TemporalModel::kCurve)], 0);
  EXPECT_GT(whole_->fit.degenerate, 0) << "the file keeps their per-step fits";
  const jobs::TemporalFitJobSummary bands =
      jobs::fit_over_time(options(*dir_ / "bands.exr", four_rows()));
  ASSERT_LT(bands.band_rows, 10);
  EXPECT_EQ(bands.fit.per_model[int(relight::TemporalModel::kCurve)],
            whole_->fit.per_model[int(relight::TemporalModel::kCurve)]);
  EXPECT_EQ(bands.fit.fitted, whole_->fit.fitted);
  EXPECT_EQ(bands.fit.degenerate, whole_->fit.degenerate);
  const Image whole = read_image(*dir_ / "whole.exr"), banded = read_image(*dir_ / "bands.exr");
  EXPECT_EQ(whole.channel_names, banded.channel_names);
  EXPECT_EQ(banded.channels, relight::kTemporalChannelCount + 6 * relight::kTemporalParamCount);
  EXPECT_TRUE(whole.pixels == banded.pixels);
  const relight::TemporalMaps maps = relight::read_temporal_maps(*dir_ / "bands.exr");
  ASSERT_EQ(maps.curves.size(), relight::read_temporal_maps(*dir_ / "whole.exr").curves.size());
  for (size_t f = 0; f < maps.curves.size(); ++f) {
    EXPECT_EQ(maps.curves[f].knots,
              relight::read_temporal_maps(*dir_ / "whole.exr").curves[f].knots);
  }
  EXPECT_FALSE(fs::exists(*dir_ / "bands.exr.partial")) << "the checkpoints are removed";
}

// Killed halfway through the bands' fits, or through offering the curves, a rerun takes the
// finished bands from the checkpoints and writes the maps of an uninterrupted run.
TEST_F(TemporalBands, AKilledFitResumesFromItsBands) {
  const jobs::FitJobOptions fit = options(*dir_ / "resumed.exr", four_rows());
  for (const std::string phase : {"fit over time (rows)", "curves offered (rows)"}) {
    fs::remove(fit.out);
    EXPECT_THROW((void)jobs::fit_over_time(fit, killed_halfway_through(phase)), Killed) << phase;
    EXPECT_FALSE(fs::exists(fit.out));
    ASSERT_TRUE(fs::exists(*dir_ / "resumed.exr.partial"));
    long resumed_offers = 0;
    const jobs::TemporalFitJobSummary resumed = jobs::fit_over_time(
        fit, [&](const std::string& p, long done, long, const std::string& item) {
          if (p == "curves offered (rows)" && item == "resumed") resumed_offers = done;
        });
    ASSERT_LT(resumed.band_rows, 30);
    if (phase == "fit over time (rows)") {
      EXPECT_GE(2 * resumed.resumed_rows, 30);
      EXPECT_LT(resumed.resumed_rows, 30);
      EXPECT_EQ(resumed_offers, 0);
    } else {
      EXPECT_EQ(resumed.resumed_rows, 30) << "every band's processes were kept";
      EXPECT_GE(2 * resumed_offers, 30);
    }
    EXPECT_TRUE(read_image(fit.out).pixels == read_image(*dir_ / "whole.exr").pixels) << phase;
    EXPECT_FALSE(fs::exists(*dir_ / "resumed.exr.partial"));
  }
}

// `relight --temporal` reads the maps a band of rows at a time (16 rows under a tiny budget): its
// time edits' transfers are summarised by passes over the bands, each band edited by its rows of
// the masks: the images of the whole maps' render, byte for byte.
TEST_F(TemporalBands, RelightAtATimeInBandsIsTheWholeMapsRender) {
  Image mask(36, 30, 3);
  for (int y = 10; y < 28; ++y) {
    for (int x = 4; x < 30; ++x) mask.at(x, y, 0) = mask.at(x, y, 1) = mask.at(x, y, 2) = 1;
  }
  write_png_preview(*dir_ / "mask.png", mask);
  {
    std::ofstream edits(*dir_ / "time.json");
    edits << R"({"time": [{"select": {"mask": "mask.png"}, "transfer_from": {"model": "dust"}},
                          {"select": {"model": "exponential"}, "rate_scale": 2}]})";
  }
  Image sky(64, 32, 3, 0.2f);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 64; ++x) sky.at(x, y, 0) = 1.0f + 0.05f * x;
  }
  write_exr(*dir_ / "sky.exr", sky);
  const auto render = [&](const std::string& out, std::size_t memory_bytes) {
    jobs::RelightOptions relight;
    relight.temporal_file = *dir_ / "whole.exr";
    relight.time_s = 400;
    relight.edits_file = *dir_ / "time.json";
    relight.maps = {*dir_ / "sky.exr"};
    relight.light_dir = Eigen::Vector3d(0.3, 0.2, 0.93).normalized();
    relight.memory_bytes = memory_bytes;
    relight.out_dir = *dir_ / out;
    return jobs::relight(relight);
  };
  const jobs::RelightSummary whole = render("at400_whole", 0);
  const jobs::RelightSummary bands = render("at400_bands", 1);
  ASSERT_EQ(whole.edit_reports, bands.edit_reports);
  ASSERT_EQ(whole.images.size(), 2u);
  EXPECT_NE(whole.edit_reports.at(0).find("changed"), std::string::npos);
  for (size_t i = 0; i < whole.images.size(); ++i) {
    EXPECT_TRUE(read_image(whole.images[i].exr).pixels == read_image(bands.images[i].exr).pixels)
        << whole.images[i].label;
  }
}

}  // namespace
}  // namespace ls
