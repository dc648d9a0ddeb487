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
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/fit/model_edit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/light_cells.h"
#include "viewer/cpu_sources.h"
#include "viewer/gl_window.h"
#include "viewer/view_lighting.h"
#include "viewer/viewer_app_impl.h"

namespace ls::viewer {

namespace fs = std::filesystem;
using namespace app_detail;

namespace {

// On software OpenGL the CPU relights the field and the PCA faster than the emulated shaders do
// (viewer/cpu_sources.h); on a GPU the shaders.
std::unique_ptr<GpuSource> field_source(const capture::ReflectanceField& field) {
  return software_renderer() ? relight_field_on_cpu(field) : upload_field(field);
}
std::unique_ptr<GpuSource> pca_source(const relight::PcaField& pca) {
  return software_renderer() ? relight_pca_on_cpu(pca) : upload_pca(pca);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// ViewerApp::Impl: lifecycle, loading, GPU sources, lighting, rendering, actions, the frame.

ViewerApp::Impl::~Impl() {
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

int ViewerApp::Impl::source_width() const {
  if (field) return field->width();
  if (pca_from_file) return pca_from_file->width();
  if (base_maps) return base_maps->maps.width;
  return 0;
}

int ViewerApp::Impl::source_height() const {
  if (field) return field->height();
  if (pca_from_file) return pca_from_file->height();
  if (base_maps) return base_maps->maps.height;
  return 0;
}

bool ViewerApp::Impl::available(Source s) const {
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

const relight::ModelMaps& ViewerApp::Impl::current_maps() {
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

GpuSource* ViewerApp::Impl::gpu_source(Source s) {
  if (!available(s)) {
    throw InputError(std::string("source ") + to_string(s) +
                     ": nothing open provides it (models need MAPS.exr from 'lightstage fit'; "
                     "pca needs a field or a .lspca)");
  }
  switch (s) {
    case Source::kField:
      if (!gpu_field) gpu_field = field_source(*field);
      return gpu_field.get();
    case Source::kPca: {
      const bool from_file = pca_from_file.has_value();
      const int rank = from_file ? pca_from_file->rank() : state.rank;
      if (!gpu_pca || gpu_pca_from_file != from_file || gpu_pca_rank != rank) {
        if (from_file) {
          gpu_pca = pca_source(*pca_from_file);
        } else {
          relight::PcaOptions options;
          options.rank = std::min(rank, field->num_lights());
          pca_from_field = relight::PcaField::build(*field, options);
          gpu_pca = pca_source(*pca_from_field);
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
        gpu_models = upload_models(current_maps(), {},
                                   state.exact_models ? ModelShading::kExact : ModelShading::kAuto);
        edits_on_gpu = state.edits;
        models_exact_on_gpu = state.exact_models;
      }
      return gpu_models.get();
  }
  return nullptr;
}

// --- Lighting -----------------------------------------------------------------------------

bool ViewerApp::Impl::shows(Source s) const {
  return state.map == ParameterMap::kNone && (state.source == s || state.split == s);
}

const ViewLighting& ViewerApp::Impl::current_lighting() {
  // Compact sources are split off only for a field on show, and distant lights made
  // only for models on show: a rotation costs what the shown sources need.
  EnvironmentNeeds needs;
  const bool field_on_show = field.has_value() && shows(Source::kField);
  const bool pca_on_show = shows(Source::kPca);
  needs.field_sources = field_on_show || pca_on_show;
  // The whole map per LED for a source that cannot add the bright sources back (the shader PCA,
  // a field shown as PCA over the GPU budget).
  needs.whole_map_led_weights = (pca_on_show && !(gpu_pca && gpu_pca->adds_bright_sources())) ||
                                (field_on_show && !(gpu_field && gpu_field->adds_bright_sources()));
  needs.model_lights = shows(Source::kModels);
  const LightingKey key{.environment = state.environment,
                        .rotation_deg = state.rotation_deg,
                        .point_light = state.point_light,
                        .light_dir = state.light_dir,
                        .led_count = leds.size(),
                        .needs = needs};
  if (lighting_key && *lighting_key == key) return lighting;
  const auto t0 = std::chrono::steady_clock::now();
  ViewLighting l;
  if (state.point_light) {
    l.lights = relight::LightingForModels::directional(state.light_dir.normalized(),
                                                       Eigen::Vector3d(1, 1, 1));
    if (!leds.empty()) {
      // Between the LEDs the field is interpolated (relight/compact/pca_field.h LightInterpolator).
      const relight::LightInterpolator interpolator(leds);
      l.led_irradiance_rgb = interpolator.led_irradiance(l.lights);
    }
  } else {
    // With LEDs known the models get the light the dome covers, as `lightstage relight`
    // --models with a field does, so field and models are lit alike.
    l = environment_lighting(*env, state.rotation_deg, leds, needs);
  }
  // The LED weights shown: the whole map's, or the field's when only those were made.
  const std::vector<float>& weights =
      l.led_irradiance_rgb.empty() ? l.field_irradiance_rgb() : l.led_irradiance_rgb;
  led_luminance.assign(leds.size(), 0.0f);
  for (size_t i = 0; i < leds.size() && 3 * i + 2 < weights.size(); ++i)
    led_luminance[i] = luminance(&weights[3 * i]);
  lighting = std::move(l);
  lighting_key = key;
  lighting_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return lighting;
}

// --- Rendering ----------------------------------------------------------------------------

void ViewerApp::Impl::ensure_target(std::unique_ptr<GpuTarget>& t, int w, int h) {
  if (!t || t->width() != w || t->height() != h) t = std::make_unique<GpuTarget>(w, h);
}

void ViewerApp::Impl::render_targets() {
  if (!source_width()) return;
  const auto t0 = std::chrono::steady_clock::now();
  if (state.map != ParameterMap::kNone) {
    if (!base_maps)
      throw InputError("map " + std::string(to_string(state.map)) +
                       ": no model maps open (MAPS.exr from 'lightstage fit')");
    ensure_target(map_target, base_maps->maps.width, base_maps->maps.height);
    if (map_in_target != state.map || !edits_in_map_target || *edits_in_map_target != state.edits) {
      Image colours = parameter_image(current_maps(), state.map, &legend);
      // draw_to_screen encodes sRGB: hand it linear values so the colours come out as chosen.
      for (float& v : colours.pixels) v = srgb_decode(v);
      map_target->upload(colours);
      map_in_target = state.map;
      edits_in_map_target = state.edits;
    }
    return;
  }
  // The sources first: what the lighting must hold depends on them.
  GpuSource* first = gpu_source(state.source);
  GpuSource* second = state.split ? gpu_source(*state.split) : nullptr;
  const ViewLighting& l = current_lighting();
  ensure_target(target, first->width(), first->height());
  first->render(l, *target);
  if (second) {
    ensure_target(split_target, second->width(), second->height());
    second->render(l, *split_target);
  }
  glFinish();
  relight_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

DisplayOptions ViewerApp::Impl::display_options() const {
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

const GpuTarget* ViewerApp::Impl::shown_target() const {
  return state.map != ParameterMap::kNone ? map_target.get() : target.get();
}

// --- Offscreen read-back of the displayed image -------------------------------------------

Image ViewerApp::Impl::displayed_image() {
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
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = rgba[(size_t(gl_row) * w + x) * 4 + c] / 255.0f;
  }
  return out;
}

// --- Actions ------------------------------------------------------------------------------

void ViewerApp::Impl::save_screenshot(const fs::path& png_path) {
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

void ViewerApp::Impl::apply(const Action& action) {
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

bool ViewerApp::Impl::frame() {
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
const std::string& ViewerApp::field_note() const { return impl_->field_note; }
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
std::string ViewerApp::source_shadows() const {
  return impl_->gpu_field ? impl_->gpu_field->shadows() : std::string();
}
double ViewerApp::last_relight_ms() const { return impl_->relight_ms; }
double ViewerApp::last_lighting_ms() const { return impl_->lighting_ms; }

}  // namespace ls::viewer
