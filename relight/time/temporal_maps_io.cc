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

}  // namespace

TemporalMapsWriter::TemporalMapsWriter(const std::filesystem::path& path, int width, int height,
                                       const TemporalMaps& header, bool step_values,
                                       double max_rate, const ExrAttributes& attributes)
    : step_channels_(step_values ? int(header.step_times_s.size()) * kTemporalParamCount : 0) {
  nlohmann::json meta = {{"step_times_s", header.step_times_s},
                         {"read_variance", header.noise.a},
                         {"shot_variance_per_unit", header.noise.b},
                         {"noise_source", header.noise_source}};
  if (!header.curves.empty()) {
    nlohmann::json families = nlohmann::json::array();
    for (const TemporalCurves& family : header.curves) families.push_back(family.knots);
    meta["curve_families"] = families;
  }
  std::vector<std::string> names = temporal_channel_names();
  for (int i = 0; i < step_channels_ / kTemporalParamCount; ++i) {
    for (int p = 0; p < kTemporalParamCount; ++p) {
      names.push_back("step." + std::to_string(i) + "." + temporal_param_name(p));
    }
  }
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
  Image named(image.width, image.height, image.channels + step_channels_);
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    float* to = &named.pixels[i * size_t(named.channels)];
    std::copy_n(&image.pixels[i * size_t(image.channels)], image.channels, to);
    if (!steps.pixels.empty()) {
      std::copy_n(&steps.pixels[i * size_t(steps.channels)], steps.channels, to + image.channels);
    }
  }
  maps_->write_rows(named);
  for (auto& preview : previews_) preview->write_rows(image);
}

void TemporalMapsWriter::commit() {
  maps_->commit();
  for (auto& preview : previews_) preview->commit();
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

TemporalMaps read_temporal_map_rows(const std::filesystem::path& path, int y0, int y1) {
  const std::string name = path.string();
  const std::vector<std::string>& names = temporal_channel_names();
  // The degenerate pixels' per-step fits, when the file has them: step.I.<param>.
  std::vector<std::string> with_steps = names;
  const std::vector<std::string> in_file = exr_channel_names(path);
  const auto step_channels = std::count_if(in_file.begin(), in_file.end(),
                                           [](const auto& c) { return c.starts_with("step."); });
  for (int i = 0; i < int(step_channels) / kTemporalParamCount; ++i) {
    for (int p = 0; p < kTemporalParamCount; ++p) {
      with_steps.push_back("step." + std::to_string(i) + "." + temporal_param_name(p));
    }
  }
  // 'curve', 'curve_seen' and the step channels are optional: files before curve families read as
  // one family whose pixels saw all of it (curve_seen 1).
  NamedChannelFile file = read_named_channels(path, with_steps, "temporal maps",
                                              "'lightstage fit --time'", /*exact=*/false,
                                              /*required=*/kTCurve, y0, y1);
  TemporalMaps out;
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
  const int width = file.image.width, height = file.image.height;
  if (step_channels > 0) {
    if (step_channels != long(out.step_times_s.size()) * kTemporalParamCount) {
      throw InputError(name + ": channels 'step.I.<param>': expected " +
                       std::to_string(out.step_times_s.size() * kTemporalParamCount) + " for the " +
                       std::to_string(out.step_times_s.size()) + " steps, got " +
                       std::to_string(step_channels));
    }
    out.step_values = Image(width, height, int(step_channels));
    out.step_values.channel_names.assign(with_steps.begin() + kTemporalChannelCount,
                                         with_steps.end());
    for (size_t i = 0; i < out.step_values.num_pixels(); ++i) {
      const float* from = &file.image.pixels[i * size_t(file.image.channels)];
      for (int c = 0; c < out.step_values.channels; ++c) {
        const float v = from[kTemporalChannelCount + c];
        if (!std::isfinite(v)) {
          throw InputError(name + ": channel '" + out.step_values.channel_names[size_t(c)] +
                           "': expected a finite value at (" + std::to_string(i % width) + ", " +
                           std::to_string(y0 + int(i / width)) + ")");
        }
        out.step_values.pixels[i * size_t(step_channels) + size_t(c)] = v;
      }
    }
  }
  out.maps = Image(width, height, kTemporalChannelCount);
  out.maps.channel_names = names;
  const bool has_seen = std::find(in_file.begin(), in_file.end(), "curve_seen") != in_file.end();
  for (size_t i = 0; i < out.maps.num_pixels(); ++i) {
    float* to = &out.maps.pixels[i * size_t(kTemporalChannelCount)];
    std::copy_n(&file.image.pixels[i * size_t(file.image.channels)], kTemporalChannelCount, to);
    if (!has_seen) to[kTCurveSeen] = 1;
  }
  TemporalSummary& summary = out.summary;
  summary.pixels = width * height;
  summary.curve_families = int(out.curves.size());
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < kTemporalChannelCount; ++c) {
        const float v = out.maps.at(x, y, c);
        if (!std::isfinite(v)) {
          throw InputError(name + ": channel '" + names[c] + "': expected a finite value at (" +
                           std::to_string(x) + ", " + std::to_string(y0 + y) + ")");
        }
      }
      const float model = out.maps.at(x, y, kTModel);
      if (!(model == std::floor(model) && model >= 0 && model < kTemporalModelCount)) {
        throw InputError(name + ": channel 'model': expected an integer in 0.." +
                         std::to_string(kTemporalModelCount - 1) + " at (" + std::to_string(x) +
                         ", " + std::to_string(y0 + y) + "), got " + std::to_string(model));
      }
      const float flags = out.maps.at(x, y, kTFlags);
      if (!(flags == std::floor(flags) && flags >= 0)) {
        throw InputError(name + ": channel 'flags': expected a non-negative integer at (" +
                         std::to_string(x) + ", " + std::to_string(y0 + y) + ")");
      }
      const float family = out.maps.at(x, y, kTCurve);
      if (model == float(TemporalModel::kCurve) &&
          !(family == std::floor(family) && family >= 0 && family < float(out.curves.size()))) {
        throw InputError(name + ": channel 'curve': a curve at (" + std::to_string(x) + ", " +
                         std::to_string(y0 + y) + ") of family " + std::to_string(family) +
                         " but " + std::to_string(out.curves.size()) + " families in attribute '" +
                         kTemporalAttribute + "'");
      }
      if (model == 0) {
        ++summary.flagged;
      } else {
        ++summary.fitted;
        ++summary.per_model[int(model)];
        summary.degenerate += (int(flags) & kTemporalDegenerate) != 0;
      }
    }
  }
  return out;
}

}  // namespace ls::relight
