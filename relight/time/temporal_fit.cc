#include "relight/time/temporal_fit.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "lightstage/errors.h"

namespace ls::relight {
namespace {

// Field with every step's lights side by side (for pooled photometric stereo).
capture::ReflectanceField pooled_field(const std::vector<const capture::ReflectanceField*>& steps) {
  std::vector<capture::FieldLight> lights;
  for (auto* f : steps) lights.insert(lights.end(), f->lights().begin(), f->lights().end());
  capture::ReflectanceField pooled(steps[0]->width(), steps[0]->height(), lights);
  for (int y = 0; y < pooled.height(); ++y) {
    for (int x = 0; x < pooled.width(); ++x) {
      float* out = pooled.pixel(x, y);
      for (auto* f : steps)
        out = std::copy(f->pixel(x, y), f->pixel(x, y) + 3 * f->num_lights(), out);
    }
  }
  return pooled;
}

// Photometric stereo on the source, then (refine_normals) each pixel's normal refined by its own
// BRDF fit on the source step (the last for kPooled): the fit's normal where it has one.
NormalMap normals_from(const std::vector<const capture::ReflectanceField*>& sorted,
                       const TemporalFitOptions& options) {
  const NormalSource source = options.normal_source;
  const capture::ReflectanceField& step =
      source == NormalSource::kFirst ? *sorted.front() : *sorted.back();
  NormalMap normals = source == NormalSource::kPooled && sorted.size() > 1
                          ? estimate_normals(pooled_field(sorted), options.brdf.normals)
                          : estimate_normals(step, options.brdf.normals);
  if (!options.refine_normals) return normals;
  FitOptions fit = options.brdf;
  fit.refine_normal = true;
  fit.materials = FitMaterials::kPerPixel;  // Only each pixel's own normal is wanted.
  fit.progress = nullptr;
  const ModelMaps fitted = fit_models(step, normals, fit);
  for (int y = 0; y < step.height(); ++y) {
    for (int x = 0; x < step.width(); ++x) {
      if (normals.flags.at(x, y, 0) != 0 || fitted.model(x, y) == FitModel::kNone) continue;
      const Eigen::Vector3d n(fitted.maps.at(x, y, kMapNormalX),
                              fitted.maps.at(x, y, kMapNormalX + 1),
                              fitted.maps.at(x, y, kMapNormalX + 2));
      if (!(n.norm() > 0.5) || !n.allFinite()) continue;
      for (int c = 0; c < 3; ++c) normals.normal.at(x, y, c) = float(n.normalized()(c));
    }
  }
  return normals;
}

std::vector<const capture::ReflectanceField*> pointers_to(
    const std::vector<capture::ReflectanceField>& fields) {
  std::vector<const capture::ReflectanceField*> out;
  out.reserve(fields.size());
  for (const auto& f : fields) out.push_back(&f);
  return out;
}

}  // namespace

const char* to_string(TemporalModel model) {
  switch (model) {
    case TemporalModel::kNone:
      return "none";
    case TemporalModel::kConstant:
      return "constant";
    case TemporalModel::kExponential:
      return "exponential";
    case TemporalModel::kSigmoid:
      return "sigmoid";
    case TemporalModel::kDust:
      return "dust";
    case TemporalModel::kCurve:
      return "curve";
    case TemporalModel::kSteps:
      return "steps";
  }
  return "?";
}

const char* temporal_param_name(int param) {
  static const char* names[kTemporalParamCount] = {"albedo.r", "albedo.g", "albedo.b",
                                                   "sigma",    "ks",       "roughness"};
  return param >= 0 && param < kTemporalParamCount ? names[param] : "?";
}

const std::vector<std::string>& temporal_channel_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n = {"normal.x", "normal.y", "normal.z", "model", "rate", "onset"};
    for (int p = 0; p < kTemporalParamCount; ++p)
      n.push_back(std::string("wet.") + temporal_param_name(p));
    for (int p = 0; p < kTemporalParamCount; ++p)
      n.push_back(std::string("dry.") + temporal_param_name(p));
    for (const char* c : {"confidence", "residual", "steps_used", "flags", "curve", "curve_seen"}) {
      n.push_back(c);
    }
    return n;
  }();
  return names;
}

std::string TemporalFitOptions::validate() const {
  if (std::string e = brdf.validate(); !e.empty()) return "brdf: " + e;
  if (!(max_rate_times_interval > 0 && std::isfinite(max_rate_times_interval))) {
    return "max_rate_times_interval: expected > 0";
  }
  if (max_iterations < 1) return "max_iterations: expected >= 1";
  if (normal_rounds_over_steps < 0 || normal_rounds_over_steps > 10) {
    return "normal_rounds_over_steps: expected 0..10";
  }
  return {};
}

std::string TemporalSummary::to_string() const {
  std::ostringstream s;
  s << fitted << " of " << pixels << " pixels fitted, " << flagged << " flagged (" << no_normal
    << " no normal, " << no_usable_step << " no usable step); models:";
  for (int m = 1; m < kTemporalModelCount; ++m) {
    s << ' ' << relight::to_string(TemporalModel(m)) << '=' << per_model[m];
  }
  s << "; flags: faster-than-sampling=" << faster_than_sampling
    << " too-few-steps=" << too_few_steps << " step-dropped=" << step_dropped
    << " not-converged=" << not_converged << " degenerate=" << degenerate << "; per-step BRDF fits "
    << seconds_steps << " s, temporal fits " << seconds_temporal << " s";
  return s.str();
}

std::vector<const capture::ReflectanceField*> steps_by_time(
    std::vector<const capture::ReflectanceField*> steps) {
  if (steps.empty()) throw InputError("temporal fit: expected at least one field, got none");
  const capture::ReflectanceField& a = *steps[0];
  for (const capture::ReflectanceField* f : steps) {
    if (f->width() != a.width() || f->height() != a.height()) {
      throw InputError(f->source + ": size: expected " + std::to_string(a.width()) + "x" +
                       std::to_string(a.height()) + " (as " + a.source + "), got " +
                       std::to_string(f->width()) + "x" + std::to_string(f->height()));
    }
    if (!std::isfinite(f->scene_time_s)) {
      throw InputError(f->source + ": scene_time_s: expected a finite time");
    }
  }
  std::stable_sort(steps.begin(), steps.end(),
                   [](auto* a, auto* b) { return a->scene_time_s < b->scene_time_s; });
  for (size_t i = 1; i < steps.size(); ++i) {
    if (steps[i]->scene_time_s == steps[i - 1]->scene_time_s) {
      throw InputError(steps[i]->source + ": scene_time_s: expected a time different from " +
                       steps[i - 1]->source + "'s, got both " +
                       std::to_string(steps[i]->scene_time_s) + " s");
    }
  }
  return steps;
}

NormalsAndStepFits fit_normals_and_steps(
    const std::vector<const capture::ReflectanceField*>& sorted, const TemporalFitOptions& options,
    const std::function<void(int rows)>& rows_done) {
  NormalsAndStepFits out{normals_from(sorted, options), {}};
  const auto fit_steps = [&] {
    out.steps.clear();
    for (auto* f : sorted) {
      out.steps.push_back(fit_step(*f, out.normals, options));
      if (rows_done) rows_done(f->height());
    }
  };
  fit_steps();
  for (int round = 0; round < normal_rounds(options, int(sorted.size())); ++round) {
    out.normals = refine_normals_over_steps(sorted, out.steps, std::move(out.normals), options);
    fit_steps();
  }
  return out;
}

int normal_rounds(const TemporalFitOptions& options, int steps) {
  return options.refine_normals && steps > 1 ? options.normal_rounds_over_steps : 0;
}

NormalMap estimate_temporal_normals(const std::vector<capture::ReflectanceField>& steps,
                                    const TemporalFitOptions& options) {
  return fit_normals_and_steps(steps_by_time(pointers_to(steps)), options).normals;
}

TemporalMaps fit_temporal(const std::vector<capture::ReflectanceField>& input,
                          const TemporalFitOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("temporal fit options: " + error);
  }
  const std::vector<const capture::ReflectanceField*> order = steps_by_time(pointers_to(input));
  const auto start_time = std::chrono::steady_clock::now();
  const long total_rows =
      long(order.size() * (normal_rounds(options, int(order.size())) + 1) + 1) * input[0].height();
  std::atomic<long> done_rows{0};
  NormalsAndStepFits fitted = fit_normals_and_steps(order, options, [&](int rows) {
    done_rows += rows;
    report(options.progress, "fit over time", done_rows, total_rows);
  });
  const NormalMap& normals = fitted.normals;
  std::vector<StepFit>& steps = fitted.steps;
  const double seconds_steps =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  TemporalFitOptions temporal = options;
  const long base = done_rows;
  if (options.progress) {
    temporal.progress = [&, base](const std::string& phase, long done, long,
                                  const std::string& item) {
      options.progress(phase, base + done, total_rows, item);
    };
  }
  TemporalMaps out = fit_temporal_models(steps, normals, temporal);
  out.summary.seconds_steps = seconds_steps;
  return out;
}

}  // namespace ls::relight
