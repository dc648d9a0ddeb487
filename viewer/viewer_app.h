#pragma once
// The interactive viewer: a GLFW window with Dear ImGui panels around the relit image
// (viewer/gpu_relight.h does the relighting and the display). Everything it shows follows from a
// ViewState (viewer/viewer_state.h), so a script of actions drives it exactly as the mouse does,
// and tests run it hidden under Xvfb.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "lightstage/image.h"
#include "viewer/gpu_relight.h"
#include "viewer/viewer_state.h"

namespace ls::viewer {

class ViewerApp {
 public:
  // Opens the window (HardwareError without a display or OpenGL 3.3) and loads what `state` names
  // (InputError naming the file when it cannot).
  explicit ViewerApp(const ViewState& state, bool visible = true);
  ~ViewerApp();
  ViewerApp(const ViewerApp&) = delete;
  ViewerApp& operator=(const ViewerApp&) = delete;

  const ViewState& state() const;
  // Applies a scripted action (loading what it names, saving a screenshot). InputError when a file
  // cannot be opened; the view is left as it was.
  void apply(const Action& action);
  // Files dropped on the window: each is opened; a file that fails shows its error in the window
  // (error_message()) and the viewer keeps what it had. Never throws.
  void handle_drop(const std::vector<std::string>& paths);
  // The error shown in the window's banner (empty: none).
  const std::string& error_message() const;
  // What the field shown is when it is not the file's (a field over --memory: reduced); empty
  // otherwise.
  const std::string& field_note() const;

  // Draws one frame (relight, tone map, panels) and swaps; returns false once the window is asked
  // to close.
  bool frame();
  // Frames until the window closes.
  void run();

  // The linear relit image of the shown source (GPU, read back), or of the parameter map when one
  // is shown. Renders first when the state changed.
  Image relit_image();
  // The image area as displayed (tone-mapped, split/difference applied) at the source's size,
  // 0..1 sRGB-encoded RGB.
  Image displayed_image();
  // PNG (displayed_image) at `png_path` and the linear EXR (relit_image) beside it (same stem);
  // prints the command line that reproduces the view to stdout.
  void save_screenshot(const std::filesystem::path& png_path);

  // The lighting of the current frame: per-LED irradiance of the whole map; for a field on show
  // under a map with bright sources, the sources split off (ViewLighting::split); distant lights
  // for models on show.
  const ViewLighting& lighting();
  // What cast the field's bright sources' shadows in the last frame (BrightSourceLight::
  // shadows); empty when no field is open or its lighting has none.
  std::string source_shadows() const;
  // Milliseconds of the last frame's GPU relighting (upload + draw + finish).
  double last_relight_ms() const;
  // The last time the environment (or point light) was turned into light weights (CPU).
  double last_lighting_ms() const;

 private:
  void make_current();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ls::viewer
