#include "capture/build_field.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <fstream>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/support/instant_sequencer.h"
#include "tests/support/test_support.h"

namespace ls::capture {
namespace {

constexpr int kLeds = 20;
constexpr int kSize = 64;

// A small dome in front of the default scene, with LEDs of unequal intensity and colour so that
// the per-channel irradiance normalisation is exercised.
Stage small_stage(CameraResponse response = {}) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(kLeds, 0.0));
  stage.camera.width = kSize;
  stage.camera.height = kSize;
  stage.camera.response = response;
  for (size_t i = 0; i < stage.leds.size(); ++i) {
    stage.leds[i].intensity = 0.5 + 0.1 * double(i % 7);
    stage.leds[i].color_gain = Eigen::Vector3d(1.0, 0.9 - 0.05 * double(i % 3), 0.8);
  }
  return stage;
}

struct Captured {
  std::unique_ptr<sim::SimStage> sim;
  Session session;
};

Captured capture(const std::filesystem::path& dir, const Stage& stage,
                 const SequencerOptions& options = ls::testing::instant_sequencer()) {
  auto sim = std::make_unique<sim::SimStage>(stage, sim::default_scene(), /*seed=*/11);
  Session session = Session::create(dir, stage, {});
  run_capture(session, sim->lights(), sim->camera(), options);
  return {std::move(sim), std::move(session)};
}

struct LedError {
  double relative_rmse = 0;
  double truth_rms = 0;
};

// Relative RMSE of one LED's slice of the field against the noise-free one-light render.
LedError compare_led(const ReflectanceField& field, int light, const Image& truth) {
  double sum_sq = 0, ref_sq = 0;
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        const double d = double(field.at(x, y, light, c)) - truth.at(x, y, c);
        sum_sq += d * d;
        ref_sq += double(truth.at(x, y, c)) * truth.at(x, y, c);
      }
    }
  }
  return {std::sqrt(sum_sq / ref_sq), std::sqrt(ref_sq / (3.0 * field.width() * field.height()))};
}

// Worst relative RMSE over the LEDs that light what the camera sees (rms of the truth at least 2%
// of the brightest LED's: grazing LEDs are mostly noise and dominate a relative measure).
double worst_error(const ReflectanceField& field, const sim::SimStage& sim, const Stage& stage,
                   double* median = nullptr) {
  std::vector<LedError> errors;
  double brightest = 0;
  const std::vector<int> order = stage.capture_order();
  for (int l = 0; l < field.num_lights(); ++l) {
    EXPECT_EQ(field.lights()[l].led_id, stage.leds[order[l]].id);
    if (!field.lights()[l].valid) continue;
    const Image truth =
        sim::render_one_light(sim.scene(), sim.hits(), stage.leds[order[l]].dir_in_stage);
    errors.push_back(compare_led(field, l, truth));
    brightest = std::max(brightest, errors.back().truth_rms);
  }
  std::vector<double> relevant;
  for (const LedError& e : errors) {
    if (e.truth_rms >= 0.02 * brightest) relevant.push_back(e.relative_rmse);
  }
  EXPECT_GE(relevant.size(), size_t(kLeds / 2));  // Most of the dome lights the scene.
  std::sort(relevant.begin(), relevant.end());
  if (median) *median = relevant[relevant.size() / 2];
  return relevant.back();
}

void expect_finite(const ReflectanceField& field) {
  for (float v : field.values()) ASSERT_TRUE(std::isfinite(v));
}

TEST(BuildField, LinearCameraMatchesNoiseFreeOneLightRenders) {
  ls::testing::TempDir dir;
  const Stage stage = small_stage();
  Captured c = capture(dir / "s", stage);
  ASSERT_TRUE(c.session.complete());
  BuildOptions options;
  int progress_calls = 0, last_done = 0;
  options.progress = [&](const std::string&, long done, long total, const std::string&) {
    ++progress_calls;
    EXPECT_EQ(total, kLeds);
    EXPECT_EQ(done, last_done + 1);
    last_done = done;
  };
  BuildSummary summary;
  const ReflectanceField field = build_field(c.session, options, &summary);
  EXPECT_EQ(field.width(), kSize);
  EXPECT_EQ(field.num_lights(), kLeds);
  EXPECT_EQ(progress_calls, kLeds);
  // The sequencer flags LEDs behind the scene (nothing they light is visible) as dead; every
  // other LED is used.
  std::vector<int> dead;
  for (const auto& [index, reason] : c.session.dead_leds()) dead.push_back(index);
  EXPECT_EQ(summary.lights_missing, dead);
  EXPECT_EQ(summary.lights_used, kLeds - int(dead.size()));
  EXPECT_GE(summary.lights_used, kLeds / 2);
  EXPECT_EQ(summary.response_used, "linear");
  EXPECT_GT(summary.seconds, 0.0);
  EXPECT_GE(summary.saturated_fraction, 0.0);
  EXPECT_LT(summary.saturated_fraction, 0.01);
  expect_finite(field);
  double median = 0;
  const double worst = worst_error(field, *c.sim, stage, &median);
  std::printf(
      "build_field vs truth (linear 12-bit): relative RMSE median %.2f%%, worst %.2f%%, "
      "saturated %.4f%%, %.3f s\n",
      100 * median, 100 * worst, 100 * summary.saturated_fraction, summary.seconds);
  // Measured 1.5% median, 3.4% worst (fixed seed): shot and read noise of single frames.
  EXPECT_LT(median, 0.025);
  EXPECT_LT(worst, 0.05);
}

TEST(BuildField, GammaAndRecoveredResponses) {
  ls::testing::TempDir dir;
  CameraResponse gamma;
  gamma.kind = CameraResponse::Kind::kGamma;
  gamma.gamma = 2.2;
  const Stage stage = small_stage(gamma);
  Captured c = capture(dir / "s", stage);
  BuildSummary summary;
  const ReflectanceField field = build_field(c.session, {}, &summary);
  EXPECT_EQ(summary.response_used, "gamma 2.2");
  double median = 0;
  const double worst = worst_error(field, *c.sim, stage, &median);
  std::printf("build_field vs truth (gamma 2.2): relative RMSE median %.2f%%, worst %.2f%%\n",
              100 * median, 100 * worst);
  // Measured 1.5% median, 2.9% worst.
  EXPECT_LT(median, 0.025);
  EXPECT_LT(worst, 0.05);

  // The same camera, its response recovered from the frames (the simulator still encodes 2.2).
  CameraResponse recover = gamma;
  recover.kind = CameraResponse::Kind::kRecover;
  const Stage recover_stage = small_stage(recover);
  Captured r = capture(dir / "r", recover_stage);
  const ReflectanceField recovered = build_field(r.session, {}, &summary);
  EXPECT_EQ(summary.response_used, "recovered");
  expect_finite(recovered);
  const double worst_recovered = worst_error(recovered, *r.sim, recover_stage, &median);
  std::printf(
      "build_field vs truth (recovered response): relative RMSE median %.2f%%, worst "
      "%.2f%%\n",
      100 * median, 100 * worst_recovered);
  // Measured 3.8% median, 6.4% worst: the curve recovered from 3 exposures x4 apart is good to a
  // few percent (response_test), which adds to the noise.
  EXPECT_LT(median, 0.06);
  EXPECT_LT(worst_recovered, 0.10);
}

TEST(BuildField, DeadAndIncompleteLedsAreInvalidAndZero) {
  ls::testing::TempDir dir;
  const Stage stage = small_stage();
  // Stop mid-capture, part way through an LED's bracket.
  std::atomic<bool> stop{false};
  SequencerOptions options = ls::testing::instant_sequencer();
  options.stop_requested = &stop;
  const int darks = stage.plan.dark_frames * int(stage.camera.bracket.size());
  options.on_progress = [&](const std::string&, long done, long, const std::string&) {
    if (done == darks + 3 * 6 + 2) stop = true;
  };
  Captured c = capture(dir / "s", stage, options);
  ASSERT_FALSE(c.session.complete());
  // Index 2 lights the scene from the front (the sequencer would not flag it).
  ASSERT_EQ(c.session.dead_leds().count(2), 0u);
  c.session.mark_dead_led(2, "no brighter than dark (test)");

  BuildSummary summary;
  const ReflectanceField field = build_field(c.session, {}, &summary);
  ASSERT_EQ(field.num_lights(), kLeds);
  const std::vector<int> order = stage.capture_order();
  int valid = 0;
  for (int l = 0; l < kLeds; ++l) {
    const int led = order[l];
    bool complete = true;
    for (int e = 0; e < 3; ++e) complete = complete && c.session.frames().count({0, led, e, 0});
    const bool expect_valid = complete && c.session.dead_leds().count(led) == 0;
    EXPECT_EQ(field.lights()[l].valid, expect_valid) << "LED index " << led;
    const bool listed =
        std::count(summary.lights_missing.begin(), summary.lights_missing.end(), led);
    EXPECT_EQ(listed, !expect_valid) << "LED index " << led;
    valid += expect_valid;
    if (!expect_valid) {
      for (int y = 0; y < kSize; y += 5) {
        for (int x = 0; x < kSize; x += 5) {
          for (int ch = 0; ch < 3; ++ch) ASSERT_EQ(field.at(x, y, l, ch), 0.0f);
        }
      }
    }
  }
  EXPECT_EQ(summary.lights_used, valid);
  EXPECT_GE(valid, 2);  // Some of LEDs 0..5 captured, minus the dead ones.
  EXPECT_FALSE(field.lights()[2].valid);
  EXPECT_LT(valid, kLeds);  // The interrupted one and those after it are missing.
}

TEST(BuildField, FieldRoundTripsThroughExr) {
  ls::testing::TempDir dir;
  const Stage stage = small_stage();
  Captured c = capture(dir / "s", stage);
  c.session.mark_dead_led(5, "test");
  const ReflectanceField field = build_field(c.session, {});
  write_field(dir / "field.exr", field);
  const ReflectanceField back = read_field(dir / "field.exr");
  ASSERT_EQ(back.values(), field.values());
  EXPECT_FALSE(back.lights()[5].valid);
  EXPECT_EQ(back.lights()[7].dir_in_stage, field.lights()[7].dir_in_stage);
}

TEST(BuildField, SaturatedPixelsAreCountedAndLowerBounds) {
  ls::testing::TempDir dir;
  Stage stage = small_stage();
  // LED index 2 lights the front of the scene; 100x its irradiance clips even the shortest
  // exposure.
  stage.leds[2].intensity = 60.0;
  Captured c = capture(dir / "s", stage);
  ASSERT_EQ(c.session.dead_leds().count(2), 0u);
  BuildSummary summary;
  const ReflectanceField field = build_field(c.session, {}, &summary);
  expect_finite(field);
  EXPECT_GT(summary.saturated_fraction, 0.0);
  const Image truth =
      sim::render_one_light(c.sim->scene(), c.sim->hits(), stage.leds[2].dir_in_stage);
  double field_sum = 0, truth_sum = 0;
  int clipped = 0;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      for (int ch = 0; ch < 3; ++ch) {
        field_sum += field.at(x, y, 2, ch);
        truth_sum += truth.at(x, y, ch);
        // Full scale in the shortest exposure, per unit irradiance of this LED.
        const double ceiling = 0.01 / 0.0025 / stage.leds[2].irradiance_rgb()[ch];
        clipped += truth.at(x, y, ch) > 1.2 * ceiling;
        // A clipped pixel reads at most the ceiling (a lower bound), never more.
        EXPECT_LT(field.at(x, y, 2, ch), 1.05 * std::max(ceiling, double(truth.at(x, y, ch))));
      }
    }
  }
  EXPECT_GT(clipped, 0);
  EXPECT_LT(field_sum, truth_sum);  // Lower bounds where clipped, unbiased elsewhere.
}

TEST(BuildField, RejectsBadTimeStep) {
  ls::testing::TempDir dir;
  const Stage stage = small_stage();
  Session session = Session::create(dir / "s", stage, {});
  BuildOptions options;
  options.time_step = 3;
  EXPECT_THROW(build_field(session, options), InputError);
}

// Built in bands through a spill file (a field larger than memory), the field has the
// values and attributes of the one built in memory, and nothing but the field is left beside it.
TEST(BuildField, InBandsWithinAMemoryBudgetGivesTheFieldBuiltInMemory) {
  ls::testing::TempDir dir;
  Stage stage = small_stage();
  for (Led& led : stage.leds) led.distance_m = 2.0;  // Near LEDs: a gain per pixel and LED.
  Captured c = capture(dir / "s", stage);
  BuildSummary whole_summary;
  const ReflectanceField whole = build_field(c.session, {}, &whole_summary);
  BuildOptions options;
  // Bands of at most 7 rows (the merges of the LEDs in flight take their share of the budget).
  options.memory = MemoryBudget(2 * ReflectanceField::bytes_for(kSize, 7, kLeds));
  int bands = 0, total_bands = 0;
  options.progress = [&](const std::string& phase, long done, long total, const std::string&) {
    if (phase != "write") return;
    EXPECT_EQ(done, bands + 1);
    bands = done;
    total_bands = total;
  };
  BuildSummary summary;
  const int rows = build_field_file(c.session, options, dir / "bands.exr", {}, &summary);
  EXPECT_GE(rows, 1);
  EXPECT_LE(rows, 7);
  EXPECT_EQ(bands, (kSize + rows - 1) / rows);
  EXPECT_EQ(total_bands, bands);
  const ReflectanceField banded = read_field(dir / "bands.exr");
  EXPECT_TRUE(banded.values() == whole.values());  // Bit for bit.
  ASSERT_EQ(banded.num_lights(), whole.num_lights());
  for (int l = 0; l < whole.num_lights(); ++l) {
    EXPECT_EQ(banded.lights()[l].saturates_at, whole.lights()[l].saturates_at);
    EXPECT_EQ(banded.lights()[l].position_in_stage, whole.lights()[l].position_in_stage);
    EXPECT_EQ(banded.lights()[l].valid, whole.lights()[l].valid);
  }
  EXPECT_TRUE(banded.noise.measured);
  EXPECT_EQ(banded.noise.read_variance, whole.noise.read_variance);
  EXPECT_EQ(banded.noise.shot_variance_per_unit, whole.noise.shot_variance_per_unit);
  EXPECT_EQ(banded.scene_time_s, whole.scene_time_s);
  ASSERT_TRUE(banded.view.has_value());
  EXPECT_EQ(banded.view->reference_z_m, whole.view->reference_z_m);
  EXPECT_EQ(summary.lights_used, whole_summary.lights_used);
  EXPECT_EQ(summary.saturated_fraction, whole_summary.saturated_fraction);
  std::vector<std::string> left;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    left.push_back(entry.path().filename().string());
  }
  EXPECT_THAT(left, ::testing::UnorderedElementsAre("s", "bands.exr"));

  // Where the spill cannot be written (beside the field, under a file), the build stops with the
  // place named and writes nothing.
  write_file_atomic(dir / "blocker", "a file, not a folder");
  options.progress = {};
  try {
    build_field_file(c.session, options, dir / "blocker" / "f.exr");
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("blocker/f.exr.partial"));
  }
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "blocker"));
}

// A session with no usable frames (its journal gone) is refused, naming the session,
// and no field is written; not an all-zero field.
TEST(BuildField, ASessionWithoutUsableFramesIsRefusedAndNothingIsWritten) {
  ls::testing::TempDir dir;
  capture(dir / "s", small_stage());
  std::filesystem::remove(dir / "s" / "frames.jsonl");
  const Session session = Session::open(dir / "s");
  try {
    build_field_file(session, {}, dir / "f.exr");
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr((dir / "s").string()));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("no LED has a complete bracket"));
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "f.exr"));

  // frames/ replaced by a file: said so.
  std::filesystem::remove_all(dir / "s" / "frames");
  std::ofstream(dir / "s" / "frames") << "not a folder";
  EXPECT_THROW(
      {
        try {
          build_field(Session::open(dir / "s"), {});
        } catch (const InputError& e) {
          EXPECT_THAT(e.what(), ::testing::HasSubstr("frames is not a folder"));
          throw;
        }
      },
      InputError);
}

}  // namespace
}  // namespace ls::capture
