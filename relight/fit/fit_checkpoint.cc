#include "relight/fit/fit_checkpoint.h"

#include <array>
#include <nlohmann/json.hpp>
#include <optional>
#include <utility>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/image.h"

namespace ls::relight {

namespace fs = std::filesystem;

namespace {

constexpr const char* kBandMagic = "lightstage fit band 1";

// A band file's parts: the normal map's images (channels prefixed: the maps have an albedo and a
// normal of their own), then the maps, with their channel names.
struct Part {
  const char* prefix;
  int channels;
};
constexpr std::array<Part, 5> kParts = {{{"ps.normal", 3},
                                         {"ps.albedo", 3},
                                         {"ps.confidence", 1},
                                         {"ps.flags", 1},
                                         {nullptr, relight::kMapChannelCount}}};

// The band file's images in kParts order (Map: NormalMap or const NormalMap; Maps likewise).
template <class Map, class Maps>
std::array<decltype(&std::declval<Map&>().normal), 5> images_of(Map& n, Maps& maps) {
  return {&n.normal, &n.albedo, &n.confidence, &n.flags, &maps.maps};
}

const std::vector<std::string>& band_channel_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const Part& part : kParts) {
      if (!part.prefix) continue;
      static const char* const kXyz[] = {".x", ".y", ".z"};
      static const char* const kRgb[] = {".r", ".g", ".b"};
      const std::string p = part.prefix;
      for (int c = 0; c < part.channels; ++c) {
        out.push_back(part.channels == 1 ? p : p + (p == "ps.normal" ? kXyz[c] : kRgb[c]));
      }
    }
    const std::vector<std::string>& maps = relight::model_map_channel_names();
    out.insert(out.end(), maps.begin(), maps.end());
    return out;
  }();
  return names;
}

// Channels [from_first, from_first + count) of every pixel of `from` into [to_first, ...) of `to`.
void copy_channels(const Image& from, int from_first, Image& to, int to_first, int count) {
  for (size_t i = 0; i < from.num_pixels(); ++i) {
    const float* src = &from.pixels[i * size_t(from.channels) + size_t(from_first)];
    std::copy(src, src + count, &to.pixels[i * size_t(to.channels) + size_t(to_first)]);
  }
}

nlohmann::json summary_json(const relight::FitSummary& s) {
  return {{"pixels", s.pixels},
          {"fitted", s.fitted},
          {"flagged", s.flagged},
          {"empty", s.empty},
          {"per_model", s.per_model},
          {"discarded_nonfinite_fits", s.discarded_nonfinite_fits},
          {"discarded_implausible_lobes", s.discarded_implausible_lobes},
          {"not_converged", s.not_converged},
          {"material_pixels", s.material_pixels}};
}

relight::FitSummary summary_from(const nlohmann::json& j) {
  relight::FitSummary s;
  s.pixels = j.at("pixels").get<int>();
  s.fitted = j.at("fitted").get<int>();
  s.flagged = j.at("flagged").get<int>();
  s.empty = j.value("empty", 0);  // Checkpoints from before kNoSignal have none.
  for (size_t k = 0; k < std::size(s.per_model); ++k) {
    s.per_model[k] = j.at("per_model").at(k).get<int>();
  }
  s.discarded_nonfinite_fits = j.at("discarded_nonfinite_fits").get<int>();
  s.discarded_implausible_lobes = j.at("discarded_implausible_lobes").get<int>();
  s.not_converged = j.at("not_converged").get<int>();
  s.material_pixels = j.at("material_pixels").get<int>();
  return s;
}

}  // namespace

BandCheckpoints::BandCheckpoints(const fs::path& out, std::string identity)
    : dir_(out, std::move(identity)) {}

fs::path BandCheckpoints::file(int y0, FitStage stage) const {
  return dir_.dir() /
         ((stage == FitStage::kPerPixel ? "rows_" : "materials_") + std::to_string(y0) + ".band");
}

bool BandCheckpoints::load(int y0, const std::vector<Eigen::Vector3f>& led_dirs,
                           relight::NormalMap& normals, relight::ModelMaps& maps,
                           FitStage stage) const {
  std::vector<std::string> names = band_channel_names();
  const int shadow_words = relight::FitShadows::words_for(int(led_dirs.size()));
  for (int w = 0; w < shadow_words; ++w) names.push_back("shadow." + std::to_string(w));
  Image image;
  const bool read = read_record(
      file(y0, stage), kBandMagic,
      [&](const nlohmann::json& info) -> std::optional<std::vector<RecordTarget>> {
        if (info.at("channels").get<std::vector<std::string>>() != names) return std::nullopt;
        image = Image(info.at("width").get<int>(), info.at("height").get<int>(), int(names.size()));
        maps.summary = summary_from(info.at("summary"));
        normals.flagged_pixels = info.at("normals_flagged").get<int>();
        const std::vector<int> material_pixels = info.at("material_pixels").get<std::vector<int>>();
        maps.materials.assign(material_pixels.size(), {});
        for (size_t k = 0; k < material_pixels.size(); ++k) {
          maps.materials[k].pixels = material_pixels[k];
        }
        return {{{image.pixels.data(), image.pixels.size() * sizeof(float)}}};
      });
  if (!read) return false;
  int first = 0;
  for (size_t k = 0; k < kParts.size(); ++k) {
    Image& part = *images_of(normals, maps)[k];
    part = Image(image.width, image.height, kParts[k].channels);
    copy_channels(image, first, part, 0, kParts[k].channels);
    first += kParts[k].channels;
  }
  maps.maps.channel_names = relight::model_map_channel_names();
  maps.shadows = relight::FitShadows::all_lit(led_dirs, image.width, image.height);
  copy_channels(image, first, maps.shadows.words, 0, shadow_words);
  return true;
}

void BandCheckpoints::save(int y0, const relight::NormalMap& normals,
                           const relight::ModelMaps& maps, FitStage stage) const {
  const Image& shadows = maps.shadows.words;
  Image band(maps.maps.width, maps.maps.height,
             int(band_channel_names().size()) + shadows.channels);
  std::vector<std::string> names = band_channel_names();
  names.insert(names.end(), shadows.channel_names.begin(), shadows.channel_names.end());
  int first = 0;
  for (size_t k = 0; k < kParts.size(); ++k) {
    copy_channels(*images_of(normals, maps)[k], 0, band, first, kParts[k].channels);
    first += kParts[k].channels;
  }
  if (!maps.shadows.empty()) copy_channels(shadows, 0, band, first, shadows.channels);
  std::vector<int> material_pixels;
  for (const relight::Material& m : maps.materials) material_pixels.push_back(m.pixels);
  const nlohmann::json info = {{"summary", summary_json(maps.summary)},
                               {"normals_flagged", normals.flagged_pixels},
                               {"material_pixels", material_pixels},
                               {"width", band.width},
                               {"height", band.height},
                               {"channels", names}};
  // A record, not an EXR: read up to four times a band on rank 0 (OpenEXR's reader took 0.7 s a
  // pass at 1024²).
  write_record(file(y0, stage), kBandMagic, info,
               {{band.pixels.data(), band.pixels.size() * sizeof(float)}});
}

}  // namespace ls::relight
