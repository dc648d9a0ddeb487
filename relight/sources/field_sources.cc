#include "relight/sources/field_sources.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdio>
#include <set>

#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"

namespace ls::relight {

std::string SplitLighting::report() const {
  std::string line;
  for (const PlacedSource& source : sources) {
    if (!line.empty()) line += "; ";
    line += source.in_stage.describe();
    if (!source.triangle) line += " (outside the dome's coverage: not rendered)";
  }
  return line.empty() ? "no bright source" : line;
}

std::vector<int> SplitLighting::leds() const {
  std::set<int> leds;
  for (const PlacedSource& source : sources) {
    if (source.triangle) leds.insert(source.triangle->leds.begin(), source.triangle->leds.end());
  }
  return {leds.begin(), leds.end()};
}

SplitLighting split_lighting(const physics::EnvironmentMap& map,
                             const std::vector<capture::FieldLight>& lights, double rotation_deg,
                             double coverage_rad, bool split, const BrightSourceOptions& options) {
  std::vector<Eigen::Vector3d> dirs;
  std::vector<bool> valid;
  for (const capture::FieldLight& light : lights) {
    dirs.push_back(light.dir_in_stage.normalized());
    valid.push_back(light.valid);
  }
  SplitLighting out;
  if (!split) {
    out.weights = integrate_environment(map, dirs, rotation_deg, coverage_rad, valid);
    return out;
  }
  SplitEnvironment parts = split_bright_sources(map, options);
  out.weights = integrate_environment(parts.rest, dirs, rotation_deg, coverage_rad, valid);
  const double coverage = coverage_rad > 0 ? coverage_rad : max_nearest_neighbour_angle(dirs);
  for (const BrightSource& found : parts.sources) {
    PlacedSource placed{found, std::nullopt};
    placed.in_stage.dir = physics::rotate_about_y(found.dir, rotation_deg);
    placed.triangle = led_triangle(dirs, valid, placed.in_stage.dir, coverage);
    out.weights.total_irradiance_rgb += found.irradiance_rgb;
    // What the dome cannot light stays in the map's account of uncovered light.
    if (!placed.triangle) out.weights.uncovered_irradiance_rgb += found.irradiance_rgb;
    out.sources.push_back(std::move(placed));
  }
  return out;
}

namespace {

// The noise the fit would weigh photometric stereo by: the field's own when measured.
NormalOptions normal_options_for(const capture::ReflectanceField& field) {
  FitOptions fit;
  fit.use_noise_of(field);
  return fit.normals;
}

// LED `led`'s values at every pixel of `field` (pixel-major) into out (3 per pixel).
void copy_led_image(const capture::ReflectanceField& field, int led, float* out) {
  const std::size_t pixels = std::size_t(field.width()) * field.height();
  const std::size_t stride = 3 * std::size_t(field.num_lights());
  const float* values = field.values().data() + 3 * std::size_t(led);
  for (std::size_t p = 0; p < pixels; ++p) {
    std::copy(values + p * stride, values + p * stride + 3, out + 3 * p);
  }
}

}  // namespace

FieldSources::FieldSources(const capture::ReflectanceField& field)
    : FieldSources(field, capture::whole_field(field), [&field](int led) {
        std::vector<float> rgb(3 * std::size_t(field.width()) * field.height());
        copy_led_image(field, led, rgb.data());
        return rgb;
      }) {}

FieldSources::FieldSources(const capture::ReflectanceField& header,
                           const capture::FieldBands& bands, LedImageFn led_image)
    : led_image_(std::move(led_image)) {
  read_fit(header, bands, {});
}

FieldSources::FieldSources(const capture::ReflectanceField& header,
                           const capture::FieldBands& bands, const std::vector<int>& leds,
                           bool with_geometry, const ProgressFn& progress) {
  const size_t pixels = size_t(header.width()) * header.height();
  std::map<int, std::vector<float>> images;
  for (const int led : leds) {
    LS_CHECK(led >= 0 && led < header.num_lights(),
             "FieldSources: no light " + std::to_string(led));
    images[led];
  }
  if (with_geometry) {
    for (int led = 0; led < header.num_lights(); ++led) images[led];
  }
  for (auto& [led, rgb] : images) rgb.resize(3 * pixels);
  // The LEDs' images in the same pass as the fit, side by side.
  std::vector<std::pair<int, float*>> copies;
  copies.reserve(images.size());
  for (auto& [led, rgb] : images) copies.emplace_back(led, rgb.data());
  read_fit(header, bands, [&](const capture::ReflectanceField& band) {
    const size_t first = size_t(band.first_row()) * header.width();
    tbb::parallel_for(0, int(copies.size()), [&](int i) {
      copy_led_image(band, copies[size_t(i)].first, copies[size_t(i)].second + 3 * first);
    });
  });
  if (with_geometry) {
    geometry_ = recovered(
        [&](int led) { return led_lit_mask(led_dirs_[size_t(led)], images.at(led), fit_); },
        progress);
  }
  for (const int led : leds) {
    shadows_.emplace(led, led_shadow(led_dirs_[size_t(led)], std::move(images.at(led)), fit_));
  }
}

void FieldSources::recover_geometry(const ProgressFn& progress) {
  LS_CHECK(led_image_ != nullptr,
           "FieldSources: the geometry needs every LED's image; this field was streamed");
  auto geometry = recovered(
      [&](int led) { return led_lit_mask(led_dirs_[size_t(led)], led_image_(led), fit_); },
      progress);
  const std::lock_guard<std::mutex> lock(mutex_);
  geometry_ = std::move(geometry);
  shapes_.clear();
}

std::shared_ptr<const ShadowGeometry> FieldSources::current_geometry() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return geometry_;
}

void FieldSources::use_geometry_of(const FieldSources& other) {
  LS_CHECK(other.fit_.normal.width == fit_.normal.width &&
               other.fit_.normal.height == fit_.normal.height && other.geometry_ != nullptr,
           "FieldSources: the geometry shared is not of a field this size, or was not recovered");
  const std::lock_guard<std::mutex> lock(mutex_);
  geometry_ = other.geometry_;
  shapes_.clear();
}

void FieldSources::prepare(const std::vector<int>& leds) {
  const std::lock_guard<std::mutex> lock(mutex_);
  for (const int led : leds) (void)shadow(led);
}

std::shared_ptr<const ShadowGeometry> FieldSources::recovered(
    const std::function<LitMask(int led)>& mask_of, const ProgressFn& progress) const {
  std::vector<int> leds;
  std::vector<Eigen::Vector3d> dirs;
  for (int led = 0; led < int(led_dirs_.size()); ++led) {
    if (!usable_[size_t(led)]) continue;
    leds.push_back(led);
    dirs.push_back(led_dirs_[size_t(led)]);
  }
  return std::make_shared<const ShadowGeometry>(
      fit_, dirs, [&](int k) { return mask_of(leds[size_t(k)]); }, progress);
}

void FieldSources::read_fit(const capture::ReflectanceField& header,
                            const capture::FieldBands& bands, const capture::BandVisitor& also) {
  fit_ = {Image(header.width(), header.height(), 3), Image(header.width(), header.height(), 3)};
  for (const capture::FieldLight& light : header.lights()) {
    led_dirs_.push_back(light.dir_in_stage);
    usable_.push_back(light.valid);
  }
  const NormalOptions normal_options = normal_options_for(header);
  bands([&](const capture::ReflectanceField& band) {
    const NormalMap normals = estimate_normals(band, normal_options);
    const long first = 3 * long(band.first_row()) * header.width();
    std::copy(normals.normal.pixels.begin(), normals.normal.pixels.end(),
              fit_.normal.pixels.begin() + first);
    std::copy(normals.albedo.pixels.begin(), normals.albedo.pixels.end(),
              fit_.albedo.pixels.begin() + first);
    if (also) also(band);
  });
}

std::size_t FieldSources::bytes_needed(int width, int height, int leds, int triangles,
                                       int all_leds) {
  const std::size_t floats_per_pixel =
      std::size_t{6} + std::size_t{7} * std::size_t(std::max(leds, 0)) +
      std::size_t{24} * std::size_t(std::max(triangles, 0)) +
      std::size_t{3} * std::size_t(std::max(all_leds, 0)) + (all_leds > 0 ? kShapesKept : 0);
  const std::size_t pixels = std::size_t(width) * std::size_t(height);
  return pixels * floats_per_pixel * sizeof(float) +
         pixels * std::size_t(std::max(all_leds, 0)) / 8;
}

// Callers hold mutex_.
const LedShadow& FieldSources::shadow(int led) const {
  auto it = shadows_.find(led);
  if (it != shadows_.end()) return it->second;
  LS_CHECK(led_image_ != nullptr, "FieldSources: LED " + std::to_string(led) + " was not read");
  LS_CHECK(led >= 0 && led < int(led_dirs_.size()),
           "FieldSources: no light " + std::to_string(led));
  std::vector<float> rgb = led_image_(led);
  LS_CHECK(rgb.size() == fit_.albedo.pixels.size(),
           "FieldSources: LED " + std::to_string(led) + "'s image is not the field's size");
  return shadows_.emplace(led, led_shadow(led_dirs_[size_t(led)], std::move(rgb), fit_))
      .first->second;
}

// The flows from each weighted LED of the triangle toward the others, `lock` held on mutex_. Those
// not made yet are made side by side (each is two optical flows on one core), unlocked as the
// shape's rays are: two threads making one flow keep the first.
PairFlows FieldSources::flows_of(const LedTriangle& triangle,
                                 const std::array<const LedShadow*, 3>& shadows,
                                 std::unique_lock<std::mutex>& lock) const {
  const auto needed = [&](int k, int j) {
    return j != k && triangle.leds[size_t(k)] != triangle.leds[size_t(j)] &&
           triangle.weights[size_t(k)] >= kMinTriangleWeight;
  };
  const auto key = [&](int k, int j) {
    return std::pair{triangle.leds[size_t(k)], triangle.leds[size_t(j)]};
  };
  std::vector<std::pair<int, int>> missing;  // (k, j) of the triangle.
  for (int k = 0; k < 3; ++k) {
    for (int j = 0; j < 3; ++j) {
      if (!needed(k, j) || flows_.count(key(k, j)) > 0) continue;
      if (std::none_of(missing.begin(), missing.end(),
                       [&](const auto& m) { return key(m.first, m.second) == key(k, j); })) {
        missing.emplace_back(k, j);
      }
    }
  }
  if (!missing.empty()) {
    lock.unlock();  // The shadows stay where they are: std::map keeps references.
    std::vector<LedPairFlow> made(missing.size());
    tbb::parallel_for(0, int(missing.size()), [&](int i) {
      const auto [k, j] = missing[size_t(i)];
      made[size_t(i)] = led_pair_flow(*shadows[size_t(k)], *shadows[size_t(j)]);
    });
    lock.lock();
    for (size_t i = 0; i < missing.size(); ++i) {
      flows_.emplace(key(missing[i].first, missing[i].second), std::move(made[i]));
    }
  }
  PairFlows flows{};
  for (int k = 0; k < 3; ++k) {
    for (int j = 0; j < 3; ++j) {
      if (needed(k, j)) flows[size_t(k)][size_t(j)] = &flows_.at(key(k, j));
    }
  }
  return flows;
}

std::shared_ptr<const Image> FieldSources::shape_of(const ShadowGeometry& geometry,
                                                    const PlacedSource& source, bool trace) const {
  const Eigen::Vector3d& dir = source.in_stage.dir;
  const ShapeKey key{dir.x(), dir.y(), dir.z(), source.in_stage.radius_rad};
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto it = shapes_.find(key);
    if (it != shapes_.end()) return it->second;
  }
  if (!trace) return nullptr;
  // Traced unlocked (seconds at 512^2): two threads tracing one source keep the first.
  auto shape = std::make_shared<const Image>(
      geometry.view(dir, source.in_stage.radius_rad).trusted_visibility());
  const std::lock_guard<std::mutex> lock(mutex_);
  if (shapes_.size() >= kShapesKept) shapes_.clear();
  return shapes_.emplace(key, std::move(shape)).first->second;
}

void FieldSources::trace_shapes(const SplitLighting& lighting) const {
  const std::shared_ptr<const ShadowGeometry> geometry = current_geometry();
  if (!geometry) return;
  for (const PlacedSource& source : lighting.sources) {
    if (source.triangle) (void)shape_of(*geometry, source, /*trace=*/true);
  }
}

bool FieldSources::add(const SplitLighting& lighting, Image& out,
                       const std::vector<const Image*>& visibility, ShapeUse use) const {
  bool complete = true;
  const std::shared_ptr<const ShadowGeometry> geometry = current_geometry();
  for (size_t i = 0; i < lighting.sources.size(); ++i) {
    const PlacedSource& source = lighting.sources[i];
    if (!source.triangle) continue;
    std::array<const LedShadow*, 3> shadows{};
    std::unique_lock<std::mutex> lock(mutex_);  // std::map keeps references: render unlocked.
    for (int k = 0; k < 3; ++k) shadows[size_t(k)] = &shadow(source.triangle->leds[size_t(k)]);
    const PairFlows flows = flows_of(*source.triangle, shadows, lock);
    lock.unlock();
    const Image* given = i < visibility.size() ? visibility[i] : nullptr;
    std::shared_ptr<const Image> shape;
    if (geometry && given == nullptr) {
      shape = shape_of(*geometry, source, use == ShapeUse::kTrace);
      complete = complete && shape != nullptr;
    }
    add_bright_source(shadows, flows, *source.triangle, source.in_stage, fit_, out, given,
                      shape.get());
  }
  return complete;
}

}  // namespace ls::relight
