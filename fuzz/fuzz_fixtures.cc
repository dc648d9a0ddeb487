#include "fuzz/fuzz_fixtures.h"

#include <cmath>

#include "fuzz/fuzz_support.h"
#include "lightstage/image.h"
#include "lightstage/stage.h"

namespace ls::fuzz {

namespace {

// Deterministic values in (0, 1) that differ per pixel, light and channel.
float pattern(int a, int b, int c) {
  return float(0.05 + 0.9 * std::fmod(0.618034 * (a * 31 + b * 7 + c), 1.0));
}

}  // namespace

capture::ReflectanceField small_field(int num_lights) {
  std::vector<capture::FieldLight> lights;
  const std::vector<Eigen::Vector3d> dirs = fibonacci_dome_directions(num_lights, 10.0);
  for (int l = 0; l < num_lights; ++l) {
    capture::FieldLight light;
    light.led_id = 3 * l + 1;
    // The dome's directions in the stage frame (+Y up), turned toward the camera (+Z): the RTI
    // fits use lights in front of the surface.
    light.dir_in_stage = Eigen::Vector3d(dirs[l].x(), dirs[l].z(), dirs[l].y());
    lights.push_back(light);
  }
  lights[1].valid = false;
  lights[2].position_in_stage = 1.5 * lights[2].dir_in_stage;
  lights[3].saturates_at = Eigen::Vector3f(0.9f, 0.95f, 1.0f);
  capture::ReflectanceField field(kFixtureWidth, kFixtureHeight, std::move(lights));
  for (int y = 0; y < kFixtureHeight; ++y) {
    for (int x = 0; x < kFixtureWidth; ++x) {
      for (int l = 0; l < num_lights; ++l) {
        for (int c = 0; c < 3; ++c) field.at(x, y, l, c) = l == 1 ? 0.0f : pattern(y * 8 + x, l, c);
      }
    }
  }
  field.scene_time_s = 12.5;
  field.noise = {1e-5, 2e-4, true, "fixture"};
  field.view = capture::FieldView{30.0, 4.0, 2.4, 0.0};
  return field;
}

relight::ModelMaps small_model_maps() {
  using namespace relight;
  ModelMaps maps;
  maps.maps = Image(kFixtureWidth, kFixtureHeight, kMapChannelCount);
  for (int y = 0; y < kFixtureHeight; ++y) {
    for (int x = 0; x < kFixtureWidth; ++x) {
      const int model = (y * kFixtureWidth + x) % 5;  // Every FitModel, 0 flagged.
      const double tilt = 0.1 * x - 0.1 * y;
      const Eigen::Vector3d n = Eigen::Vector3d(tilt, 0.05 * x, 1.0).normalized();
      for (int c = 0; c < 3; ++c) maps.maps.at(x, y, kMapNormalX + c) = float(n(c));
      for (int c = 0; c < 3; ++c) maps.maps.at(x, y, kMapAlbedoR + c) = pattern(x, y, c);
      const bool lobe =
          model == int(FitModel::kLambertTorranceSparrow) || model == int(FitModel::kLambertPhong);
      maps.maps.at(x, y, kMapSigma) = model == int(FitModel::kOrenNayar) ? 0.3f : 0.0f;
      maps.maps.at(x, y, kMapKs) = lobe ? 0.2f : 0.0f;
      maps.maps.at(x, y, kMapRoughness) = lobe ? 0.25f : 0.0f;
      maps.maps.at(x, y, kMapModel) = float(model);
      maps.maps.at(x, y, kMapConfidence) = model == 0 ? 0.0f : 0.9f;
      maps.maps.at(x, y, kMapResidual) = model == 0 ? 0.0f : 1.1f;
      maps.maps.at(x, y, kMapFlags) = model == 0 ? float(kFitFailed) : (x == 2 ? 128.0f : 0.0f);
      if (model == int(FitModel::kLambert) || model == int(FitModel::kLambertTorranceSparrow)) {
        maps.maps.at(x, y, kMapMaterial) = model == int(FitModel::kLambert) ? 1.0f : 2.0f;
        maps.maps.at(x, y, kMapMaterialWeight) = 1.0f;
      }
    }
  }
  Material matte;
  matte.model = FitModel::kLambert;
  matte.albedo = {0.5, 0.4, 0.3};
  matte.pixels = 3;
  matte.scene_material = 1;
  Material glossy = matte;
  glossy.model = FitModel::kLambertTorranceSparrow;
  glossy.ks = 0.2;
  glossy.roughness = 0.25;
  glossy.pixels = 2;
  glossy.scene_material = 2;
  maps.materials = {matte, glossy};
  maps.noise = {1e-5, 2e-4};
  maps.noise_source = "fixture";
  // Ten LEDs (two shadow words), LED x of pixel (x, y) y/7 in shadow.
  std::vector<Eigen::Vector3f> leds;
  leds.reserve(10);
  for (int l = 0; l < 10; ++l)
    leds.push_back(Eigen::Vector3f(std::sin(0.6f * l), std::cos(0.6f * l), 1).normalized());
  maps.shadows = FitShadows::all_lit(leds, kFixtureWidth, kFixtureHeight);
  for (int y = 0; y < kFixtureHeight; ++y) {
    for (int x = 0; x < kFixtureWidth && x < 10; ++x) {
      uint32_t words[2] = {0, 0};
      words[x / FitShadows::kLedsPerWord] =
          uint32_t(y % 8) << (FitShadows::kBitsPerLed * (x % FitShadows::kLedsPerWord));
      maps.shadows.set_pixel_words(x, y, words);
    }
  }
  return maps;
}

relight::TemporalMaps small_temporal_maps() {
  using namespace relight;
  TemporalMaps maps;
  maps.maps = Image(kFixtureWidth, kFixtureHeight, kTemporalChannelCount);
  const float wet[kTemporalParamCount] = {0.2f, 0.2f, 0.25f, 0.1f, 0.5f, 0.1f};
  const float dry[kTemporalParamCount] = {0.6f, 0.55f, 0.5f, 0.3f, 0.05f, 0.4f};
  for (int y = 0; y < kFixtureHeight; ++y) {
    for (int x = 0; x < kFixtureWidth; ++x) {
      const int model = (y * kFixtureWidth + x) % kTemporalModelCount;  // 0: flagged.
      maps.maps.at(x, y, kTNormalZ) = 1.0f;
      maps.maps.at(x, y, kTModel) = float(model);
      maps.maps.at(x, y, kTRate) = model > 1 ? 0.05f : 0.0f;
      maps.maps.at(x, y, kTOnset) = model > 1 ? 20.0f : 0.0f;
      for (int p = 0; p < kTemporalParamCount; ++p) {
        maps.maps.at(x, y, kTWet + p) = model == 0 ? 0.0f : wet[p];
        maps.maps.at(x, y, kTDry + p) = model == 0 ? 0.0f : dry[p];
      }
      maps.maps.at(x, y, kTConfidence) = model == 0 ? 0.0f : 0.8f;
      maps.maps.at(x, y, kTResidual) = model == 0 ? 0.0f : 1.2f;
      maps.maps.at(x, y, kTStepsUsed) = model == 0 ? 0.0f : 4.0f;
      maps.maps.at(x, y, kTFlags) = model == 0 ? float(kTemporalNoNormal) : 0.0f;
    }
  }
  maps.step_times_s = {0.0, 30.0, 60.0, 90.0};
  // Two curve families for the kCurve pixels (every other one follows the second): up and down
  // for the albedo, down for the rest; the second with a curve that rises.
  TemporalCurves first, second;
  first.knots.assign(kTemporalParamCount, {1.0, 0.6, 0.2, 0.0});
  for (int c = 0; c < 3; ++c) first.knots[size_t(c)] = {0.0, 1.0, 0.4, 0.1};
  second.knots.assign(kTemporalParamCount, {0.0, 0.3, 0.7, 1.0});
  maps.curves = {first, second};
  for (int y = 0; y < kFixtureHeight; ++y) {
    for (int x = 0; x < kFixtureWidth; ++x) {
      if (maps.model(x, y) != TemporalModel::kCurve) continue;
      maps.maps.at(x, y, kTCurve) = float(x % 2);
      maps.maps.at(x, y, kTCurveSeen) = 0.8f;
    }
  }
  maps.noise = {1e-5, 2e-4};
  maps.noise_source = "fixture";
  return maps;
}

Stage small_stage() {
  Stage stage = stage_with_directions(fibonacci_dome_directions(3, 10.0));
  stage.name = "fuzz";
  stage.camera.width = 8;
  stage.camera.height = 4;
  stage.camera.bracket = {{0.01, 1.0}, {0.04, 1.0}};
  stage.plan.dark_frames = 2;
  stage.plan.time_steps = 2;
  stage.plan.interval_s = 30.0;
  return stage;
}

CapturedFrame small_frame(const PlannedFrame& planned) {
  const FrameKey& key = planned.key;
  CapturedFrame frame;
  frame.raw = {8, 4, 3, 12, std::vector<uint16_t>(size_t{8} * 4 * 3, 40)};
  for (size_t i = 0; i < frame.raw.pixels.size(); ++i) {
    const double lit = key.is_dark() ? 0.0 : 3000.0 * pattern(int(i), key.led_index, key.time_step);
    frame.raw.pixels[i] = uint16_t(40 + lit * (key.exposure_index + 1) / 2 + key.repeat);
  }
  frame.exposure_s = planned.request.exposure_s;
  frame.gain = planned.request.gain;
  return frame;
}

void write_small_frames(const std::filesystem::path& session_dir, const Stage& stage) {
  std::filesystem::create_directories(session_dir / "frames");
  for (const PlannedFrame& planned : plan_frames(stage)) {
    (void)write_raw_frame(session_dir / "frames" / (planned.key.name(stage) + ".png"),
                          small_frame(planned).raw);
  }
}

void write_half_white_png(const std::filesystem::path& path) {
  Image image(kFixtureWidth, kFixtureHeight, 3);
  for (int y = 0; y < kFixtureHeight; ++y) {
    for (int x = 0; x < kFixtureWidth / 2; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = 1.0f;
    }
  }
  write_png_preview(path, image);
}

const std::filesystem::path& edits_dir() {
  static const std::filesystem::path dir = [] {
    write_half_white_png(work_dir() / "mask.png");
    return work_dir();
  }();
  return dir;
}

}  // namespace ls::fuzz
