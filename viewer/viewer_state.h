#pragma once
// The whole state of a view as plain data (no GL): what is open, which source is shown and how it
// is lit, displayed and edited. Scripts change it through apply(), and to_command_line() writes the
// `lightstage view ...` line that reproduces it (parse_view_command_line reads it back).
//
// Directions are in the stage frame (physics/envmap.h: +Y up, unit, toward the light);
// rotation is the environment's rotation about +Y in degrees, as `lightstage relight --rotate`.
#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lightstage/memory.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_edit.h"

namespace CLI {
class App;
}

namespace ls::viewer {

// What the image area shows.
enum class Source { kField, kPca, kModels };
const char* to_string(Source source);  // "field", "pca", "models".
std::optional<Source> parse_source(std::string_view name);

// A parameter map of the fitted models shown instead of the relit image (kNone: the relit image).
enum class ParameterMap {
  kNone,
  kNormal,
  kAlbedo,
  kRoughness,
  kKs,
  kSigma,
  kModel,
  kConfidence,
  kResidual
};
const char* to_string(ParameterMap map);  // "none", "normal", ...
std::optional<ParameterMap> parse_parameter_map(std::string_view name);

// What a file to open is, from its name and (for EXR) its channel names.
enum class InputKind { kField, kModels, kPca, kSession };
// Throws InputError naming the file when it is none of them.
InputKind classify_input(const std::filesystem::path& path);

// One round dab of the edit brush, in image pixels (x right, y down, centre of pixel 0 at 0.5).
struct BrushDab {
  double x = 0, y = 0, radius_px = 8;
  bool operator==(const BrushDab&) const = default;
};

// An edit of the fitted models: the selection (a model class, a basis material and/or the brush;
// more than one: AND) and what it does. Becomes one entry of the edit file relight/fit/model_edit.h
// reads.
struct ViewEdit {
  std::optional<relight::FitModel> model_class;
  int material = 0;             // 1-based basis material (relight/fit/fit.h); 0: any.
  std::vector<BrushDab> brush;  // Empty: no brush (the model class alone selects).
  Eigen::Vector3d albedo_tint{1, 1, 1};
  double roughness_scale = 1;
  double specular_scale = 1;

  // "model=torrance_sparrow;material=3;brush=10,20,5/30,40,5;tint=1,0.6,0.6;roughness=2;
  // specular=0.5"
  // (every part optional, numbers round-trip exactly). parse throws InputError naming `source`.
  std::string to_spec() const;
  static ViewEdit parse_spec(std::string_view spec, const std::string& source);
  // The edit as model_edit.h applies it; the brush rasterised to a width x height mask.
  relight::ModelEdit to_model_edit(int width, int height) const;
  bool operator==(const ViewEdit&) const = default;
};

// Writes the edit file (JSON, relight/fit/model_edit.h) beside which brush masks go as PNGs
// (<stem>.mask<i>.png). `lightstage relight --models M --edits FILE` reproduces the edited render.
void write_edit_file(const std::filesystem::path& path, const std::vector<ViewEdit>& edits,
                     int width, int height);

// A scripted action (a JSON object with "action" naming it; see parse_script for the keys).
struct Action {
  enum class Kind {
    kOpen,         // "path"
    kEnvironment,  // "env": a file or a built-in name (builtin_environment_names)
    kRotate,       // "deg" (absolute) or "by" (relative)
    kExposure,     // "stops" (absolute) or "by"
    kSource,       // "source", optional "rank"
    kSplit,        // "source" ("none" ends the split), optional "divider"
    kDifference,   // "on"
    kMap,          // "map"
    kPointLight,   // "on", optional "dir" [x, y, z]
    kEdit,         // "model", "brush" [[x, y, r], ...], "tint", "roughness_scale",
                   // "specular_scale"; or "clear": true
    kTime,         // "step"
    kScreenshot,   // "path" (PNG; an EXR with the same stem beside it)
  };
  Kind kind = Kind::kOpen;
  std::string text;  // Path, source, map or environment name.
  double value = 0;
  bool relative = false;
  bool on = false;
  bool clear = false;
  std::optional<int> rank;
  std::optional<double> divider;
  std::optional<Eigen::Vector3d> dir;
  ViewEdit edit;
};

// Reads a script: a JSON array of actions. InputErrors name the file and the element, e.g.
// "s.json: [2].deg: expected a number, got string "a"". Relative paths resolve against base_dir.
std::vector<Action> parse_script(std::string_view json_text, const std::string& source,
                                 const std::filesystem::path& base_dir);
std::vector<Action> read_script(const std::filesystem::path& path);

// Built-in environments: "uniform" (white, radiance 1 everywhere) and the maps shipped in
// data/envmaps ("sky_sun", "softbox_studio", "small_source"). The procedural generators live in
// sim/, which the viewer does not link, so those are read from the data folder.
std::vector<std::string> builtin_environment_names();

struct ViewState {
  // What is open (empty: nothing).
  std::filesystem::path session_dir;
  std::filesystem::path field_file;
  std::filesystem::path models_file;
  std::filesystem::path pca_file;
  int time_step = 0;  // Sessions with several time steps.
  // What a field may take in memory; a larger one opens at a reduced resolution
  // (capture/reduced_field.h).
  MemoryBudget memory;

  // Lighting.
  std::string environment = "uniform";  // A file path or a builtin_environment_names() entry.
  double rotation_deg = 0;
  bool point_light = false;
  Eigen::Vector3d light_dir{0, 0, 1};  // Unit, toward the light; irradiance 1 at normal incidence.

  // Display.
  Source source = Source::kField;
  int rank = 16;  // PCA rank when the PCA is built from the open field (a .lspca has its own).
  std::optional<Source> split;  // Second source, right of the divider.
  double divider = 0.5;         // 0..1 across the image.
  bool difference = false;      // |first - second| instead of the split.
  // Models under an environment: the exact sum over its lights (seconds a frame on llvmpipe)
  // instead of the prefiltered environment (milliseconds, a few % off; gpu_relight.h).
  bool exact_models = false;
  double exposure_stops = 0;
  ParameterMap map = ParameterMap::kNone;

  std::vector<ViewEdit> edits;

  // Window size.
  int window_width = 1280, window_height = 800;

  // What apply() asks its caller to do beyond changing the state.
  struct Effect {
    bool reload = false;  // Files, time step or environment changed.
    std::optional<std::filesystem::path> screenshot;
  };
  // Applies an action. Opening records the file in its slot (classify_input); errors are
  // InputErrors and leave the state unchanged.
  Effect apply(const Action& action);
  void open(const std::filesystem::path& path);

  // The `lightstage view ...` arguments (argv[1..]) and one shell-quoted line.
  std::vector<std::string> to_args() const;
  std::string to_command_line() const;

  bool operator==(const ViewState&) const = default;
};

// The view's command-line options as CLI11 parses them; to_state() validates and converts.
struct ViewArgs {
  std::vector<std::filesystem::path> inputs;  // Positional: field, maps, session, .lspca.
  std::string environment = "uniform";
  double rotation_deg = 0, exposure_stops = 0, divider = 0.5;
  std::string source = "field", split = "none", map = "none", size = "1280x800";
  int rank = 16, time_step = 0;
  MemoryBudget memory;
  bool difference = false;
  bool exact_models = false;
  std::vector<double> light;  // X Y Z: point-light mode.
  std::vector<std::string> edits;
  ViewState to_state() const;  // InputError (naming the option) on a bad value.
};
// Adds the view's options to a CLI11 (sub)command. Used by `lightstage view` and by
// parse_view_command_line.
void add_view_options(CLI::App& command, ViewArgs& args);
// Parses what to_args() wrote. Throws InputError on a bad line.
ViewState parse_view_command_line(const std::vector<std::string>& args);

}  // namespace ls::viewer
