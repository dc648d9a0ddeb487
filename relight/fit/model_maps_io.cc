#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>

#include "lightstage/errors.h"
#include "lightstage/exr_channels.h"
#include "physics/brdf.h"
#include "relight/fit/fit.h"

// Model maps on disk (relight/fit/fit.h): one EXR of named channels, with the fit's noise model
// and the basis materials as attributes, and PNG previews beside it.
namespace ls::relight {
namespace {

using physics::brdf::kPi;
constexpr double kMaxSigma = 0.5 * kPi + 1e-6;  // Oren-Nayar's range, and rounding.
constexpr const char* kFitNoiseAttribute = "lightstage:fit_noise";
constexpr const char* kMaterialsAttribute = "lightstage:materials";
// The LEDs of ModelMaps::shadows: [[x, y, z], ...], unit, stage frame.
constexpr const char* kShadowLedsAttribute = "lightstage:shadow_leds";
// The flags channel holds bits up to 1024 (fit.h, normals.h); room for more, and always an int.
constexpr int kMaxFlags = 65535;

nlohmann::json to_json(const std::vector<Material>& materials) {
  nlohmann::json out = nlohmann::json::array();
  for (const Material& m : materials) {
    out.push_back({{"model", to_string(m.model)},
                   {"albedo", {m.albedo(0), m.albedo(1), m.albedo(2)}},
                   {"sigma", m.sigma},
                   {"ks", m.ks},
                   {"roughness", m.roughness},
                   {"pixels", m.pixels},
                   {"scene_material", m.scene_material}});
  }
  return out;
}

// An integer member of a material: a fraction, or a number no int holds, is refused rather than
// converted (the conversion is undefined behaviour).
int int_member(const nlohmann::json& material, const char* key, const std::string& at) {
  const nlohmann::json& value = material.at(key);
  if (!value.is_number_integer() || value.get<int64_t>() < std::numeric_limits<int>::min() ||
      value.get<int64_t>() > std::numeric_limits<int>::max()) {
    throw InputError(at + ": " + key + ": expected an integer, got " + value.dump());
  }
  return int(value.get<int64_t>());
}

// The materials attribute; InputErrors name the file, the attribute and the material.
std::vector<Material> materials_from(const std::string& text, const std::string& file) {
  std::vector<Material> out;
  const std::string where = file + ": attribute '" + kMaterialsAttribute + "'";
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where + ": not JSON: " + e.what());
  }
  if (!j.is_array()) throw InputError(where + ": expected an array of materials");
  for (size_t k = 0; k < j.size(); ++k) {
    const std::string at = where + ": material " + std::to_string(k + 1);
    Material m;
    try {
      const std::string model = j[k].at("model").get<std::string>();
      m.model = FitModel::kNone;
      for (const FitModel f :
           {FitModel::kLambert, FitModel::kOrenNayar, FitModel::kLambertTorranceSparrow}) {
        if (model == to_string(f)) m.model = f;
      }
      if (m.model == FitModel::kNone) throw InputError(at + ": unknown model '" + model + "'");
      for (int c = 0; c < 3; ++c) m.albedo(c) = j[k].at("albedo").at(size_t(c)).get<double>();
      m.sigma = j[k].at("sigma").get<double>();
      m.ks = j[k].at("ks").get<double>();
      m.roughness = j[k].at("roughness").get<double>();
      m.pixels = int_member(j[k], "pixels", at);
      // Maps written before scene materials: each basis material is its own.
      m.scene_material =
          j[k].contains("scene_material") ? int_member(j[k], "scene_material", at) : int(k) + 1;
      if (m.scene_material < 1 || m.scene_material > int(j.size())) {
        throw InputError(at + ": scene_material " + std::to_string(m.scene_material) +
                         " is not one of 1.." + std::to_string(j.size()));
      }
    } catch (const nlohmann::json::exception& e) {
      throw InputError(
          at + ": expected {model, albedo [r, g, b], sigma, ks, roughness, pixels}: " + e.what());
    }
    const bool ok = (m.albedo.array() >= 0).all() && m.sigma >= 0 && m.sigma <= kMaxSigma &&
                    m.ks >= 0 && m.roughness >= 0 && m.roughness <= 1 && m.pixels >= 0;
    if (!ok) throw InputError(at + ": parameters out of their bounds (relight/fit/fit.h)");
    out.push_back(m);
  }
  return out;
}

// STEM.materials.png: each pixel in its main material's colour (hues a golden angle apart), a
// per-pixel fit dark grey, no fit black.
Image material_preview(const Image& maps) {
  Image image(maps.width, maps.height, 3);
  for (size_t i = 0; i < maps.num_pixels(); ++i) {
    const float* m = &maps.pixels[i * maps.channels];
    const int material = int(m[kMapMaterial]);
    float rgb[3] = {0, 0, 0};
    if (material > 0) {
      const double hue = std::fmod(0.618033988749895 * (material - 1), 1.0) * 6;
      for (int c = 0; c < 3; ++c) {
        // A fully saturated hue: 1 within 1 of its centre, falling to 0 by 2.
        const double d = std::abs(std::fmod(hue - 2 * c + 6, 6.0) - 3);
        rgb[c] = float(std::clamp(d - 1, 0.0, 1.0) * 0.8 + 0.05);
      }
    } else if (m[kMapModel] != 0) {
      rgb[0] = rgb[1] = rgb[2] = 0.03f;
    }
    for (int c = 0; c < 3; ++c) image.pixels[i * 3 + c] = rgb[c];
  }
  return image;
}

nlohmann::json to_json(const std::vector<Eigen::Vector3f>& dirs) {
  nlohmann::json out = nlohmann::json::array();
  for (const Eigen::Vector3f& d : dirs) out.push_back({d.x(), d.y(), d.z()});
  return out;
}

std::vector<Eigen::Vector3f> shadow_leds_from(const std::string& text, const std::string& file) {
  const std::string where = file + ": attribute '" + kShadowLedsAttribute + "'";
  std::vector<Eigen::Vector3f> dirs;
  try {
    for (const nlohmann::json& d : nlohmann::json::parse(text)) {
      const Eigen::Vector3f dir(d.at(0).get<float>(), d.at(1).get<float>(), d.at(2).get<float>());
      if (d.size() != 3 || !(std::abs(dir.norm() - 1) < 1e-3f)) {
        throw InputError(where + ": LED " + std::to_string(dirs.size()) +
                         ": expected a unit direction [x, y, z]");
      }
      dirs.push_back(dir);
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where + ": expected [[x, y, z], ...]: " + e.what());
  }
  return dirs;
}

// Shadow channel w (FitShadows) holds kLedsPerWord levels: an integer below 2^kBitsPerWord.
void check_shadow_words(const Image& words, const std::string& file) {
  for (int y = 0; y < words.height; ++y) {
    for (int x = 0; x < words.width; ++x) {
      for (int w = 0; w < words.channels; ++w) {
        const float v = words.at(x, y, w);
        if (!(v == std::floor(v) && v >= 0 && v < float(1 << FitShadows::kBitsPerWord))) {
          char at[96];
          std::snprintf(at, sizeof at, " at (%d, %d), got %.9g", x, y, double(v));
          throw InputError(file + ": channel 'shadow." + std::to_string(w) +
                           "': expected an integer in 0.." +
                           std::to_string((1 << FitShadows::kBitsPerWord) - 1) + at);
        }
      }
    }
  }
}

}  // namespace

const std::vector<std::string>& model_map_channel_names() {
  static const std::vector<std::string> names = {
      "normal.x", "normal.y", "normal.z",        "albedo.r",  "albedo.g",        "albedo.b",
      "sigma",    "ks",       "roughness",       "model",     "confidence",      "residual",
      "flags",    "material", "material.weight", "material2", "material2.weight"};
  return names;
}

ModelMapsWriter::ModelMapsWriter(const std::filesystem::path& path, int width, int height,
                                 const ModelMaps& header, const ExrAttributes& attributes,
                                 Files files) {
  const nlohmann::json noise = {{"read_variance", header.noise.a},
                                {"shot_variance_per_unit", header.noise.b},
                                {"source", header.noise_source}};
  const Image& shadows = header.shadows.words;
  shadows_ = !header.shadows.empty();
  std::vector<std::string> names = model_map_channel_names();
  names.insert(names.end(), shadows.channel_names.begin(), shadows.channel_names.end());
  ExrAttributes exr = attributes;
  if (shadows_) {
    exr.emplace_back(kShadowLedsAttribute, to_json(header.shadows.led_dirs_in_stage).dump());
  }
  exr.emplace_back(kFitNoiseAttribute, noise.dump());
  if (!header.materials.empty()) {
    exr.emplace_back(kMaterialsAttribute, to_json(header.materials).dump());
  }
  if (files != Files::kPreviews) {
    maps_ = std::make_unique<ImageRowWriter>(path, width, height, int(names.size()), names, exr);
  }
  if (files == Files::kMaps) return;
  const auto preview = [&](const std::string& name, int channels, PreviewRowWriter::Values values) {
    previews_.push_back(
        std::make_unique<PreviewRowWriter>(path, name, width, height, channels, std::move(values)));
  };
  const auto channel = [&](const std::string& name, int first, int channels,
                           const std::function<float(float)>& transform) {
    preview(name, channels, channel_values(first, channels, transform));
  };
  const auto identity = [](float v) { return v; };
  channel("normal", kMapNormalX, 3, [](float v) { return 0.5f + 0.5f * v; });
  channel("albedo", kMapAlbedoR, 3, identity);
  channel("sigma", kMapSigma, 1, [](float v) { return float(v / (0.5 * kPi)); });
  channel("ks", kMapKs, 1, identity);
  channel("roughness", kMapRoughness, 1, identity);
  channel("model", kMapModel, 1, [](float v) { return v / 4; });
  channel("confidence", kMapConfidence, 1, identity);
  channel("residual", kMapResidual, 1,
          [](float v) { return std::log10(1 + std::max(v, 0.f)) / 2; });
  channel("flags", kMapFlags, 1, [](float v) { return v / 2047; });  // Bits up to 1024.
  if (!header.materials.empty()) preview("materials", 3, material_preview);
}

ModelMapsWriter::~ModelMapsWriter() = default;

void ModelMapsWriter::write_rows(const ModelMaps& band) {
  const Image& image = band.maps;
  const Image& shadows = band.shadows.words;
  LS_CHECK(image.channels == kMapChannelCount &&
               image.pixels.size() == image.num_pixels() * kMapChannelCount &&
               band.shadows.empty() != shadows_,
           "model maps have " + std::to_string(image.channels) + " channels");
  if (maps_) write_rows_beside(*maps_, image, shadows, shadows_ ? shadows.channels : 0);
  write_preview_rows(previews_, image);
}

void ModelMapsWriter::commit() {
  std::vector<ImageRowWriter*> files;
  if (maps_) files.push_back(maps_.get());
  for (auto& preview : previews_) files.push_back(&preview->file());
  commit_together(files);
}

void write_model_maps(const std::filesystem::path& path, const ModelMaps& maps,
                      const ExrAttributes& attributes) {
  ModelMapsWriter writer(path, maps.maps.width, maps.maps.height, maps, attributes);
  writer.write_rows(maps);
  writer.commit();
}

ModelMaps read_model_maps(const std::filesystem::path& path) {
  return read_model_map_rows(path, 0, -1);
}

namespace {

// The fit's noise model, from attribute lightstage:fit_noise when the file has it, into `out`.
void read_fit_noise(const NamedChannelFile& file, const std::string& name, ModelMaps& out) {
  out.noise_source = "unknown (no '" + std::string(kFitNoiseAttribute) + "' attribute)";
  const std::string* noise = file.attribute(kFitNoiseAttribute);
  if (!noise) return;
  try {
    const nlohmann::json j = nlohmann::json::parse(*noise);
    out.noise.a = j.at("read_variance").get<double>();
    out.noise.b = j.at("shot_variance_per_unit").get<double>();
    out.noise_source = j.value("source", std::string());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(name + ": attribute '" + kFitNoiseAttribute +
                     "': expected {read_variance, shot_variance_per_unit, source}: " + e.what());
  }
  if (!(std::isfinite(out.noise.a) && out.noise.a >= 0 && std::isfinite(out.noise.b) &&
        out.noise.b >= 0)) {
    throw InputError(name + ": attribute '" + kFitNoiseAttribute +
                     "': expected finite non-negative variances");
  }
}

// The shadow words of the file's `shadow_words` channels after the maps', and their LEDs from
// attribute lightstage:shadow_leds; none when the file has neither.
FitShadows read_shadows(const NamedChannelFile& file, int shadow_words, const std::string& name) {
  const std::string* shadow_leds = file.attribute(kShadowLedsAttribute);
  if (shadow_leds == nullptr && shadow_words == 0) return {};
  if (shadow_leds == nullptr) {
    throw InputError(name + ": shadow channels without attribute '" + kShadowLedsAttribute + "'");
  }
  std::vector<Eigen::Vector3f> leds = shadow_leds_from(*shadow_leds, name);
  if (FitShadows::words_for(int(leds.size())) != shadow_words) {
    throw InputError(name + ": channels 'shadow.N': expected " +
                     std::to_string(FitShadows::words_for(int(leds.size()))) + " for the " +
                     std::to_string(leds.size()) + " LEDs of attribute '" + kShadowLedsAttribute +
                     "', got " + std::to_string(shadow_words));
  }
  const Image& all = file.image;
  FitShadows out = FitShadows::all_lit(std::move(leds), all.width, all.height);
  for (size_t i = 0; i < all.num_pixels(); ++i) {
    std::copy_n(&all.pixels[i * size_t(all.channels) + kMapChannelCount], shadow_words,
                &out.words.pixels[i * size_t(shadow_words)]);
  }
  check_shadow_words(out.words, name);
  return out;
}

// Checks that every pixel of `maps` holds valid parameters for its model (`materials` basis
// materials), and counts them into `summary`.
void check_model_maps(const Image& maps, size_t materials, const std::string& name, int y0,
                      FitSummary& summary) {
  const std::vector<std::string>& names = model_map_channel_names();
  summary.pixels = maps.width * maps.height;
  auto fail = [&](int channel, int x, int y, const std::string& expected) {
    char where[96];
    std::snprintf(where, sizeof where, " at (%d, %d), got %.9g", x, y0 + y,
                  double(maps.at(x, y, channel)));
    throw InputError(name + ": channel '" + names[channel] + "': expected " + expected + where);
  };
  for (int y = 0; y < maps.height; ++y) {
    for (int x = 0; x < maps.width; ++x) {
      for (int c = 0; c < kMapChannelCount; ++c) {
        if (!std::isfinite(maps.at(x, y, c))) fail(c, x, y, "a finite value");
      }
      const float model = maps.at(x, y, kMapModel);
      if (!(model == std::floor(model) && model >= 0 && model <= 4)) {
        fail(kMapModel, x, y, "an integer in 0..4 (FitModel)");
      }
      const float flags = maps.at(x, y, kMapFlags);
      if (!(flags == std::floor(flags) && flags >= 0 && flags <= kMaxFlags)) {
        fail(kMapFlags, x, y, "flag bits, an integer in 0.." + std::to_string(kMaxFlags));
      }
      for (int j = 0; j < 2; ++j) {
        const float material = maps.at(x, y, kMapMaterial + 2 * j);
        if (!(material == std::floor(material) && material >= 0 && material <= float(materials))) {
          fail(kMapMaterial + 2 * j, x, y,
               "an integer in 0.." + std::to_string(materials) + " (the materials in attribute '" +
                   kMaterialsAttribute + "')");
        }
        if (!(maps.at(x, y, kMapMaterialWeight + 2 * j) >= 0)) {
          fail(kMapMaterialWeight + 2 * j, x, y, "a weight >= 0");
        }
      }
      summary.material_pixels += maps.at(x, y, kMapMaterial) > 0;
      if (model == 0) {
        ++((int(flags) & kNoSignal) != 0 ? summary.empty : summary.flagged);
        continue;
      }
      ++summary.fitted;
      ++summary.per_model[int(model)];
      summary.not_converged += (int(flags) & kFitNotConverged) != 0;
      const Eigen::Vector3d n(maps.at(x, y, kMapNormalX), maps.at(x, y, kMapNormalY),
                              maps.at(x, y, kMapNormalZ));
      if (std::abs(n.norm() - 1) > 1e-3) fail(kMapNormalX, x, y, "a unit normal (x, y, z)");
      for (int c = kMapAlbedoR; c <= kMapAlbedoB; ++c) {
        if (maps.at(x, y, c) < 0) fail(c, x, y, "an albedo >= 0");
      }
      const float sigma = maps.at(x, y, kMapSigma);
      if (!(sigma >= 0 && sigma <= kMaxSigma)) fail(kMapSigma, x, y, "sigma in [0, pi/2] rad");
      if (!(maps.at(x, y, kMapKs) >= 0)) fail(kMapKs, x, y, "k_s >= 0");
      const float roughness = maps.at(x, y, kMapRoughness);
      const bool has_lobe = model == float(FitModel::kLambertTorranceSparrow) ||
                            model == float(FitModel::kLambertPhong);
      if (has_lobe && !(roughness > 0 && roughness <= 1)) {
        fail(kMapRoughness, x, y, "a roughness in (0, 1] on a pixel with a specular lobe");
      }
    }
  }
}

}  // namespace

ModelMaps read_model_map_rows(const std::filesystem::path& path, int y0, int y1) {
  const std::string name = path.string();
  const std::vector<std::string>& names = model_map_channel_names();
  std::vector<std::string> with_shadows = names;
  for (const std::string& channel : exr_channel_names(path)) {
    if (channel.starts_with("shadow.")) {
      with_shadows.push_back("shadow." + std::to_string(with_shadows.size() - names.size()));
    }
  }
  NamedChannelFile file = read_named_channels(
      path, with_shadows, "model maps", "'lightstage fit'", /*exact=*/true,
      /*required=*/kMapMaterial, y0, y1);  // kMapMaterial: maps from before basis materials.
  ModelMaps out;
  read_fit_noise(file, name, out);
  if (const std::string* materials = file.attribute(kMaterialsAttribute)) {
    out.materials = materials_from(*materials, name);
    out.summary.materials = int(out.materials.size());
    for (const Material& m : out.materials) {
      out.summary.scene_materials = std::max(out.summary.scene_materials, m.scene_material);
    }
  }
  out.shadows = read_shadows(file, int(with_shadows.size() - names.size()), name);
  out.maps = Image(file.image.width, file.image.height, kMapChannelCount);
  out.maps.channel_names = names;
  for (size_t i = 0; i < out.maps.num_pixels(); ++i) {
    std::copy_n(&file.image.pixels[i * size_t(file.image.channels)], kMapChannelCount,
                &out.maps.pixels[i * size_t(kMapChannelCount)]);
  }
  check_model_maps(out.maps, out.materials.size(), name, y0, out.summary);
  return out;
}

}  // namespace ls::relight
