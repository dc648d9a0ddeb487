#include "viewer/viewer_app.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>
// glcorearb.h first: GLFW must not pull in the legacy <GL/gl.h>.
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>
#include <imgui_stdlib.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>

#include "capture/build_field.h"
#include "lightstage/errors.h"
#include "lightstage/session.h"
#include "relight/envmap.h"
#include "relight/light_cells.h"
#include "relight/model_edit.h"
#include "relight/model_render.h"
#include "relight/pca_field.h"
#include "viewer/gl_window.h"

namespace ls::viewer {

namespace fs = std::filesystem;

namespace {

constexpr float kPanelWidth = 340.0f;
constexpr int kStripWidth = 256, kStripHeight = 128;
constexpr float kStripPanelHeight = kStripHeight + 56.0f;

fs::path data_dir() {
  if (const char* env = std::getenv("LIGHTSTAGE_DATA")) return env;
  return LIGHTSTAGE_DATA_DIR;
}

float srgb_encode(float linear) {
  linear = std::clamp(linear, 0.0f, 1.0f);
  return linear <= 0.0031308f ? 12.92f * linear : 1.055f * std::pow(linear, 1.0f / 2.4f) - 0.055f;
}
float srgb_decode(float encoded) {
  return encoded <= 0.04045f ? encoded / 12.92f : std::pow((encoded + 0.055f) / 1.055f, 2.4f);
}
float luminance(const float* rgb) { return 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2]; }

// A perceptually ordered colour ramp (viridis, 5 stops), t in [0, 1] -> sRGB-encoded RGB.
Eigen::Vector3f ramp(float t) {
  static const Eigen::Vector3f stops[] = {{0.267f, 0.005f, 0.329f},
                                          {0.229f, 0.322f, 0.546f},
                                          {0.128f, 0.567f, 0.551f},
                                          {0.369f, 0.789f, 0.383f},
                                          {0.993f, 0.906f, 0.144f}};
  t = std::clamp(std::isfinite(t) ? t : 0.0f, 0.0f, 1.0f) * 4.0f;
  const int i = std::min(3, int(t));
  return stops[i] + (stops[i + 1] - stops[i]) * (t - float(i));
}

// Categorical colours of FitModel (sRGB-encoded): none, Lambert, Oren-Nayar, TS, Phong.
const Eigen::Vector3f kModelColours[] = {{0.0f, 0.0f, 0.0f},
                                         {0.55f, 0.6f, 0.7f},
                                         {0.3f, 0.75f, 0.35f},
                                         {0.95f, 0.55f, 0.15f},
                                         {0.65f, 0.4f, 0.85f}};

struct Legend {
  bool categorical = false;
  std::string low, high;  // Ramp ends.
};

// A parameter map as sRGB-encoded colours, and its legend.
Image parameter_image(const relight::ModelMaps& maps, ParameterMap which, Legend* legend) {
  const Image& m = maps.maps;
  Image out(m.width, m.height, 3);
  *legend = {};
  switch (which) {
    case ParameterMap::kRoughness:
      *legend = {false, "m = 0", "m = 1"};
      break;
    case ParameterMap::kKs:
      *legend = {false, "ks = 0", "ks = 1"};
      break;
    case ParameterMap::kSigma:
      *legend = {false, "sigma = 0", "sigma = 90 deg"};
      break;
    case ParameterMap::kConfidence:
      *legend = {false, "0", "1"};
      break;
    case ParameterMap::kResidual:
      *legend = {false, "chi2/dof = 0", "chi2/dof = 99 (log)"};
      break;
    case ParameterMap::kModel:
      legend->categorical = true;
      break;
    case ParameterMap::kNormal:
      *legend = {false, "", ""};
      break;
    default:
      break;
  }
  for (int y = 0; y < m.height; ++y) {
    for (int x = 0; x < m.width; ++x) {
      const float* p = &m.pixels[(size_t(y) * m.width + x) * m.channels];
      Eigen::Vector3f c(0, 0, 0);
      const bool fitted = p[relight::kMapModel] > 0.5f;
      switch (which) {
        case ParameterMap::kNormal:
          if (fitted)
            c = Eigen::Vector3f(p[relight::kMapNormalX], p[relight::kMapNormalY],
                                p[relight::kMapNormalZ]) *
                    0.5f +
                Eigen::Vector3f::Constant(0.5f);
          break;
        case ParameterMap::kAlbedo:
          c = Eigen::Vector3f(srgb_encode(p[relight::kMapAlbedoR]),
                              srgb_encode(p[relight::kMapAlbedoG]),
                              srgb_encode(p[relight::kMapAlbedoB]));
          break;
        case ParameterMap::kRoughness:
          if (p[relight::kMapKs] > 0) c = ramp(p[relight::kMapRoughness]);
          break;
        case ParameterMap::kKs:
          if (fitted) c = ramp(p[relight::kMapKs]);
          break;
        case ParameterMap::kSigma:
          if (fitted) c = ramp(p[relight::kMapSigma] / float(M_PI / 2));
          break;
        case ParameterMap::kModel:
          c = kModelColours[std::clamp(int(std::lround(p[relight::kMapModel])), 0, 4)];
          break;
        case ParameterMap::kConfidence:
          if (fitted) c = ramp(p[relight::kMapConfidence]);
          break;
        case ParameterMap::kResidual:
          if (fitted) c = ramp(std::log10(1.0f + p[relight::kMapResidual]) / 2.0f);
          break;
        case ParameterMap::kNone:
          break;
      }
      for (int k = 0; k < 3; ++k) out.at(x, y, k) = std::clamp(c[k], 0.0f, 1.0f);
    }
  }
  return out;
}

// LED directions and validity from a .lspca header (layout in relight/pca_field.cc): "LSPCA1\n",
// int32 width, height, lights, rank, tile_size, float64 sigma, per LED float64 x, y, z, uint8
// valid.
void read_pca_leds(const fs::path& path, std::vector<Eigen::Vector3d>& dirs,
                   std::vector<bool>& valid) {
  std::ifstream in(path, std::ios::binary);
  char magic[7];
  int32_t header[5];
  double sigma = 0;
  in.read(magic, 7);
  in.read(reinterpret_cast<char*>(header), sizeof header);
  in.read(reinterpret_cast<char*>(&sigma), sizeof sigma);
  if (!in || header[2] < 0 || header[2] > 100000)
    throw InputError(path.string() + ": header: expected a lightstage PCA file");
  dirs.resize(header[2]);
  valid.resize(header[2]);
  for (int l = 0; l < header[2]; ++l) {
    double xyz[3];
    uint8_t v = 0;
    in.read(reinterpret_cast<char*>(xyz), sizeof xyz);
    in.read(reinterpret_cast<char*>(&v), 1);
    dirs[l] = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    valid[l] = v != 0;
  }
  if (!in) throw InputError(path.string() + ": LED directions: expected more data");
}

// Writes an RGB image (row 0 at the top) into a target's RGBA32F texture, in the row order
// GpuTarget::read_back reads back.
void upload_to_target(const Image& image, GpuTarget& target) {
  std::vector<float> rgba(size_t(image.width) * image.height * 4, 1.0f);
  for (int y = 0; y < image.height; ++y) {
    // GL's row 0 is the bottom: the image's last row goes first.
    const int gl_row = image.height - 1 - y;
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c)
        rgba[(size_t(gl_row) * image.width + x) * 4 + c] =
            image.at(x, y, std::min(c, image.channels - 1));
    }
  }
  glBindTexture(GL_TEXTURE_2D, target.texture());
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, image.width, image.height, GL_RGBA, GL_FLOAT,
                  rgba.data());
  glBindTexture(GL_TEXTURE_2D, 0);
}

relight::EnvironmentMap load_environment(const std::string& name) {
  if (name == "uniform") return relight::EnvironmentMap(Image(64, 32, 3, 1.0f), "uniform");
  const auto names = builtin_environment_names();
  if (std::find(names.begin(), names.end(), name) != names.end()) {
    const fs::path path = data_dir() / "envmaps" / (name + ".exr");
    if (!fs::exists(path)) {
      throw InputError(path.string() + ": built-in environment \"" + name +
                       "\" not found (run 'lightstage envmaps' to write it)");
    }
    return relight::EnvironmentMap::load(path);
  }
  return relight::EnvironmentMap::load(name);
}

}  // namespace

struct ViewerApp::Impl {
  ViewState state;
  std::unique_ptr<GlWindow> window;
  bool imgui_ready = false;
  ImGuiContext* imgui = nullptr;  // Each viewer has its own (ImGui's current one is global).
  std::string error;

  // What is loaded, and from where (so a reload touches only what changed).
  std::optional<capture::ReflectanceField> field;
  int time_steps = 1;
  fs::path loaded_session, loaded_field, loaded_models, loaded_pca;
  int loaded_time_step = -1;
  std::optional<relight::ModelMaps> base_maps, edited_maps;
  std::optional<std::vector<ViewEdit>> edits_in_maps;
  std::optional<relight::PcaField> pca_from_file, pca_from_field;
  std::vector<Eigen::Vector3d> led_dirs;
  std::vector<bool> led_valid;
  std::optional<relight::EnvironmentMap> env;
  std::string loaded_env;
  double env_display_stops = 0;

  // On the GPU.
  std::unique_ptr<GpuSource> gpu_field, gpu_pca, gpu_models;
  int gpu_pca_rank = -1;
  bool gpu_pca_from_file = false;
  std::optional<std::vector<ViewEdit>> edits_on_gpu;
  bool models_exact_on_gpu = false;
  std::unique_ptr<GpuTarget> target, split_target, map_target;
  ParameterMap map_in_target = ParameterMap::kNone;
  std::optional<std::vector<ViewEdit>> edits_in_map_target;
  Legend legend;
  unsigned strip_texture = 0;
  std::vector<int> strip_nearest_led;  // Per strip pixel, -1 outside the dome.
  unsigned screenshot_fbo = 0, screenshot_rbo = 0;
  int screenshot_w = 0, screenshot_h = 0;

  // Lighting and what it was computed for.
  ViewLighting lighting;
  std::optional<std::tuple<std::string, double, bool, Eigen::Vector3d, size_t>> lighting_key;
  std::vector<float> led_luminance;

  double relight_ms = 0;   // Last frame: light weights (when they changed) + GPU relighting.
  double lighting_ms = 0;  // The last time the light weights were computed.
  std::string last_command_line;
  bool painting = false, dragging_divider = false;

  // UI inputs.
  std::string open_path, env_path, edit_file = "edits.json", screenshot_path = "view.png";
  int edit_model_choice = 0;  // 0 = any class.
  bool brush_mode = false;
  float brush_radius = 8.0f;
  float tint[3] = {1, 1, 1};
  float roughness_scale = 1, specular_scale = 1;

  // Image area in window pixels (top-left origin).
  float area_x = 0, area_y = 0, area_w = 0, area_h = 0;

  ~Impl() {
    if (window) {
      // GL objects are deleted in their own context (another viewer's may be current).
      glfwMakeContextCurrent(window->handle());
      if (imgui) ImGui::SetCurrentContext(imgui);
      if (strip_texture) glDeleteTextures(1, &strip_texture);
      if (screenshot_fbo) glDeleteFramebuffers(1, &screenshot_fbo);
      if (screenshot_rbo) glDeleteRenderbuffers(1, &screenshot_rbo);
      gpu_field.reset();
      gpu_pca.reset();
      gpu_models.reset();
      target.reset();
      split_target.reset();
      map_target.reset();
      if (imgui_ready) {
        ImGui_ImplOpenGL3_Shutdown();
        ImGui_ImplGlfw_Shutdown();
      }
      if (imgui) ImGui::DestroyContext(imgui);
    }
  }

  // --- Loading ------------------------------------------------------------------------------

  int source_width() const {
    if (field) return field->width();
    if (pca_from_file) return pca_from_file->width();
    if (base_maps) return base_maps->maps.width;
    return 0;
  }
  int source_height() const {
    if (field) return field->height();
    if (pca_from_file) return pca_from_file->height();
    if (base_maps) return base_maps->maps.height;
    return 0;
  }

  bool available(Source s) const {
    switch (s) {
      case Source::kField:
        return field.has_value();
      case Source::kPca:
        return field.has_value() || pca_from_file.has_value();
      case Source::kModels:
        return base_maps.has_value();
    }
    return false;
  }

  void check_size(int w, int h, const fs::path& path) const {
    const int sw = source_width(), sh = source_height();
    if (sw && (w != sw || h != sh)) {
      throw InputError(path.string() + ": size: expected " + std::to_string(sw) + "x" +
                       std::to_string(sh) + " (the size of what is open), got " +
                       std::to_string(w) + "x" + std::to_string(h));
    }
  }

  void set_leds_from_field() {
    led_dirs.clear();
    led_valid.clear();
    for (const auto& light : field->lights()) {
      led_dirs.push_back(light.dir_in_stage);
      led_valid.push_back(light.valid);
    }
    strip_nearest_led.clear();
  }

  // Brings the loaded data in line with the state. InputError on a file that cannot be read;
  // what was loaded before stays.
  void load() {
    if (!state.session_dir.empty() &&
        (state.session_dir != loaded_session || state.time_step != loaded_time_step)) {
      const Session session = Session::open(state.session_dir);
      time_steps = std::max(1, session.stage().plan.time_steps);
      if (state.time_step < 0 || state.time_step >= time_steps) {
        throw InputError(state.session_dir.string() + ": time step: expected 0.." +
                         std::to_string(time_steps - 1) + ", got " +
                         std::to_string(state.time_step));
      }
      capture::BuildOptions options;
      options.time_step = state.time_step;
      field = capture::build_field(session, options);
      loaded_session = state.session_dir;
      loaded_time_step = state.time_step;
      loaded_field.clear();
      on_field_changed();
    }
    if (!state.field_file.empty() && state.field_file != loaded_field) {
      capture::ReflectanceField read = capture::read_field(state.field_file);
      field = std::move(read);
      time_steps = 1;
      loaded_field = state.field_file;
      loaded_session.clear();
      loaded_time_step = -1;
      on_field_changed();
    }
    if (!state.pca_file.empty() && state.pca_file != loaded_pca) {
      relight::PcaField pca = relight::PcaField::read(state.pca_file);
      if (field) check_size(pca.width(), pca.height(), state.pca_file);
      std::vector<Eigen::Vector3d> dirs;
      std::vector<bool> valid;
      read_pca_leds(state.pca_file, dirs, valid);
      pca_from_file = std::move(pca);
      if (!field) {
        led_dirs = dirs;
        led_valid = valid;
        strip_nearest_led.clear();
      }
      loaded_pca = state.pca_file;
      gpu_pca.reset();
      lighting_key.reset();
    }
    if (!state.models_file.empty() && state.models_file != loaded_models) {
      relight::ModelMaps maps = relight::read_model_maps(state.models_file);
      check_size(maps.maps.width, maps.maps.height, state.models_file);
      base_maps = std::move(maps);
      edited_maps.reset();
      edits_in_maps.reset();
      gpu_models.reset();
      loaded_models = state.models_file;
    }
    if (!env || state.environment != loaded_env) {
      env = load_environment(state.environment);
      env_display_stops = auto_exposure_stops(env->radiance(), 0.95);
      loaded_env = state.environment;
      lighting_key.reset();
    }
    // Opening a file of another kind shows it when what was shown is not available.
    if (!available(state.source)) {
      for (Source s : {Source::kField, Source::kModels, Source::kPca}) {
        if (available(s)) {
          state.source = s;
          break;
        }
      }
    }
    if (state.split && !available(*state.split)) state.split.reset();
  }

  void on_field_changed() {
    if (field->width() != source_width() || field->height() != source_height()) {
      // A field of another size replaces everything else that was open.
      if (base_maps &&
          (base_maps->maps.width != field->width() || base_maps->maps.height != field->height())) {
        base_maps.reset();
        edited_maps.reset();
        state.models_file.clear();
        loaded_models.clear();
      }
    }
    set_leds_from_field();
    pca_from_field.reset();
    gpu_field.reset();
    if (!gpu_pca_from_file) gpu_pca.reset();
    gpu_pca_rank = -1;
    lighting_key.reset();
  }

  const relight::ModelMaps& current_maps() {
    if (!edited_maps || !edits_in_maps || *edits_in_maps != state.edits) {
      edited_maps = *base_maps;
      relight::ModelEdits edits;
      edits.source = "viewer edits";
      for (const ViewEdit& e : state.edits)
        edits.edits.push_back(e.to_model_edit(base_maps->maps.width, base_maps->maps.height));
      relight::apply_model_edits(edits, *edited_maps);
      edits_in_maps = state.edits;
    }
    return *edited_maps;
  }

  // --- GPU sources --------------------------------------------------------------------------

  GpuSource* gpu_source(Source s) {
    if (!available(s)) {
      throw InputError(std::string("source ") + to_string(s) +
                       ": nothing open provides it (models need MAPS.exr from 'lightstage fit'; "
                       "pca needs a field or a .lspca)");
    }
    switch (s) {
      case Source::kField:
        if (!gpu_field) gpu_field = upload_field(*field);
        return gpu_field.get();
      case Source::kPca: {
        const bool from_file = pca_from_file.has_value();
        const int rank = from_file ? pca_from_file->rank() : state.rank;
        if (!gpu_pca || gpu_pca_from_file != from_file || gpu_pca_rank != rank) {
          if (from_file) {
            gpu_pca = upload_pca(*pca_from_file);
          } else {
            relight::PcaOptions options;
            options.rank = std::min(rank, field->num_lights());
            pca_from_field = relight::PcaField::build(*field, options);
            gpu_pca = upload_pca(*pca_from_field);
          }
          gpu_pca_from_file = from_file;
          gpu_pca_rank = rank;
        }
        return gpu_pca.get();
      }
      case Source::kModels:
        if (!gpu_models || !edits_on_gpu || *edits_on_gpu != state.edits ||
            models_exact_on_gpu != state.exact_models) {
          // kAuto: the prefiltered environment, or the exact sum for a point light.
          gpu_models = upload_models(
              current_maps(), {}, state.exact_models ? ModelShading::kExact : ModelShading::kAuto);
          edits_on_gpu = state.edits;
          models_exact_on_gpu = state.exact_models;
        }
        return gpu_models.get();
    }
    return nullptr;
  }

  // --- Lighting -----------------------------------------------------------------------------

  const ViewLighting& current_lighting() {
    const auto key = std::make_tuple(state.environment, state.rotation_deg, state.point_light,
                                     state.light_dir, led_dirs.size());
    if (lighting_key && *lighting_key == key) return lighting;
    const auto t0 = std::chrono::steady_clock::now();
    ViewLighting l;
    if (state.point_light) {
      l.lights = relight::LightingForModels::directional(state.light_dir.normalized(),
                                                         Eigen::Vector3d(1, 1, 1));
      if (!led_dirs.empty()) {
        // Between the LEDs the field is interpolated (relight/pca_field.h LightInterpolator).
        const relight::LightInterpolator interpolator(led_dirs, led_valid);
        l.led_irradiance_rgb = interpolator.led_irradiance(l.lights);
      }
    } else {
      if (!led_dirs.empty()) {
        l.led_irradiance_rgb =
            relight::integrate_environment(*env, led_dirs, state.rotation_deg, 0.0, led_valid)
                .irradiance_rgb;
      }
      // With LEDs known the models get the light the dome covers, as `lightstage relight`
      // --models with a field does, so field and models are lit alike.
      relight::EnvironmentSampling sampling;
      sampling.covered_by_leds = led_dirs;
      l.lights = relight::LightingForModels::environment(*env, state.rotation_deg, sampling);
    }
    led_luminance.assign(led_dirs.size(), 0.0f);
    for (size_t i = 0; i < led_dirs.size() && 3 * i + 2 < l.led_irradiance_rgb.size(); ++i)
      led_luminance[i] = luminance(&l.led_irradiance_rgb[3 * i]);
    lighting = std::move(l);
    lighting_key = key;
    lighting_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return lighting;
  }

  // --- Rendering ----------------------------------------------------------------------------

  void ensure_target(std::unique_ptr<GpuTarget>& t, int w, int h) {
    if (!t || t->width() != w || t->height() != h) t = std::make_unique<GpuTarget>(w, h);
  }

  // Renders the shown source (and the split one) into their targets, or the parameter map.
  void render_targets() {
    if (!source_width()) return;
    const auto t0 = std::chrono::steady_clock::now();
    if (state.map != ParameterMap::kNone) {
      if (!base_maps)
        throw InputError("map " + std::string(to_string(state.map)) +
                         ": no model maps open (MAPS.exr from 'lightstage fit')");
      ensure_target(map_target, base_maps->maps.width, base_maps->maps.height);
      if (map_in_target != state.map || !edits_in_map_target ||
          *edits_in_map_target != state.edits) {
        Image colours = parameter_image(current_maps(), state.map, &legend);
        // draw_to_screen encodes sRGB: hand it linear values so the colours come out as chosen.
        for (float& v : colours.pixels) v = srgb_decode(v);
        upload_to_target(colours, *map_target);
        map_in_target = state.map;
        edits_in_map_target = state.edits;
      }
      return;
    }
    const ViewLighting& l = current_lighting();
    GpuSource* first = gpu_source(state.source);
    ensure_target(target, first->width(), first->height());
    first->render(l, *target);
    if (state.split) {
      GpuSource* second = gpu_source(*state.split);
      ensure_target(split_target, second->width(), second->height());
      second->render(l, *split_target);
    }
    glFinish();
    relight_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }

  DisplayOptions display_options() const {
    DisplayOptions o;
    if (state.map != ParameterMap::kNone) return o;
    o.exposure_stops = state.exposure_stops;
    if (state.split && split_target) {
      o.split = split_target.get();
      o.divider = state.divider;
      o.difference = state.difference;
    }
    return o;
  }

  const GpuTarget* shown_target() const {
    return state.map != ParameterMap::kNone ? map_target.get() : target.get();
  }

  // --- Environment strip --------------------------------------------------------------------

  void update_strip() {
    if (!strip_texture) glGenTextures(1, &strip_texture);
    if (strip_nearest_led.empty()) {
      strip_nearest_led.assign(kStripWidth * kStripHeight, -1);
      const double coverage = led_dirs.size() > 1 ? relight::max_nearest_neighbour_angle(led_dirs)
                                                  : M_PI;  // Cells stop at the dome's coverage.
      for (int y = 0; y < kStripHeight; ++y) {
        for (int x = 0; x < kStripWidth; ++x) {
          const Eigen::Vector3d d =
              relight::EnvironmentMap::direction((x + 0.5) / kStripWidth, (y + 0.5) / kStripHeight);
          double best = -2;
          int best_led = -1;
          for (size_t l = 0; l < led_dirs.size(); ++l) {
            if (!led_valid[l]) continue;
            const double c = d.dot(led_dirs[l].normalized());
            if (c > best) {
              best = c;
              best_led = int(l);
            }
          }
          if (best_led >= 0 && std::acos(std::clamp(best, -1.0, 1.0)) <= coverage)
            strip_nearest_led[y * kStripWidth + x] = best_led;
        }
      }
    }
    std::vector<uint8_t> rgba(kStripWidth * kStripHeight * 4, 255);
    const float scale = float(std::exp2(env_display_stops));
    for (int y = 0; y < kStripHeight; ++y) {
      for (int x = 0; x < kStripWidth; ++x) {
        const Eigen::Vector3d d =
            relight::EnvironmentMap::direction((x + 0.5) / kStripWidth, (y + 0.5) / kStripHeight);
        const Eigen::Vector3f radiance = env->radiance_toward(d, state.rotation_deg);
        const int cell = strip_nearest_led[y * kStripWidth + x];
        const int right = strip_nearest_led[y * kStripWidth + (x + 1) % kStripWidth];
        const int below =
            y + 1 < kStripHeight ? strip_nearest_led[(y + 1) * kStripWidth + x] : cell;
        // Voronoi cell boundaries darkened; outside the dome dimmed.
        const float shade = cell != right || cell != below ? 0.35f : cell < 0 ? 0.5f : 1.0f;
        for (int c = 0; c < 3; ++c) {
          rgba[(y * kStripWidth + x) * 4 + c] =
              uint8_t(std::lround(255.0f * srgb_encode(radiance[c] * scale) * shade));
        }
      }
    }
    glBindTexture(GL_TEXTURE_2D, strip_texture);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, kStripWidth, kStripHeight, 0, GL_RGBA,
                 GL_UNSIGNED_BYTE, rgba.data());
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glBindTexture(GL_TEXTURE_2D, 0);
  }

  // --- Offscreen read-back of the displayed image -------------------------------------------

  Image displayed_image() {
    render_targets();
    const GpuTarget* shown = shown_target();
    if (!shown) throw InputError("screenshot: nothing is open");
    const int w = shown->width(), h = shown->height();
    if (!screenshot_fbo || screenshot_w != w || screenshot_h != h) {
      if (!screenshot_fbo) glGenFramebuffers(1, &screenshot_fbo);
      if (!screenshot_rbo) glGenRenderbuffers(1, &screenshot_rbo);
      glBindRenderbuffer(GL_RENDERBUFFER, screenshot_rbo);
      glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
      glBindFramebuffer(GL_FRAMEBUFFER, screenshot_fbo);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                                screenshot_rbo);
      screenshot_w = w;
      screenshot_h = h;
    }
    glBindFramebuffer(GL_FRAMEBUFFER, screenshot_fbo);
    glViewport(0, 0, w, h);
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    draw_to_screen(*shown, display_options(), 0, 0, w, h);
    std::vector<uint8_t> rgba(size_t(w) * h * 4);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    Image out(w, h, 3);
    for (int y = 0; y < h; ++y) {
      const int gl_row = h - 1 - y;  // GL's row 0 is the bottom.
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c)
          out.at(x, y, c) = rgba[(size_t(gl_row) * w + x) * 4 + c] / 255.0f;
    }
    return out;
  }

  // --- Actions ------------------------------------------------------------------------------

  void save_screenshot(const fs::path& png_path) {
    Image shown = displayed_image();
    for (float& v : shown.pixels) v = srgb_decode(v);  // write_png_preview encodes sRGB again.
    if (!png_path.parent_path().empty()) fs::create_directories(png_path.parent_path());
    write_png_preview(png_path, shown);
    Image linear = shown_target()->read_back();
    linear.channel_names = {"R", "G", "B"};
    fs::path exr_path = png_path;
    exr_path.replace_extension(".exr");
    write_exr(exr_path, linear);
    last_command_line = state.to_command_line();
    std::printf("screenshot: %s, %s\nview: %s\n", png_path.c_str(), exr_path.c_str(),
                last_command_line.c_str());
    std::fflush(stdout);
  }

  void apply(const Action& action) {
    const ViewState before = state;
    try {
      const ViewState::Effect effect = state.apply(action);
      if (effect.reload) load();
      if (action.kind == Action::Kind::kSource || action.kind == Action::Kind::kSplit) {
        // An explicit choice of a source nothing provides is an error, not a silent fallback.
        if (!available(state.source) || (state.split && !available(*state.split)))
          gpu_source(!available(state.source) ? state.source : *state.split);
      }
      if (action.kind == Action::Kind::kMap && state.map != ParameterMap::kNone && !base_maps)
        throw InputError("map " + action.text + ": no model maps open");
      if (action.kind == Action::Kind::kEdit && !action.clear && !base_maps)
        throw InputError("edit: edits apply to model maps: open MAPS.exr from 'lightstage fit'");
      if (effect.screenshot) save_screenshot(*effect.screenshot);
    } catch (...) {
      state = before;
      throw;
    }
  }

  void open_dropped(const std::vector<std::string>& paths) {
    for (const std::string& path : paths) {
      Action a;
      a.kind = Action::Kind::kOpen;
      a.text = path;
      try {
        apply(a);
        error.clear();
      } catch (const std::exception& e) {
        error = e.what();
      }
    }
  }

  // --- The frame ----------------------------------------------------------------------------

  void pixel_under_mouse(int* px, int* py) const {
    *px = *py = -1;
    const ImVec2 mouse = ImGui::GetIO().MousePos;
    const int w = source_width(), h = source_height();
    if (!w) return;
    const float scale = std::min(area_w / w, area_h / h);
    const float x0 = area_x + 0.5f * (area_w - w * scale),
                y0 = area_y + 0.5f * (area_h - h * scale);
    const int x = int(std::floor((mouse.x - x0) / scale)),
              y = int(std::floor((mouse.y - y0) / scale));
    if (x >= 0 && y >= 0 && x < w && y < h) {
      *px = x;
      *py = y;
    }
  }

  void image_rect(float* x0, float* y0, float* w, float* h) const {
    const int sw = source_width(), sh = source_height();
    const float scale = sw ? std::min(area_w / sw, area_h / sh) : 1.0f;
    *w = sw * scale;
    *h = sh * scale;
    *x0 = area_x + 0.5f * (area_w - *w);
    *y0 = area_y + 0.5f * (area_h - *h);
  }

  void handle_image_mouse() {
    ImGuiIO& io = ImGui::GetIO();
    if (io.WantCaptureMouse) return;
    const ImVec2 m = io.MousePos;
    const bool inside =
        m.x >= area_x && m.y >= area_y && m.x < area_x + area_w && m.y < area_y + area_h;
    float ix, iy, iw, ih;
    image_rect(&ix, &iy, &iw, &ih);
    if (inside && io.MouseWheel != 0) state.exposure_stops += 0.25 * io.MouseWheel;
    if (inside && ImGui::IsMouseClicked(ImGuiMouseButton_Left)) {
      const float divider_x = ix + float(state.divider) * iw;
      dragging_divider = state.split && std::abs(m.x - divider_x) < 6;
      painting = !dragging_divider && brush_mode && base_maps;
      if (painting) {
        ViewEdit edit;
        if (edit_model_choice > 0) edit.model_class = relight::FitModel(edit_model_choice);
        edit.albedo_tint = Eigen::Vector3d(tint[0], tint[1], tint[2]);
        edit.roughness_scale = roughness_scale;
        edit.specular_scale = specular_scale;
        state.edits.push_back(edit);
      }
    }
    if (!ImGui::IsMouseDown(ImGuiMouseButton_Left)) {
      dragging_divider = painting = false;
      return;
    }
    if (dragging_divider) {
      state.divider = std::clamp(double((m.x - ix) / std::max(1.0f, iw)), 0.0, 1.0);
    } else if (painting) {
      int px, py;
      pixel_under_mouse(&px, &py);
      if (px >= 0 && !state.edits.empty()) {
        const float scale = iw / std::max(1, source_width());
        const BrushDab dab{(m.x - ix) / scale, (m.y - iy) / scale, brush_radius};
        auto& brush = state.edits.back().brush;
        if (brush.empty() ||
            std::hypot(brush.back().x - dab.x, brush.back().y - dab.y) > 0.5 * brush_radius)
          brush.push_back(dab);
      }
    } else if (inside || ImGui::IsMouseDragging(ImGuiMouseButton_Left)) {
      if (io.MouseDelta.x != 0 && area_w > 0) {
        state.rotation_deg += 360.0 * io.MouseDelta.x / area_w;
        state.rotation_deg -= 360.0 * std::floor(state.rotation_deg / 360.0);
      }
    }
  }

  void source_radio(const char* label, Source s, Source* value) {
    ImGui::BeginDisabled(!available(s));
    if (ImGui::RadioButton(label, *value == s)) *value = s;
    ImGui::EndDisabled();
  }

  void panel() {
    ImGui::SetNextWindowPos(ImVec2(0, 0));
    ImGui::SetNextWindowSize(ImVec2(kPanelWidth, ImGui::GetIO().DisplaySize.y));
    ImGui::Begin("lightstage view", nullptr,
                 ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
    ImGui::Text("%.1f fps; relight %.2f ms (last light weights %.2f ms)", ImGui::GetIO().Framerate,
                relight_ms, lighting_ms);
    if (ImGui::CollapsingHeader("Open", ImGuiTreeNodeFlags_DefaultOpen)) {
      ImGui::InputText("##open", &open_path);
      ImGui::SameLine();
      if (ImGui::Button("Open")) open_dropped({open_path});
      ImGui::TextWrapped("Or drop a field / maps / .lspca / session folder on the window.");
      for (const auto* p :
           {&state.session_dir, &state.field_file, &state.models_file, &state.pca_file})
        if (!p->empty()) ImGui::TextWrapped("%s", p->filename().c_str());
      if (time_steps > 1) {
        int step = state.time_step;
        if (ImGui::SliderInt("time step", &step, 0, time_steps - 1) && step != state.time_step) {
          Action a;
          a.kind = Action::Kind::kTime;
          a.value = step;
          try {
            apply(a);
          } catch (const std::exception& e) {
            error = e.what();
          }
        }
      }
    }
    if (ImGui::CollapsingHeader("Source", ImGuiTreeNodeFlags_DefaultOpen)) {
      source_radio("field", Source::kField, &state.source);
      ImGui::SameLine();
      source_radio("pca", Source::kPca, &state.source);
      ImGui::SameLine();
      source_radio("models", Source::kModels, &state.source);
      if (!pca_from_file && field) {
        ImGui::SliderInt("rank", &state.rank, 1, std::min(64, field->num_lights()));
      }
      const char* split_names[] = {"none", "field", "pca", "models"};
      int split_index = state.split ? int(*state.split) + 1 : 0;
      if (ImGui::Combo("split", &split_index, split_names, 4)) {
        const std::optional<Source> s =
            split_index == 0 ? std::nullopt : std::optional<Source>(Source(split_index - 1));
        if (!s || available(*s)) state.split = s;
      }
      if (state.split) {
        float divider = float(state.divider);
        if (ImGui::SliderFloat("divider", &divider, 0, 1)) state.divider = divider;
        ImGui::Checkbox("difference", &state.difference);
      }
      if (GpuSource* s = gpu_field.get(); s && state.source == Source::kField)
        ImGui::TextWrapped("%s", s->note().c_str());
    }
    if (ImGui::CollapsingHeader("Lighting", ImGuiTreeNodeFlags_DefaultOpen)) {
      const auto names = builtin_environment_names();
      if (ImGui::BeginCombo("environment", state.environment.c_str())) {
        for (const std::string& name : names) {
          if (ImGui::Selectable(name.c_str(), name == state.environment)) {
            Action a;
            a.kind = Action::Kind::kEnvironment;
            a.text = name;
            try {
              apply(a);
            } catch (const std::exception& e) {
              error = e.what();
            }
          }
        }
        ImGui::EndCombo();
      }
      ImGui::InputText("##env", &env_path);
      ImGui::SameLine();
      if (ImGui::Button("Load map")) {
        Action a;
        a.kind = Action::Kind::kEnvironment;
        a.text = env_path;
        try {
          apply(a);
        } catch (const std::exception& e) {
          error = e.what();
        }
      }
      float rotation = float(state.rotation_deg);
      if (ImGui::SliderFloat("rotation", &rotation, 0, 360, "%.1f deg"))
        state.rotation_deg = rotation;
      float exposure = float(state.exposure_stops);
      if (ImGui::SliderFloat("exposure", &exposure, -10, 10, "%.2f stops"))
        state.exposure_stops = exposure;
      ImGui::Checkbox("point light (drag on the strip)", &state.point_light);
      if (state.point_light) {
        ImGui::Text("light dir %.2f %.2f %.2f", state.light_dir.x(), state.light_dir.y(),
                    state.light_dir.z());
      }
      if (!led_luminance.empty()) {
        ImGui::PlotHistogram("LED weights", led_luminance.data(), int(led_luminance.size()), 0,
                             nullptr, 0.0f, FLT_MAX, ImVec2(0, 50));
      }
    }
    if (ImGui::CollapsingHeader("Parameter map")) {
      const char* map_names[] = {"none",  "normal", "albedo",     "roughness", "ks",
                                 "sigma", "model",  "confidence", "residual"};
      int map_index = int(state.map);
      ImGui::BeginDisabled(!base_maps);
      if (ImGui::Combo("map", &map_index, map_names, 9)) state.map = ParameterMap(map_index);
      ImGui::EndDisabled();
      draw_legend();
    }
    if (ImGui::CollapsingHeader("Edit models")) edit_panel();
    if (ImGui::CollapsingHeader("Screenshot", ImGuiTreeNodeFlags_DefaultOpen)) {
      ImGui::InputText("##shot", &screenshot_path);
      ImGui::SameLine();
      if (ImGui::Button("Save")) {
        try {
          save_screenshot(screenshot_path);
        } catch (const std::exception& e) {
          error = e.what();
        }
      }
      if (!last_command_line.empty()) {
        ImGui::TextWrapped("%s", last_command_line.c_str());
        if (ImGui::Button("Copy command line")) ImGui::SetClipboardText(last_command_line.c_str());
      }
    }
    hover_info();
    ImGui::End();
  }

  void draw_legend() {
    if (state.map == ParameterMap::kNone) return;
    if (legend.categorical) {
      const char* names[] = {"flagged", "Lambert", "Oren-Nayar", "Lambert + TS", "Lambert + Phong"};
      for (int i = 0; i < 5; ++i) {
        const Eigen::Vector3f& c = kModelColours[i];
        ImGui::ColorButton(names[i], ImVec4(c.x(), c.y(), c.z(), 1), ImGuiColorEditFlags_NoTooltip,
                           ImVec2(12, 12));
        ImGui::SameLine();
        ImGui::TextUnformatted(names[i]);
      }
      return;
    }
    if (legend.low.empty()) {
      ImGui::TextWrapped(state.map == ParameterMap::kNormal ? "RGB = 0.5 + 0.5 (x, y, z)"
                                                            : "albedo RGB (sRGB display)");
      return;
    }
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float w = ImGui::GetContentRegionAvail().x, h = 12;
    for (int i = 0; i < 64; ++i) {
      const Eigen::Vector3f c = ramp((i + 0.5f) / 64);
      draw->AddRectFilled(ImVec2(p.x + w * i / 64, p.y), ImVec2(p.x + w * (i + 1) / 64, p.y + h),
                          ImColor(c.x(), c.y(), c.z()));
    }
    ImGui::Dummy(ImVec2(w, h));
    ImGui::TextUnformatted(legend.low.c_str());
    ImGui::SameLine(std::max(0.0f, w - ImGui::CalcTextSize(legend.high.c_str()).x));
    ImGui::TextUnformatted(legend.high.c_str());
    ImGui::TextDisabled("black: no fit / no lobe");
  }

  void edit_panel() {
    ImGui::BeginDisabled(!base_maps);
    const char* classes[] = {"any model", "lambert", "oren_nayar", "torrance_sparrow", "phong"};
    ImGui::Combo("select", &edit_model_choice, classes, 5);
    ImGui::ColorEdit3("albedo tint", tint, ImGuiColorEditFlags_Float);
    ImGui::SliderFloat("roughness x", &roughness_scale, 0.1f, 5.0f, "%.2f",
                       ImGuiSliderFlags_Logarithmic);
    ImGui::SliderFloat("specular x", &specular_scale, 0.0f, 5.0f, "%.2f");
    if (ImGui::Button("Apply to the class")) {
      ViewEdit edit;
      if (edit_model_choice > 0) edit.model_class = relight::FitModel(edit_model_choice);
      edit.albedo_tint = Eigen::Vector3d(tint[0], tint[1], tint[2]);
      edit.roughness_scale = roughness_scale;
      edit.specular_scale = specular_scale;
      state.edits.push_back(edit);
    }
    ImGui::Checkbox("brush (paint on the image)", &brush_mode);
    ImGui::SliderFloat("brush radius", &brush_radius, 1, 64, "%.0f px");
    ImGui::Text("%zu edits", state.edits.size());
    ImGui::SameLine();
    if (ImGui::Button("Undo") && !state.edits.empty()) state.edits.pop_back();
    ImGui::SameLine();
    if (ImGui::Button("Clear")) state.edits.clear();
    ImGui::InputText("##edits", &edit_file);
    ImGui::SameLine();
    if (ImGui::Button("Save edit file")) {
      try {
        write_edit_file(edit_file, state.edits, base_maps->maps.width, base_maps->maps.height);
        error.clear();
      } catch (const std::exception& e) {
        error = e.what();
      }
    }
    ImGui::EndDisabled();
  }

  // Values of the pixel under the mouse, and a polar plot of its samples against its fit along
  // the plane of incidence (normal and view direction).
  void hover_info() {
    int px, py;
    pixel_under_mouse(&px, &py);
    if (px < 0) return;
    ImGui::Separator();
    ImGui::Text("pixel (%d, %d)", px, py);
    if (field) {
      double sum[3] = {0, 0, 0};
      const auto& e = current_lighting().led_irradiance_rgb;
      const float* r = field->pixel(px, py);
      for (int l = 0; l < field->num_lights() && 3 * size_t(l) + 2 < e.size(); ++l)
        for (int c = 0; c < 3; ++c) sum[c] += double(r[3 * l + c]) * e[3 * l + c];
      ImGui::Text("field relit %.4g %.4g %.4g", sum[0], sum[1], sum[2]);
    }
    if (!base_maps) return;
    const relight::ModelMaps& maps = current_maps();
    const relight::FitModel model = maps.model(px, py);
    ImGui::Text("model %s", relight::to_string(model));
    if (model == relight::FitModel::kNone) return;
    const Eigen::Vector3d n(maps.at(px, py, relight::kMapNormalX),
                            maps.at(px, py, relight::kMapNormalY),
                            maps.at(px, py, relight::kMapNormalZ));
    ImGui::Text("normal %.3f %.3f %.3f", n.x(), n.y(), n.z());
    ImGui::Text("albedo %.3f %.3f %.3f", maps.at(px, py, relight::kMapAlbedoR),
                maps.at(px, py, relight::kMapAlbedoG), maps.at(px, py, relight::kMapAlbedoB));
    ImGui::Text("ks %.3f  m %.3f  sigma %.3f", maps.at(px, py, relight::kMapKs),
                maps.at(px, py, relight::kMapRoughness), maps.at(px, py, relight::kMapSigma));
    ImGui::Text("confidence %.3f  chi2/dof %.3g", maps.at(px, py, relight::kMapConfidence),
                maps.at(px, py, relight::kMapResidual));
    polar_plot(maps, px, py, n);
  }

  void polar_plot(const relight::ModelMaps& maps, int px, int py, const Eigen::Vector3d& n) {
    const Eigen::Vector3d wo(0, 0, 1);  // Orthographic view, as the fit assumes by default.
    Eigen::Vector3d t = wo - n * n.dot(wo);
    if (t.norm() < 1e-3) t = Eigen::Vector3d(1, 0, 0) - n * n.x();
    t.normalize();
    const Eigen::Vector3d plane_normal = n.cross(t).normalized();
    // The fit: a one-pixel copy of the maps rendered under a unit light from each angle.
    relight::ModelMaps one;
    one.maps = Image(1, 1, maps.maps.channels);
    for (int c = 0; c < maps.maps.channels; ++c) one.maps.at(0, 0, c) = maps.maps.at(px, py, c);
    one.maps.channel_names = maps.maps.channel_names;
    std::vector<std::pair<float, float>> curve;  // (angle from the normal, luminance).
    float peak = 1e-12f;
    for (int a = -88; a <= 88; a += 4) {
      const double rad = a * M_PI / 180;
      const Eigen::Vector3d wi = std::cos(rad) * n + std::sin(rad) * t;
      const Image v = relight::render_models(
          one, relight::LightingForModels::directional(wi, Eigen::Vector3d(1, 1, 1)));
      curve.emplace_back(float(rad), luminance(v.pixels.data()));
      peak = std::max(peak, curve.back().second);
    }
    std::vector<std::pair<float, float>> samples;
    if (field) {
      for (int l = 0; l < field->num_lights(); ++l) {
        if (!field->lights()[l].valid) continue;
        const Eigen::Vector3d d = field->lights()[l].dir_in_stage.normalized();
        if (std::abs(d.dot(plane_normal)) > std::sin(15 * M_PI / 180) || d.dot(n) <= 0) continue;
        samples.emplace_back(float(std::atan2(d.dot(t), d.dot(n))),
                             luminance(field->pixel(px, py) + 3 * l));
        peak = std::max(peak, samples.back().second);
      }
    }
    ImGui::Text("plane of incidence (+-15 deg): samples vs fit");
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float radius = 110;
    const ImVec2 origin(p.x + radius + 5, p.y + radius + 5);
    ImGui::Dummy(ImVec2(2 * radius + 10, radius + 15));
    draw->AddCircle(origin, radius, IM_COL32(90, 90, 90, 255), 48);
    draw->AddLine(ImVec2(origin.x - radius, origin.y), ImVec2(origin.x + radius, origin.y),
                  IM_COL32(90, 90, 90, 255));
    auto to_screen = [&](float angle, float value) {
      const float r = radius * value / peak;
      return ImVec2(origin.x + r * std::sin(angle), origin.y - r * std::cos(angle));
    };
    for (size_t i = 1; i < curve.size(); ++i) {
      draw->AddLine(to_screen(curve[i - 1].first, curve[i - 1].second),
                    to_screen(curve[i].first, curve[i].second), IM_COL32(255, 170, 40, 255), 2);
    }
    for (const auto& [angle, value] : samples)
      draw->AddCircleFilled(to_screen(angle, value), 3, IM_COL32(80, 200, 255, 255));
    ImGui::TextDisabled("orange: fit (f cos, unit light); blue: measured");
  }

  void strip_panel() {
    const ImVec2 display = ImGui::GetIO().DisplaySize;
    ImGui::SetNextWindowPos(ImVec2(kPanelWidth, display.y - kStripPanelHeight));
    ImGui::SetNextWindowSize(ImVec2(display.x - kPanelWidth, kStripPanelHeight));
    ImGui::Begin("environment", nullptr,
                 ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                     ImGuiWindowFlags_NoScrollbar);
    update_strip();
    const float w = 2.0f * kStripHeight, h = float(kStripHeight);
    const ImVec2 p = ImGui::GetCursorScreenPos();
    ImGui::Image(ImTextureID(intptr_t(strip_texture)), ImVec2(w, h));
    ImGui::SetCursorScreenPos(p);
    ImGui::InvisibleButton("strip", ImVec2(w, h));
    if (ImGui::IsItemActive() && state.point_light) {
      const ImVec2 m = ImGui::GetIO().MousePos;
      const double u = std::clamp((m.x - p.x) / w, 0.0f, 0.9999f);
      const double v = std::clamp((m.y - p.y) / h, 0.0f, 1.0f);
      state.light_dir = relight::EnvironmentMap::direction(u, v);
    }
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const float max_weight = led_luminance.empty()
                                 ? 0.0f
                                 : *std::max_element(led_luminance.begin(), led_luminance.end());
    for (size_t l = 0; l < led_dirs.size(); ++l) {
      const Eigen::Vector2d uv = relight::EnvironmentMap::uv(led_dirs[l].normalized());
      const float weight = max_weight > 0 && l < led_luminance.size()
                               ? std::sqrt(std::max(0.0f, led_luminance[l]) / max_weight)
                               : 0.0f;
      draw->AddCircleFilled(
          ImVec2(p.x + float(uv.x()) * w, p.y + float(uv.y()) * h), 1.5f + 4.0f * weight,
          led_valid[l] ? IM_COL32(255, 230, 60, 220) : IM_COL32(255, 60, 60, 220));
    }
    if (state.point_light) {
      const Eigen::Vector2d uv = relight::EnvironmentMap::uv(state.light_dir.normalized());
      draw->AddCircle(ImVec2(p.x + float(uv.x()) * w, p.y + float(uv.y()) * h), 7,
                      IM_COL32(255, 255, 255, 255), 16, 2);
    }
    ImGui::SameLine();
    ImGui::BeginGroup();
    ImGui::Text("%s, rotated %.1f deg", state.environment.c_str(), state.rotation_deg);
    ImGui::TextWrapped(
        "LEDs (yellow, size ~ weight; red: dead) and their Voronoi cells; dimmed: not covered by "
        "the dome. Drag on the image to rotate, scroll for exposure%s.",
        state.point_light ? "; drag here to move the light" : "");
    ImGui::EndGroup();
    ImGui::End();
  }

  void error_banner() {
    if (error.empty()) return;
    const ImVec2 display = ImGui::GetIO().DisplaySize;
    ImGui::SetNextWindowPos(ImVec2(kPanelWidth + 10, 10));
    ImGui::SetNextWindowSize(ImVec2(std::max(200.0f, display.x - kPanelWidth - 20), 0));
    ImGui::PushStyleColor(ImGuiCol_WindowBg, IM_COL32(140, 20, 20, 235));
    ImGui::Begin("error", nullptr,
                 ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                     ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::TextWrapped("%s", error.c_str());
    if (ImGui::Button("Dismiss")) error.clear();
    ImGui::End();
    ImGui::PopStyleColor();
  }

  bool frame() {
    glfwPollEvents();
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    const ImVec2 display = ImGui::GetIO().DisplaySize;
    area_x = kPanelWidth;
    area_y = 0;
    area_w = std::max(1.0f, display.x - kPanelWidth);
    area_h = std::max(1.0f, display.y - kStripPanelHeight);
    panel();
    strip_panel();
    error_banner();
    handle_image_mouse();
    ImGui::Render();

    int fb_w = 0, fb_h = 0;
    glfwGetFramebufferSize(window->handle(), &fb_w, &fb_h);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, fb_w, fb_h);
    glClearColor(0.1f, 0.1f, 0.11f, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    try {
      render_targets();
      if (const GpuTarget* shown = shown_target()) {
        float ix, iy, iw, ih;
        image_rect(&ix, &iy, &iw, &ih);
        const float sx = display.x > 0 ? fb_w / display.x : 1.0f;
        const float sy = display.y > 0 ? fb_h / display.y : 1.0f;
        draw_to_screen(*shown, display_options(), int(std::lround(ix * sx)),
                       int(std::lround(fb_h - (iy + ih) * sy)), int(std::lround(iw * sx)),
                       int(std::lround(ih * sy)));
        glViewport(0, 0, fb_w, fb_h);
      }
    } catch (const InputError& e) {
      error = e.what();
    }
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    glfwSwapBuffers(window->handle());
    return !glfwWindowShouldClose(window->handle());
  }
};

ViewerApp::ViewerApp(const ViewState& state, bool visible) : impl_(std::make_unique<Impl>()) {
  impl_->state = state;
  impl_->window = std::make_unique<GlWindow>(state.window_width, state.window_height,
                                             "lightstage view", visible);
  glfwSwapInterval(visible ? 1 : 0);
  IMGUI_CHECKVERSION();
  impl_->imgui = ImGui::CreateContext();
  ImGui::SetCurrentContext(impl_->imgui);
  ImGui::GetIO().IniFilename = nullptr;  // No imgui.ini beside the user's files.
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(impl_->window->handle(), /*install_callbacks=*/true);
  ImGui_ImplOpenGL3_Init("#version 330 core");
  impl_->imgui_ready = true;
  glfwSetWindowUserPointer(impl_->window->handle(), impl_.get());
  glfwSetDropCallback(impl_->window->handle(),
                      [](GLFWwindow* window, int count, const char** paths) {
                        auto* impl = static_cast<Impl*>(glfwGetWindowUserPointer(window));
                        if (impl)
                          impl->open_dropped(std::vector<std::string>(paths, paths + count));
                      });
  impl_->load();
}

ViewerApp::~ViewerApp() = default;

const ViewState& ViewerApp::state() const { return impl_->state; }
void ViewerApp::apply(const Action& action) {
  make_current();
  impl_->apply(action);
}
void ViewerApp::handle_drop(const std::vector<std::string>& paths) {
  make_current();
  impl_->open_dropped(paths);
}
const std::string& ViewerApp::error_message() const { return impl_->error; }
bool ViewerApp::frame() {
  make_current();
  return impl_->frame();
}
void ViewerApp::run() {
  while (impl_->frame()) {
  }
}

Image ViewerApp::relit_image() {
  make_current();
  impl_->render_targets();
  const GpuTarget* shown = impl_->shown_target();
  if (!shown) throw InputError("nothing is open");
  return shown->read_back();
}

Image ViewerApp::displayed_image() {
  make_current();
  return impl_->displayed_image();
}
void ViewerApp::save_screenshot(const fs::path& png_path) {
  make_current();
  impl_->save_screenshot(png_path);
}
const ViewLighting& ViewerApp::lighting() { return impl_->current_lighting(); }

// Several viewers may live in one process (tests): each call works in its own GL context.
void ViewerApp::make_current() {
  if (glfwGetCurrentContext() != impl_->window->handle())
    glfwMakeContextCurrent(impl_->window->handle());
  ImGui::SetCurrentContext(impl_->imgui);
}
double ViewerApp::last_relight_ms() const { return impl_->relight_ms; }
double ViewerApp::last_lighting_ms() const { return impl_->lighting_ms; }

}  // namespace ls::viewer
