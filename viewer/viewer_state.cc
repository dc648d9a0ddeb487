#include "viewer/viewer_state.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/image_file.h"
#include "lightstage/json_reader.h"

namespace ls::viewer {

namespace fs = std::filesystem;

namespace {

constexpr std::pair<Source, const char*> kSourceNames[] = {
    {Source::kField, "field"}, {Source::kPca, "pca"}, {Source::kModels, "models"}};
constexpr std::pair<ParameterMap, const char*> kMapNames[] = {
    {ParameterMap::kNone, "none"},
    {ParameterMap::kNormal, "normal"},
    {ParameterMap::kAlbedo, "albedo"},
    {ParameterMap::kRoughness, "roughness"},
    {ParameterMap::kKs, "ks"},
    {ParameterMap::kSigma, "sigma"},
    {ParameterMap::kModel, "model"},
    {ParameterMap::kConfidence, "confidence"},
    {ParameterMap::kResidual, "residual"}};
constexpr std::pair<relight::FitModel, const char*> kModelNames[] = {
    {relight::FitModel::kLambert, "lambert"},
    {relight::FitModel::kOrenNayar, "oren_nayar"},
    {relight::FitModel::kLambertTorranceSparrow, "torrance_sparrow"},
    {relight::FitModel::kLambertPhong, "phong"}};

// Shortest text that reads back to exactly the same double.
std::string number(double value) {
  char buf[32];
  const auto result = std::to_chars(buf, buf + sizeof buf, value);
  return std::string(buf, result.ptr);
}

double parse_number(std::string_view text, const std::string& what) {
  double value = 0;
  const auto result = std::from_chars(text.data(), text.data() + text.size(), value);
  if (result.ec != std::errc() || result.ptr != text.data() + text.size() || !std::isfinite(value))
    throw InputError(what + ": expected a number, got \"" + std::string(text) + "\"");
  return value;
}

std::vector<std::string_view> split(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  size_t start = 0;
  while (true) {
    const size_t end = text.find(separator, start);
    parts.push_back(text.substr(start, end == std::string_view::npos ? end : end - start));
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return parts;
}

std::optional<relight::FitModel> parse_model(std::string_view name) {
  for (const auto& [model, text] : kModelNames)
    if (name == text) return model;
  return std::nullopt;
}

std::string shell_quote(const std::string& arg) {
  if (!arg.empty() && arg.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                            "0123456789-_./=:,+") == std::string::npos)
    return arg;
  std::string quoted = "'";
  for (char c : arg) {
    if (c == '\'')
      quoted += "'\\''";
    else
      quoted += c;
  }
  return quoted + "'";
}

fs::path resolve(const fs::path& path, const fs::path& base_dir) {
  return path.is_absolute() || base_dir.empty() ? path : base_dir / path;
}

}  // namespace

const char* to_string(Source source) {
  for (const auto& [value, name] : kSourceNames)
    if (value == source) return name;
  return "field";
}

std::optional<Source> parse_source(std::string_view name) {
  for (const auto& [value, text] : kSourceNames)
    if (name == text) return value;
  return std::nullopt;
}

const char* to_string(ParameterMap map) {
  for (const auto& [value, name] : kMapNames)
    if (value == map) return name;
  return "none";
}

std::optional<ParameterMap> parse_parameter_map(std::string_view name) {
  for (const auto& [value, text] : kMapNames)
    if (name == text) return value;
  return std::nullopt;
}

InputKind classify_input(const fs::path& path) {
  if (fs::is_directory(path)) {
    if (fs::exists(path / "manifest.json")) return InputKind::kSession;
    throw InputError(path.string() + ": expected a session directory (with manifest.json)");
  }
  if (!fs::exists(path)) throw InputError(path.string() + ": no such file or directory");
  if (path.extension() == ".lspca") return InputKind::kPca;
  if (path.extension() == ".exr") {
    std::string error;
    const auto input = image_file::open(path, error);
    if (!input) throw InputError(path.string() + ": not a readable EXR (" + error + ")");
    bool has_led = false, has_normal = false;
    for (const auto& name : input->spec().channel_names) {
      has_led |= name.rfind("led", 0) == 0;
      has_normal |= name == "normal.x";
    }
    if (has_normal) return InputKind::kModels;
    if (has_led) return InputKind::kField;
    throw InputError(path.string() +
                     ": channels: expected a reflectance field (led000.R, ...) or fitted model "
                     "maps (normal.x, ...), got neither");
  }
  throw InputError(path.string() +
                   ": expected a field or model maps (.exr), a PCA field (.lspca) or a session "
                   "directory, got extension \"" +
                   path.extension().string() + "\"");
}

std::string ViewEdit::to_spec() const {
  std::vector<std::string> parts;
  if (model_class) parts.push_back(std::string("model=") + relight::edit_model_name(*model_class));
  if (material > 0) parts.push_back("material=" + std::to_string(material));
  if (!brush.empty()) {
    std::string dabs = "brush=";
    for (size_t i = 0; i < brush.size(); ++i) {
      if (i) dabs += "/";
      dabs += number(brush[i].x) + "," + number(brush[i].y) + "," + number(brush[i].radius_px);
    }
    parts.push_back(dabs);
  }
  if (albedo_tint != Eigen::Vector3d(1, 1, 1)) {
    parts.push_back("tint=" + number(albedo_tint.x()) + "," + number(albedo_tint.y()) + "," +
                    number(albedo_tint.z()));
  }
  if (roughness_scale != 1) parts.push_back("roughness=" + number(roughness_scale));
  if (specular_scale != 1) parts.push_back("specular=" + number(specular_scale));
  std::string spec;
  for (size_t i = 0; i < parts.size(); ++i) spec += (i ? ";" : "") + parts[i];
  return spec.empty() ? "all" : spec;
}

ViewEdit ViewEdit::parse_spec(std::string_view spec, const std::string& source) {
  ViewEdit edit;
  if (spec == "all") return edit;
  for (std::string_view part : split(spec, ';')) {
    const size_t eq = part.find('=');
    if (eq == std::string_view::npos) {
      throw InputError(source + ": expected key=value, got \"" + std::string(part) + "\"");
    }
    const std::string_view key = part.substr(0, eq), value = part.substr(eq + 1);
    const std::string what = source + ": " + std::string(key);
    if (key == "model") {
      edit.model_class = parse_model(value);
      if (!edit.model_class) {
        throw InputError(what +
                         ": expected lambert, oren_nayar, torrance_sparrow or phong, got \"" +
                         std::string(value) + "\"");
      }
    } else if (key == "material") {
      const double id = parse_number(value, what);
      if (!(id >= 1 && id == std::floor(id) && id < 1 << 20))
        throw InputError(what + ": expected a material number >= 1");
      edit.material = int(id);
    } else if (key == "brush") {
      for (std::string_view dab : split(value, '/')) {
        const auto xyr = split(dab, ',');
        if (xyr.size() != 3) throw InputError(what + ": expected x,y,radius per dab");
        const BrushDab d{parse_number(xyr[0], what), parse_number(xyr[1], what),
                         parse_number(xyr[2], what)};
        if (!(d.radius_px > 0)) throw InputError(what + ": expected a positive radius");
        edit.brush.push_back(d);
      }
    } else if (key == "tint") {
      const auto rgb = split(value, ',');
      if (rgb.size() != 3) throw InputError(what + ": expected r,g,b");
      for (int c = 0; c < 3; ++c) {
        edit.albedo_tint[c] = parse_number(rgb[c], what);
        if (edit.albedo_tint[c] < 0) throw InputError(what + ": expected values >= 0");
      }
    } else if (key == "roughness" || key == "specular") {
      const double scale = parse_number(value, what);
      if (!(scale >= 0) || (key == "roughness" && scale == 0))
        throw InputError(what + ": expected a positive scale, got " + std::string(value));
      (key == "roughness" ? edit.roughness_scale : edit.specular_scale) = scale;
    } else {
      throw InputError(
          what + ": unknown key (expected model, material, brush, tint, roughness, specular)");
    }
  }
  return edit;
}

relight::ModelEdit ViewEdit::to_model_edit(int width, int height) const {
  relight::ModelEdit edit;
  edit.select.model = model_class;
  edit.select.material = material;
  if (!brush.empty()) {
    edit.select.mask.assign(size_t(width) * height, 0);
    for (const BrushDab& dab : brush) {
      const int x0 = std::max(0, int(std::floor(dab.x - dab.radius_px)));
      const int x1 = std::min(width - 1, int(std::ceil(dab.x + dab.radius_px)));
      const int y0 = std::max(0, int(std::floor(dab.y - dab.radius_px)));
      const int y1 = std::min(height - 1, int(std::ceil(dab.y + dab.radius_px)));
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          const double dx = x + 0.5 - dab.x, dy = y + 0.5 - dab.y;
          if (dx * dx + dy * dy <= dab.radius_px * dab.radius_px)
            edit.select.mask[size_t(y) * width + x] = 1;
        }
      }
    }
  }
  edit.albedo_tint = albedo_tint;
  edit.roughness_scale = roughness_scale;
  edit.specular_scale = specular_scale;
  return edit;
}

void write_edit_file(const fs::path& path, const std::vector<ViewEdit>& edits, int width,
                     int height) {
  nlohmann::json list = nlohmann::json::array();
  for (size_t i = 0; i < edits.size(); ++i) {
    const ViewEdit& edit = edits[i];
    nlohmann::json select = nlohmann::json::object();
    if (edit.model_class) select["model"] = relight::edit_model_name(*edit.model_class);
    if (edit.material > 0) select["material"] = edit.material;
    if (!edit.brush.empty()) {
      const relight::ModelEdit rasterised = edit.to_model_edit(width, height);
      Image mask(width, height, 3);
      for (size_t p = 0; p < rasterised.select.mask.size(); ++p)
        for (int c = 0; c < 3; ++c) mask.pixels[p * 3 + c] = rasterised.select.mask[p];
      const std::string name = path.stem().string() + ".mask" + std::to_string(i) + ".png";
      write_png_preview(path.parent_path() / name, mask);
      select["mask"] = name;
    }
    auto add = [&](const nlohmann::json& selection) {
      list.push_back(
          {{"select", selection},
           {"albedo_tint", {edit.albedo_tint.x(), edit.albedo_tint.y(), edit.albedo_tint.z()}},
           {"roughness_scale", edit.roughness_scale},
           {"specular_scale", edit.specular_scale}});
    };
    // The edit file needs a selection: "all" is every fitted model class.
    if (!select.empty()) add(select);
    for (const auto& [model, name] : kModelNames)
      if (select.empty()) add({{"model", name}});
  }
  write_file_atomic(path, nlohmann::json{{"edits", list}}.dump(2) + "\n");
}

std::vector<Action> parse_script(std::string_view json_text, const std::string& source,
                                 const fs::path& base_dir) {
  const nlohmann::json json = JsonReader::parse(json_text, source);
  const JsonReader root(json, source);
  root.expect_array();
  std::vector<Action> actions;
  for (size_t i = 0; i < root.size(); ++i) {
    const JsonReader r = root[i];
    if (!r.value().is_object() || !r.has("action")) r.fail("an object with \"action\"");
    const std::string name =
        r["action"].one_of({"open", "env", "rotate", "exposure", "source", "split", "difference",
                            "map", "point_light", "edit", "time", "screenshot"});
    Action a;
    auto absolute_or_relative = [&](const char* absolute_key) {
      r.expect_object({"action", absolute_key, "by"});
      if (r.has("by")) {
        a.relative = true;
        a.value = r["by"].number();
      } else {
        a.value = r[absolute_key].number();
      }
    };
    if (name == "open" || name == "screenshot") {
      r.expect_object({"action", "path"});
      a.kind = name == "open" ? Action::Kind::kOpen : Action::Kind::kScreenshot;
      a.text = resolve(r["path"].string(), base_dir).string();
    } else if (name == "env") {
      r.expect_object({"action", "env"});
      a.kind = Action::Kind::kEnvironment;
      a.text = r["env"].string();
      const auto names = builtin_environment_names();
      if (std::find(names.begin(), names.end(), a.text) == names.end())
        a.text = resolve(a.text, base_dir).string();
    } else if (name == "rotate") {
      a.kind = Action::Kind::kRotate;
      absolute_or_relative("deg");
    } else if (name == "exposure") {
      a.kind = Action::Kind::kExposure;
      absolute_or_relative("stops");
    } else if (name == "source") {
      r.expect_object({"action", "source", "rank"});
      a.kind = Action::Kind::kSource;
      a.text = r["source"].one_of({"field", "pca", "models"});
      if (r.has("rank")) a.rank = r["rank"].integer_in(1, 100000);
    } else if (name == "split") {
      r.expect_object({"action", "source", "divider"});
      a.kind = Action::Kind::kSplit;
      a.text = r["source"].one_of({"field", "pca", "models", "none"});
      if (r.has("divider")) a.divider = r["divider"].number_in(0, 1);
    } else if (name == "difference") {
      r.expect_object({"action", "on"});
      a.kind = Action::Kind::kDifference;
      a.on = r["on"].boolean();
    } else if (name == "map") {
      r.expect_object({"action", "map"});
      a.kind = Action::Kind::kMap;
      a.text = r["map"].one_of({"none", "normal", "albedo", "roughness", "ks", "sigma", "model",
                                "confidence", "residual"});
    } else if (name == "point_light") {
      r.expect_object({"action", "on", "dir"});
      a.kind = Action::Kind::kPointLight;
      a.on = r.has("on") ? r["on"].boolean() : true;
      if (r.has("dir")) a.dir = r["dir"].unit_vec3();
    } else if (name == "edit") {
      r.expect_object({"action", "clear", "model", "material", "brush", "tint", "roughness_scale",
                       "specular_scale"});
      a.kind = Action::Kind::kEdit;
      if (r.has("clear")) a.clear = r["clear"].boolean();
      if (r.has("model")) {
        a.edit.model_class =
            parse_model(r["model"].one_of({"lambert", "oren_nayar", "torrance_sparrow", "phong"}));
      }
      if (r.has("material")) a.edit.material = r["material"].integer_in(1, 1 << 20);
      if (r.has("brush")) {
        const JsonReader dabs = r["brush"];
        dabs.expect_array();
        for (size_t d = 0; d < dabs.size(); ++d) {
          const Eigen::Vector3d xyr = dabs[d].vec3();
          if (!(xyr.z() > 0)) dabs[d].fail("[x, y, radius] with a positive radius");
          a.edit.brush.push_back({xyr.x(), xyr.y(), xyr.z()});
        }
      }
      if (r.has("tint")) {
        a.edit.albedo_tint = r["tint"].vec3();
        if (a.edit.albedo_tint.minCoeff() < 0) r["tint"].fail("three numbers >= 0");
      }
      if (r.has("roughness_scale")) a.edit.roughness_scale = r["roughness_scale"].positive();
      if (r.has("specular_scale")) a.edit.specular_scale = r["specular_scale"].number_in(0, 1e6);
    } else if (name == "time") {
      r.expect_object({"action", "step"});
      a.kind = Action::Kind::kTime;
      a.value = r["step"].integer_in(0, 1000000);
    }
    actions.push_back(std::move(a));
  }
  return actions;
}

std::vector<Action> read_script(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open the script");
  std::stringstream text;
  text << in.rdbuf();
  return parse_script(text.str(), path.string(), path.parent_path());
}

std::vector<std::string> builtin_environment_names() {
  return {"uniform", "sky_sun", "softbox_studio", "small_source"};
}

void ViewState::open(const fs::path& path) {
  switch (classify_input(path)) {
    case InputKind::kField:
      field_file = path;
      session_dir.clear();
      break;
    case InputKind::kSession:
      session_dir = path;
      field_file.clear();
      time_step = 0;
      break;
    case InputKind::kModels:
      models_file = path;
      break;
    case InputKind::kPca:
      pca_file = path;
      break;
  }
}

ViewState::Effect ViewState::apply(const Action& a) {
  Effect effect;
  switch (a.kind) {
    case Action::Kind::kOpen:
      open(a.text);
      effect.reload = true;
      break;
    case Action::Kind::kEnvironment:
      environment = a.text;
      effect.reload = true;
      break;
    case Action::Kind::kRotate:
      rotation_deg = a.relative ? rotation_deg + a.value : a.value;
      rotation_deg -= 360.0 * std::floor(rotation_deg / 360.0);  // Keep it in [0, 360).
      break;
    case Action::Kind::kExposure:
      exposure_stops = a.relative ? exposure_stops + a.value : a.value;
      break;
    case Action::Kind::kSource:
      source = *parse_source(a.text);
      if (a.rank) rank = *a.rank;
      break;
    case Action::Kind::kSplit:
      split = a.text == "none" ? std::nullopt : parse_source(a.text);
      if (a.divider) divider = *a.divider;
      break;
    case Action::Kind::kDifference:
      difference = a.on;
      break;
    case Action::Kind::kMap:
      map = *parse_parameter_map(a.text);
      break;
    case Action::Kind::kPointLight:
      point_light = a.on;
      if (a.dir) light_dir = *a.dir;
      break;
    case Action::Kind::kEdit:
      if (a.clear)
        edits.clear();
      else
        edits.push_back(a.edit);
      break;
    case Action::Kind::kTime:
      time_step = int(a.value);
      effect.reload = true;
      break;
    case Action::Kind::kScreenshot:
      effect.screenshot = a.text;
      break;
  }
  return effect;
}

std::vector<std::string> ViewState::to_args() const {
  std::vector<std::string> args = {"view"};
  for (const fs::path& input : {session_dir, field_file, models_file, pca_file})
    if (!input.empty()) args.push_back(input.string());
  auto option = [&](const char* name, const std::string& value) {
    args.push_back(name);
    args.push_back(value);
  };
  option("--env", environment);
  if (rotation_deg != 0) option("--rotate", number(rotation_deg));
  if (exposure_stops != 0) option("--exposure", number(exposure_stops));
  option("--source", to_string(source));
  // The rank of a PCA built from the field; a PCA file has its own.
  if (pca_file.empty()) option("--rank", std::to_string(rank));
  if (split) option("--split", to_string(*split));
  if (divider != 0.5) option("--divider", number(divider));
  if (difference) args.push_back("--difference");
  if (exact_models) args.push_back("--exact-models");
  if (map != ParameterMap::kNone) option("--map", to_string(map));
  if (point_light) {
    args.push_back("--light");
    for (int i = 0; i < 3; ++i) args.push_back(number(light_dir[i]));
  }
  for (const ViewEdit& edit : edits) option("--edit", edit.to_spec());
  if (time_step != 0) option("--time", std::to_string(time_step));
  if (memory.given()) option("--memory", std::to_string(memory.given_bytes()));
  option("--size", std::to_string(window_width) + "x" + std::to_string(window_height));
  return args;
}

std::string ViewState::to_command_line() const {
  std::string line = "lightstage";
  for (const std::string& arg : to_args()) line += " " + shell_quote(arg);
  return line;
}

}  // namespace ls::viewer
