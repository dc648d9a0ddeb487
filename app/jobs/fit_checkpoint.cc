#include "app/jobs/fit_checkpoint.h"

#include <array>
#include <nlohmann/json.hpp>
#include <tuple>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/exr_channels.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

constexpr const char* kBandAttribute = "lightstage:fit_band";

// The normal map's channels, prefixed (the maps have an albedo and a normal of their own), then
// the maps'.
const std::vector<std::string>& band_channel_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out = {"ps.normal.x", "ps.normal.y", "ps.normal.z",   "ps.albedo.r",
                                    "ps.albedo.g", "ps.albedo.b", "ps.confidence", "ps.flags"};
    const std::vector<std::string>& maps = relight::model_map_channel_names();
    out.insert(out.end(), maps.begin(), maps.end());
    return out;
  }();
  return names;
}

// The normal map's images with their first band channel and channel count (Map: NormalMap or
// const NormalMap).
template <class Map>
auto normal_parts(Map& n) {
  using Part = std::tuple<decltype(&n.normal), int, int>;
  return std::array<Part, 4>{Part{&n.normal, 0, 3}, Part{&n.albedo, 3, 3},
                             Part{&n.confidence, 6, 1}, Part{&n.flags, 7, 1}};
}
constexpr int kMapsFirst = 8;  // The band channel of the maps' first.

nlohmann::json summary_json(const relight::FitSummary& s) {
  return {{"pixels", s.pixels},
          {"fitted", s.fitted},
          {"flagged", s.flagged},
          {"per_model", s.per_model},
          {"discarded_nonfinite_fits", s.discarded_nonfinite_fits},
          {"discarded_implausible_lobes", s.discarded_implausible_lobes},
          {"not_converged", s.not_converged}};
}

relight::FitSummary summary_from(const nlohmann::json& j) {
  relight::FitSummary s;
  s.pixels = j.at("pixels").get<int>();
  s.fitted = j.at("fitted").get<int>();
  s.flagged = j.at("flagged").get<int>();
  for (int k = 0; k < 5; ++k) s.per_model[k] = j.at("per_model").at(size_t(k)).get<int>();
  s.discarded_nonfinite_fits = j.at("discarded_nonfinite_fits").get<int>();
  s.discarded_implausible_lobes = j.at("discarded_implausible_lobes").get<int>();
  s.not_converged = j.at("not_converged").get<int>();
  return s;
}

}  // namespace

std::string fit_identity(const fs::path& field_file, const std::string& options_json, int rows) {
  std::error_code error;
  const auto size = fs::file_size(field_file, error);
  const auto time = fs::last_write_time(field_file, error).time_since_epoch().count();
  return nlohmann::json{{"field", fs::absolute(field_file).string()},
                        {"bytes", error ? 0 : size},
                        {"time", error ? 0 : time},
                        {"options", options_json},
                        {"rows", rows}}
      .dump();
}

BandCheckpoints::BandCheckpoints(const fs::path& out, std::string identity)
    : dir_(out.string() + ".partial"), identity_(std::move(identity)) {}

fs::path BandCheckpoints::file(int y0) const {
  return dir_ / ("rows_" + std::to_string(y0) + ".exr");
}

bool BandCheckpoints::load(int y0, relight::NormalMap& normals, relight::ModelMaps& maps) const {
  if (!fs::exists(file(y0))) return false;
  NamedChannelFile band;
  nlohmann::json info;
  try {
    band = read_named_channels(file(y0), band_channel_names(), "fit checkpoint",
                               "'lightstage fit --memory'", /*exact=*/true);
    const std::string* text = band.attribute(kBandAttribute);
    if (!text) return false;
    info = nlohmann::json::parse(*text);
    if (info.at("identity").get<std::string>() != identity_) return false;
    maps.summary = summary_from(info.at("summary"));
    normals.flagged_pixels = info.at("normals_flagged").get<int>();
  } catch (const InputError&) {
    return false;
  } catch (const nlohmann::json::exception&) {
    return false;
  }
  const Image& image = band.image;
  for (auto [part, first, channels] : normal_parts(normals)) {
    *part = Image(image.width, image.height, channels);
    for (int c = 0; c < channels; ++c) {  // Their names without "ps.".
      part->channel_names.push_back(band_channel_names()[(size_t(first) + size_t(c))].substr(3));
    }
    for (size_t i = 0; i < image.num_pixels(); ++i) {
      for (int c = 0; c < channels; ++c) {
        part->pixels[i * size_t(channels) + size_t(c)] =
            image.pixels[i * image.channels + (size_t(first) + size_t(c))];
      }
    }
  }
  maps.maps = Image(image.width, image.height, relight::kMapChannelCount);
  maps.maps.channel_names = relight::model_map_channel_names();
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    for (int c = 0; c < relight::kMapChannelCount; ++c) {
      maps.maps.pixels[i * relight::kMapChannelCount + size_t(c)] =
          image.pixels[i * image.channels + (size_t(kMapsFirst) + size_t(c))];
    }
  }
  return true;
}

void BandCheckpoints::save(int y0, const relight::NormalMap& normals,
                           const relight::ModelMaps& maps) const {
  const Image& m = maps.maps;
  Image band(m.width, m.height, int(band_channel_names().size()));
  band.channel_names = band_channel_names();
  for (auto [part, first, channels] : normal_parts(normals)) {
    for (size_t i = 0; i < band.num_pixels(); ++i) {
      for (int c = 0; c < channels; ++c) {
        band.pixels[i * band.channels + (size_t(first) + size_t(c))] =
            part->pixels[i * size_t(channels) + size_t(c)];
      }
    }
  }
  for (size_t i = 0; i < band.num_pixels(); ++i) {
    for (int c = 0; c < m.channels; ++c) {
      band.pixels[i * band.channels + (size_t(kMapsFirst) + size_t(c))] =
          m.pixels[i * m.channels + size_t(c)];
    }
  }
  const nlohmann::json info = {{"identity", identity_},
                               {"summary", summary_json(maps.summary)},
                               {"normals_flagged", normals.flagged_pixels}};
  fs::create_directories(dir_);
  write_exr(file(y0), band, ExrPixelType::kFloat, {{kBandAttribute, info.dump()}});
}

void BandCheckpoints::remove() const {
  std::error_code ignored;
  fs::remove_all(dir_, ignored);
}

}  // namespace ls::jobs
