// Temporal maps file I/O: one EXR with named channels and the step times, PNG previews beside it.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/exr_channels.h"
#include "relight/time/temporal_fit.h"

namespace ls::relight {
namespace {

constexpr const char* kTemporalAttribute = "lightstage:temporal";

// The channels of the per-step fits of `steps` steps: step.I.<param>.
std::vector<std::string> step_channel_names(int steps) {
  std::vector<std::string> names;
  for (int i = 0; i < steps; ++i) {
    for (int p = 0; p < kTemporalParamCount; ++p) {
      names.push_back("step." + std::to_string(i) + "." + temporal_param_name(p));
    }
  }
  return names;
}

}  // namespace

TemporalMapsWriter::TemporalMapsWriter(const std::filesystem::path& path, int width, int height,
                                       const TemporalMaps& header, bool step_values,
                                       double max_rate, const ExrAttributes& attributes)
    : step_channels_(step_values ? int(header.step_times_s.size()) * kTemporalParamCount : 0) {
  nlohmann::json meta = {{"step_times_s", header.step_times_s},
                         {"read_variance", header.noise.a},
                         {"shot_variance_per_unit", header.noise.b},
                         {"noise_source", header.noise_source},
                         {"modelled_steps", header.modelled_steps}};
  if (!header.curves.empty()) {
    nlohmann::json families = nlohmann::json::array();
    for (const TemporalCurves& family : header.curves) families.push_back(family.knots);
    meta["curve_families"] = families;
  }
  std::vector<std::string> names = temporal_channel_names();
  const std::vector<std::string> steps = step_channel_names(step_channels_ / kTemporalParamCount);
  names.insert(names.end(), steps.begin(), steps.end());
  ExrAttributes exr = attributes;
  exr.emplace_back(kTemporalAttribute, meta.dump());
  maps_ = std::make_unique<ImageRowWriter>(path, width, height, int(names.size()), names, exr);
  const double first = header.first_time_s();
  const double span = std::max(header.last_time_s() - first, 1e-9);
  const auto preview = [&](const std::string& name, int channel, int channels,
                           const std::function<float(float)>& transform) {
    previews_.push_back(std::make_unique<PreviewRowWriter>(
        path, name, width, height, channels, channel_values(channel, channels, transform)));
  };
  const auto identity = [](float v) { return v; };
  preview("model", kTModel, 1, [](float v) { return v / (kTemporalModelCount - 1); });
  preview("rate", kTRate, 1, [max_rate](float v) { return max_rate > 0 ? v / max_rate : 0.0; });
  preview("onset", kTOnset, 1, [first, span](float v) { return (v - first) / span; });
  preview("wet_albedo", kTWet, 3, identity);
  preview("dry_albedo", kTDry, 3, identity);
  preview("wet_ks", kTWet + int(kParamKs), 1, identity);
  preview("dry_ks", kTDry + int(kParamKs), 1, identity);
  preview("confidence", kTConfidence, 1, identity);
  preview("flags", kTFlags, 1, [](float v) { return v / 511; });  // Bits up to 256.
}

TemporalMapsWriter::~TemporalMapsWriter() = default;

void TemporalMapsWriter::write_rows(const TemporalMaps& band) {
  const Image& image = band.maps;
  const Image& steps = band.step_values;
  LS_CHECK(image.channels == kTemporalChannelCount &&
               image.pixels.size() == image.num_pixels() * kTemporalChannelCount,
           "temporal maps have " + std::to_string(image.channels) + " channels");
  LS_CHECK(steps.pixels.empty() || (steps.width == image.width && steps.height == image.height &&
                                    steps.channels == step_channels_),
           "temporal maps: step values do not fit the maps");
  write_rows_beside(*maps_, image, steps, step_channels_);
  write_preview_rows(previews_, image);
}

void TemporalMapsWriter::commit() {
  std::vector<ImageRowWriter*> files = {maps_.get()};
  for (auto& preview : previews_) files.push_back(&preview->file());
  commit_together(files);
}

double max_temporal_rate(const Image& maps) {
  double max_rate = 0;
  for (size_t i = 0; i < maps.num_pixels(); ++i) {
    max_rate = std::max(max_rate, double(maps.pixels[i * size_t(maps.channels) + kTRate]));
  }
  return max_rate;
}

void write_temporal_maps(const std::filesystem::path& path, const TemporalMaps& maps,
                         const ExrAttributes& attributes) {
  TemporalMapsWriter writer(path, maps.maps.width, maps.maps.height, maps,
                            !maps.step_values.pixels.empty(), max_temporal_rate(maps.maps),
                            attributes);
  writer.write_rows(maps);
  writer.commit();
}

TemporalMaps read_temporal_maps(const std::filesystem::path& path) {
  return read_temporal_map_rows(path, 0, -1);
}

namespace {

// The step times, noise model and curve families of attribute lightstage:temporal, into `out`.
void read_temporal_attribute(const NamedChannelFile& file, const std::string& name,
                             TemporalMaps& out) {
  const std::string* meta = file.attribute(kTemporalAttribute);
  if (!meta) {
    throw InputError(name + ": attribute '" + kTemporalAttribute + "': missing (step times)");
  }
  try {
    const nlohmann::json j = nlohmann::json::parse(*meta);
    out.step_times_s = j.at("step_times_s").get<std::vector<double>>();
    out.noise.a = j.at("read_variance").get<double>();
    out.noise.b = j.at("shot_variance_per_unit").get<double>();
    out.noise_source = j.value("noise_source", std::string());
    out.modelled_steps = j.value("modelled_steps", false);
    // "curves": one family (files before families); "curve_families": a list of them.
    std::vector<nlohmann::json> families;
    if (j.contains("curves")) families.push_back(j.at("curves"));
    if (j.contains("curve_families")) {
      families = j.at("curve_families").get<std::vector<nlohmann::json>>();
    }
    for (size_t f = 0; f < families.size(); ++f) {
      TemporalCurves& curves = out.curves.emplace_back();
      curves.knots = families[f].get<std::vector<std::vector<double>>>();
      bool valid = curves.knots.size() == size_t(kTemporalParamCount);
      for (const std::vector<double>& c : curves.knots) {
        valid = valid && c.size() >= 2 && c.size() == curves.knots[0].size() &&
                std::all_of(c.begin(), c.end(), [](double v) { return std::isfinite(v); });
      }
      if (!valid) {
        throw InputError(name + ": attribute '" + kTemporalAttribute + "': curve family " +
                         std::to_string(f) + ": expected " + std::to_string(kTemporalParamCount) +
                         " lists of the same number (at least 2) of finite knots");
      }
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(
        name + ": attribute '" + kTemporalAttribute +
        "': expected {step_times_s, read_variance, shot_variance_per_unit}: " + e.what());
  }
  if (out.step_times_s.empty() ||
      !std::is_sorted(out.step_times_s.begin(), out.step_times_s.end())) {
    throw InputError(name + ": attribute '" + kTemporalAttribute +
                     "': step_times_s: expected a non-empty increasing list");
  }
}

// The degenerate pixels' per-step fits: the file's channels after the maps', named `step_names`;
// `step_channels` (those named step.*) must be kTemporalParamCount per step.
Image read_step_values(const NamedChannelFile& file, const std::vector<std::string>& step_names,
                       long step_channels, size_t steps, const std::string& name, int y0) {
  const Image& all = file.image;
  if (step_channels != long(steps) * kTemporalParamCount) {
    throw InputError(name + ": channels 'step.I.<param>': expected " +
                     std::to_string(steps * kTemporalParamCount) + " for the " +
                     std::to_string(steps) + " steps, got " + std::to_string(step_channels));
  }
  Image out(all.width, all.height, int(step_channels));
  out.channel_names = step_names;
  for (size_t i = 0; i < out.num_pixels(); ++i) {
    const float* from = &all.pixels[i * size_t(all.channels)];
    for (int c = 0; c < out.channels; ++c) {
      const float v = from[kTemporalChannelCount + c];
      if (!std::isfinite(v)) {
        throw InputError(name + ": channel '" + out.channel_names[size_t(c)] +
                         "': expected a finite value at (" + std::to_string(i % all.width) + ", " +
                         std::to_string(y0 + int(i / all.width)) + ")");
      }
      out.pixels[i * size_t(step_channels) + size_t(c)] = v;
    }
  }
  return out;
}

// The maps' channels of the file; curve_seen 1 where the file has no such channel.
Image copy_temporal_maps(const NamedChannelFile& file, bool has_seen) {
  Image out(file.image.width, file.image.height, kTemporalChannelCount);
  out.channel_names = temporal_channel_names();
  for (size_t i = 0; i < out.num_pixels(); ++i) {
    float* to = &out.pixels[i * size_t(kTemporalChannelCount)];
    std::copy_n(&file.image.pixels[i * size_t(file.image.channels)], kTemporalChannelCount, to);
    if (!has_seen) to[kTCurveSeen] = 1;
  }
  return out;
}

// Checks that every pixel of `maps` holds a valid model, flags and curve family (of `families`),
// and counts them.
TemporalSummary check_temporal_maps(const Image& maps, size_t families, bool step_values,
                                    const std::string& name, int y0) {
  const std::vector<std::string>& names = temporal_channel_names();
  TemporalSummary summary;
  summary.pixels = maps.width * maps.height;
  summary.curve_families = int(families);
  for (int y = 0; y < maps.height; ++y) {
    for (int x = 0; x < maps.width; ++x) {
      for (int c = 0; c < kTemporalChannelCount; ++c) {
        const float v = maps.at(x, y, c);
        if (!std::isfinite(v)) {
          throw InputError(name + ": channel '" + names[c] + "': expected a finite value at (" +
                           std::to_string(x) + ", " + std::to_string(y0 + y) + ")");
        }
      }
      const float model = maps.at(x, y, kTModel);
      if (!(model == std::floor(model) && model >= 0 && model < kTemporalModelCount)) {
        throw InputError(name + ": channel 'model': expected an integer in 0.." +
                         std::to_string(kTemporalModelCount - 1) + " at (" + std::to_string(x) +
                         ", " + std::to_string(y0 + y) + "), got " + std::to_string(model));
      }
      const float flags = maps.at(x, y, kTFlags);
      if (!(flags == std::floor(flags) && flags >= 0)) {
        throw InputError(name + ": channel 'flags': expected a non-negative integer at (" +
                         std::to_string(x) + ", " + std::to_string(y0 + y) + ")");
      }
      const float family = maps.at(x, y, kTCurve);
      if (model == float(TemporalModel::kCurve) &&
          !(family == std::floor(family) && family >= 0 && family < float(families))) {
        throw InputError(name + ": channel 'curve': a curve at (" + std::to_string(x) + ", " +
                         std::to_string(y0 + y) + ") of family " + std::to_string(family) +
                         " but " + std::to_string(families) + " families in attribute '" +
                         kTemporalAttribute + "'");
      }
      if (model == float(TemporalModel::kSteps) && !step_values) {
        throw InputError(name + ": channel 'model': per-step fits (\"steps\") at (" +
                         std::to_string(x) + ", " + std::to_string(y0 + y) +
                         ") but no step.I.<param> channels to render them from");
      }
      if (model == 0) {
        ++summary.flagged;
        ++((int(flags) & kTemporalNoNormal) != 0 ? summary.no_normal : summary.no_usable_step);
      } else {
        ++summary.fitted;
        ++summary.per_model[int(model)];
        summary.degenerate += (int(flags) & kTemporalDegenerate) != 0;
      }
    }
  }
  return summary;
}

}  // namespace

TemporalMaps read_temporal_map_rows(const std::filesystem::path& path, int y0, int y1) {
  const std::string name = path.string();
  // The degenerate pixels' per-step fits, when the file has them: step.I.<param>.
  const std::vector<std::string> in_file = exr_channel_names(path);
  const auto step_channels = std::count_if(in_file.begin(), in_file.end(),
                                           [](const auto& c) { return c.starts_with("step."); });
  const std::vector<std::string> step_names =
      step_channel_names(int(step_channels) / kTemporalParamCount);
  std::vector<std::string> with_steps = temporal_channel_names();
  with_steps.insert(with_steps.end(), step_names.begin(), step_names.end());
  // 'curve', 'curve_seen' and the step channels are optional: files before curve families read as
  // one family whose pixels saw all of it (curve_seen 1).
  NamedChannelFile file = read_named_channels(path, with_steps, "temporal maps",
                                              "'lightstage fit --time'", /*exact=*/false,
                                              /*required=*/kTCurve, y0, y1);
  TemporalMaps out;
  read_temporal_attribute(file, name, out);
  if (step_channels > 0) {
    out.step_values =
        read_step_values(file, step_names, step_channels, out.step_times_s.size(), name, y0);
  }
  const bool has_seen = std::find(in_file.begin(), in_file.end(), "curve_seen") != in_file.end();
  out.maps = copy_temporal_maps(file, has_seen);
  out.summary = check_temporal_maps(out.maps, out.curves.size(), step_channels > 0, name, y0);
  return out;
}

}  // namespace ls::relight
