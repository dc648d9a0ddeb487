#include "app/jobs/calibrate_job.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <optional>
#include <regex>
#include <utility>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/run_outputs.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

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

using Photos = std::vector<std::pair<fs::path, int>>;  // File and the LED index it shows.

// The photographs of DIR, each with its LED index: "led042.*" names LED id 42; otherwise the
// sorted files are the stage's LEDs in file order.
Photos list_photos(const fs::path& dir, const Stage& stage, const fs::path& exclude) {
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
  Photos out;
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

// Calibrates one photograph at a time with calibrate_one(image, file name, LED index), and
// gathers the estimates and problems under each photograph's LED.
template <class Calibration, class CalibrateOne>
Calibration calibrate_each_photo(const Photos& photos, const char* phase,
                                 const ProgressFn& progress, CalibrateOne calibrate_one) {
  Calibration all;
  report(progress, phase, 0, long(photos.size()));
  for (size_t i = 0; i < photos.size(); ++i) {
    const Image image = read_image(photos[i].first);
    Calibration one = calibrate_one(image, photos[i].first.filename().string(), photos[i].second);
    for (auto& e : one.leds) e.led_index = photos[i].second;
    for (auto& p : one.problems) p.led_index = photos[i].second;
    all.leds.insert(all.leds.end(), one.leds.begin(), one.leds.end());
    all.problems.insert(all.problems.end(), one.problems.begin(), one.problems.end());
    report(progress, phase, long(i + 1), long(photos.size()));
  }
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

// "FLAG: expected a finite number, got V", or empty.
std::string finite(const char* flag, double value) {
  if (std::isfinite(value)) return {};
  return std::string(flag) + ": expected a finite number, got " + std::to_string(value);
}

std::string first_problem(std::initializer_list<std::string> problems) {
  for (const std::string& p : problems) {
    if (!p.empty()) return p;
  }
  return {};
}

// The spheres' outlines in the reference shot (options.reference or the folder's reference.*).
std::vector<capture::SphereOutline> outlines_from_reference(
    const CalibrateDirectionsOptions& options, const Stage& nominal) {
  fs::path ref = options.reference;
  for (const char* name : {"reference.exr", "reference.png", "reference.jpg", "ref.JPG"}) {
    if (ref.empty() && fs::exists(options.images_dir / name)) ref = options.images_dir / name;
  }
  if (ref.empty()) {
    throw InputError(options.images_dir.string() +
                     ": no reference shot (reference.exr/png/jpg): give --reference or --circle");
  }
  const Image reference = read_image(ref);
  check_size(reference, ref, nominal);
  std::vector<capture::SphereOutline> outlines =
      capture::find_sphere_outlines(reference, options.spheres);
  if (outlines.empty()) {
    throw InputError(ref.string() + ": no sphere found (nothing stands out from the background)");
  }
  return outlines;
}

}  // namespace

std::string CalibrateDirectionsOptions::validate() const {
  if (circles.size() % 3 != 0) {
    return "--circle: expected cx,cy,r per sphere, got " + std::to_string(circles.size()) +
           " numbers";
  }
  for (double c : circles) {
    if (!std::isfinite(c)) return finite("--circle", c);
  }
  return first_problem({finite("--sphere-radius", sphere_radius_m),
                        finite("--sphere-z", sphere_z_m), finite("--blob-fraction", blob_fraction),
                        finite("--saturation", saturation)});
}

CalibrateDirectionsSummary calibrate_directions(const CalibrateDirectionsOptions& options,
                                                const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) throw InputError(problem);
  CalibrateDirectionsSummary summary;
  summary.nominal = load_stage(options.stage_file);
  const Stage& nominal = summary.nominal;
  const Photos photos = list_photos(options.images_dir, nominal, options.reference);
  const capture::ViewCamera camera = capture::ViewCamera::from_spec(nominal.camera);
  std::vector<capture::SphereOutline> outlines;
  if (!options.circles.empty()) {
    outlines = capture::outlines_from_circles(options.circles);
  } else {
    outlines = outlines_from_reference(options, nominal);
    summary.found_outlines = outlines;
  }
  std::vector<capture::MirrorSphere> spheres;
  spheres.reserve(outlines.size());
  for (const auto& o : outlines) {
    spheres.push_back(
        capture::locate_sphere(o, camera, options.sphere_radius_m, options.sphere_z_m));
  }
  capture::DirectionOptions direction_options;
  direction_options.highlight.blob_fraction = options.blob_fraction;
  direction_options.highlight.saturation_level = options.saturation;
  summary.calibration = calibrate_each_photo<capture::DirectionCalibration>(
      photos, "calibrate directions", progress,
      [&](const Image& image, const std::string& name, int) {
        return capture::calibrate_directions({&image}, {name}, outlines, spheres, camera,
                                             direction_options);
      });
  summary.calibrated = nominal;
  summary.update = capture::apply_directions(summary.calibration, &summary.calibrated);
  if (summary.update.directions_changed == 0) return summary;
  write_file_atomic(options.out, stage_to_json(summary.calibrated));
  summary.written = true;
  return summary;
}

std::string CalibrateIntensitiesOptions::validate() const {
  if (std::string problem =
          first_problem({finite("--albedo", albedo), finite("--plane-z", plane_z_m),
                         finite("--saturation", saturation)});
      !problem.empty()) {
    return problem;
  }
  for (const fs::path& file : {out, flat_field}) {
    if (file.empty()) continue;  // flat_field: beside out by default.
    const fs::path folder = fs::absolute(file).parent_path();
    if (!fs::is_directory(folder)) {
      return file.string() + ": folder " + folder.string() + " does not exist";
    }
  }
  return {};
}

fs::path CalibrateIntensitiesOptions::flat_field_file() const {
  if (!flat_field.empty()) return flat_field;
  return fs::path(out).replace_extension(".flatfield.exr");
}

CalibrateIntensitiesSummary calibrate_intensities(const CalibrateIntensitiesOptions& options,
                                                  const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) throw InputError(problem);
  CalibrateIntensitiesSummary summary;
  summary.nominal = load_stage(options.stage_file);
  const Stage& stage = summary.nominal;
  const Photos photos = list_photos(options.white_dir, stage, {});
  const capture::ViewCamera camera = capture::ViewCamera::from_spec(stage.camera);
  capture::WhitePlane plane;
  plane.center_in_stage = Eigen::Vector3d(0, 0, options.plane_z_m);
  plane.albedo = options.albedo;
  capture::IntensityOptions intensity_options;
  intensity_options.saturation_level = options.saturation;
  summary.calibration = calibrate_each_photo<capture::IntensityCalibration>(
      photos, "calibrate intensities", progress,
      [&](const Image& image, const std::string& name, int led_index) {
        Stage one_led = stage;
        one_led.leds = {stage.leds[led_index]};
        return capture::calibrate_intensities({&image}, {name}, one_led, plane, camera,
                                              intensity_options);
      });
  summary.calibrated = stage;
  summary.update = capture::apply_intensities(summary.calibration, &summary.calibrated);
  summary.flat_field = options.flat_field_file();
  if (summary.update.intensities_changed == 0) return summary;
  const fs::path& flat = summary.flat_field;
  // A stage that cannot be written takes its side car with it: nothing half-calibrated is left.
  RunOutputs outputs(fs::absolute(flat).parent_path());
  outputs.add(flat);
  write_exr(flat,
            capture::flat_field_image(summary.calibration, stage, 64,
                                      std::max(1, 64 * stage.camera.height / stage.camera.width)));
  // The calibrated stage names its side car (relative to itself when beside it), so that `build`
  // divides the flat fields out; written after the side car, so it never names a missing file.
  const fs::path out_dir = fs::absolute(options.out).parent_path();
  summary.calibrated.calibration.flat_field = fs::absolute(flat).parent_path() == out_dir
                                                  ? flat.filename()
                                                  : fs::absolute(flat).lexically_normal();
  write_file_atomic(options.out, stage_to_json(summary.calibrated));
  outputs.keep();
  summary.written = true;
  return summary;
}

capture::ChessboardSpec parse_chessboard(const std::string& text, double square_mm) {
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

std::string CalibrateCameraOptions::validate() const {
  if (std::string problem = finite("--square", square_mm); !problem.empty()) return problem;
  try {
    parse_chessboard(board, square_mm);
  } catch (const InputError& e) {
    return e.what();
  }
  if (!out.empty() && stage_file.empty()) return "--out: needs --stage (the stage to update)";
  return {};
}

CalibrateCameraSummary calibrate_camera(const CalibrateCameraOptions& options,
                                        const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) throw InputError(problem);
  const capture::ChessboardSpec board = parse_chessboard(options.board, options.square_mm);
  if (!fs::is_directory(options.images_dir)) {
    throw InputError(options.images_dir.string() + ": expected a directory of images");
  }
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(options.images_dir)) {
    if (e.is_regular_file() && is_image(e.path())) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(options.images_dir.string() + ": no images");
  std::vector<Image> images;
  std::vector<std::string> names;
  const char* phase = "read chessboard views";
  report(progress, phase, 0, long(files.size()));
  for (size_t i = 0; i < files.size(); ++i) {
    images.push_back(read_image(files[i]));
    names.push_back(files[i].filename().string());
    report(progress, phase, long(i + 1), long(files.size()));
  }
  // The stage to update is checked before the fit: its camera must be the photographs' size.
  std::optional<Stage> stage;
  if (!options.out.empty()) {
    stage = load_stage(options.stage_file);
    const int width = images.front().width, height = images.front().height;
    if (stage->camera.width != width || stage->camera.height != height) {
      throw InputError(options.stage_file.string() + ": camera: expected " + std::to_string(width) +
                       "x" + std::to_string(height) + " like the photographs, got " +
                       std::to_string(stage->camera.width) + "x" +
                       std::to_string(stage->camera.height));
    }
  }
  std::vector<const Image*> pointers;
  pointers.reserve(images.size());
  for (const Image& im : images) pointers.push_back(&im);
  capture::CameraCalibrationOptions calibration_options;
  calibration_options.fix_aspect_ratio = options.square_pixels;
  CalibrateCameraSummary summary;
  summary.calibration = capture::calibrate_camera(pointers, names, board, calibration_options);
  const capture::CameraCalibration& cal = summary.calibration;
  if (!cal.ok || !stage) return summary;
  // The stage file's camera is a centred pinhole: only the field of view carries over.
  stage->camera.fov_y_deg = cal.fov_y_deg();
  write_file_atomic(options.out, stage_to_json(*stage));
  summary.written = true;
  return summary;
}

}  // namespace ls::jobs
