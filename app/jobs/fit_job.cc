#include "app/jobs/fit_job.h"

#include <algorithm>
#include <chrono>
#include <memory>
#include <nlohmann/json.hpp>
#include <tuple>

#include "app/jobs/ranks.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "capture/object_sample.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "lightstage/exr_channels.h"
#include "lightstage/memory.h"
#include "lightstage/run_outputs.h"
#include "relight/fit/basis_materials.h"
#include "relight/fit/fit_bands.h"
#include "relight/fit/fit_checkpoint.h"
#include "relight/fit/noise_choice.h"
#include "relight/fit/noise_from_data.h"
#include "relight/fit/normals.h"
#include "relight/time/time_bands.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

// --method of fit and normals: photometric stereo's, "robust" or "ls".
std::string method_problem(const std::string& method) {
  if (method == "robust" || method == "ls") return {};
  return "--method: expected robust or ls, got \"" + method + "\"";
}
relight::NormalMethod normal_method(const std::string& method) {
  return method == "ls" ? relight::NormalMethod::kLeastSquares : relight::NormalMethod::kRobust;
}

}  // namespace

std::string FitJobOptions::validate() const {
  if (!time_inputs.empty() && !field_file.empty()) {
    return "give either a field or --time FIELDS..., not both";
  }
  if (time_inputs.empty() && field_file.empty()) return "a field (or --time FIELDS...) is required";
  if (out.empty()) return "--out: give the maps file to write (.exr)";
  // Checked before fitting: a wrong name must not cost the fit.
  if (out.extension() != ".exr") {
    return "--out: the maps are an OpenEXR file (named channels): give a path ending in .exr, got "
           "\"" +
           out.string() + "\"";
  }
  if (std::string problem = method_problem(method); !problem.empty()) return problem;
  if (materials != "basis" && materials != "per-pixel") {
    return "--materials: expected basis or per-pixel, got \"" + materials + "\"";
  }
  return {};
}

std::string FitJobOptions::to_json() const {
  nlohmann::json j;
  j["field"] = field_file.string();
  for (const fs::path& t : time_inputs) j["time"].push_back(t.string());
  j["phong"] = phong;
  j["dim_samples"] = dim_samples;
  j["method"] = method;
  j["materials"] = materials;
  j["memory_bytes"] = memory.given_bytes();
  return j.dump();
}

namespace {

void check(const FitJobOptions& options) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("fit: " + problem);
  }
  if (!options.field_file.empty()) refuse_output_over_input(options.out, options.field_file);
}

// The time-step fields: files as given, or the field_t*.exr (else *.exr) files of a directory.
std::vector<fs::path> expand_time_inputs(const std::vector<fs::path>& inputs) {
  std::vector<fs::path> files;
  for (const fs::path& in : inputs) {
    if (!fs::is_directory(in)) {
      files.push_back(in);
      continue;
    }
    std::vector<fs::path> found, any;
    for (const auto& entry : fs::directory_iterator(in)) {
      if (entry.path().extension() != ".exr") continue;
      any.push_back(entry.path());
      if (entry.path().filename().string().rfind("field_t", 0) == 0) found.push_back(entry.path());
    }
    if (found.empty()) found = any;
    if (found.empty()) throw InputError(in.string() + ": expected field .exr files, found none");
    std::sort(found.begin(), found.end());
    files.insert(files.end(), found.begin(), found.end());
  }
  return files;
}

// The fields' own measured noise when one carries it (a capture's dark frames and bracket: the same
// camera for every step of a time series); else the noise of their data (an imported set): from
// the residuals of a robust Lambertian fit (relight/fit/noise_from_data.h) over about 8k of the
// object's pixels (capture/object_sample.h: the same pixels however the frame is cropped), pooled
// over the fields (the steps of a time series: one camera, one exposure; a dark step alone may
// hold too few lit pixels), then scaled or flattened as held-out lights say
// (relight/fit/noise_choice.h); estimated on rank 0 and shared, so that whole, banded and MPI fits
// weigh alike; else NoiseModel's defaults (the simulated 12-bit camera near mid exposure). Said in
// fit.noise_source.
constexpr long kNoiseSamplePixels = 8192;
constexpr std::size_t kNoiseScanBytes = std::size_t(64) << 20;

void choose_noise(const std::vector<capture::FieldStream*>& fields, relight::FitOptions& fit) {
  const auto measured = std::find_if(fields.begin(), fields.end(),
                                     [](const auto* f) { return f->header().noise.measured; });
  fit.use_noise_of((measured != fields.end() ? *measured : fields.front())->header());
  if (measured != fields.end()) return;
  const Ranks& ranks = Ranks::world();
  // Estimated (1), the estimate's a, b, samples and pixels; the chosen candidate, its a, b, error.
  std::vector<double> found(9, 0.0);
  if (ranks.root()) {
    const capture::ReflectanceField sample =
        capture::object_sample(fields, kNoiseSamplePixels, kNoiseScanBytes);
    if (sample.height() > 0) {
      if (const auto noise = relight::noise_from_data(sample, fit.normals)) {
        const relight::NoiseChoice choice =
            relight::choose_noise_by_held_out_lights(sample, fit, noise->model);
        found = {1,
                 noise->model.a,
                 noise->model.b,
                 double(noise->samples),
                 double(noise->pixels),
                 double(choice.chosen),
                 choice.best().model.a,
                 choice.best().model.b,
                 choice.best().held_out_error};
      }
    }
  }
  ranks.broadcast(found);
  if (found[0] == 0) {
    fit.noise_source += "; too few lit pixels to estimate it from the data";
    return;
  }
  relight::DataNoise estimate;
  estimate.model = {found[1], found[2]};
  estimate.samples = long(found[3]);
  estimate.pixels = int(found[4]);
  fit.normals.noise = {found[6], found[7]};
  fit.noise_source =
      estimate.describe() + "; assumed: " + relight::describe_noise_choice(int(found[5]), found[8]);
}

// Pixels of `rows` whose flags (channel `flags`) say they hold no signal (relight::kNoSignal).
long pixels_without_signal(const Image& rows, int flags) {
  long count = 0;
  for (size_t i = 0; i < rows.num_pixels(); ++i) {
    count +=
        (int(rows.pixels[i * size_t(rows.channels) + size_t(flags)]) & relight::kNoSignal) != 0;
  }
  return count;
}

}  // namespace

FitJobSummary fit(const FitJobOptions& options, const ProgressFn& progress,
                  const NoiseNoticeFn& noise_notice) {
  check(options);
  if (!options.time_inputs.empty()) throw InputError("fit: --time fields: use fit_over_time");
  capture::FieldStream stream(options.field_file);
  const capture::ReflectanceField& field = stream.header();
  relight::FitOptions fit;
  fit.fit_phong = options.phong;
  fit.readmit_dim_samples = options.dim_samples;
  fit.materials = options.materials == "per-pixel" ? relight::FitMaterials::kPerPixel
                                                   : relight::FitMaterials::kBasis;
  fit.normals.method = normal_method(options.method);
  // The noise model weights every residual and sets the shadow threshold (choose_noise).
  const auto noise_start = Clock::now();
  choose_noise({&stream}, fit);
  const double noise_s = seconds_since(noise_start);
  if (noise_notice) noise_notice(fit.noise_source, fit.normals.noise);
  if (const std::string error = fit.validate(); !error.empty()) {
    throw InputError(options.field_file.string() + ": noise: " + error);
  }
  const Ranks& ranks = Ranks::world();
  int rows = band_rows_for_ranks(stream.band_rows(options.memory), field.height(),
                                 stream.row_alignment(), ranks.size());
  auto start = Clock::now();
  const ExrAttributes attributes = {{kOptionsAttribute, options.to_json()}};
  relight::BandFit result;
  relight::BandFitTimes times;
  if (rows < field.height() || ranks.size() > 1) {  // Under MPI, only rank 0 writes.
    relight::BandCheckpoints checkpoints(options.out,
                                         input_identity(options.field_file, options.to_json()));
    // Rank 0 decides (and may clear an earlier run's checkpoints); the others follow.
    rows = checkpoints.agreed_rows(rows, ranks.split());
    result = relight::fit_in_bands(stream, rows, fit, checkpoints, ranks.split(), options.out,
                                   attributes, progress, times);
    ranks.barrier();  // Rank 0 has written the maps from every rank's checkpoints.
    if (ranks.root()) checkpoints.remove();
  } else {
    capture::ReflectanceField whole;
    stream.read_rows(0, field.height(), whole);
    start = Clock::now();
    report(progress, "normals", 0, 1, "photometric stereo");
    const relight::NormalMap normals = relight::estimate_normals(whole, fit.normals);
    const double normals_s = seconds_since(start);
    report(progress, "normals", 1, 1);
    fit.progress = progress;
    const relight::ModelMaps maps = relight::fit_models(whole, normals, fit);
    const auto writing_start = Clock::now();
    relight::write_model_maps(options.out, maps, attributes);
    result = {maps.summary, maps.materials};
    result.summary.times.normals = normals_s;
    result.summary.times.writing = seconds_since(writing_start);
  }
  result.summary.times.noise = noise_s;
  FitJobSummary summary{result.summary,
                        result.materials,
                        field.width(),
                        field.height(),
                        fit.noise_source,
                        fit.normals.noise,
                        seconds_since(start) - times.read_seconds,
                        rows};
  summary.resumed_rows = times.resumed_rows;
  summary.ranks = ranks.size();
  return summary;
}

TemporalFitJobSummary fit_over_time(const FitJobOptions& options, const ProgressFn& progress,
                                    const NoiseNoticeFn& noise_notice) {
  check(options);
  if (options.time_inputs.empty()) throw InputError("fit: give the time-step fields (--time)");
  const std::vector<fs::path> files = expand_time_inputs(options.time_inputs);
  for (const fs::path& file : files) refuse_output_over_input(options.out, file);
  // Every step opened (its header read), sorted by time.
  std::vector<std::unique_ptr<capture::FieldStream>> steps;
  std::vector<const capture::ReflectanceField*> headers;
  headers.reserve(files.size());
  for (const fs::path& f : files) {
    headers.push_back(&steps.emplace_back(std::make_unique<capture::FieldStream>(f))->header());
  }
  if (files.size() < 2) {
    throw InputError(files.front().string() +
                     ": --time: expected the fields of at least two time steps, got one (a single "
                     "step is fitted by 'lightstage fit FIELD')");
  }
  relight::TemporalFitOptions fit;
  fit.brdf.normals.method = normal_method(options.method);
  fit.brdf.readmit_dim_samples = options.dim_samples;
  headers = relight::steps_by_time(headers);
  // The noise as plain fit's: measured by a step, else estimated from every step's data.
  std::vector<capture::FieldStream*> streams;
  streams.reserve(steps.size());
  for (const auto& step : steps) streams.push_back(step.get());
  choose_noise(streams, fit.brdf);
  std::sort(steps.begin(), steps.end(), [&](const auto& a, const auto& b) {
    return std::find(headers.begin(), headers.end(), &a->header()) <
           std::find(headers.begin(), headers.end(), &b->header());
  });
  if (const std::string error = fit.validate(); !error.empty()) {
    throw InputError(files.front().string() + ": noise: " + error);
  }
  if (noise_notice) noise_notice(fit.brdf.noise_source, fit.brdf.normals.noise);
  const capture::FieldStream& first = *steps.front();
  const int width = first.width(), height = first.height();
  // The whole series in memory when its fields and fits take at most the budget (by default half
  // of what is available); else bands of rows within it.
  const std::size_t budget = options.memory.bytes();
  const std::size_t row_bytes =
      relight::time_band_row_bytes(first, int(steps.size()), fit.normal_source);
  const std::size_t whole_bytes =
      std::size_t(height) * (row_bytes + steps.size() * capture::ReflectanceField::bytes_for(
                                                            width, 1, first.header().num_lights()));
  const Ranks& ranks = Ranks::world();
  const int alignment = first.row_alignment();
  int rows = band_rows_for_ranks(
      whole_bytes <= budget ? height : rows_within(budget, row_bytes, height, alignment), height,
      alignment, ranks.size());
  const auto start = Clock::now();
  const ExrAttributes attributes = {{kOptionsAttribute, options.to_json()}};
  TemporalFitJobSummary summary;
  if (rows < height || ranks.size() > 1) {
    nlohmann::json identity = nlohmann::json::array();
    for (const fs::path& f : files) identity.push_back(input_identity(f, options.to_json()));
    const CheckpointDir checkpoints(options.out, identity.dump());
    // Rank 0 decides (and may clear an earlier run's checkpoints); the others follow.
    rows = agreed_band_rows(checkpoints, rows, ranks.split());
    const relight::TimeBandFit result = relight::fit_over_time_in_bands(
        steps, rows, fit, checkpoints, ranks.split(), options.out, attributes, progress);
    ranks.barrier();  // Rank 0 has written the maps from every rank's checkpoints.
    if (ranks.root()) checkpoints.remove();
    summary.fit = result.summary;
    summary.resumed_rows = result.resumed_rows;
  } else {
    std::vector<capture::ReflectanceField> fields;
    for (const auto& step : steps) {
      capture::ReflectanceField& field = fields.emplace_back();
      step->read_rows(0, height, field);
      report(progress, "read fields", long(fields.size()), long(steps.size()),
             fs::path(field.source).filename());
    }
    fit.progress = progress;
    const relight::TemporalMaps maps = relight::fit_temporal(fields, fit);
    relight::write_temporal_maps(options.out, maps, attributes);
    summary.fit = maps.summary;
  }
  summary.width = width;
  summary.height = height;
  for (const auto& step : steps) summary.step_times_s.push_back(step->header().scene_time_s);
  summary.noise_source = fit.brdf.noise_source;
  summary.seconds = seconds_since(start);
  summary.band_rows = rows;
  summary.ranks = ranks.size();
  return summary;
}

std::string NormalsJobOptions::validate() const {
  if (field_file.empty()) return "a field is required";
  if (out.extension() != ".exr") {
    return "--out: the normals are an OpenEXR file: give a path ending in .exr, got \"" +
           out.string() + "\"";
  }
  if (std::string problem = method_problem(method); !problem.empty()) return problem;
  return {};
}

const std::vector<std::string>& normals_channel_names() {
  static const std::vector<std::string> names = {"normal.x", "normal.y", "normal.z",   "albedo.r",
                                                 "albedo.g", "albedo.b", "confidence", "flags"};
  return names;
}

NormalsJobSummary estimate_normals(const NormalsJobOptions& options, const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("normals: " + problem);
  }
  refuse_output_over_input(options.out, options.field_file);
  capture::FieldStream stream(options.field_file);
  const capture::ReflectanceField& header = stream.header();
  relight::FitOptions fit;
  choose_noise({&stream}, fit);
  relight::NormalOptions normal_options = fit.normals;
  normal_options.method = normal_method(options.method);
  if (const std::string error = normal_options.validate(); !error.empty()) {
    throw InputError(options.field_file.string() + ": noise: " + error);
  }
  NormalsJobSummary summary;
  summary.width = header.width(), summary.height = header.height();
  summary.noise_source = fit.noise_source;
  summary.band_rows =
      stream.band_rows(MemoryBudget(options.memory.bytes_or(MemoryBudget::kNormalsBandBytes)));
  const std::vector<std::string>& names = normals_channel_names();
  const nlohmann::json noise = {{"read_variance", normal_options.noise.a},
                                {"shot_variance_per_unit", normal_options.noise.b},
                                {"source", fit.noise_source}};
  const nlohmann::json recorded = {{"field", options.field_file.string()},
                                   {"method", options.method}};
  // The file and its previews, on rank 0 under MPI.
  std::optional<ImageRowWriter> file;
  std::vector<std::unique_ptr<PreviewRowWriter>> previews;
  if (Ranks::world().root()) {
    file.emplace(options.out, header.width(), header.height(), int(names.size()), names,
                 ExrAttributes{{kOptionsAttribute, recorded.dump()},
                               {"lightstage:fit_noise", noise.dump()}});
  }
  // Previews beside it, as the fit's: STEM.normal.png (0.5 + 0.5 n), .albedo.png, .confidence.png.
  const auto identity = [](float v) { return v; };
  for (auto [name, first, channels, transform] :
       {std::tuple{"normal", 0, 3,
                   std::function<float(float)>([](float v) { return 0.5f + 0.5f * v; })},
        std::tuple{"albedo", 3, 3, std::function<float(float)>(identity)},
        std::tuple{"confidence", 6, 1, std::function<float(float)>(identity)}}) {
    if (!file) break;
    previews.push_back(
        std::make_unique<PreviewRowWriter>(options.out, name, header.width(), header.height(),
                                           channels, channel_values(first, channels, transform)));
  }
  const auto start = Clock::now();
  double read_seconds = 0;
  capture::ReflectanceField band;
  // Band [y0, y1)'s normals, albedo, confidence and flags, as the file holds them.
  const auto estimate = [&](int y0, int y1) {
    const auto read_start = Clock::now();
    stream.read_rows(y0, y1, band);
    read_seconds += seconds_since(read_start);
    const relight::NormalMap normals = relight::estimate_normals(band, normal_options);
    Image rows(band.width(), band.height(), int(names.size()));
    for (size_t i = 0; i < rows.num_pixels(); ++i) {
      float* out = &rows.pixels[i * names.size()];
      std::copy_n(&normals.normal.pixels[i * 3], 3, out);
      std::copy_n(&normals.albedo.pixels[i * 3], 3, out + 3);
      out[6] = normals.confidence.pixels[i];
      out[7] = normals.flags.pixels[i];
    }
    return std::pair{rows, normals.flagged_pixels};
  };
  const auto write = [&](const Image& rows, long flagged, int y1) {
    summary.flagged_pixels += flagged;
    summary.empty_pixels += pixels_without_signal(rows, 7);
    file->write_rows(rows);
    for (auto& preview : previews) preview->write_rows(rows);
    report(progress, "normals (rows)", y1, header.height());
  };
  const Ranks& ranks = Ranks::world();
  const int height = header.height();
  summary.ranks = ranks.size();
  if (ranks.size() == 1) {
    for (int y0 = 0; y0 < height; y0 += summary.band_rows) {
      const int y1 = std::min(height, y0 + summary.band_rows);
      const auto [rows, flagged] = estimate(y0, y1);
      write(rows, flagged, y1);
    }
  } else {
    // Under MPI each rank estimates its bands (round robin) into records beside the output;
    // rank 0 writes the file from them in order.
    summary.band_rows =
        band_rows_for_ranks(summary.band_rows, height, stream.row_alignment(), ranks.size());
    const CheckpointDir checkpoints(options.out,
                                    input_identity(options.field_file, recorded.dump()));
    summary.band_rows = agreed_band_rows(checkpoints, summary.band_rows, ranks.split());
    constexpr const char* kMagic = "lightstage normals band 1";
    const auto record = [&](int y0) {
      return checkpoints.dir() / ("normals_" + std::to_string(y0) + ".band");
    };
    for (int b = ranks.rank(), y0; (y0 = b * summary.band_rows) < height; b += ranks.size()) {
      const auto [rows, flagged] = estimate(y0, std::min(height, y0 + summary.band_rows));
      write_record(record(y0), kMagic, {{"flagged", flagged}},
                   {{rows.pixels.data(), rows.pixels.size() * sizeof(float)}});
    }
    ranks.barrier();  // Every band is in its record.
    if (!ranks.root()) return summary;
    for (int y0 = 0; y0 < height; y0 += summary.band_rows) {
      const int y1 = std::min(height, y0 + summary.band_rows);
      Image rows(header.width(), y1 - y0, int(names.size()));
      long flagged = 0;
      if (!read_record(record(y0), kMagic, [&](const nlohmann::json& info) {
            flagged = info.at("flagged").get<long>();
            return std::optional<std::vector<RecordTarget>>{
                {{rows.pixels.data(), rows.pixels.size() * sizeof(float)}}};
          })) {
        throw InputError(record(y0).string() +
                         ": a band's normals are missing (did its rank fail?)");
      }
      write(rows, flagged, y1);
    }
    checkpoints.remove();
  }
  std::vector<ImageRowWriter*> files = {&*file};
  for (auto& preview : previews) files.push_back(&preview->file());
  commit_together(files);
  summary.seconds = seconds_since(start) - read_seconds;
  return summary;
}

}  // namespace ls::jobs
