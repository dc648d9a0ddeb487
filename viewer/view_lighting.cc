#include "viewer/view_lighting.h"

#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <utility>

#include "relight/lighting/light_cells.h"
#include "relight/sources/map_relight.h"

namespace ls::viewer {

namespace {

// How the viewer relights under a map: automatic coverage, the sources' shadows by the LEDs'
// flows alone (no seconds spent recovering the scene's shape before the first frame).
relight::MapRelightOptions view_options(bool bright_sources) {
  relight::MapRelightOptions options;
  options.bright_sources = bright_sources;
  options.source_geometry = false;
  return options;
}

}  // namespace

ViewLighting environment_lighting(const physics::EnvironmentMap& map, double rotation_deg,
                                  const std::vector<capture::FieldLight>& leds,
                                  const EnvironmentNeeds& needs) {
  ViewLighting l;
  if (!leds.empty()) {
    if (needs.field_sources) {
      relight::SplitLighting split =
          relight::map_lighting(map, leds, rotation_deg, view_options(/*bright_sources=*/true));
      if (!split.sources.empty()) l.split = std::move(split);
    }
    // The whole map, sun included, for the sources that cannot add a bright source back (PCA).
    if (needs.whole_map_led_weights || !l.split) {
      l.led_irradiance_rgb =
          relight::map_lighting(map, leds, rotation_deg, view_options(/*bright_sources=*/false))
              .weights.irradiance_rgb;
    }
  }
  if (needs.model_lights) {
    relight::EnvironmentSampling sampling;
    sampling.covered_by_leds = capture::light_directions(leds);
    l.lights = relight::LightingForModels::environment(map, rotation_deg, sampling);
  }
  return l;
}

bool renders_bright_sources(const ViewLighting& lighting) {
  return lighting.split && relight::MapRelighter::renders_sources(*lighting.split);
}

BrightSourceLight::BrightSourceLight(const capture::ReflectanceField& field)
    : width_(field.width()),
      height_(field.height()),
      relighter_(std::make_unique<relight::MapRelighter>(field, view_options(true))),
      of_field_(true) {}

BrightSourceLight::BrightSourceLight(const relight::PcaField& pca)
    : width_(pca.width()),
      height_(pca.height()),
      relighter_(std::make_unique<relight::MapRelighter>(pca, view_options(true))) {}

namespace {

struct Stopped {};  // Thrown through the shape's recovery to end it early.

// Work for later frames runs on all cores but one, which the frames keep.
template <typename Work>
auto in_the_background(Work work) {
  return std::async(std::launch::async, [work = std::move(work)]() mutable {
    tbb::task_arena arena(std::max(1, tbb::info::default_concurrency() - 1));
    return arena.execute(work);
  });
}

}  // namespace

BrightSourceLight::~BrightSourceLight() {
  stop_ = true;
  try {
    if (recovering_.valid()) recovering_.get();
  } catch (...) {  // NOLINT(bugprone-empty-catch): stopped, or failed; nothing to show now.
  }
  if (tracing_.valid()) tracing_.wait();
}

void BrightSourceLight::take_shape() {
  if (!recovering_.valid() ||
      recovering_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
    return;
  }
  try {
    recovering_.get();
    shape_ = true;
  } catch (const std::exception& e) {
    shape_problem_ = e.what();
  }
}

void BrightSourceLight::add(const ViewLighting& lighting, Image& out) {
  by_shape_ = false;
  if (!renders_bright_sources(lighting)) return;
  take_shape();
  using ShapeUse = relight::FieldSources::ShapeUse;
  by_shape_ = relighter_->add_sources(*lighting.split, out, {}, ShapeUse::kIfTraced) && shape_;
  // The shape from the normals and LED images the frames' sources already hold.
  if (of_field_ && !shape_ && !recovering_.valid() && shape_problem_.empty()) {
    recovering_ = in_the_background([this] {
      relighter_->recover_geometry(
          [this](const std::string&, long done, long total, const std::string&) {
            if (stop_) throw Stopped{};
            recovered_leds_ = done;
            recovery_steps_ = total;
          });
    });
  }
  const bool tracing =
      tracing_.valid() && tracing_.wait_for(std::chrono::seconds(0)) != std::future_status::ready;
  if (shape_ && !by_shape_ && !tracing && shape_problem_.empty()) {
    try {
      if (tracing_.valid()) tracing_.get();  // The last direction's, done.
      tracing_ =
          in_the_background([this, split = *lighting.split] { relighter_->trace_shapes(split); });
    } catch (const std::exception& e) {  // Out of memory, say: the flows go on alone.
      shape_problem_ = e.what();
    }
  }
}

bool BrightSourceLight::render(const ViewLighting& lighting, Image& out) {
  if (!renders_bright_sources(lighting)) return false;
  if (out.width != width_ || out.height != height_ || out.channels != 3) {
    out = Image(width_, height_, 3);
  } else {
    std::fill(out.pixels.begin(), out.pixels.end(), 0.0f);
  }
  add(lighting, out);
  return true;
}

std::string BrightSourceLight::shadows() const {
  if (by_shape_) return "the scene's shape where it agrees with the LEDs (as lightstage relight)";
  if (!of_field_) return "the LEDs' flows (a PCA)";
  if (!shape_problem_.empty()) return "the LEDs' flows (the scene's shape: " + shape_problem_ + ")";
  if (shape_) return "the LEDs' flows while the shape's shadows are traced for this direction";
  if (!recovering_.valid()) return "the LEDs' flows";
  return "the LEDs' flows while the scene's shape is recovered (" +
         std::to_string(recovered_leds_.load()) + " of " + std::to_string(recovery_steps_.load()) +
         " steps)";
}

}  // namespace ls::viewer
