#include "evaluation/temporal_held_out.h"

#include <cmath>
#include <functional>
#include <opencv2/imgproc.hpp>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "relight/time/temporal_render.h"
#include "sim/noisy_field.h"
#include "sim/sim_stage.h"
#include "sim/time_varying.h"

namespace ls::evaluation {

double ErrorSum::relative() const { return ref2 > 0 ? std::sqrt(err2 / ref2) : 0; }

ErrorSum total(const ErrorsByMaterial& errors) {
  ErrorSum sum;
  for (const auto& [name, e] : errors) sum.err2 += e.err2, sum.ref2 += e.ref2;
  return sum;
}

TimeLapse rise_and_fall_time_lapse(int leds, int width, int height, int steps, double duration_s,
                                   uint64_t seed, double exposure) {
  TimeLapse out;
  out.stage = stage_with_directions(fibonacci_dome_directions(leds, -11.5));
  out.stage.camera.width = width;
  out.stage.camera.height = height;
  out.scene = sim::rise_and_fall_scene();
  out.hits = sim::trace_camera(out.scene, out.stage.camera);
  for (int i = 0; i < steps; ++i) {
    sim::SimFieldOptions at;
    at.scene_time_s = steps > 1 ? duration_s * i / (steps - 1) : 0;
    out.ideal.push_back(sim::render_ideal_field(out.stage, out.scene, at));
    for (int y = 0; y < height; ++y) {
      float* row = out.ideal.back().pixel(0, y);
      for (size_t v = 0; v < size_t(width) * out.ideal.back().num_lights() * 3; ++v) {
        row[v] *= float(exposure);
      }
    }
    out.noisy.push_back(out.ideal.back());
    sim::add_sensor_noise(out.noisy.back(), relight::NoiseModel{}.as_field_noise(), seed + i);
    out.noisy.back().source = "sim t=" + std::to_string(at.scene_time_s);
  }
  return out;
}

namespace {

// value(x, y, k, c) for valid light k against the ideal field of `step`, per varying material.
using SampleValue = std::function<double(int x, int y, int k, int c)>;

void accumulate(const TimeLapse& lapse, int step, const SampleValue& value,
                ErrorsByMaterial& errors) {
  const capture::ReflectanceField& truth = lapse.ideal[size_t(step)];
  const capture::ValidLights lights = capture::valid_lights(truth);
  for (const sim::SurfaceHit& h : lapse.hits) {
    if (!h.hit || h.material_index < 0) continue;
    const sim::SceneMaterial& material = lapse.scene.materials[size_t(h.material_index)];
    if (!sim::truth_at(material, h.st.x(), h.st.y()).varying) continue;
    ErrorSum& e = errors[material.name];
    for (size_t k = 0; k < lights.index.size(); ++k) {
      const Eigen::Vector3d& dir = lights.dirs_in_stage[k];
      if (h.normal.dot(dir) <= 0 || !sim::visible(lapse.scene, h.position + 1e-3 * h.normal, dir)) {
        continue;
      }
      for (int c = 0; c < 3; ++c) {
        const double t = truth.at(h.pixel_x, h.pixel_y, lights.index[k], c);
        const double d = value(h.pixel_x, h.pixel_y, int(k), c) - t;
        e.err2 += d * d;
        e.ref2 += t * t;
      }
    }
  }
}

// Temporal maps at time t under each valid LED: one radiance image per light.
SampleValue rendered(const relight::TemporalMaps& maps, double t,
                     const capture::ValidLights& lights) {
  auto images = std::make_shared<std::vector<Image>>();
  for (const Eigen::Vector3d& dir : lights.dirs_in_stage) {
    images->push_back(relight::render_temporal(
        maps, t, relight::LightingForModels::directional(dir, Eigen::Vector3d(1, 1, 1))));
  }
  return [images](int x, int y, int k, int c) { return (*images)[size_t(k)].at(x, y, c); };
}

}  // namespace

HeldOutScores score_held_out(const TimeLapse& lapse, const std::vector<int>& captured,
                             const relight::TemporalFitOptions& options) {
  const int steps = int(lapse.noisy.size());
  if (captured.size() < 2 || captured.front() != 0 || captured.back() != steps - 1 ||
      !std::is_sorted(captured.begin(), captured.end())) {
    throw InputError("held-out score: captured steps: expected increasing indices from 0 to " +
                     std::to_string(steps - 1) + ", at least two");
  }
  std::vector<capture::ReflectanceField> fields;
  fields.reserve(captured.size());
  for (const int i : captured) fields.push_back(lapse.noisy[size_t(i)]);
  HeldOutScores out;
  out.maps = relight::fit_temporal(fields, options);
  relight::TemporalFitOptions bic_alone = options;
  bic_alone.hold_out_steps = false;
  const relight::TemporalMaps by_bic = relight::fit_temporal(fields, bic_alone);
  bic_alone.fit_curves = false;
  const relight::TemporalMaps processes = relight::fit_temporal(fields, bic_alone);
  const relight::NormalMap normals = relight::estimate_temporal_normals(fields, options);
  std::vector<relight::StepFit> step_fits;
  step_fits.reserve(fields.size());
  for (const capture::ReflectanceField& field : fields) {
    step_fits.push_back(relight::fit_step(field, normals, options));
  }
  const relight::TemporalMaps interpolated =
      relight::every_pixel_from_its_steps(out.maps, step_fits);
  const capture::ValidLights lights = capture::valid_lights(lapse.ideal[0]);
  size_t next = 0;  // Index into `captured` of the first captured step at or after `step`.
  for (int step = 0; step < steps; ++step) {
    while (captured[next] < step) ++next;
    const double t = lapse.ideal[size_t(step)].scene_time_s;
    if (captured[next] == step) {
      accumulate(lapse, step, rendered(out.maps, t, lights), out.fit_at_captured);
      // A one-step temporal model is that step's fit: its constant.
      const relight::TemporalMaps alone =
          relight::fit_temporal_models({step_fits[next]}, normals, options);
      accumulate(lapse, step, rendered(alone, t, lights), out.step_fits_at_captured);
      const capture::ReflectanceField& photo = lapse.noisy[size_t(step)];
      accumulate(
          lapse, step,
          [&](int x, int y, int k, int c) { return photo.at(x, y, lights.index[size_t(k)], c); },
          out.photos_at_captured);
      continue;
    }
    accumulate(lapse, step, rendered(out.maps, t, lights), out.fit);
    accumulate(lapse, step, rendered(by_bic, t, lights), out.by_bic_alone);
    accumulate(lapse, step, rendered(processes, t, lights), out.processes_only);
    accumulate(lapse, step, rendered(interpolated, t, lights), out.step_fits_interpolated);
    const capture::ReflectanceField &before = lapse.noisy[size_t(captured[next - 1])],
                                    &after = lapse.noisy[size_t(captured[next])];
    const double w = (t - before.scene_time_s) / (after.scene_time_s - before.scene_time_s);
    const auto light = [&](int k) { return lights.index[size_t(k)]; };
    accumulate(
        lapse, step,
        [&](int x, int y, int k, int c) {
          return (1 - w) * before.at(x, y, light(k), c) + w * after.at(x, y, light(k), c);
        },
        out.linear);
    const capture::ReflectanceField& nearest = w <= 0.5 ? before : after;
    accumulate(
        lapse, step, [&](int x, int y, int k, int c) { return nearest.at(x, y, light(k), c); },
        out.nearest);
  }
  return out;
}

std::vector<int> evenly_spaced_steps(int steps, int count) {
  std::vector<int> out;
  for (int i = 0; i < count; ++i) {
    const int step = count > 1 ? int(std::lround(double(i) * (steps - 1) / (count - 1))) : 0;
    if (out.empty() || step != out.back()) out.push_back(step);
  }
  return out;
}

namespace {

// Pixels of the material named `name` (1) in a mask the size of the camera.
relight::TemporalSelection material_mask(const TimeLapse& lapse, const std::string& name) {
  relight::TemporalSelection s;
  s.mask.assign(size_t(lapse.stage.camera.width) * lapse.stage.camera.height, 0);
  for (const sim::SurfaceHit& h : lapse.hits) {
    if (h.hit && h.material_index >= 0 &&
        lapse.scene.materials[size_t(h.material_index)].name == name) {
      s.mask[size_t(h.pixel_y) * lapse.stage.camera.width + h.pixel_x] = 1;
    }
  }
  return s;
}

}  // namespace

void write_time_edit_figure(const std::filesystem::path& png, const TimeLapse& lapse,
                            const relight::TemporalMaps& maps, int columns) {
  relight::TemporalEdits faster{"bench: slab x2", {}},
      transfer{"bench: metal takes the slab's", {}};
  relight::TemporalEdit edit;
  edit.select = material_mask(lapse, "stone-slab");
  edit.rate_scale = 2;
  faster.edits.push_back(edit);
  relight::TemporalEdit take;
  take.select = material_mask(lapse, "corroding-metal");
  take.transfer_from = material_mask(lapse, "stone-slab");
  transfer.edits.push_back(take);
  std::vector<relight::TemporalMaps> rows = {maps, maps, maps};
  relight::apply_temporal_edits(faster, rows[1]);
  relight::apply_temporal_edits(transfer, rows[2]);
  const char* labels[] = {"fitted", "slab x2 speed", "metal takes slab's curve"};
  const int w = maps.maps.width, h = maps.maps.height;
  Image grid(w * columns, h * int(rows.size()), 3);
  const Eigen::Vector3d light = Eigen::Vector3d(0.3, 0.45, 0.84).normalized();
  const double t0 = maps.first_time_s(), t1 = maps.last_time_s();
  for (size_t r = 0; r < rows.size(); ++r) {
    for (int col = 0; col < columns; ++col) {
      const double t = t0 + (t1 - t0) * col / std::max(1, columns - 1);
      const Image frame = relight::render_temporal(
          rows[r], t, relight::LightingForModels::directional(light, Eigen::Vector3d(1, 1, 1)));
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          for (int c = 0; c < 3; ++c) grid.at(col * w + x, int(r) * h + y, c) = frame.at(x, y, c);
        }
      }
    }
  }
  // The renders as one preview, 8-bit sRGB as write_png_preview encodes them (in memory, RGB
  // order), then enlarged with a label per row and a time per column.
  const float scale = float(std::exp2(auto_exposure_stops(grid)));
  cv::Mat small(grid.height, grid.width, CV_8UC3);
  for (int y = 0; y < grid.height; ++y) {
    auto* row = small.ptr<cv::Vec3b>(y);
    for (int x = 0; x < grid.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = grid.at(x, y, c) * scale;
        row[x][c] = uchar(std::lround(255.0f * srgb_encode(std::isfinite(v) ? v : 0.0f)));
      }
    }
  }
  constexpr int kScale = 6, kLeft = 200, kTop = 30;
  cv::Mat big;
  cv::resize(small, big, {}, kScale, kScale, cv::INTER_NEAREST);
  cv::Mat figure(big.rows + kTop, big.cols + kLeft, CV_8UC3, cv::Scalar(255, 255, 255));
  big.copyTo(figure(cv::Rect(kLeft, kTop, big.cols, big.rows)));
  const cv::Scalar black(0, 0, 0);
  for (size_t r = 0; r < rows.size(); ++r) {
    cv::putText(figure, labels[r], {8, kTop + int(r) * h * kScale + h * kScale / 2},
                cv::FONT_HERSHEY_SIMPLEX, 0.5, black, 1, cv::LINE_AA);
  }
  for (int col = 0; col < columns; ++col) {
    const double t = t0 + (t1 - t0) * col / std::max(1, columns - 1);
    cv::putText(figure, std::to_string(int(std::lround(t))) + " s",
                {kLeft + col * w * kScale + 8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.5, black, 1,
                cv::LINE_AA);
  }
  write_rgb8(png, figure.cols, figure.rows, figure.ptr<uint8_t>());  // A new Mat: continuous.
}

}  // namespace ls::evaluation
