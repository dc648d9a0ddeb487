// The view command's options (CLI11) and ViewArgs -> ViewState: what `lightstage view` and a
// screenshot's reproduce line (ViewState::to_command_line) bind.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/memory_option.h"
#include "viewer/viewer_state.h"

namespace ls::viewer {

namespace fs = std::filesystem;

ViewState ViewArgs::to_state() const {
  ViewState state;
  for (const fs::path& input : inputs) state.open(input);
  state.environment = environment;
  const auto names = builtin_environment_names();
  if (std::find(names.begin(), names.end(), environment) == names.end() &&
      !fs::exists(environment)) {
    std::string list;
    for (const auto& name : names) list += (list.empty() ? "" : ", ") + name;
    throw InputError("--env: expected a map file or one of " + list + ", got \"" + environment +
                     "\"");
  }
  state.rotation_deg = rotation_deg;
  state.exposure_stops = exposure_stops;
  const auto parsed_source = parse_source(source);
  if (!parsed_source) throw InputError("--source: expected field, pca or models, got " + source);
  state.source = *parsed_source;
  state.rank = rank;
  if (split != "none") {
    state.split = parse_source(split);
    if (!state.split)
      throw InputError("--split: expected field, pca, models or none, got " + split);
  }
  state.divider = divider;
  state.difference = difference;
  state.exact_models = exact_models;
  const auto parsed_map = parse_parameter_map(map);
  if (!parsed_map) throw InputError("--map: unknown map \"" + map + "\"");
  state.map = *parsed_map;
  if (!light.empty()) {
    Eigen::Vector3d dir(light[0], light[1], light[2]);
    if (!(dir.norm() > 0)) throw InputError("--light: expected a non-zero direction");
    state.point_light = true;
    // Keep a unit direction as given (bit-exact round trip); normalise anything else.
    state.light_dir = std::abs(dir.norm() - 1) < 1e-12 ? dir : dir.normalized();
  }
  for (const std::string& spec : edits) state.edits.push_back(ViewEdit::parse_spec(spec, "--edit"));
  state.time_step = time_step;
  state.memory = memory;
  int w = 0, h = 0;
  char x = 0;
  std::istringstream size_text(size);
  if (!(size_text >> w >> x >> h) || x != 'x' || w < 64 || h < 64 || w > 16384 || h > 16384)
    throw InputError("--size: expected WxH (64..16384 each), got \"" + size + "\"");
  state.window_width = w;
  state.window_height = h;
  return state;
}

void add_view_options(CLI::App& cmd, ViewArgs& args) {
  cmd.add_option("inputs", args.inputs,
                 "What to open: a reflectance field (.exr), fitted model maps (.exr from "
                 "'lightstage fit'), a PCA field (.lspca) or a session directory; several "
                 "(a field and its maps) may be given.");
  cmd.add_option("--env", args.environment,
                 "Environment: a lat-long map file (.exr, .hdr) or a built-in name (uniform, "
                 "sky_sun, softbox_studio, small_source).")
      ->capture_default_str();
  cmd.add_option("--rotate", args.rotation_deg, "Rotation of the map about +Y, degrees.")
      ->capture_default_str();
  cmd.add_option("--exposure", args.exposure_stops, "Display exposure, stops.")
      ->capture_default_str();
  cmd.add_option("--source", args.source, "Source shown: field, pca or models.")
      ->check(CLI::IsMember({"field", "pca", "models"}))
      ->capture_default_str();
  cmd.add_option("--rank", args.rank, "PCA rank when the PCA is built from the field.")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd.add_option("--split", args.split, "Second source right of the divider (or none).")
      ->check(CLI::IsMember({"field", "pca", "models", "none"}))
      ->capture_default_str();
  cmd.add_option("--divider", args.divider, "Split divider position, 0..1 across the image.")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd.add_flag("--difference", args.difference, "Show |source - split source| instead.");
  cmd.add_flag("--exact-models", args.exact_models,
               "Render models by the exact sum over the environment's lights (slow) rather than "
               "against the prefiltered environment.");
  cmd.add_option("--map", args.map,
                 "Parameter map shown: none, normal, albedo, roughness, ks, sigma, model, "
                 "confidence, residual.")
      ->capture_default_str();
  cmd.add_option("--light", args.light,
                 "Point-light mode: one distant light from direction X Y Z (stage frame).")
      ->expected(3);
  cmd.add_option("--edit", args.edits,
                 "A model edit, e.g. \"model=torrance_sparrow;tint=1,0.6,0.6;roughness=2;"
                 "specular=0.5;brush=X,Y,R/X,Y,R\" (repeatable; applied in order).");
  cmd.add_option("--time", args.time_step, "Time step of a session.")->capture_default_str();
  add_memory_option(cmd, args.memory,
                    "View: the field shown; a larger one opens at a reduced resolution, each "
                    "pixel the mean of a block, instead of in bands.");
  cmd.add_option("--size", args.size, "Window size WxH.")->capture_default_str();
}

ViewState parse_view_command_line(const std::vector<std::string>& args) {
  CLI::App app{"view"};
  ViewArgs view_args;
  add_view_options(app, view_args);
  std::vector<std::string> reversed(args.rbegin(), args.rend());
  if (!reversed.empty() && reversed.back() == "view") reversed.pop_back();
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    throw InputError(std::string("view command line: ") + e.what());
  }
  return view_args.to_state();
}

}  // namespace ls::viewer
