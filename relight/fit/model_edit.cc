#include "relight/fit/model_edit.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/json_reader.h"

namespace ls::relight {
namespace {

constexpr double kMinRoughness = 0.02;  // fit.cc's bound on Torrance-Sparrow roughness.
constexpr double kMinPhongExponent = 1, kMaxPhongExponent = 1e4;

double phong_roughness(double exponent) { return std::sqrt(2 / (exponent + 2)); }

FitModel read_model_name(const JsonReader& r) {
  const std::string name = r.one_of({"lambert", "oren_nayar", "torrance_sparrow", "phong"});
  if (name == "lambert") return FitModel::kLambert;
  if (name == "oren_nayar") return FitModel::kOrenNayar;
  if (name == "torrance_sparrow") return FitModel::kLambertTorranceSparrow;
  return FitModel::kLambertPhong;
}

ModelSelection read_selection(const JsonReader& r, const std::filesystem::path& base_dir, int width,
                              int height) {
  r.expect_object({"model", "material", "mask"});
  if (!r.has("model") && !r.has("material") && !r.has("mask")) {
    r.fail(R"(an object with "model", "material" and/or "mask")");
  }
  ModelSelection s;
  if (r.has("model")) s.model = read_model_name(r["model"]);
  if (r.has("material")) s.material = r["material"].integer_in(1, 1 << 20);
  if (r.has("mask")) s.mask = read_selection_mask(r["mask"], base_dir, width, height, &s.mask_file);
  return s;
}

ModelSwap read_swap(const JsonReader& r) {
  r.expect_object({"model", "sigma_rad", "ks", "roughness", "exponent"});
  ModelSwap s;
  s.model = read_model_name(r["model"]);
  // Only the parameters of the chosen model, and all of them: a swap says what it means.
  auto refuse = [&](std::initializer_list<const char*> keys) {
    for (const char* key : keys) {
      if (r.has(key)) {
        r[key].fail(std::string("no such parameter for \"") + edit_model_name(s.model) +
                    "\" (remove it)");
      }
    }
  };
  switch (s.model) {
    case FitModel::kLambert:
      refuse({"sigma_rad", "ks", "roughness", "exponent"});
      break;
    case FitModel::kOrenNayar:
      refuse({"ks", "roughness", "exponent"});
      s.sigma_rad = r["sigma_rad"].number_in(0, 0.5 * std::numbers::pi, "(radians)");
      break;
    case FitModel::kLambertTorranceSparrow:
      refuse({"sigma_rad", "exponent"});
      s.ks = r["ks"].number_in(0, 1e6);
      s.roughness = r["roughness"].number_in(kMinRoughness, 1, "(Beckmann m)");
      break;
    default:
      refuse({"sigma_rad", "roughness"});
      s.ks = r["ks"].number_in(0, 1e6);
      s.phong_exponent = r["exponent"].number_in(kMinPhongExponent, kMaxPhongExponent);
      break;
  }
  return s;
}

// Whether basis materials a and b (1-based, within maps.materials: read_model_maps and
// apply_model_edits check both; 0 = none) are parts of one scene material.
bool same_scene_material(const ModelMaps& maps, int a, int b) {
  if (a == b) return true;
  if (a <= 0 || b <= 0) return false;
  const int scene = maps.materials[size_t(a - 1)].scene_material;
  return scene > 0 && scene == maps.materials[size_t(b - 1)].scene_material;
}

// (x, y) of the maps, row first_row + y of the frame the selection's mask covers.
bool selected(const ModelSelection& s, const ModelMaps& maps, int x, int y, int first_row) {
  const FitModel model = maps.model(x, y);
  if (model == FitModel::kNone) return false;
  if (s.model && model != *s.model) return false;
  if (s.material > 0 && !same_scene_material(maps, int(maps.at(x, y, kMapMaterial)), s.material)) {
    return false;
  }
  if (!s.mask.empty() && !s.mask[size_t(first_row + y) * maps.maps.width + x]) return false;
  return true;
}

void apply_edit(const ModelEdit& e, float* m) {
  if (e.set_model) {
    const ModelSwap& s = *e.set_model;
    m[kMapModel] = float(int(s.model));
    m[kMapSigma] = s.model == FitModel::kOrenNayar ? float(s.sigma_rad) : 0.0f;
    m[kMapKs] = 0;
    m[kMapRoughness] = 0;
    if (s.model == FitModel::kLambertTorranceSparrow) {
      m[kMapKs] = float(s.ks);
      m[kMapRoughness] = float(s.roughness);
    } else if (s.model == FitModel::kLambertPhong) {
      m[kMapKs] = float(s.ks);
      m[kMapRoughness] = float(phong_roughness(s.phong_exponent));
    }
  }
  for (int c = 0; c < 3; ++c) {
    const double albedo = m[kMapAlbedoR + c];
    m[kMapAlbedoR + c] = float(std::clamp(albedo * e.albedo_tint[c], 0.0, std::max(1.0, albedo)));
  }
  const FitModel model = FitModel(int(m[kMapModel]));
  if (model == FitModel::kOrenNayar) {
    m[kMapSigma] = float(std::clamp(m[kMapSigma] * e.sigma_scale, 0.0, 0.5 * std::numbers::pi));
  }
  if (model == FitModel::kLambertTorranceSparrow || model == FitModel::kLambertPhong) {
    m[kMapKs] = float(std::max(0.0, m[kMapKs] * e.specular_scale));
    const double lo = model == FitModel::kLambertTorranceSparrow
                          ? kMinRoughness
                          : phong_roughness(kMaxPhongExponent);
    const double hi =
        model == FitModel::kLambertTorranceSparrow ? 1.0 : phong_roughness(kMinPhongExponent);
    m[kMapRoughness] = float(std::clamp(m[kMapRoughness] * e.roughness_scale, lo, hi));
  }
}

}  // namespace

const char* edit_model_name(FitModel model) {
  switch (model) {
    case FitModel::kLambert:
      return "lambert";
    case FitModel::kOrenNayar:
      return "oren_nayar";
    case FitModel::kLambertTorranceSparrow:
      return "torrance_sparrow";
    case FitModel::kLambertPhong:
      return "phong";
    default:
      return "none";
  }
}

ModelEdits parse_model_edits(std::string_view json_text, const std::string& source,
                             const std::filesystem::path& base_dir, int width, int height) {
  const nlohmann::json json = JsonReader::parse(json_text, source);
  const JsonReader root(json, source);
  root.expect_object({"edits"});
  const JsonReader list = root["edits"];
  ModelEdits out;
  out.source = source;
  for (size_t i = 0; i < list.size(); ++i) {
    const JsonReader r = list[i];
    r.expect_object(
        {"select", "set_model", "albedo_tint", "roughness_scale", "specular_scale", "sigma_scale"});
    ModelEdit e;
    e.select = read_selection(r["select"], base_dir, width, height);
    if (r.has("set_model")) e.set_model = read_swap(r["set_model"]);
    if (r.has("albedo_tint")) {
      const JsonReader tint = r["albedo_tint"];
      e.albedo_tint = tint.vec3();
      if (!(e.albedo_tint.minCoeff() >= 0)) tint.fail("three numbers >= 0");
    }
    if (r.has("roughness_scale")) e.roughness_scale = r["roughness_scale"].positive();
    if (r.has("specular_scale")) e.specular_scale = r["specular_scale"].number_in(0, 1e6);
    if (r.has("sigma_scale")) e.sigma_scale = r["sigma_scale"].number_in(0, 1e6);
    out.edits.push_back(std::move(e));
  }
  return out;
}

ModelEdits read_model_edits(const std::filesystem::path& path, int width, int height) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open the edit file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_model_edits(text.str(), path.string(), path.parent_path(), width, height);
}

std::vector<int> apply_model_edits(const ModelEdits& edits, ModelMaps& maps, int first_row) {
  const int width = maps.maps.width, height = maps.maps.height;
  LS_CHECK(maps.maps.channels == kMapChannelCount, "model maps expected");
  std::vector<int> counts;
  for (size_t i = 0; i < edits.edits.size(); ++i) {
    const ModelEdit& e = edits.edits[i];
    if (e.select.material > int(maps.materials.size())) {
      const std::string expected =
          maps.materials.empty()
              ? "no material: the maps have none (fitted with --materials per-pixel?)"
              : "1.." + std::to_string(maps.materials.size()) + " (the maps' basis materials)";
      throw InputError(edits.source + ": edits[" + std::to_string(i) +
                       "].select.material: expected " + expected + ", got " +
                       std::to_string(e.select.material));
    }
    LS_CHECK(e.select.mask.empty() ||
                 e.select.mask.size() >= (size_t(first_row) + height) * size_t(width),
             "mask of " + std::to_string(e.select.mask.size()) + " pixels for maps of " +
                 std::to_string(maps.maps.num_pixels()));
    int count = 0;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        if (!selected(e.select, maps, x, y, first_row)) continue;
        apply_edit(e, &maps.maps.at(x, y, 0));
        ++count;
      }
    }
    counts.push_back(count);
  }
  return counts;
}

std::vector<uint8_t> read_selection_mask(const JsonReader& m, const std::filesystem::path& base_dir,
                                         int width, int height, std::filesystem::path* mask_file) {
  *mask_file = m.string();
  const std::filesystem::path file = mask_file->is_absolute() ? *mask_file : base_dir / *mask_file;
  Image image;
  try {
    image = read_image(file);
  } catch (const InputError& e) {
    m.fail(std::string("a readable mask image (") + e.what() + ")");
  }
  if (image.width != width || image.height != height) {
    m.fail("a mask of " + std::to_string(width) + "x" + std::to_string(height) +
           " pixels (the maps' size), but " + file.string() + " is " + std::to_string(image.width) +
           "x" + std::to_string(image.height));
  }
  const int colour = std::min(image.channels, 3);
  std::vector<uint8_t> mask(image.num_pixels());
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    float sum = 0;
    for (int c = 0; c < colour; ++c) sum += image.pixels[i * image.channels + c];
    mask[i] = sum / colour >= 0.5f;
  }
  return mask;
}

}  // namespace ls::relight
