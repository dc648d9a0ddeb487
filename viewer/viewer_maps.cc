// Parameter maps of fitted models as false-colour images, and their legend (viewer_app_impl.h).
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

namespace {

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

}  // namespace

namespace app_detail {

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
          if (fitted) {
            c = Eigen::Vector3f(p[relight::kMapNormalX], p[relight::kMapNormalY],
                                p[relight::kMapNormalZ]) *
                    0.5f +
                Eigen::Vector3f::Constant(0.5f);
          }
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

}  // namespace app_detail

void ViewerApp::Impl::draw_legend() {
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

}  // namespace ls::viewer
