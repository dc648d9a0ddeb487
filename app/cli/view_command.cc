// lightstage view: the interactive viewer (viewer/viewer_app.h). With --script it runs a list of
// actions and, with --screenshot, saves the view and exits: how tests and batch jobs drive it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>

#include "app/cli/commands.h"
#include "lightstage/errors.h"
#include "viewer/viewer_app.h"
#include "viewer/viewer_state.h"

namespace ls::cli {

namespace fs = std::filesystem;

void add_view_command(CLI::App& app) {
  struct Args {
    viewer::ViewArgs view;
    fs::path script;
    fs::path screenshot;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand(
      "view",
      "Interactive viewer: relights a field, its PCA or its fitted models live on the GPU under an "
      "environment map (drag to rotate, scroll for exposure), with split and difference views, "
      "parameter maps, a point light, model edits and screenshots. Needs a display (under a "
      "headless machine: xvfb-run -a lightstage view ...).");
  viewer::add_view_options(*cmd, args->view);
  cmd->add_option("--script", args->script,
                  "JSON list of actions to run after opening, e.g. [{\"action\": \"rotate\", "
                  "\"deg\": 90}, {\"action\": \"source\", \"source\": \"models\"}]. Actions: "
                  "open, env, rotate, exposure, source, split, difference, map, point_light, edit, "
                  "time, screenshot.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--screenshot", args->screenshot,
                  "Save the view as OUT.png (tone-mapped) and OUT.exr (linear), print its command "
                  "line, and exit (after --script).");
  add_quiet_flag(*cmd);
  cmd->callback([args] {
    const viewer::ViewState state = args->view.to_state();
    const std::vector<viewer::Action> actions =
        args->script.empty() ? std::vector<viewer::Action>{} : viewer::read_script(args->script);
    const bool batch = !args->screenshot.empty();  // Else the window stays open.
    viewer::ViewerApp app(state, /*visible=*/!batch);
    for (const viewer::Action& action : actions) {
      app.apply(action);
      app.frame();
    }
    if (!args->screenshot.empty()) {
      app.frame();
      app.save_screenshot(args->screenshot);
      // What relighting cost: the last frame on the GPU, the last change of lighting on the CPU.
      std::fprintf(stderr,
                   "relight: %.2f ms (last frame: GPU draw + finish); light weights: %.2f ms\n",
                   app.last_relight_ms(), app.last_lighting_ms());
    }
    if (!batch) app.run();
    std::printf("view: %s\n", app.state().to_command_line().c_str());
  });
}

}  // namespace ls::cli
