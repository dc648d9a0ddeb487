// lightstage calibrate: LED directions (mirror spheres) and intensities (white target) from
// photographs, written into a calibrated stage file.
//   lightstage calibrate directions --stage S.json --images DIR --out CAL.json
//   lightstage calibrate intensities --stage CAL.json --white DIR --out CAL2.json
//   lightstage calibrate camera --images DIR --board 9x6 --square 30 [--stage S --out CAL.json]
#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <memory>
#include <regex>

#include "app/cli/commands.h"
#include "capture/camera_calibration.h"
#include "capture/light_calibration.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"

namespace ls::cli {
namespace {

// CLI11's numeric checks let NaN through (every comparison with it is false): the measurements
// given on the command line must be finite numbers.
const CLI::Validator kFinite(
    [](std::string& text) {
      double value = 0;
      const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
      const bool ok =
          error == std::errc() && end == text.data() + text.size() && std::isfinite(value);
      return ok ? std::string() : "expected a finite number, got " + text;
    },
    "FINITE");

}  // namespace

namespace fs = std::filesystem;

namespace {

struct CalibrateArgs {
  fs::path stage_file;
  fs::path images_dir;
  fs::path reference;
  std::vector<double> circles;  // cx, cy, r per sphere (pixels, x right, y down).
  int spheres = 2;
  double sphere_radius_m = 0.0;
  double sphere_z_m = 0.0;
  double blob_fraction = 0.25;
  double saturation = 0.0;
  double albedo = 1.0;
  double plane_z_m = 0.0;
  fs::path flat_field;
  fs::path out;
  bool quiet = false;
  std::string board = "9x6";  // Inner corners, WxH.
  double square_mm = 30.0;
  bool square_pixels = false;
};

// An LED id from a photo's name (ledNNN): InputError naming the file when it is out of range.
int parse_led_id(const std::string& digits, const fs::path& file) {
  int id = 0;
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
  if (error != std::errc() || end != digits.data() + digits.size()) {
    throw InputError(file.string() + ": LED id " + digits + " is out of range");
  }
  return id;
}

bool is_image(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext == ".exr" || ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".hdr" ||
         ext == ".tif" || ext == ".tiff";
}

// The photographs of DIR, each with its LED index: "led042.*" names LED id 42; otherwise the
// sorted files are the stage's LEDs in file order.
std::vector<std::pair<fs::path, int>> list_photos(const fs::path& dir, const Stage& stage,
                                                  const fs::path& exclude) {
  if (!fs::is_directory(dir)) throw InputError(dir.string() + ": expected a directory of images");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file() || !is_image(e.path())) continue;
    const std::string stem = e.path().stem().string();
    if (stem == "reference" || stem == "ref" || (!exclude.empty() && e.path() == exclude)) {
      continue;
    }
    files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  const std::regex led_name(R"(led0*(\d+))", std::regex::icase);
  std::vector<std::pair<fs::path, int>> out;
  bool all_named = !files.empty();
  for (const auto& f : files) {
    std::smatch m;
    const std::string stem = f.stem().string();
    if (!std::regex_match(stem, m, led_name)) {
      all_named = false;
      break;
    }
    const int index = stage.led_index(parse_led_id(m[1].str(), f));
    if (index < 0) {
      throw InputError(f.string() + ": the stage " + stage.source + " has no LED with id " +
                       m[1].str());
    }
    out.push_back({f, index});
  }
  if (all_named) return out;
  if (files.size() != stage.leds.size()) {
    throw InputError(dir.string() + ": expected one image per LED (" +
                     std::to_string(stage.leds.size()) + ", or files named ledNNN), got " +
                     std::to_string(files.size()));
  }
  out.clear();
  for (size_t i = 0; i < files.size(); ++i) out.push_back({files[i], int(i)});
  return out;
}

// Calibrates one photograph at a time (a dome's worth need not fit in memory) with
// calibrate_one(image, file name, LED index), and gathers the estimates and problems under each
// photograph's LED.
template <class Calibration, class CalibrateOne>
Calibration calibrate_each_photo(const std::vector<std::pair<fs::path, int>>& photos,
                                 const char* what, bool quiet, CalibrateOne calibrate_one) {
  Calibration all;
  ProgressReporter progress(what, long(photos.size()), quiet);
  for (size_t i = 0; i < photos.size(); ++i) {
    const Image image = read_image(photos[i].first);
    Calibration one = calibrate_one(image, photos[i].first.filename().string(), photos[i].second);
    for (auto& e : one.leds) e.led_index = photos[i].second;
    for (auto& p : one.problems) p.led_index = photos[i].second;
    all.leds.insert(all.leds.end(), one.leds.begin(), one.leds.end());
    all.problems.insert(all.problems.end(), one.problems.begin(), one.problems.end());
    progress.update(long(i + 1));
  }
  progress.done();
  return all;
}

void check_size(const Image& image, const fs::path& file, const Stage& stage) {
  if (image.width != stage.camera.width || image.height != stage.camera.height) {
    throw InputError(stage.source + ": camera: expected the photographs' size " +
                     std::to_string(image.width) + "x" + std::to_string(image.height) + " (" +
                     file.string() + "), got " + std::to_string(stage.camera.width) + "x" +
                     std::to_string(stage.camera.height));
  }
}

void print_problems(const std::vector<capture::ImageProblem>& problems) {
  if (problems.empty()) return;
  std::printf("\n%zu problem(s); those images were left out, the LEDs keep their old values:\n",
              problems.size());
  for (const auto& p : problems) {
    if (p.sphere >= 0) {
      std::printf("  %s: sphere %d: %s\n", p.image.c_str(), p.sphere, p.what.c_str());
    } else {
      std::printf("  %s: %s\n", p.image.c_str(), p.what.c_str());
    }
  }
}

int run_directions(const CalibrateArgs& args) {
  const Stage nominal = load_stage(args.stage_file);
  const auto photos = list_photos(args.images_dir, nominal, args.reference);
  const capture::ViewCamera camera = capture::ViewCamera::from_spec(nominal.camera);
  std::vector<capture::SphereOutline> outlines;
  if (!args.circles.empty()) {
    if (args.circles.size() % 3 != 0) {
      throw InputError("--circle: expected cx,cy,r per sphere, got " +
                       std::to_string(args.circles.size()) + " numbers");
    }
    for (size_t i = 0; i < args.circles.size(); i += 3) {
      capture::SphereOutline o;
      o.center_px = Eigen::Vector2d(args.circles[i], args.circles[i + 1]);
      o.radius_px = args.circles[i + 2];
      o.major_semi_axis_px = Eigen::Vector2d(o.radius_px, 0);
      outlines.push_back(o);
    }
  } else {
    fs::path ref = args.reference;
    for (const char* name : {"reference.exr", "reference.png", "reference.jpg", "ref.JPG"}) {
      if (ref.empty() && fs::exists(args.images_dir / name)) ref = args.images_dir / name;
    }
    if (ref.empty()) {
      throw InputError(args.images_dir.string() +
                       ": no reference shot (reference.exr/png/jpg): give --reference or --circle");
    }
    const Image reference = read_image(ref);
    check_size(reference, ref, nominal);
    outlines = capture::find_sphere_outlines(reference, args.spheres);
    if (outlines.empty()) {
      throw InputError(ref.string() + ": no sphere found (nothing stands out from the background)");
    }
    for (size_t s = 0; s < outlines.size(); ++s) {
      std::printf("sphere %zu: centre (%.2f, %.2f) px, radius %.2f px\n", s,
                  outlines[s].center_px.x(), outlines[s].center_px.y(), outlines[s].radius_px);
    }
  }
  std::vector<capture::MirrorSphere> spheres;
  for (const auto& o : outlines) {
    spheres.push_back(capture::locate_sphere(o, camera, args.sphere_radius_m, args.sphere_z_m));
  }
  capture::DirectionOptions options;
  options.highlight.blob_fraction = args.blob_fraction;
  options.highlight.saturation_level = args.saturation;
  const auto all = calibrate_each_photo<capture::DirectionCalibration>(
      photos, "calibrate directions", args.quiet,
      [&](const Image& image, const std::string& name, int) {
        return capture::calibrate_directions({&image}, {name}, outlines, spheres, camera, options);
      });
  Stage calibrated = nominal;
  const capture::StageUpdate update = capture::apply_directions(all, &calibrated);
  std::printf("%6s %10s %12s %s\n", "LED", "moved deg", "distance m", "status");
  for (const auto& e : all.leds) {
    const Led& before = nominal.leds[e.led_index];
    if (!e.ok) {
      std::printf("%6d %10s %12s %s\n", before.id, "-", "-", "kept (see problems)");
      continue;
    }
    char distance[32] = "-";
    if (e.position_in_stage)
      std::snprintf(distance, sizeof distance, "%.4f", e.position_in_stage->norm());
    std::printf("%6d %10.3f %12s %s\n", before.id,
                capture::angle_between_deg(before.dir_in_stage, e.dir_in_stage), distance,
                e.rays.size() > 1 ? "calibrated" : "calibrated (one sphere)");
  }
  print_problems(all.problems);
  if (update.directions_changed == 0) {
    std::printf("\nno LED direction calibrated: %s not written\n", args.out.c_str());
    return kExitInputError;
  }
  write_file_atomic(args.out, stage_to_json(calibrated));
  std::printf("\n%d of %zu LED directions calibrated -> %s\n", update.directions_changed,
              nominal.leds.size(), args.out.c_str());
  return 0;
}

int run_intensities(const CalibrateArgs& args) {
  // Outputs go into folders that exist (a typo in a path is not a new folder).
  for (const fs::path& file : {args.out, args.flat_field}) {
    if (file.empty()) continue;  // --flat-field: beside --out by default.
    const fs::path folder = fs::absolute(file).parent_path();
    if (!fs::is_directory(folder)) {
      throw InputError(file.string() + ": folder " + folder.string() + " does not exist");
    }
  }
  const Stage stage = load_stage(args.stage_file);
  const auto photos = list_photos(args.images_dir, stage, {});
  const capture::ViewCamera camera = capture::ViewCamera::from_spec(stage.camera);
  capture::WhitePlane plane;
  plane.center_in_stage = Eigen::Vector3d(0, 0, args.plane_z_m);
  plane.albedo = args.albedo;
  capture::IntensityOptions options;
  options.saturation_level = args.saturation;
  const auto all = calibrate_each_photo<capture::IntensityCalibration>(
      photos, "calibrate intensities", args.quiet,
      [&](const Image& image, const std::string& name, int led_index) {
        Stage one_led = stage;
        one_led.leds = {stage.leds[led_index]};
        return capture::calibrate_intensities({&image}, {name}, one_led, plane, camera, options);
      });
  Stage calibrated = stage;
  const capture::StageUpdate update = capture::apply_intensities(all, &calibrated);
  std::printf("%6s %12s %10s %20s %10s\n", "LED", "intensity", "change %", "colour (R G B)",
              "flat rms%");
  for (const auto& e : all.leds) {
    const Led& before = stage.leds[e.led_index];
    if (!e.ok) {
      std::printf("%6d %12s %10s %20s %10s\n", before.id, "-", "-", "kept (see problems)", "-");
      continue;
    }
    const Led& after = calibrated.leds[e.led_index];
    std::printf("%6d %12.5f %+10.2f %6.3f %6.3f %6.3f %10.3f\n", before.id, after.intensity,
                100.0 * (after.intensity / before.intensity - 1.0), after.color_gain[0],
                after.color_gain[1], after.color_gain[2], 100.0 * e.fit_rms);
  }
  print_problems(all.problems);
  fs::path flat = args.flat_field;
  if (flat.empty()) flat = fs::path(args.out).replace_extension(".flatfield.exr");
  if (update.intensities_changed == 0) {
    std::printf("\nno LED intensity calibrated: %s and %s not written\n", args.out.c_str(),
                flat.c_str());
    return kExitInputError;
  }
  write_exr(flat, capture::flat_field_image(
                      all, stage, 64, std::max(1, 64 * stage.camera.height / stage.camera.width)));
  // The calibrated stage names its side car (relative to itself when beside it), so that `build`
  // divides the flat fields out; written after the side car, so it never names a missing file.
  if (update.intensities_changed > 0) {
    const fs::path out_dir = fs::absolute(args.out).parent_path();
    calibrated.calibration.flat_field = fs::absolute(flat).parent_path() == out_dir
                                            ? flat.filename()
                                            : fs::absolute(flat).lexically_normal();
  }
  write_file_atomic(args.out, stage_to_json(calibrated));
  std::printf("\n%d of %zu LED intensities calibrated -> %s (flat fields: %s)\n",
              update.intensities_changed, stage.leds.size(), args.out.c_str(), flat.c_str());
  return 0;
}

capture::ChessboardSpec parse_board(const std::string& text, double square_mm) {
  static const std::regex pattern(R"((\d+)[xX](\d+))");
  std::smatch m;
  if (!std::regex_match(text, m, pattern)) {
    throw InputError("--board: expected WxH inner corners (e.g. 9x6), got \"" + text + "\"");
  }
  capture::ChessboardSpec spec;
  auto corners = [&](const std::string& digits) {
    int count = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), count);
    if (error != std::errc() || end != digits.data() + digits.size() || count > 1000) {
      throw InputError("--board: expected at most 1000 inner corners a side, got \"" + text + "\"");
    }
    return count;
  };
  spec.inner_cols = corners(m[1].str());
  spec.inner_rows = corners(m[2].str());
  spec.square_m = square_mm * 1e-3;
  spec.check();
  return spec;
}

int run_camera(const CalibrateArgs& args) {
  const capture::ChessboardSpec board = parse_board(args.board, args.square_mm);
  if (!fs::is_directory(args.images_dir)) {
    throw InputError(args.images_dir.string() + ": expected a directory of images");
  }
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(args.images_dir)) {
    if (e.is_regular_file() && is_image(e.path())) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(args.images_dir.string() + ": no images");
  std::vector<Image> images;
  std::vector<std::string> names;
  ProgressReporter progress("read chessboard views", long(files.size()), args.quiet);
  for (size_t i = 0; i < files.size(); ++i) {
    images.push_back(read_image(files[i]));
    names.push_back(files[i].filename().string());
    progress.update(long(i + 1));
  }
  progress.done();
  std::vector<const Image*> pointers;
  for (const Image& im : images) pointers.push_back(&im);
  capture::CameraCalibrationOptions options;
  options.fix_aspect_ratio = args.square_pixels;
  const capture::CameraCalibration cal = capture::calibrate_camera(pointers, names, board, options);
  for (const auto& v : cal.views) {
    if (v.found) {
      std::printf("%-32s board found, reprojection RMS %.3f px\n", v.image.c_str(),
                  v.rms_reprojection_px);
    } else {
      std::printf("%-32s no %s board found: left out\n", v.image.c_str(), args.board.c_str());
    }
  }
  if (!cal.ok) {
    std::fprintf(stderr, "calibrate camera: %s\n", cal.problem.c_str());
    return kExitInputError;
  }
  std::printf(
      "\n%dx%d: fx %.3f fy %.3f px, principal point (%.3f, %.3f) px (pixel centres at +0.5), "
      "fov_y %.4f deg\n",
      cal.width, cal.height, cal.fx, cal.fy, cal.cx, cal.cy, cal.fov_y_deg());
  std::printf("distortion (k1 k2 p1 p2 k3):");
  for (double d : cal.distortion) std::printf(" %.6f", d);
  std::printf("\nreprojection RMS %.4f px\n", cal.rms_reprojection_px);
  if (!args.out.empty()) {
    if (args.stage_file.empty()) throw InputError("--out: needs --stage (the stage to update)");
    Stage stage = load_stage(args.stage_file);
    if (stage.camera.width != cal.width || stage.camera.height != cal.height) {
      throw InputError(args.stage_file.string() + ": camera: expected " +
                       std::to_string(cal.width) + "x" + std::to_string(cal.height) +
                       " like the photographs, got " + std::to_string(stage.camera.width) + "x" +
                       std::to_string(stage.camera.height));
    }
    // The stage file's camera is a centred pinhole: only the field of view carries over.
    stage.camera.fov_y_deg = cal.fov_y_deg();
    write_file_atomic(args.out, stage_to_json(stage));
    std::printf("fov_y_deg %.4f -> %s (principal point and distortion not stored)\n",
                stage.camera.fov_y_deg, args.out.c_str());
  }
  return 0;
}

}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "calibrate",
      "Calibrate the dome from photographs: LED directions (and positions, with two spheres) from "
      "mirror spheres, LED intensities, colours and flat fields from a matte white target. Writes "
      "a calibrated stage file; images with problems are listed and left out.");
  cmd->require_subcommand(1);
  {
    auto args = std::make_shared<CalibrateArgs>();
    auto* sub = cmd->add_subcommand(
        "directions",
        "Mirror spheres: one photograph per LED in --images (ledNNN.* or in stage order) and a "
        "reference shot (reference.*, the spheres brighter than the background) or --circle.");
    sub->add_option("--stage", args->stage_file, "Stage file (its camera took the photographs).")
        ->required()
        ->check(CLI::ExistingFile);
    sub->add_option("--images", args->images_dir, "Directory of photographs.")->required();
    sub->add_option("--reference", args->reference, "Reference shot for the sphere outlines.");
    sub->add_option("--circle", args->circles,
                    "Sphere outline(s) instead: cx,cy,r in pixels (x right, y down, pixel "
                    "centres at +0.5); repeat per sphere.")
        ->delimiter(',');
    sub->add_option("--spheres", args->spheres, "Spheres to look for in the reference shot.")
        ->capture_default_str();
    sub->add_option("--sphere-radius", args->sphere_radius_m,
                    "Sphere radius in metres (needed with a perspective camera).")
        ->check(kFinite);
    sub->add_option("--sphere-z", args->sphere_z_m,
                    "Sphere centres' z in metres (orthographic camera).")
        ->capture_default_str()
        ->check(kFinite);
    sub->add_option("--blob-fraction", args->blob_fraction,
                    "Highlight pixels: above this fraction of the peak (0.975 for 8-bit JPEGs).")
        ->capture_default_str()
        ->check(kFinite);
    sub->add_option("--saturation", args->saturation, "Clipped value of the images (0: none).")
        ->check(kFinite);
    sub->add_option("--out", args->out, "Calibrated stage file to write.")->required();
    sub->add_flag("--quiet", args->quiet, "No progress output.");
    sub->callback([args] {
      if (const int code = run_directions(*args); code != 0) throw CLI::RuntimeError(code);
    });
  }
  {
    auto args = std::make_shared<CalibrateArgs>();
    auto* sub = cmd->add_subcommand(
        "intensities",
        "White target: one photograph per LED in --white of a matte plane facing the camera. LED "
        "directions come from --stage (calibrate directions first).");
    sub->add_option("--stage", args->stage_file, "Stage file, directions already calibrated.")
        ->required()
        ->check(CLI::ExistingFile);
    sub->add_option("--white", args->images_dir, "Directory of photographs.")->required();
    sub->add_option("--albedo", args->albedo,
                    "Reflectance of the target (1: intensities relative to it).")
        ->capture_default_str()
        ->check(kFinite);
    sub->add_option("--plane-z", args->plane_z_m, "The plane's z in metres.")
        ->capture_default_str()
        ->check(kFinite);
    sub->add_option("--saturation", args->saturation, "Clipped value of the images (0: none).")
        ->check(kFinite);
    sub->add_option("--flat-field", args->flat_field,
                    "Where to write the flat fields (default: OUT with .flatfield.exr).");
    sub->add_option("--out", args->out, "Calibrated stage file to write.")->required();
    sub->add_flag("--quiet", args->quiet, "No progress output.");
    sub->callback([args] {
      if (const int code = run_intensities(*args); code != 0) throw CLI::RuntimeError(code);
    });
  }
  {
    auto args = std::make_shared<CalibrateArgs>();
    auto* sub = cmd->add_subcommand(
        "camera",
        "Camera intrinsics from photographs of a chessboard in --images (several poses, tilted): "
        "focal lengths, principal point, distortion. With --stage and --out, writes the stage "
        "with the fitted fov_y_deg.");
    sub->add_option("--images", args->images_dir, "Directory of chessboard photographs.")
        ->required();
    sub->add_option("--board", args->board, "Inner corners, WxH (W != H).")->capture_default_str();
    sub->add_option("--square", args->square_mm, "Square size in millimetres.")
        ->capture_default_str()
        ->check(kFinite);
    sub->add_flag("--square-pixels", args->square_pixels, "Fit one focal length (fx = fy).");
    sub->add_option("--stage", args->stage_file, "Stage file to update (with --out).")
        ->check(CLI::ExistingFile);
    sub->add_option("--out", args->out, "Stage file to write with the fitted field of view.");
    sub->add_flag("--quiet", args->quiet, "No progress output.");
    sub->callback([args] {
      if (const int code = run_camera(*args); code != 0) throw CLI::RuntimeError(code);
    });
  }
}

}  // namespace ls::cli
