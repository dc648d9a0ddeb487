#pragma once
// Fields shared by the compact-field tests, rendered once per process: the three simulated RTI
// scenes (64 x 64, 150-LED dome over the camera's hemisphere, realistic read and shot noise) and
// the real RTI set in ../shared/data/rti (imported through capture/olat_import.h).
#include <filesystem>
#include <map>
#include <memory>

#include "capture/field.h"
#include "capture/olat_import.h"
#include "evaluation/leave_lights_out.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"
#include "tests/support/test_support.h"

namespace ls::compact_testing {

// Read noise sigma 3.2e-3 and shot variance 2e-4 per unit: about 1.5% and 2.5% of the brightest
// diffuse value (a white Lambertian patch lit head-on has radiance 1/pi), like an 8-bit RTI camera.
inline capture::FieldNoise sim_noise() {
  capture::FieldNoise noise;
  noise.read_variance = 1e-5;
  noise.shot_variance_per_unit = 2e-4;
  noise.method = "simulated";
  return noise;
}

inline const capture::ReflectanceField& sim_field(sim::RtiScene scene) {
  static std::map<sim::RtiScene, capture::ReflectanceField> cache;
  auto it = cache.find(scene);
  if (it == cache.end()) {
    it = cache
             .emplace(scene, sim::render_noisy_field(sim::rti_dome_stage(), sim::rti_scene(scene),
                                                     sim_noise(), 7))
             .first;
  }
  return it->second;
}

inline std::filesystem::path real_lp() {
  return testing::shared_data_dir() / "rti/loewenkopf_klein/dirs.lp";
}

inline const capture::ReflectanceField& real_field() {
  static const capture::ReflectanceField field =
      capture::import_rti_lp(real_lp(), capture::OlatImportOptions{});
  return field;
}

inline evaluation::CompactBuilder pca_builder(
    int rank, int tile_size = 0, relight::PcaRankRule rule = relight::PcaRankRule::kNoiseFloor) {
  return [=](const capture::ReflectanceField& f) -> std::unique_ptr<relight::CompactField> {
    relight::PcaOptions options;
    options.rank_rule = rule;
    options.rank = rank;
    options.tile_size = tile_size;
    return std::make_unique<relight::PcaField>(relight::PcaField::build(f, options));
  };
}

inline evaluation::CompactBuilder rti_builder(relight::RtiBasis basis, bool lrgb = false) {
  return [=](const capture::ReflectanceField& f) -> std::unique_ptr<relight::CompactField> {
    relight::RtiFitOptions options;
    options.basis = basis;
    options.lrgb = lrgb;
    return std::make_unique<relight::RtiField>(relight::RtiField::fit(f, options));
  };
}

inline evaluation::CompactBuilder raw_builder() {
  return [](const capture::ReflectanceField& f) -> std::unique_ptr<relight::CompactField> {
    return std::make_unique<relight::RawCompactField>(capture::ReflectanceField(f));
  };
}

inline evaluation::CompactBuilder model_builder() {
  return [](const capture::ReflectanceField& f) -> std::unique_ptr<relight::CompactField> {
    relight::FitOptions options;
    options.use_noise_of(f);
    return std::make_unique<relight::ModelCompactField>(relight::fit_models(f, options));
  };
}

}  // namespace ls::compact_testing
