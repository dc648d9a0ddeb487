// `lightstage fit --time` on imported time-lapse fields, which carry no measured noise: the noise
// is estimated from the steps' data as plain `fit` estimates it, so the same scene captured five
// times darker (the same sensor) gets the same pixels fitted and flagged; the default noise model
// (the simulated 12-bit camera, a thousand times this sensor's read variance) would leave the
// dark capture's shadows and dark metal without normals. A single step is refused.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/fit_job.h"
#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "relight/time/temporal_fit.h"
#include "sim/noisy_field.h"
#include "sim/scene.h"
#include "sim/time_varying.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 32, kHeight = 24;
// A 16-bit camera's noise: read variance 1e-9, shot 1e-6 per unit (the default model: 1e-6, 1e-4).
const relight::NoiseModel kSensor{1e-9, 1e-6};

// The rise-and-fall scene at 6 times, exposed by `exposure`, with kSensor's noise, written as an
// import writes fields: no measured noise. Returns the folder.
fs::path write_time_lapse(const fs::path& dir, double exposure) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(40, -11.5));
  stage.camera.width = kWidth;
  stage.camera.height = kHeight;
  const sim::Scene scene = sim::rise_and_fall_scene();
  fs::create_directories(dir);
  int i = 0;
  for (const double t : {0.0, 240.0, 480.0, 720.0, 960.0, 1200.0}) {
    sim::SimFieldOptions at;
    at.scene_time_s = t;
    capture::ReflectanceField field = sim::render_ideal_field(stage, scene, at);
    for (int y = 0; y < kHeight; ++y) {
      float* row = field.pixel(0, y);
      for (int v = 0; v < kWidth * field.num_lights() * 3; ++v) row[v] *= float(exposure);
    }
    sim::add_sensor_noise(field, kSensor.as_field_noise(), 90 + i);
    field.noise = {};  // An imported set: no dark frames, no bracket.
    char name[32];
    std::snprintf(name, sizeof name, "field_t%03d.exr", i++);
    capture::write_field(dir / name, field);
  }
  return dir;
}

jobs::TemporalFitJobSummary fit(const fs::path& fields, const fs::path& out) {
  jobs::FitJobOptions options;
  options.time_inputs = {fields};
  options.out = out;
  return jobs::fit_over_time(options);
}

TEST(TemporalNoise, ImportedTimeLapseFlagsTheSamePixelsAtEitherExposure) {
  const testing::TempDir dir;
  const jobs::TemporalFitJobSummary bright =
      fit(write_time_lapse(dir / "bright", 1.0), dir / "bright.exr");
  const jobs::TemporalFitJobSummary dark =
      fit(write_time_lapse(dir / "dark", 0.2), dir / "dark.exr");
  for (const auto* s : {&bright, &dark}) {
    EXPECT_NE(s->noise_source.find("estimated from the data"), std::string::npos)
        << s->noise_source;
  }
  std::printf("bright: %s\ndark:   %s\n", bright.fit.to_string().c_str(),
              dark.fit.to_string().c_str());
  const relight::TemporalMaps a = relight::read_temporal_maps(dir / "bright.exr");
  const relight::TemporalMaps b = relight::read_temporal_maps(dir / "dark.exr");
  int fitted = 0, differ = 0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const bool fitted_a = a.model(x, y) != relight::TemporalModel::kNone;
      const bool fitted_b = b.model(x, y) != relight::TemporalModel::kNone;
      fitted += fitted_a;
      differ += fitted_a != fitted_b;
    }
  }
  // The object covers most of the frame; at most a few pixels on its silhouette may differ.
  EXPECT_GT(fitted, kWidth * kHeight / 3);
  EXPECT_LE(differ, kWidth * kHeight / 100) << "of " << fitted << " fitted";
  EXPECT_EQ(bright.fit.flagged, bright.fit.no_normal + bright.fit.no_usable_step);
  EXPECT_EQ(dark.fit.flagged, dark.fit.no_normal + dark.fit.no_usable_step);
}

TEST(TemporalNoise, ASingleStepIsRefusedNamingIt) {
  const testing::TempDir dir;
  const fs::path fields = write_time_lapse(dir / "fields", 1.0);
  jobs::FitJobOptions options;
  options.time_inputs = {fields / "field_t000.exr"};
  options.out = dir / "one.exr";
  try {
    jobs::fit_over_time(options);
    FAIL() << "a single step was fitted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("field_t000.exr"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("at least two"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "one.exr"));
}

}  // namespace
}  // namespace ls
