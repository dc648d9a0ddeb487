// ViewerApp::Impl: opening fields, model maps, PCA files and sessions, and dropped files
// (viewer_app_impl.h).

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
#include <optional>

#include "capture/build_field.h"
#include "capture/field_file.h"
#include "capture/reduced_field.h"
#include "lightstage/errors.h"
#include "lightstage/memory.h"
#include "lightstage/session.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/fit/model_edit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/light_cells.h"
#include "viewer/cpu_sources.h"
#include "viewer/gl_window.h"
#include "viewer/viewer_app_impl.h"

namespace ls::viewer {

namespace fs = std::filesystem;
using namespace app_detail;

namespace {

fs::path data_dir() {
  if (const char* env = std::getenv("LIGHTSTAGE_DATA")) return env;
  return LIGHTSTAGE_DATA_DIR;
}

physics::EnvironmentMap load_environment(const std::string& name) {
  if (name == "uniform") return physics::EnvironmentMap(Image(64, 32, 3, 1.0f), "uniform");
  const auto names = builtin_environment_names();
  if (std::find(names.begin(), names.end(), name) != names.end()) {
    const fs::path path = data_dir() / "envmaps" / (name + ".exr");
    if (!fs::exists(path)) {
      throw InputError(path.string() + ": built-in environment \"" + name +
                       "\" not found (run 'lightstage envmaps' to write it)");
    }
    return physics::EnvironmentMap::load(path);
  }
  return physics::EnvironmentMap::load(name);
}

}  // namespace

void ViewerApp::Impl::check_size(int w, int h, const fs::path& path) const {
  const int sw = source_width(), sh = source_height();
  if (sw && (w != sw || h != sh)) {
    throw InputError(path.string() + ": size: expected " + std::to_string(sw) + "x" +
                     std::to_string(sh) + " (the size of what is open), got " + std::to_string(w) +
                     "x" + std::to_string(h));
  }
}

void ViewerApp::Impl::set_leds_from_field() {
  leds = field->lights();
  strip_nearest_led.clear();
}

capture::ReflectanceField ViewerApp::Impl::read_field_within(const fs::path& file,
                                                             const MemoryBudget& memory) {
  capture::FieldStream stream(file);
  const std::size_t budget = memory.bytes();
  const std::size_t bytes = capture::ReflectanceField::bytes_for(stream.width(), stream.height(),
                                                                 stream.header().num_lights());
  if (bytes <= budget) {
    field_note.clear();
    return capture::read_field(file);
  }
  // Half the budget for the reduced field, half for the band being read.
  const int factor = capture::reduction_factor(stream.width(), stream.height(),
                                               stream.header().num_lights(), budget / 2);
  const auto mib = [](std::size_t b) { return std::to_string(b >> 20) + " MiB"; };
  field_note = file.string() + ": " + mib(bytes) + " of values, over the " + mib(budget) +
               " memory budget (--memory): shown at 1/" + std::to_string(factor) +
               " resolution, each pixel the mean of " + std::to_string(factor) + "x" +
               std::to_string(factor) + " (fits and `lightstage relight` read the whole field)";
  std::fprintf(stderr, "%s\n", field_note.c_str());
  return capture::read_reduced_field(stream, factor, budget / 2);
}

void ViewerApp::Impl::load() {
  if (!state.session_dir.empty() &&
      (state.session_dir != loaded_session || state.time_step != loaded_time_step)) {
    const Session session = Session::open(state.session_dir);
    time_steps = std::max(1, session.stage().plan.time_steps);
    if (state.time_step < 0 || state.time_step >= time_steps) {
      throw InputError(state.session_dir.string() + ": time step: expected 0.." +
                       std::to_string(time_steps - 1) + ", got " + std::to_string(state.time_step));
    }
    capture::BuildOptions options;
    options.time_step = state.time_step;
    const CameraSpec& camera = session.stage().camera;
    const std::size_t budget = state.memory.bytes();
    if (capture::ReflectanceField::bytes_for(camera.width, camera.height,
                                             int(session.stage().leds.size())) <= budget) {
      field = capture::build_field(session, options);
      field_note.clear();
    } else {
      // Larger than the budget: built in bands into a file beside the session (as `lightstage
      // build` does), opened reduced (read_field_within says so), then removed.
      const fs::path file =
          state.session_dir.string() + ".view_t" + std::to_string(state.time_step) + ".exr";
      options.memory = MemoryBudget(budget);
      capture::build_field_file(session, options, file, {});
      capture::ReflectanceField reduced = read_field_within(file, state.memory);
      field = std::move(reduced);
      std::error_code ignored;
      fs::remove(file, ignored);
    }
    loaded_session = state.session_dir;
    loaded_time_step = state.time_step;
    loaded_field.clear();
    on_field_changed();
  }
  if (!state.field_file.empty() && state.field_file != loaded_field) {
    capture::ReflectanceField read = read_field_within(state.field_file, state.memory);
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
    if (!field) {
      leds = pca.lights();
      strip_nearest_led.clear();
    }
    pca_from_file = std::move(pca);
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

void ViewerApp::Impl::on_field_changed() {
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

void ViewerApp::Impl::open_dropped(const std::vector<std::string>& paths) {
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

}  // namespace ls::viewer
