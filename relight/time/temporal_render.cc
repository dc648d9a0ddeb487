#include "relight/time/temporal_render.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/json_reader.h"
#include "physics/brdf.h"
#include "relight/fit/model_edit.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight {
namespace {

using temporal_internal::clamp_param;
using temporal_internal::interpolate_params;
using temporal_internal::kMinRoughness;
using temporal_internal::params_at;
using temporal_internal::to_fitted_space;

TemporalModel read_temporal_model_name(const JsonReader& r) {
  const std::string name =
      r.one_of({"constant", "exponential", "sigmoid", "dust", "curve", "steps"});
  if (name == "constant") return TemporalModel::kConstant;
  if (name == "steps") return TemporalModel::kSteps;
  if (name == "curve") return TemporalModel::kCurve;
  if (name == "exponential") return TemporalModel::kExponential;
  if (name == "sigmoid") return TemporalModel::kSigmoid;
  return TemporalModel::kDust;
}

TemporalSelection read_selection(const JsonReader& r, const std::filesystem::path& base_dir,
                                 int width, int height) {
  r.expect_object({"model", "mask"});
  if (!r.has("model") && !r.has("mask")) r.fail(R"(an object with "model" and/or "mask")");
  TemporalSelection s;
  if (r.has("model")) s.model = read_temporal_model_name(r["model"]);
  if (r.has("mask")) s.mask = read_selection_mask(r["mask"], base_dir, width, height, &s.mask_file);
  return s;
}

// (x, y) of the maps, row first_row + y of the frame the selection's mask covers.
bool selected(const TemporalSelection& s, const TemporalMaps& maps, int x, int y, int first_row) {
  const TemporalModel model = maps.model(x, y);
  if (model == TemporalModel::kNone) return false;
  // A degenerate pixel renders from its per-step fits: it has no process to edit or to give.
  if ((int(maps.at(x, y, kTFlags)) & kTemporalDegenerate) != 0) return false;
  if (s.model && *s.model != model) return false;
  if (!s.mask.empty() && !s.mask[size_t(first_row + y) * maps.maps.width + x]) return false;
  return true;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Where time t falls among a kSteps pixel's steps: the step before, the step after and the weight
// of the one after; its time scaled about the first step by its rate (1 unless edited), held at
// the first and the last step beyond them.
struct StepBlend {
  int before = 0, after = 0;
  double w = 0;
};
StepBlend step_blend(const std::vector<double>& times, float rate, double t) {
  const double warped = times.front() + rate * (t - times.front());
  StepBlend b;
  b.after =
      int(std::min(size_t(std::upper_bound(times.begin(), times.end(), warped) - times.begin()),
                   times.size() - 1));
  b.before = std::max(b.after - 1, 0);
  if (b.after != b.before) {
    b.w = std::clamp(
        (warped - times[size_t(b.before)]) / (times[size_t(b.after)] - times[size_t(b.before)]),
        0.0, 1.0);
  }
  return b;
}

// Which parameters a kSteps pixel takes in a state: its steps' blended (models_at_time), or the
// step before's or after's alone (render_temporal blends their renders).
enum class StepsSide { kBlended, kBefore, kAfter };

void steps_params(const TemporalMaps& maps, const float* m, int x, int y, double t, StepsSide side,
                  double* q) {
  const StepBlend b = step_blend(maps.step_times_s, m[kTRate], t);
  double before[kTemporalParamCount], after[kTemporalParamCount];
  for (int p = 0; p < kTemporalParamCount; ++p) {
    before[p] = clamp_param(p, maps.step_values.at(x, y, b.before * kTemporalParamCount + p));
    after[p] = clamp_param(p, maps.step_values.at(x, y, b.after * kTemporalParamCount + p));
  }
  if (side == StepsSide::kBlended) {
    interpolate_params(before, after, b.w, q);
  } else {
    std::copy_n(side == StepsSide::kBefore ? before : after, kTemporalParamCount, q);
  }
}

// A modelled pixel's parameters at time t within its steps: its model there plus its steps'
// departures from it (TemporalMaps::step_values), interpolated between the two steps around t.
void model_with_departures(const TemporalMaps& maps, const float* m, int x, int y, double t,
                           double* q) {
  params_at(m, t, maps.first_time_s(), maps.curves_at(x, y), q);
  // A rate edit's scale s: the pixel at t is as captured at first + s (t - first).
  const double first = maps.first_time_s();
  const float scale = maps.edited_time_scale.empty()
                          ? 1.0f
                          : maps.edited_time_scale[size_t(y) * maps.maps.width + x];
  const double captured_t = first + scale * (t - first);
  if (captured_t > maps.last_time_s()) return;  // Beyond its steps: the model alone.
  const StepBlend b = step_blend(maps.step_times_s, scale, t);
  double departure[2][kTemporalParamCount];
  const int around[2] = {b.before, b.after};
  for (int side = 0; side < 2; ++side) {
    const int k = around[side];
    double* d = departure[side];
    // The model at the step, in the pixel's (edited) time.
    const double step_t = first + (maps.step_times_s[size_t(k)] - first) / scale;
    params_at(m, step_t, first, maps.curves_at(x, y), d);
    to_fitted_space(d);
    double step[kTemporalParamCount];
    for (int p = 0; p < kTemporalParamCount; ++p) {
      step[p] = clamp_param(p, maps.step_values.at(x, y, k * kTemporalParamCount + p));
    }
    to_fitted_space(step);
    for (int p = 0; p < kTemporalParamCount; ++p) d[p] = step[p] - d[p];
  }
  to_fitted_space(q);
  temporal_internal::add_departures(departure[0], departure[1], b.w, q);
  temporal_internal::from_fitted_space(q);
}

TemporalState models_at(const TemporalMaps& maps, double time_s, StepsSide side);

// The diffuse (Oren-Nayar) and the lobe (Torrance-Sparrow) parts of a state rendered through
// render_models, summed (render_models is linear in the BRDF).
Image render_state(const ModelMaps& state, const LightingForModels& lighting,
                   const ModelRenderOptions& options) {
  ModelMaps diffuse = state, lobe = state;
  for (size_t i = 0; i < diffuse.maps.num_pixels(); ++i) {
    float* d = &diffuse.maps.pixels[i * kMapChannelCount];
    float* l = &lobe.maps.pixels[i * kMapChannelCount];
    if (d[kMapModel] == 0) continue;
    d[kMapModel] = float(FitModel::kOrenNayar);
    d[kMapKs] = 0;
    l[kMapModel] = float(FitModel::kLambertTorranceSparrow);
    l[kMapAlbedoR] = l[kMapAlbedoG] = l[kMapAlbedoB] = 0;
  }
  Image out = render_models(diffuse, lighting, options);
  ModelRenderOptions lobe_options = options;
  lobe_options.flagged_fallback = nullptr;  // Already in the diffuse part.
  const Image specular = render_models(lobe, lighting, lobe_options);
  for (size_t i = 0; i < out.pixels.size(); ++i) {
    const float v = out.pixels[i] + specular.pixels[i];
    out.pixels[i] = std::isfinite(v) ? v : 0.0f;
  }
  return out;
}

TemporalState models_at(const TemporalMaps& maps, double time_s, StepsSide side) {
  const int width = maps.maps.width, height = maps.maps.height;
  TemporalState out;
  out.maps.maps = Image(width, height, kMapChannelCount);
  out.maps.maps.channel_names = model_map_channel_names();
  out.maps.noise = maps.noise;
  out.maps.noise_source = maps.noise_source;
  const bool outside = time_s < maps.first_time_s() || time_s > maps.last_time_s();
  // Degenerate pixels render from their nearest per-step fit (TemporalMaps::step_values).
  int nearest_step = -1;
  if (!maps.step_values.pixels.empty()) {
    for (size_t i = 0; i < maps.step_times_s.size(); ++i) {
      if (nearest_step < 0 || std::abs(maps.step_times_s[i] - time_s) <
                                  std::abs(maps.step_times_s[size_t(nearest_step)] - time_s)) {
        nearest_step = int(i);
      }
    }
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const float* m = maps.maps.pixels.data() + (size_t(y) * width + x) * kTemporalChannelCount;
      float* o = &out.maps.maps.at(x, y, 0);
      const TemporalModel model = TemporalModel(int(m[kTModel]));
      int flags = int(m[kTFlags]) & ~kExtrapolated;
      if (model == TemporalModel::kNone) {
        o[kMapFlags] = float(flags | kFitFailed);
        continue;
      }
      if (outside && model != TemporalModel::kConstant) {
        flags |= kExtrapolated;
        ++out.extrapolated_pixels;
      }
      double q[kTemporalParamCount];
      if (model == TemporalModel::kSteps && !maps.step_values.pixels.empty()) {
        steps_params(maps, m, x, y, time_s, side, q);
      } else if ((flags & kTemporalDegenerate) != 0 && nearest_step >= 0) {
        for (int p = 0; p < kTemporalParamCount; ++p) {
          q[p] = clamp_param(p, maps.step_values.at(x, y, nearest_step * kTemporalParamCount + p));
        }
      } else if (maps.modelled_steps && !outside && !maps.step_values.pixels.empty()) {
        model_with_departures(maps, m, x, y, time_s, q);
      } else {
        params_at(m, time_s, maps.first_time_s(), maps.curves_at(x, y), q);
      }
      for (int c = 0; c < 3; ++c) {
        o[kMapNormalX + c] = m[kTNormalX + c];
        o[kMapAlbedoR + c] = float(q[kParamAlbedoR + c]);
      }
      o[kMapSigma] = float(q[kParamSigma]);
      o[kMapKs] = float(q[kParamKs]);
      o[kMapRoughness] = float(q[kParamRoughness]);
      o[kMapModel] =
          float(q[kParamKs] > 0 ? FitModel::kLambertTorranceSparrow : FitModel::kOrenNayar);
      o[kMapConfidence] = m[kTConfidence];
      o[kMapResidual] = m[kTResidual];
      o[kMapFlags] = float(flags);
    }
  }
  return out;
}

}  // namespace

TemporalState models_at_time(const TemporalMaps& maps, double time_s) {
  return models_at(maps, time_s, StepsSide::kBlended);
}

Image render_temporal(const TemporalMaps& maps, double time_s, const LightingForModels& lighting,
                      const ModelRenderOptions& options, int* extrapolated_pixels) {
  const int width = maps.maps.width, height = maps.maps.height;
  // A kSteps pixel between two steps is the blend of their renders (a blend of their BRDFs): a
  // blend of their parameters would make a lobe of one's width with the other's energy.
  std::vector<float> blend(size_t(width) * height, 0.0f);
  bool any_steps = false;
  for (int y = 0; y < height && !maps.step_values.pixels.empty(); ++y) {
    for (int x = 0; x < width; ++x) {
      if (maps.model(x, y) != TemporalModel::kSteps) continue;
      any_steps = true;
      const float rate = maps.at(x, y, kTRate);
      blend[size_t(y) * width + x] = float(step_blend(maps.step_times_s, rate, time_s).w);
    }
  }
  const TemporalState state =
      models_at(maps, time_s, any_steps ? StepsSide::kBefore : StepsSide::kBlended);
  if (extrapolated_pixels) *extrapolated_pixels = state.extrapolated_pixels;
  Image out = render_state(state.maps, lighting, options);
  if (!any_steps) return out;
  const Image after =
      render_state(models_at(maps, time_s, StepsSide::kAfter).maps, lighting, options);
  for (size_t i = 0; i < out.num_pixels(); ++i) {
    for (int c = 0; c < out.channels; ++c) {
      float& v = out.pixels[i * size_t(out.channels) + size_t(c)];
      v += blend[i] * (after.pixels[i * size_t(out.channels) + size_t(c)] - v);
    }
  }
  return out;
}

TemporalEdits parse_temporal_edits(std::string_view json_text, const std::string& source,
                                   const std::filesystem::path& base_dir, int width, int height) {
  const nlohmann::json root = JsonReader::parse(json_text, source);
  const JsonReader r(root, source);
  r.expect_object({"time"});
  TemporalEdits out;
  out.source = source;
  if (!r.has("time")) return out;
  const JsonReader list = r["time"];
  list.expect_array();
  for (size_t i = 0; i < list.size(); ++i) {
    const JsonReader e = list[i];
    e.expect_object({"select", "rate_scale", "transfer_from"});
    TemporalEdit edit;
    edit.select = read_selection(e["select"], base_dir, width, height);
    if (e.has("rate_scale")) edit.rate_scale = e["rate_scale"].positive();
    if (e.has("transfer_from")) {
      edit.transfer_from = read_selection(e["transfer_from"], base_dir, width, height);
    }
    out.edits.push_back(std::move(edit));
  }
  return out;
}

TemporalEdits read_temporal_edits(const std::filesystem::path& path, int width, int height) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot read the edit file");
  std::stringstream text;
  text << in.rdbuf();
  return parse_temporal_edits(text.str(), path.string(), path.parent_path(), width, height);
}

namespace {

// Pixel (x, y)'s end state, in the curves' space when `curve_space` (temporal_fit.h), else the
// BRDF's: a process's dry endpoint (where it settles), a curve's state at the last captured step
// (its dry endpoint is where its curve bottoms, which it may never reach).
void end_state(const TemporalMaps& maps, int x, int y, bool curve_space, double* q) {
  const float* m = &maps.maps.pixels[(size_t(y) * maps.maps.width + x) * kTemporalChannelCount];
  const bool curve = maps.model(x, y) == TemporalModel::kCurve;
  if (curve) {
    params_at(m, maps.last_time_s(), maps.first_time_s(), maps.curves_at(x, y), q);
  } else {
    std::copy_n(m + kTDry, kTemporalParamCount, q);
  }
  if (curve_space) to_fitted_space(q);
}

}  // namespace

namespace {

// What a transfer's source region shows, gathered over every band: first the votes for its
// process (the varying one most of its pixels follow), then that process's values.
struct SourceGather {
  int votes[kTemporalModelCount] = {};
  TemporalModel model = TemporalModel::kNone;
  std::vector<double> rates, onsets, seen, to_dry[kTemporalParamCount], to_wet[kTemporalParamCount];
  std::vector<int> family_votes;

  void vote(const TemporalSelection& from, const TemporalMaps& band, int first_row) {
    for (int y = 0; y < band.maps.height; ++y) {
      for (int x = 0; x < band.maps.width; ++x) {
        if (selected(from, band, x, y, first_row)) ++votes[int(band.model(x, y))];
      }
    }
  }
  // After every band voted: the source's process; false when it has no varying one.
  bool choose() {
    int best = 0;
    for (int k = 2; k < kTemporalModelCount; ++k) {
      // Per-step fits are the pixel's own data: nothing to move onto another.
      if (TemporalModel(k) == TemporalModel::kSteps) continue;
      if (votes[k] > votes[best]) best = k;
    }
    model = TemporalModel(best);
    return best != 0;
  }
  void gather(const TemporalSelection& from, const TemporalMaps& band, int first_row) {
    family_votes.resize(band.curves.size());
    for (int y = 0; y < band.maps.height; ++y) {
      for (int x = 0; x < band.maps.width; ++x) {
        if (!selected(from, band, x, y, first_row) || band.model(x, y) != model) continue;
        rates.push_back(band.at(x, y, kTRate));
        seen.push_back(band.at(x, y, kTCurveSeen));
        onsets.push_back(band.at(x, y, kTOnset));
        // The source's endpoints against its own end state (ratios for the albedo).
        double end[kTemporalParamCount];
        end_state(band, x, y, model == TemporalModel::kCurve, end);
        for (int p = 0; p < kTemporalParamCount; ++p) {
          const double wet = band.at(x, y, kTWet + p), dry = band.at(x, y, kTDry + p);
          if (p <= kParamAlbedoB) {
            to_dry[p].push_back(end[p] > 1e-4 ? dry / end[p] : 1.0);
            to_wet[p].push_back(end[p] > 1e-4 ? wet / end[p] : 1.0);
          } else {
            to_dry[p].push_back(dry - end[p]);
            to_wet[p].push_back(wet - end[p]);
          }
        }
        const int f = int(band.at(x, y, kTCurve));
        if (model == TemporalModel::kCurve && f >= 0 && f < int(family_votes.size())) {
          ++family_votes[size_t(f)];
        }
      }
    }
  }
  TemporalTransfer transfer() const {
    TemporalTransfer t;
    t.model = model;
    if (model == TemporalModel::kCurve && !family_votes.empty()) {
      t.family =
          int(std::max_element(family_votes.begin(), family_votes.end()) - family_votes.begin());
    }
    t.rate = median(rates);
    t.seen = median(seen);
    t.onset = median(onsets);
    for (int p = 0; p < kTemporalParamCount; ++p) {
      t.change_dry[p] = median(to_dry[p]);
      t.change_wet[p] = median(to_wet[p]);
    }
    return t;
  }
};

// Edit e on a band whose rows start at first_row of the frame; returns the pixels it changed.
int apply_edit(const TemporalEdit& edit, const std::optional<TemporalTransfer>& source,
               TemporalMaps& band, int first_row) {
  const double first = band.first_time_s();
  int count = 0;
  for (int y = 0; y < band.maps.height; ++y) {
    for (int x = 0; x < band.maps.width; ++x) {
      if (!selected(edit.select, band, x, y, first_row)) continue;
      float* m = &band.maps.at(x, y, 0);
      if (source) {
        // The target's own end state, moved as the source moves from its own.
        const bool to_curve = source->model == TemporalModel::kCurve;
        double base[kTemporalParamCount];
        end_state(band, x, y, to_curve, base);
        m[kTModel] = float(source->model);
        m[kTCurve] = float(source->family);
        m[kTCurveSeen] = float(source->seen);
        m[kTRate] = float(source->rate);
        m[kTOnset] = float(source->onset);
        for (int p = 0; p < kTemporalParamCount; ++p) {
          const bool ratio = p <= kParamAlbedoB;
          const double dry =
              ratio ? base[p] * source->change_dry[p] : base[p] + source->change_dry[p];
          const double wet =
              ratio ? base[p] * source->change_wet[p] : base[p] + source->change_wet[p];
          // Within the parameter's bounds in the space the endpoints are in (a curve's: 1/m).
          const auto bounded = [&](double v) {
            return float(to_curve && p == kParamRoughness ? std::clamp(v, 1.0, 1 / kMinRoughness)
                                                          : clamp_param(p, v));
          };
          m[kTDry + p] = bounded(dry);
          m[kTWet + p] = bounded(wet);
        }
      }
      const bool departures = band.modelled_steps && !band.step_values.pixels.empty() &&
                              temporal_internal::renders_from_model(m);
      std::vector<float>& scale = band.edited_time_scale;
      const size_t i = size_t(y) * band.maps.width + x;
      // A transfer's material is another's: the target's departures from its own model go.
      if (source && departures) {
        temporal_internal::write_modelled_steps(nullptr, x, y, band);
        if (!scale.empty()) scale[i] = 1;
      }
      if (edit.rate_scale != 1.0 && band.model(x, y) != TemporalModel::kConstant) {
        m[kTRate] = float(m[kTRate] * edit.rate_scale);
        m[kTOnset] = float(first + (m[kTOnset] - first) / edit.rate_scale);
        if (departures) {
          if (scale.empty()) scale.assign(band.maps.num_pixels(), 1.0f);
          scale[i] = float(scale[i] * edit.rate_scale);
        }
      }
      ++count;
    }
  }
  return count;
}

}  // namespace

std::vector<std::optional<TemporalTransfer>> temporal_transfers(const TemporalEdits& edits,
                                                                const TemporalMapsBands& bands) {
  std::vector<std::optional<TemporalTransfer>> transfers;
  for (size_t e = 0; e < edits.edits.size(); ++e) {
    const TemporalEdit& edit = edits.edits[e];
    if (!edit.transfer_from) {
      transfers.emplace_back();
      continue;
    }
    // The source as the edits before this one left it.
    const auto edited = [&](const std::function<void(const TemporalMaps&, int)>& visit) {
      bands([&](TemporalMaps& band, int first_row) {
        for (size_t before = 0; before < e; ++before) {
          apply_edit(edits.edits[before], transfers[before], band, first_row);
        }
        visit(band, first_row);
      });
    };
    SourceGather source;
    edited([&](const TemporalMaps& band, int y0) { source.vote(*edit.transfer_from, band, y0); });
    if (!source.choose()) {
      throw InputError(edits.source + ": time[" + std::to_string(e) +
                       "].transfer_from: expected a region with a varying (non-constant) "
                       "process, got none");
    }
    edited([&](const TemporalMaps& band, int y0) { source.gather(*edit.transfer_from, band, y0); });
    transfers.emplace_back(source.transfer());
  }
  return transfers;
}

std::vector<int> apply_temporal_edits(const TemporalEdits& edits,
                                      const std::vector<std::optional<TemporalTransfer>>& transfers,
                                      TemporalMaps& band, int first_row) {
  LS_CHECK(transfers.size() == edits.edits.size(), "one transfer (or none) per edit");
  std::vector<int> counts;
  for (size_t e = 0; e < edits.edits.size(); ++e) {
    counts.push_back(apply_edit(edits.edits[e], transfers[e], band, first_row));
  }
  return counts;
}

std::vector<int> apply_temporal_edits(const TemporalEdits& edits, TemporalMaps& maps) {
  const std::vector<std::optional<TemporalTransfer>> transfers =
      temporal_transfers(edits, [&](const std::function<void(TemporalMaps&, int)>& visit) {
        TemporalMaps copy = maps;  // Each pass sees the maps as they came.
        visit(copy, 0);
      });
  return apply_temporal_edits(edits, transfers, maps, 0);
}

}  // namespace ls::relight
