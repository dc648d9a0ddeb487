#pragma once
// Internal to the viewer library: ViewerApp's implementation, shared by viewer/viewer_app.cc
// (lifecycle, sources, lighting, the frame) and viewer/viewer_panels.cc (ImGui panels, legend,
// polar plot, environment strip).
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/fit/model_render.h"
#include "viewer/gl_window.h"
#include "viewer/gpu_relight.h"
#include "viewer/view_lighting.h"
#include "viewer/viewer_app.h"
#include "viewer/viewer_state.h"

struct ImGuiContext;

namespace ls::viewer {

namespace app_detail {

inline constexpr float kPanelWidth = 340.0f;
inline constexpr int kStripWidth = 256, kStripHeight = 128;
inline constexpr float kStripPanelHeight = kStripHeight + 56.0f;

// What a frame's lighting was computed for (ViewerApp::Impl::current_lighting): it is computed
// again when any of this changes.
struct LightingKey {
  std::string environment;
  double rotation_deg = 0;
  bool point_light = false;
  Eigen::Vector3d light_dir{0, 0, 0};
  size_t led_count = 0;
  EnvironmentNeeds needs;
  bool operator==(const LightingKey&) const = default;
};

struct Legend {
  bool categorical = false;
  std::string low, high;  // Ramp ends.
};

// A parameter map as sRGB-encoded colours, and its legend (viewer/viewer_panels.cc).
Image parameter_image(const relight::ModelMaps& maps, ParameterMap which, Legend* legend);

}  // namespace app_detail

struct ViewerApp::Impl {
  ViewState state;
  std::unique_ptr<GlWindow> window;
  bool imgui_ready = false;
  ImGuiContext* imgui = nullptr;  // Each viewer has its own (ImGui's current one is global).
  std::string error;

  // What is loaded, and from where (so a reload touches only what changed).
  std::optional<capture::ReflectanceField> field;
  int time_steps = 1;
  std::filesystem::path loaded_session, loaded_field, loaded_models, loaded_pca;
  int loaded_time_step = -1;
  // What the field shown is when it is not the file's (a field over --memory, reduced).
  std::string field_note;
  std::optional<relight::ModelMaps> base_maps, edited_maps;
  std::optional<std::vector<ViewEdit>> edits_in_maps;
  std::optional<relight::PcaField> pca_from_file, pca_from_field;
  std::vector<capture::FieldLight> leds;  // The field's lights, or the PCA's without a field.
  std::optional<physics::EnvironmentMap> env;
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
  app_detail::Legend legend;
  unsigned strip_texture = 0;
  std::vector<int> strip_nearest_led;  // Per strip pixel, -1 outside the dome.
  unsigned screenshot_fbo = 0, screenshot_rbo = 0;
  int screenshot_w = 0, screenshot_h = 0;

  // Lighting and what it was computed for.
  ViewLighting lighting;
  std::optional<app_detail::LightingKey> lighting_key;
  std::vector<float> led_luminance;

  double relight_ms = 0;   // Last frame: light weights (when they changed) + GPU relighting.
  double lighting_ms = 0;  // The last time the light weights were computed.
  std::string last_command_line;
  bool painting = false, dragging_divider = false;

  // UI inputs.
  std::string open_path, env_path, edit_file = "edits.json", screenshot_path = "view.png";
  int edit_model_choice = 0;  // 0 = any class.
  // "Make this material rougher": with picking on, a click on the image selects the basis
  // material of the pixel under it (relight/fit/fit.h kMapMaterial; 0 = none).
  bool pick_material = false;
  int edit_material = 0;
  bool brush_mode = false;
  float brush_radius = 8.0f;
  float tint[3] = {1, 1, 1};
  float roughness_scale = 1, specular_scale = 1;

  // Image area in window pixels (top-left origin).
  float area_x = 0, area_y = 0, area_w = 0, area_h = 0;

  ~Impl();

  // --- Loading ------------------------------------------------------------------------------

  int source_width() const;
  int source_height() const;
  bool available(Source s) const;
  void check_size(int w, int h, const std::filesystem::path& path) const;
  void set_leds_from_field();

  // Brings the loaded data in line with the state. InputError on a file that cannot be read;
  // what was loaded before stays.
  void load();
  // The field file whole, or reduced to fit `memory` (capture/reduced_field.h), field_note
  // saying so.
  capture::ReflectanceField read_field_within(const std::filesystem::path& file,
                                              const MemoryBudget& memory);
  void on_field_changed();
  const relight::ModelMaps& current_maps();

  // --- GPU sources --------------------------------------------------------------------------

  GpuSource* gpu_source(Source s);

  // --- Lighting -----------------------------------------------------------------------------

  // Whether the image area shows source `s` (left of the divider or right of it).
  bool shows(Source s) const;
  // The lighting of the frame, computed when the environment, its rotation, the point light or
  // what is shown changed.
  const ViewLighting& current_lighting();

  // --- Rendering ----------------------------------------------------------------------------

  void ensure_target(std::unique_ptr<GpuTarget>& t, int w, int h);

  // Renders the shown source (and the split one) into their targets, or the parameter map.
  void render_targets();
  DisplayOptions display_options() const;
  const GpuTarget* shown_target() const;

  // --- Environment strip --------------------------------------------------------------------

  void update_strip();

  // --- Offscreen read-back of the displayed image -------------------------------------------

  Image displayed_image();

  // --- Actions ------------------------------------------------------------------------------

  void save_screenshot(const std::filesystem::path& png_path);
  void apply(const Action& action);
  void open_dropped(const std::vector<std::string>& paths);

  // --- The frame ----------------------------------------------------------------------------

  void pixel_under_mouse(int* px, int* py) const;
  void image_rect(float* x0, float* y0, float* w, float* h) const;
  void handle_image_mouse();
  void source_radio(const char* label, Source s, Source* value);
  void try_apply(const Action& action);
  void open_section();
  void source_section();
  void lighting_section();
  void panel();
  void draw_legend();
  void edit_panel();

  // Values of the pixel under the mouse, and a polar plot of its samples against its fit along
  // the plane of incidence (normal and view direction).
  void hover_info();
  void polar_plot(const relight::ModelMaps& maps, int px, int py, const Eigen::Vector3d& n);
  void strip_panel();
  void error_banner();
  bool frame();
};

}  // namespace ls::viewer
