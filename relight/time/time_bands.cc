#include "relight/time/time_bands.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "capture/field_file.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "relight/fit/fit.h"

namespace ls::relight {

namespace fs = std::filesystem;

namespace {

// A band's checkpoint after its processes (its per-step fits, maps and BICs), or after the curves
// were offered to it (its maps and the degenerate pixels' step values).
enum class TimeStage { kProcesses, kCurves };
constexpr const char* kProcessesMagic = "lightstage fit --time band 2";
constexpr const char* kCurvesMagic = "lightstage fit --time curves band 2";

nlohmann::json summary_json(const relight::TemporalSummary& s) {
  return {{"pixels", s.pixels},
          {"fitted", s.fitted},
          {"flagged", s.flagged},
          {"no_normal", s.no_normal},
          {"no_usable_step", s.no_usable_step},
          {"per_model", s.per_model},
          {"faster_than_sampling", s.faster_than_sampling},
          {"too_few_steps", s.too_few_steps},
          {"step_dropped", s.step_dropped},
          {"not_converged", s.not_converged},
          {"degenerate", s.degenerate},
          {"seconds_steps", s.seconds_steps},
          {"seconds_temporal", s.seconds_temporal}};
}

relight::TemporalSummary summary_from(const nlohmann::json& j) {
  relight::TemporalSummary s;
  s.pixels = j.at("pixels").get<int>();
  s.fitted = j.at("fitted").get<int>();
  s.flagged = j.at("flagged").get<int>();
  s.no_normal = j.at("no_normal").get<int>();
  s.no_usable_step = j.at("no_usable_step").get<int>();
  for (size_t m = 0; m < std::size(s.per_model); ++m) {
    s.per_model[m] = j.at("per_model").at(m).get<int>();
  }
  s.faster_than_sampling = j.at("faster_than_sampling").get<int>();
  s.too_few_steps = j.at("too_few_steps").get<int>();
  s.step_dropped = j.at("step_dropped").get<int>();
  s.not_converged = j.at("not_converged").get<int>();
  s.degenerate = j.at("degenerate").get<int>();
  s.seconds_steps = j.at("seconds_steps").get<double>();
  s.seconds_temporal = j.at("seconds_temporal").get<double>();
  return s;
}

void add(relight::TemporalSummary& to, const relight::TemporalSummary& band) {
  to.pixels += band.pixels;
  to.fitted += band.fitted;
  to.flagged += band.flagged;
  to.no_normal += band.no_normal;
  to.no_usable_step += band.no_usable_step;
  for (size_t m = 0; m < std::size(to.per_model); ++m) to.per_model[m] += band.per_model[m];
  to.faster_than_sampling += band.faster_than_sampling;
  to.too_few_steps += band.too_few_steps;
  to.step_dropped += band.step_dropped;
  to.not_converged += band.not_converged;
  to.degenerate += band.degenerate;
  to.seconds_steps += band.seconds_steps;
  to.seconds_temporal += band.seconds_temporal;
}

RecordTarget floats(Image& image) {
  return {image.pixels.data(), image.pixels.size() * sizeof(float)};
}
RecordBytes floats(const Image& image) {
  return {image.pixels.data(), image.pixels.size() * sizeof(float)};
}

// The images of a step's fit in the checkpoint's order, with their channels.
template <class Step>
auto step_images(Step& step) {
  return std::array{std::pair{&step.value, int(relight::kTemporalParamCount)},
                    std::pair{&step.sigma, int(relight::kTemporalParamCount)},
                    std::pair{&step.flags, 1},
                    std::pair{&step.rendered_sigma, int(relight::kRenderedCount)}};
}

// The bands of the steps' fields, one band's fits at a time, and their checkpoints.
class TimeBands : public BandPlan {
 public:
  TimeBands(const std::vector<std::unique_ptr<capture::FieldStream>>& steps, int rows,
            const relight::TemporalFitOptions& options, const CheckpointDir& checkpoints)
      : BandPlan(steps.front()->height(), rows),
        steps_(steps),
        options_(options),
        checkpoints_(checkpoints) {
    for (const auto& step : steps) times_.push_back(step->header().scene_time_s);
    options_.progress = {};
  }

  const std::vector<double>& times() const { return times_; }

  // Band b's normals, each step's BRDF fit and each pixel's process.
  void fit(int b) {
    const int y0 = first_row(b), y1 = end_row(b);
    const auto start = Clock::now();
    // Every step's rows: the normals are refined over all of them (fit_normals_and_steps).
    std::vector<capture::ReflectanceField> fields(steps_.size());
    std::vector<const capture::ReflectanceField*> sorted;
    for (size_t s = 0; s < steps_.size(); ++s) {
      steps_[s]->read_rows(y0, y1, fields[s]);
      sorted.push_back(&fields[s]);
    }
    relight::NormalsAndStepFits fitted =
        relight::fit_normals_and_steps(relight::steps_by_time(sorted), options_);
    fits = std::move(fitted.steps);
    const double seconds_steps = seconds_since(start);
    const auto processes = Clock::now();
    maps = relight::fit_temporal_processes(fits, fitted.normals, options_, best_bic);
    maps.summary.seconds_steps = seconds_steps;
    maps.summary.seconds_temporal = seconds_since(processes);
  }

  // The curves offered to the band's pixels (its processes loaded), and its counts.
  void offer(const std::vector<relight::TemporalCurves>& curves) {
    const auto start = Clock::now();
    relight::offer_temporal_curves(fits, best_bic, curves, maps);
    relight::hold_out_steps(fits, options_, maps);
    relight::count_temporal_models(fits, maps);
    maps.summary.seconds_temporal += seconds_since(start);
  }

  void save(int b, TimeStage stage) const {
    nlohmann::json info = {{"width", maps.maps.width},
                           {"height", maps.maps.height},
                           {"summary", summary_json(maps.summary)}};
    if (stage == TimeStage::kCurves) {
      info["step_channels"] = maps.step_values.channels;
      info["max_rate"] = relight::max_temporal_rate(maps.maps);
      write_record(file(b, stage), kCurvesMagic, info,
                   {floats(maps.maps), floats(maps.step_values)});
      return;
    }
    std::vector<int> valid_lights;
    for (const relight::StepFit& s : fits) valid_lights.push_back(s.valid_lights);
    info["valid_lights"] = valid_lights;
    std::vector<RecordBytes> blocks = {floats(maps.maps),
                                       {best_bic.data(), best_bic.size() * sizeof(double)}};
    for (const relight::StepFit& s : fits) {
      for (const auto& [image, channels] : step_images(s)) blocks.push_back(floats(*image));
    }
    write_record(file(b, stage), kProcessesMagic, info, blocks);
  }

  // Band b as an earlier step (or run) left it; false when it has no checkpoint of `stage`.
  bool load(int b, TimeStage stage) {
    const int width = steps_.front()->width(), rows = end_row(b) - first_row(b);
    maps = band_header();
    const auto place = [&](const nlohmann::json& info) -> std::optional<std::vector<RecordTarget>> {
      if (info.at("width").get<int>() != width || info.at("height").get<int>() != rows) {
        return std::nullopt;
      }
      maps.summary = summary_from(info.at("summary"));
      maps.maps = Image(width, rows, relight::kTemporalChannelCount);
      maps.maps.channel_names = relight::temporal_channel_names();
      std::vector<RecordTarget> targets = {floats(maps.maps)};
      if (stage == TimeStage::kCurves) {
        const int step_channels = info.at("step_channels").get<int>();
        maps.step_values = step_channels > 0 ? Image(width, rows, step_channels) : Image{};
        targets.push_back(floats(maps.step_values));
        max_rate = info.at("max_rate").get<double>();
        return targets;
      }
      const std::vector<int> valid_lights = info.at("valid_lights").get<std::vector<int>>();
      if (valid_lights.size() != times_.size()) return std::nullopt;
      best_bic.assign(size_t(width) * rows, 0.0);
      targets.push_back({best_bic.data(), best_bic.size() * sizeof(double)});
      fits.assign(times_.size(), {});
      for (size_t s = 0; s < fits.size(); ++s) {
        fits[s].time_s = times_[s];
        fits[s].valid_lights = valid_lights[s];
        for (const auto& [image, channels] : step_images(fits[s])) {
          *image = Image(width, rows, channels);
          targets.push_back(floats(*image));
        }
      }
      return targets;
    };
    return read_record(file(b, stage), stage == TimeStage::kCurves ? kCurvesMagic : kProcessesMagic,
                       place);
  }
  void load_finished(int b, TimeStage stage) {
    if (!load(b, stage)) {
      // What this run wrote itself and cannot read back: its storage failed.
      throw StorageError(file(b, stage).string() +
                         ": a finished band's checkpoint is missing or unreadable (removed while "
                         "the fit ran?)");
    }
  }

  // What every band's maps share: the step times, the noise.
  relight::TemporalMaps band_header() const {
    relight::TemporalMaps header;
    header.step_times_s = times_;
    header.noise = options_.brdf.normals.noise;
    header.noise_source = options_.brdf.noise_source;
    header.modelled_steps = true;  // count_temporal_models writes them.
    return header;
  }

  // The band held: as fitted or loaded.
  std::vector<relight::StepFit> fits;
  relight::TemporalMaps maps;
  std::vector<double> best_bic;
  double max_rate = 0;  // Loaded with the curves.

 private:
  fs::path file(int b, TimeStage stage) const {
    return checkpoints_.dir() / ((stage == TimeStage::kProcesses ? "steps_" : "curves_") +
                                 std::to_string(first_row(b)) + ".band");
  }
  const std::vector<std::unique_ptr<capture::FieldStream>>& steps_;
  relight::TemporalFitOptions options_;
  const CheckpointDir& checkpoints_;
  std::vector<double> times_;
};

// The curves on every rank as rank 0 learnt them: families, knots a curve, then the knots.
void broadcast(const RankSplit& split, std::vector<relight::TemporalCurves>& curves) {
  std::vector<double> values = {double(curves.size()),
                                curves.empty() ? 0.0 : double(curves[0].knots[0].size())};
  for (const relight::TemporalCurves& family : curves) {
    for (const std::vector<double>& knots : family.knots) {
      values.insert(values.end(), knots.begin(), knots.end());
    }
  }
  split.share(values);
  const size_t families = size_t(values[0]), knots = size_t(values[1]);
  curves.assign(families, {});
  const double* v = values.data() + 2;
  for (relight::TemporalCurves& family : curves) {
    family.knots.resize(relight::kTemporalParamCount);
    for (std::vector<double>& k : family.knots) k.assign(v, v + knots), v += knots;
  }
}

}  // namespace

std::size_t time_band_row_bytes(const capture::FieldStream& step, int steps,
                                relight::NormalSource source) {
  const std::size_t width = std::size_t(step.width());
  const std::size_t field_row = width * 3 * std::size_t(step.header().num_lights()) * sizeof(float);
  constexpr int kStepChannels = 2 * relight::kTemporalParamCount + 1 + relight::kRenderedCount;
  const std::size_t fits_row =
      width * sizeof(float) *
          (std::size_t(steps) * kStepChannels + std::size_t(2) * relight::kTemporalChannelCount +
           relight::kMapChannelCount) +
      width * sizeof(double);
  // Every step's band (the normals are refined over all of them), its reader's buffer (a
  // quarter), the fits; pooled normals also hold a copy of every step's band side by side.
  const std::size_t field_rows =
      (source == relight::NormalSource::kPooled ? 2 : 1) * std::size_t(steps);
  return field_rows * field_row * 5 / 4 + fits_row;
}

TimeBandFit fit_over_time_in_bands(const std::vector<std::unique_ptr<capture::FieldStream>>& steps,
                                   int rows, const relight::TemporalFitOptions& fit,
                                   const CheckpointDir& checkpoints, const RankSplit& split,
                                   const fs::path& out, const ExrAttributes& attributes,
                                   const ProgressFn& progress) {
  const int width = steps.front()->width(), height = steps.front()->height();
  TimeBands bands(steps, rows, fit, checkpoints);
  TimeBandFit result;
  const long own_rows = bands.rows_mine(split);
  long done_rows = 0;
  for (int b = split.rank; b < bands.count(); b += split.size) {
    const int band_rows = bands.end_row(b) - bands.first_row(b);
    const bool resumed = bands.load(b, TimeStage::kProcesses);
    if (resumed) {
      result.resumed_rows += band_rows;
    } else {
      bands.fit(b);
      bands.save(b, TimeStage::kProcesses);
    }
    report(progress, "fit over time (rows)", done_rows += band_rows, own_rows,
           resumed ? "resumed" : "");
  }
  split.wait();  // Every band's processes are in its checkpoint.
  std::vector<relight::TemporalCurves> curves;
  if (fit.fit_curves && split.root()) {
    relight::CurveSample sample;
    for (int b = 0; b < bands.count(); ++b) {
      bands.load_finished(b, TimeStage::kProcesses);
      sample.count(bands.maps.maps);
    }
    for (int b = 0; b < bands.count(); ++b) {
      bands.load_finished(b, TimeStage::kProcesses);
      sample.gather(bands.fits, bands.maps.maps);
      report(progress, "curves (bands read)", b + 1, bands.count());
    }
    curves = sample.learn(bands.times());
  }
  broadcast(split, curves);
  done_rows = 0;
  for (int b = split.rank; b < bands.count(); b += split.size) {
    const bool resumed = bands.load(b, TimeStage::kCurves);
    if (!resumed) {
      bands.load_finished(b, TimeStage::kProcesses);
      bands.offer(curves);
      bands.save(b, TimeStage::kCurves);
    }
    report(progress, "curves offered (rows)", done_rows += bands.end_row(b) - bands.first_row(b),
           own_rows, resumed ? "resumed" : "");
  }
  split.wait();  // Every band is final.
  if (!split.root()) return result;
  // The file's header needs what every band holds: whether any has step values, the largest rate.
  double max_rate = 0;
  bool step_values = false;
  for (int b = 0; b < bands.count(); ++b) {
    bands.load_finished(b, TimeStage::kCurves);
    add(result.summary, bands.maps.summary);
    max_rate = std::max(max_rate, bands.max_rate);
    step_values = step_values || !bands.maps.step_values.pixels.empty();
  }
  result.summary.curve_families = int(curves.size());
  relight::TemporalMaps header = bands.band_header();
  header.curves = curves;
  relight::TemporalMapsWriter writer(out, width, height, header, step_values, max_rate, attributes);
  for (int b = 0; b < bands.count(); ++b) {
    bands.load_finished(b, TimeStage::kCurves);
    writer.write_rows(bands.maps);
    report(progress, "write maps (rows)", bands.end_row(b), height);
  }
  writer.commit();
  return result;
}

}  // namespace ls::relight
