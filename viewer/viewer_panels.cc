// ViewerApp::Impl's ImGui panels, legend, polar plot and environment strip (viewer_app_impl.h).
#include "viewer/viewer_app_impl.h"

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
#include "viewer/gl_window.h"

namespace ls::viewer {

namespace fs = std::filesystem;
using namespace app_detail;

// --- Environment strip --------------------------------------------------------------------

void ViewerApp::Impl::update_strip() {
  if (!strip_texture) glGenTextures(1, &strip_texture);
  if (strip_nearest_led.empty()) {
    strip_nearest_led.assign(kStripWidth * kStripHeight, -1);
    const double coverage = leds.size() > 1
                                ? max_nearest_neighbour_angle(capture::light_directions(leds))
                                : M_PI;  // Cells stop at the dome's coverage.
    for (int y = 0; y < kStripHeight; ++y) {
      for (int x = 0; x < kStripWidth; ++x) {
        const Eigen::Vector3d d =
            physics::EnvironmentMap::direction((x + 0.5) / kStripWidth, (y + 0.5) / kStripHeight);
        double best = -2;
        int best_led = -1;
        for (size_t l = 0; l < leds.size(); ++l) {
          if (!leds[l].valid) continue;
          const double c = d.dot(leds[l].dir_in_stage.normalized());
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
          physics::EnvironmentMap::direction((x + 0.5) / kStripWidth, (y + 0.5) / kStripHeight);
      const Eigen::Vector3f radiance = env->radiance_toward(d, state.rotation_deg);
      const int cell = strip_nearest_led[y * kStripWidth + x];
      const int right = strip_nearest_led[y * kStripWidth + (x + 1) % kStripWidth];
      const int below = y + 1 < kStripHeight ? strip_nearest_led[(y + 1) * kStripWidth + x] : cell;
      // Voronoi cell boundaries darkened; outside the dome dimmed.
      const float shade = cell != right || cell != below ? 0.35f : cell < 0 ? 0.5f : 1.0f;
      for (int c = 0; c < 3; ++c) {
        rgba[(y * kStripWidth + x) * 4 + c] =
            uint8_t(std::lround(255.0f * srgb_encode(radiance[c] * scale) * shade));
      }
    }
  }
  glBindTexture(GL_TEXTURE_2D, strip_texture);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, kStripWidth, kStripHeight, 0, GL_RGBA, GL_UNSIGNED_BYTE,
               rgba.data());
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glBindTexture(GL_TEXTURE_2D, 0);
}

// --- The frame ----------------------------------------------------------------------------

void ViewerApp::Impl::pixel_under_mouse(int* px, int* py) const {
  *px = *py = -1;
  const ImVec2 mouse = ImGui::GetIO().MousePos;
  const int w = source_width(), h = source_height();
  if (!w) return;
  const float scale = std::min(area_w / w, area_h / h);
  const float x0 = area_x + 0.5f * (area_w - w * scale), y0 = area_y + 0.5f * (area_h - h * scale);
  const int x = int(std::floor((mouse.x - x0) / scale)),
            y = int(std::floor((mouse.y - y0) / scale));
  if (x >= 0 && y >= 0 && x < w && y < h) {
    *px = x;
    *py = y;
  }
}

void ViewerApp::Impl::image_rect(float* x0, float* y0, float* w, float* h) const {
  const int sw = source_width(), sh = source_height();
  const float scale = sw ? std::min(area_w / sw, area_h / sh) : 1.0f;
  *w = sw * scale;
  *h = sh * scale;
  *x0 = area_x + 0.5f * (area_w - *w);
  *y0 = area_y + 0.5f * (area_h - *h);
}

void ViewerApp::Impl::handle_image_mouse() {
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
    if (!dragging_divider && pick_material && base_maps) {
      int px, py;
      pixel_under_mouse(&px, &py);
      if (px >= 0) edit_material = int(base_maps->at(px, py, relight::kMapMaterial));
      pick_material = false;
      return;
    }
    painting = !dragging_divider && brush_mode && base_maps;
    if (painting) {
      ViewEdit edit;
      if (edit_model_choice > 0) edit.model_class = relight::FitModel(edit_model_choice);
      edit.material = edit_material;
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

void ViewerApp::Impl::source_radio(const char* label, Source s, Source* value) {
  ImGui::BeginDisabled(!available(s));
  if (ImGui::RadioButton(label, *value == s)) *value = s;
  ImGui::EndDisabled();
}

// Applies an action from a widget; a failure shows in the error banner instead of ending the app.
void ViewerApp::Impl::try_apply(const Action& action) {
  try {
    apply(action);
  } catch (const std::exception& e) {
    error = e.what();
  }
}

void ViewerApp::Impl::open_section() {
  if (!ImGui::CollapsingHeader("Open", ImGuiTreeNodeFlags_DefaultOpen)) return;
  ImGui::InputText("##open", &open_path);
  ImGui::SameLine();
  if (ImGui::Button("Open")) open_dropped({open_path});
  ImGui::TextWrapped("Or drop a field / maps / .lspca / session folder on the window.");
  for (const auto* p : {&state.session_dir, &state.field_file, &state.models_file, &state.pca_file})
    if (!p->empty()) ImGui::TextWrapped("%s", p->filename().c_str());
  if (time_steps > 1) {
    int step = state.time_step;
    if (ImGui::SliderInt("time step", &step, 0, time_steps - 1) && step != state.time_step) {
      Action a;
      a.kind = Action::Kind::kTime;
      a.value = step;
      try_apply(a);
    }
  }
}

void ViewerApp::Impl::source_section() {
  if (!ImGui::CollapsingHeader("Source", ImGuiTreeNodeFlags_DefaultOpen)) return;
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
  if (!field_note.empty() && state.source == Source::kField) {
    ImGui::TextWrapped("%s", field_note.c_str());
  }
  if (GpuSource* s = gpu_field.get(); s && state.source == Source::kField)
    ImGui::TextWrapped("%s", s->note().c_str());
}

void ViewerApp::Impl::lighting_section() {
  if (!ImGui::CollapsingHeader("Lighting", ImGuiTreeNodeFlags_DefaultOpen)) return;
  const auto names = builtin_environment_names();
  if (ImGui::BeginCombo("environment", state.environment.c_str())) {
    for (const std::string& name : names) {
      if (ImGui::Selectable(name.c_str(), name == state.environment)) {
        Action a;
        a.kind = Action::Kind::kEnvironment;
        a.text = name;
        try_apply(a);
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
    try_apply(a);
  }
  float rotation = float(state.rotation_deg);
  if (ImGui::SliderFloat("rotation", &rotation, 0, 360, "%.1f deg")) state.rotation_deg = rotation;
  float exposure = float(state.exposure_stops);
  if (ImGui::SliderFloat("exposure", &exposure, -10, 10, "%.2f stops"))
    state.exposure_stops = exposure;
  ImGui::Checkbox("point light (drag on the strip)", &state.point_light);
  if (state.point_light) {
    ImGui::Text("light dir %.2f %.2f %.2f", state.light_dir.x(), state.light_dir.y(),
                state.light_dir.z());
  } else if (lighting.split && shows(Source::kField)) {
    // What the field renders at its true direction instead of by LED cells.
    ImGui::TextWrapped("field: bright sources at their true direction (orange on the strip): %s",
                       lighting.split->report().c_str());
    if (gpu_field) ImGui::TextWrapped("shadows by %s", gpu_field->shadows().c_str());
  }
  if (!led_luminance.empty()) {
    ImGui::PlotHistogram("LED weights", led_luminance.data(), int(led_luminance.size()), 0, nullptr,
                         0.0f, FLT_MAX, ImVec2(0, 50));
  }
}

void ViewerApp::Impl::panel() {
  ImGui::SetNextWindowPos(ImVec2(0, 0));
  ImGui::SetNextWindowSize(ImVec2(kPanelWidth, ImGui::GetIO().DisplaySize.y));
  ImGui::Begin("lightstage view", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
  ImGui::Text("%.1f fps; relight %.2f ms (last light weights %.2f ms)", ImGui::GetIO().Framerate,
              relight_ms, lighting_ms);
  open_section();
  source_section();
  lighting_section();
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

void ViewerApp::Impl::edit_panel() {
  ImGui::BeginDisabled(!base_maps);
  const char* classes[] = {"any model", "lambert", "oren_nayar", "torrance_sparrow", "phong"};
  ImGui::Combo("select", &edit_model_choice, classes, 5);
  ImGui::BeginDisabled(!base_maps || base_maps->materials.empty());
  ImGui::Checkbox("pick material (click a pixel)", &pick_material);
  ImGui::EndDisabled();
  if (edit_material > 0 && base_maps && size_t(edit_material) <= base_maps->materials.size()) {
    const relight::Material& picked = base_maps->materials[size_t(edit_material - 1)];
    ImGui::Text("material %d: %s, albedo %.2f %.2f %.2f", edit_material,
                relight::to_string(picked.model), picked.albedo(0), picked.albedo(1),
                picked.albedo(2));
    ImGui::SameLine();
    if (ImGui::Button("any material")) edit_material = 0;
  } else {
    ImGui::TextDisabled("any material");
  }
  ImGui::ColorEdit3("albedo tint", tint, ImGuiColorEditFlags_Float);
  ImGui::SliderFloat("roughness x", &roughness_scale, 0.1f, 5.0f, "%.2f",
                     ImGuiSliderFlags_Logarithmic);
  ImGui::SliderFloat("specular x", &specular_scale, 0.0f, 5.0f, "%.2f");
  if (ImGui::Button(edit_material > 0 ? "Apply to the material" : "Apply to the class")) {
    ViewEdit edit;
    if (edit_model_choice > 0) edit.model_class = relight::FitModel(edit_model_choice);
    edit.material = edit_material;
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

void ViewerApp::Impl::hover_info() {
  int px, py;
  pixel_under_mouse(&px, &py);
  if (px < 0) return;
  ImGui::Separator();
  ImGui::Text("pixel (%d, %d)", px, py);
  if (field) {
    double sum[3] = {0, 0, 0};
    const ViewLighting& l = current_lighting();
    const auto& e = l.field_irradiance_rgb();
    const float* r = field->pixel(px, py);
    for (int i = 0; i < field->num_lights() && 3 * size_t(i) + 2 < e.size(); ++i)
      for (int c = 0; c < 3; ++c) sum[c] += double(r[3 * i + c]) * e[3 * i + c];
    ImGui::Text(l.split ? "field by LED cells %.4g %.4g %.4g (+ bright sources)"
                        : "field relit %.4g %.4g %.4g",
                sum[0], sum[1], sum[2]);
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
  if (const int material = int(maps.at(px, py, relight::kMapMaterial)); material > 0) {
    ImGui::Text("material %d (weight %.3f)", material,
                maps.at(px, py, relight::kMapMaterialWeight));
  }
  polar_plot(maps, px, py, n);
}

void ViewerApp::Impl::polar_plot(const relight::ModelMaps& maps, int px, int py,
                                 const Eigen::Vector3d& n) {
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

void ViewerApp::Impl::strip_panel() {
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
    state.light_dir = physics::EnvironmentMap::direction(u, v);
  }
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const float max_weight =
      led_luminance.empty() ? 0.0f : *std::max_element(led_luminance.begin(), led_luminance.end());
  for (size_t l = 0; l < leds.size(); ++l) {
    const Eigen::Vector2d uv = physics::EnvironmentMap::uv(leds[l].dir_in_stage.normalized());
    const float weight = max_weight > 0 && l < led_luminance.size()
                             ? std::sqrt(std::max(0.0f, led_luminance[l]) / max_weight)
                             : 0.0f;
    draw->AddCircleFilled(ImVec2(p.x + float(uv.x()) * w, p.y + float(uv.y()) * h),
                          1.5f + 4.0f * weight,
                          leds[l].valid ? IM_COL32(255, 230, 60, 220) : IM_COL32(255, 60, 60, 220));
  }
  if (state.point_light) {
    const Eigen::Vector2d uv = physics::EnvironmentMap::uv(state.light_dir.normalized());
    draw->AddCircle(ImVec2(p.x + float(uv.x()) * w, p.y + float(uv.y()) * h), 7,
                    IM_COL32(255, 255, 255, 255), 16, 2);
  } else if (lighting.split && shows(Source::kField)) {
    for (const relight::PlacedSource& source : lighting.split->sources) {
      const Eigen::Vector2d uv = physics::EnvironmentMap::uv(source.in_stage.dir);
      draw->AddCircle(ImVec2(p.x + float(uv.x()) * w, p.y + float(uv.y()) * h), 9,
                      IM_COL32(255, 140, 0, 255), 16, 2);
    }
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

void ViewerApp::Impl::error_banner() {
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

}  // namespace ls::viewer
