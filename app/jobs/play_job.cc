#include "app/jobs/play_job.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <tuple>

#include "capture/field_file.h"
#include "capture/light_calibration.h"
#include "capture/played_photo.h"
#include "lightstage/backend_registry.h"
#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/run_outputs.h"
#include "lightstage/session.h"
#include "physics/envmap.h"
#include "relight/lighting/light_cells.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

// Software PWM: shorter on-times than this each period are lost in the timer's jitter.
constexpr double kMinOnTimeS = 100e-6;

// The longest exposure that puts the relit field's brightest values (99.9th percentile) at 70%
// of full scale: the photograph's bracket (capture/played_photo.h) reaches 16x below it.
double exposure_for(const Image& radiance, const CameraSpec& camera) {
  std::vector<float> values(radiance.pixels);
  const size_t k = std::min(values.size() - 1, size_t(0.999 * double(values.size())));
  std::nth_element(values.begin(), values.begin() + long(k), values.end());
  const double peak = std::max(double(values[k]), 1e-12);
  return std::clamp(0.7 * camera.radiometric_scale / peak, 1e-5, 60.0);
}

class Player {
 public:
  Player(const Stage& stage, const capture::ReflectanceField& field, LightController& lights,
         Camera& camera, const PlayOptions& options, const ProgressFn& progress)
      : stage_(stage),
        field_(field),
        lights_(lights),
        camera_(camera),
        options_(options),
        progress_(progress),
        response_(response_of(stage)) {
    if (!stage.calibration.flat_field.empty()) {
      flat_ = capture::read_flat_field(stage.calibration.flat_field, stage);
    }
    // What the build divided each light's image by (build_field.h): a near LED's falloff from the
    // reference point, the LED's flat field.
    pixel_gain_ = [this](int light, int x, int y) {
      const capture::FieldLight& l = field_.lights()[size_t(light)];
      const int w = field_.width(), h = field_.height();
      double gain = 1.0;
      if (l.position_in_stage && field_.view) {
        gain = (*l.position_in_stage - capture::reference_point(*field_.view, w, h, x, y))
                   .squaredNorm() /
               l.position_in_stage->squaredNorm();
      }
      if (flat_) gain /= flat_->at(l.led_id, x, y, w, h);
      return float(gain);
    };
  }

  PlayResult run() {
    const physics::EnvironmentMap map = physics::EnvironmentMap::load(options_.env_map);
    std::vector<Eigen::Vector3d> dirs;
    std::vector<bool> valid;
    for (const capture::FieldLight& light : field_.lights()) {
      dirs.push_back(light.dir_in_stage);
      valid.push_back(light.valid && stage_.led_index(light.led_id) >= 0);
    }
    const relight::LightWeights weights = relight::integrate_environment(
        map, dirs, options_.rotate_deg, stage_.coverage_radius_deg * M_PI / 180, valid);
    result_.uncovered_fraction = weights.uncovered_fraction();
    // White LEDs play the map's luminance: each at its cell's share over its own irradiance.
    level_.assign(field_.lights().size(), 0.0);
    double top = 0;
    for (size_t i = 0; i < level_.size(); ++i) {
      if (!valid[i]) continue;
      const Led& led = stage_.leds[size_t(stage_.led_index(field_.lights()[i].led_id))];
      const Eigen::Vector3d e(weights.irradiance_rgb[3 * i], weights.irradiance_rgb[3 * i + 1],
                              weights.irradiance_rgb[3 * i + 2]);
      level_[i] = luminance(e) / std::max(luminance(led.irradiance_rgb()), 1e-30);
      top = std::max(top, level_[i]);
    }
    if (!(top > 0)) {
      throw InputError(options_.env_map.string() + ": no light of this map falls on an LED");
    }
    for (double& l : level_) l /= top;
    std::vector<int> all;
    for (size_t i = 0; i < level_.size(); ++i) {
      if (level_[i] > 0) all.push_back(int(i));
    }
    capture::PlayedPhoto photo;
    relight::PlayedRelit relit;
    result_.check = play(all, &photo, &relit);
    result_.agrees = !result_.check.disagrees(options_.gain_tolerance);
    if (!options_.out_dir.empty()) write_outputs(photo, relit);
    if (!options_.locate) return result_;
    const size_t group = options_.audit_group_size > 0 ? size_t(options_.audit_group_size) : 0;
    if (group == 0) {
      if (!result_.agrees) locate(dome_order(all), result_.check);
      return result_;
    }
    std::vector<int> every;  // The audit tests every LED of the field, used by the map or not.
    every.reserve(valid.size());
    for (size_t i = 0; i < valid.size(); ++i) {
      if (valid[i]) every.push_back(int(i));
    }
    const std::vector<int> order = dome_order(every);
    // The audit lights each LED fully, whatever its share of the map: every LED is tested.
    for (size_t i = 0; i < level_.size(); ++i) level_[i] = valid[i] ? 1.0 : 0.0;
    for (size_t start = 0; start < order.size(); start += group) {
      const std::vector<int> part(order.begin() + long(start),
                                  order.begin() + long(std::min(order.size(), start + group)));
      const relight::SuperpositionCheck part_check = play(part, &photo, &relit);
      if (part_check.disagrees(options_.gain_tolerance)) locate(part, part_check);
    }
    return result_;
  }

 private:
  static capture::ResponseCurve response_of(const Stage& stage) {
    const CameraSpec& camera = stage.camera;
    if (camera.response.kind == CameraResponse::Kind::kRecover) {
      throw InputError(stage.source +
                       ": camera.response: play needs the camera's response given (linear, gamma "
                       "or a table), not one to recover");
    }
    return capture::ResponseCurve::from_spec(camera.response, camera.bit_depth, camera.channels);
  }

  // Plays the field lights `subset` at their levels (scaled so the brightest is fully on) and
  // checks the photograph against the field relit with them.
  relight::SuperpositionCheck play(const std::vector<int>& subset, capture::PlayedPhoto* photo,
                                   relight::PlayedRelit* relit) {
    double top = 0;
    for (const int i : subset) top = std::max(top, level_[size_t(i)]);
    std::vector<double> stage_level(stage_.leds.size(), 0.0);
    std::vector<Eigen::Vector3f> weight(field_.lights().size(), Eigen::Vector3f::Zero());
    for (const int i : subset) {
      const int led = stage_.led_index(field_.lights()[size_t(i)].led_id);
      stage_level[size_t(led)] = level_[size_t(i)] / top;
      weight[size_t(i)] =
          (stage_level[size_t(led)] * stage_.leds[size_t(led)].irradiance_rgb()).cast<float>();
    }
    *relit = relight::relight_played(field_, weight, pixel_gain_);
    double exposure_s = exposure_for(relit->radiance, stage_.camera);
    // Modulated lights (software PWM) need the shortest exposure to span 50 periods (a level is
    // then right to 2% of a period): the levels are lowered instead, the same light per exposure.
    const double period_s = lights_.level_period_s();
    if (period_s > 0) {
      const double dim = std::min(1.0, exposure_s / 16 / (50 * period_s));
      exposure_s = std::max(exposure_s, 16 * 50 * period_s);
      // An LED on for less than the timer's resolution each period is not played, nor relit.
      int played = 0;
      bool dropped = false;
      for (const int i : subset) {
        const size_t led = size_t(stage_.led_index(field_.lights()[size_t(i)].led_id));
        stage_level[led] *= dim;
        weight[size_t(i)] *= float(dim);
        if (stage_level[led] > 0 && stage_level[led] * period_s < kMinOnTimeS) {
          stage_level[led] = 0;
          weight[size_t(i)].setZero();
          dropped = true;
        }
        played += stage_level[led] > 0;
      }
      if (played == 0) {
        throw HardwareError(
            "play: the scene is too bright for software PWM: each LED would be "
            "on for less than " +
            std::to_string(kMinOnTimeS * 1e6) +
            " us a period; lower the camera's gain or stop the lens down");
      }
      if (dropped) {
        *relit = relight::relight_played(field_, weight, pixel_gain_);
      } else {  // The same lights, dimmer: the relit field scales.
        for (float& v : relit->radiance.pixels) v *= float(dim);
        for (float& v : relit->variance.pixels) v *= float(dim * dim);
      }
    }
    // Keys far above any capture's (session.cc: sequence_key), one range per pattern.
    const uint64_t key_base = (uint64_t(1) << 62) + uint64_t(result_.patterns) * 1024;
    *photo = capture::shoot_played_photo(stage_, lights_, camera_, response_, stage_level,
                                         exposure_s, key_base);
    ++result_.patterns;
    result_.frames += photo->frames;
    report(progress_, "play", result_.patterns, 0, std::to_string(subset.size()) + " LEDs");
    return relight::compare_played(*photo, *relit);
  }

  // Field lights in rings of 20 degrees of elevation, each by azimuth: runs of neighbours.
  std::vector<int> dome_order(const std::vector<int>& lights) const {
    std::vector<std::tuple<int, double, int>> keyed;  // (ring, azimuth, light)
    keyed.reserve(lights.size());
    for (const int i : lights) {
      const Eigen::Vector3d& d = field_.lights()[size_t(i)].dir_in_stage;
      const int ring = int(std::floor(std::asin(std::clamp(d.y(), -1.0, 1.0)) * 180 / M_PI / 20));
      keyed.emplace_back(ring, std::atan2(d.x(), d.z()), i);
    }
    std::sort(keyed.begin(), keyed.end());
    std::vector<int> ordered;
    ordered.reserve(keyed.size());
    for (const auto& [ring, azimuth, i] : keyed) ordered.push_back(i);
    return ordered;
  }

  // Bisects `group`, whose check disagreed, down to the LEDs that do: each half played alone.
  void locate(const std::vector<int>& group, const relight::SuperpositionCheck& check) {
    if (group.size() == 1) {
      result_.suspects.push_back({field_.lights()[size_t(group[0])].led_id, check});
      return;
    }
    const std::vector<int>& sorted = group;  // In dome order: halves are regions.
    const std::vector<int> halves[2] = {
        std::vector<int>(sorted.begin(), sorted.begin() + long(sorted.size() / 2)),
        std::vector<int>(sorted.begin() + long(sorted.size() / 2), sorted.end())};
    bool any = false;
    for (const std::vector<int>& half : halves) {
      capture::PlayedPhoto photo;
      relight::PlayedRelit relit;
      const relight::SuperpositionCheck half_check = play(half, &photo, &relit);
      if (half_check.disagrees(options_.gain_tolerance)) {
        any = true;
        locate(half, half_check);
      }
    }
    if (!any) {
      std::vector<int> ids;
      ids.reserve(group.size());
      for (const int i : group) ids.push_back(field_.lights()[size_t(i)].led_id);
      result_.unresolved_groups.push_back(ids);
    }
  }

  void write_outputs(const capture::PlayedPhoto& photo, const relight::PlayedRelit& relit) const {
    fs::create_directories(options_.out_dir);
    write_exr(options_.out_dir / "photo.exr", photo.radiance);
    write_exr(options_.out_dir / "relit.exr", relit.radiance);
    // Photograph | relit | |difference| x 8, one exposure for all three.
    const int w = photo.radiance.width, h = photo.radiance.height;
    Image sheet(3 * w, h, 3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        for (int c = 0; c < 3; ++c) {
          const float p = photo.radiance.at(x, y, c), q = relit.radiance.at(x, y, c);
          sheet.at(x, y, c) = p;
          sheet.at(w + x, y, c) = q;
          sheet.at(2 * w + x, y, c) = 8 * std::abs(p - q);
        }
      }
    }
    write_png_preview(options_.out_dir / "compare.png", sheet, auto_exposure_stops(relit.radiance));
  }

  const Stage& stage_;
  const capture::ReflectanceField& field_;
  LightController& lights_;
  Camera& camera_;
  const PlayOptions& options_;
  const ProgressFn& progress_;
  const capture::ResponseCurve response_;
  std::optional<capture::FlatFieldMaps> flat_;
  relight::PixelGain pixel_gain_;
  std::vector<double> level_;  // Per field light: its share of the map, the brightest 1.
  PlayResult result_;
};

// A field's LED within this of the stage's is the same LED (calibration moves them less).
constexpr double kSameLedRad = 0.01;

}  // namespace

std::string SuspectLed::describe() const {
  char text[240];
  std::snprintf(text, sizeof text,
                "LED %d: played alone, its light is %+.1f%% off what the field recorded and "
                "differs in %d of %d regions (relative RMSE %.1f%%): %s",
                led_id, (check.gain - 1) * 100, check.outlying_blocks, 3 * check.blocks,
                check.relative_rmse * 100,
                check.outlying_blocks >= 2 ? "its light falls differently (moved, or shadowed)"
                                           : "dimmer or brighter than at capture");
  return text;
}

PlayResult play_map(const Stage& stage, const capture::ReflectanceField& field,
                    LightController& lights, Camera& camera, const PlayOptions& options,
                    const ProgressFn& progress) {
  std::optional<RunOutputs> outputs;  // A run that fails leaves none of its files.
  if (!options.out_dir.empty()) {
    outputs.emplace(options.out_dir);
    for (const char* file : {"photo.exr", "relit.exr", "compare.png", "report.json"}) {
      outputs->add(options.out_dir / file);
    }
  }
  Player player(stage, field, lights, camera, options, progress);
  PlayResult result = player.run();
  if (outputs) {
    nlohmann::json suspects = nlohmann::json::array();
    for (const SuspectLed& s : result.suspects) {
      suspects.push_back({{"led_id", s.led_id},
                          {"gain", s.check.gain},
                          {"reduced_chi2", s.check.reduced_chi2},
                          {"what", s.describe()}});
    }
    const nlohmann::json report = {{"env_map", options.env_map.string()},
                                   {"rotate_deg", options.rotate_deg},
                                   {"psnr_db", result.check.psnr_db},
                                   {"relative_rmse", result.check.relative_rmse},
                                   {"reduced_chi2", result.check.reduced_chi2},
                                   {"outlying_blocks", result.check.outlying_blocks},
                                   {"noise_scale", result.check.noise_scale},
                                   {"gain", result.check.gain},
                                   {"agrees", result.agrees},
                                   {"uncovered_fraction", result.uncovered_fraction},
                                   {"patterns", result.patterns},
                                   {"frames", result.frames},
                                   {"suspects", suspects},
                                   {"unresolved_groups", result.unresolved_groups}};
    write_file_atomic(options.out_dir / "report.json", report.dump(2) + "\n");
    outputs->keep();
  }
  return result;
}

PlayResult play_session(const PlaySessionOptions& options, const ProgressFn& progress) {
  if (std::string problem = rotation_problem(options.play.rotate_deg); !problem.empty()) {
    throw InputError("play: " + problem);
  }
  const Session session = Session::open(options.session_dir);
  const capture::ReflectanceField field = capture::read_field(options.field);
  // The field must be this session's (its LEDs, where the stage has them): another capture's
  // would be judged a faulty dome.
  const Stage& stage = session.stage();
  for (const capture::FieldLight& light : field.lights()) {
    const int led = stage.led_index(light.led_id);
    if (led < 0 ||
        angle_between(stage.leds[size_t(led)].dir_in_stage, light.dir_in_stage) > kSameLedRad) {
      throw InputError(options.field.string() + ": --field: LED " + std::to_string(light.led_id) +
                       (led < 0 ? " is not one of the session's stage"
                                : " is not where the session's stage has it") +
                       " (" + stage.source + "): give the field built from " +
                       options.session_dir.string());
    }
  }
  const OpenedBackend devices = open_session_backend(session);
  return play_map(session.stage(), field, *devices.lights, *devices.camera, options.play, progress);
}

}  // namespace ls::jobs
