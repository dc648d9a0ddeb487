// lightstage stage: validate and summarise a stage file, or write the built-in one to start from.
// lightstage envmaps: write the procedural environment maps that ship for the demo.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "app/cli/commands.h"
#include "lightstage/image.h"
#include "lightstage/run_outputs.h"
#include "lightstage/session.h"
#include "lightstage/stage.h"
#include "relight/lighting/light_cells.h"
#include "sim/envmaps.h"

namespace ls::cli {

namespace fs = std::filesystem;

void add_stage_command(CLI::App& app) {
  struct Args {
    fs::path file, write;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand(
      "stage",
      "Check a stage file and summarise it (LEDs, coverage, solid angle per LED, camera, plan), "
      "or write the built-in dome as a starting point with --write.");
  cmd->add_option("file", args->file, "Stage file to check (default: the built-in dome).");
  cmd->add_option("--write", args->write, "Write the stage (built-in or FILE) as JSON here.");
  add_quiet_flag(*cmd);
  cmd->callback([args] {
    const Stage stage = args->file.empty() ? default_stage() : load_stage(args->file);
    require_stage_files(stage);
    if (!args->write.empty()) {
      const auto lock = lock_output(args->write);
      write_file_atomic(args->write, stage_to_json(stage));
      std::printf("wrote %s\n", args->write.c_str());
      return;
    }
    const auto dirs = stage.led_directions();
    const relight::LightCells cells = relight::LightCells::compute(
        dirs, stage.coverage_radius_deg * M_PI / 180.0, /*resolution=*/1024);
    std::vector<double> sr = cells.solid_angle_sr;
    std::sort(sr.begin(), sr.end());
    double lowest = 90;
    for (const auto& d : dirs) lowest = std::min(lowest, std::asin(d.y()) * 180 / M_PI);
    std::printf("%s (%s)\n", stage.name.c_str(), stage.source.c_str());
    std::printf("  LEDs: %zu, lowest at %.1f deg elevation, coverage radius %.1f deg\n",
                stage.leds.size(), lowest, cells.coverage_radius_rad * 180 / M_PI);
    std::printf(
        "  solid angle per LED: min %.4f, median %.4f, max %.4f sr (max/min %.2f); "
        "uncovered %.3f sr of 4pi\n",
        sr.front(), sr[sr.size() / 2], sr.back(), sr.back() / sr.front(), cells.uncovered_sr);
    const CameraSpec& c = stage.camera;
    std::printf("  camera: %s %dx%dx%d, %d-bit, bracket:", c.backend.c_str(), c.width, c.height,
                c.channels, c.bit_depth);
    for (const auto& s : c.bracket) std::printf(" %gs@x%g", s.exposure_s, s.gain);
    std::printf("\n  plan: %d dark frames per step, %d time step(s), %zu frames in all\n",
                stage.plan.dark_frames, stage.plan.time_steps, plan_frames(stage).size());
  });
}

void add_envmaps_command(CLI::App& app) {
  struct Args {
    fs::path out = data_dir() / "envmaps";
    int width = 512;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand(
      "envmaps",
      "Write the procedural lat-long radiance maps that ship for the demo: sky_sun.exr, "
      "softbox_studio.exr, small_source.exr (and PNG previews).");
  cmd->add_option("--out", args->out, "Directory.")->capture_default_str();
  cmd->add_option("--width", args->width, "Map width (height is half).")
      ->capture_default_str()
      ->check(CLI::Range(8, 16384));
  add_quiet_flag(*cmd);
  cmd->callback([args] {
    if (args->width % 2 != 0) {
      throw CLI::ValidationError("--width", "expected an even width (the height is half), got " +
                                                std::to_string(args->width));
    }
    const auto lock = lock_output(args->out);
    RunOutputs outputs(args->out);  // A run that fails leaves none of its maps.
    fs::create_directories(args->out);
    const std::pair<const char*, Image> maps[] = {
        {"sky_sun", sim::make_sky_with_sun(args->width)},
        {"softbox_studio", sim::make_studio(args->width)},
        {"small_source", sim::make_small_source(args->width)}};
    for (auto& [name, image] : maps) {
      Image copy = image;
      copy.channel_names = {"R", "G", "B"};
      outputs.add(args->out / (std::string(name) + ".exr"));
      outputs.add(args->out / (std::string(name) + ".png"));
      write_exr(args->out / (std::string(name) + ".exr"), copy);
      write_png_preview(args->out / (std::string(name) + ".png"), copy,
                        auto_exposure_stops(copy, 0.95));
      std::printf("wrote %s\n", (args->out / (std::string(name) + ".exr")).c_str());
    }
    outputs.keep();
  });
}

fs::path data_dir() {
  if (const char* env = std::getenv("LIGHTSTAGE_DATA")) return env;
  return LIGHTSTAGE_DATA_DIR;
}

std::vector<fs::path> shipped_environment_maps(bool include_shared) {
  std::vector<fs::path> maps;
  auto collect = [&](const fs::path& dir) {
    if (!fs::is_directory(dir)) return;
    std::vector<fs::path> found;
    for (const auto& e : fs::directory_iterator(dir)) {
      const auto ext = e.path().extension();
      if (ext == ".exr" || ext == ".hdr") found.push_back(e.path());
    }
    std::sort(found.begin(), found.end());
    maps.insert(maps.end(), found.begin(), found.end());
  };
  collect(data_dir() / "envmaps");
  if (include_shared)
    collect(fs::path(LIGHTSTAGE_DATA_DIR).parent_path().parent_path() / "shared" / "data" /
            "envmaps");
  return maps;
}

}  // namespace ls::cli
