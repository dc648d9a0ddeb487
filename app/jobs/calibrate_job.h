#pragma once
// Calibrate the dome from photographs (capture/light_calibration.h, capture/camera_calibration.h):
// LED directions (and positions, with two spheres) from mirror spheres, LED intensities, colours
// and flat fields from a matte white target, the camera's field of view from a chessboard. Each
// writes a calibrated stage file; images with problems are listed in the summary and left out.
//
// The photographs of a light calibration are one per LED: files named "ledNNN.*" are LED id NNN,
// otherwise the sorted images of the folder are the stage's LEDs in order ("reference.*" and
// "ref.*" are not LED photographs). A dome's worth need not fit in memory: they are read one at a
// time.
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/job.h"
#include "capture/camera_calibration.h"
#include "capture/light_calibration.h"
#include "lightstage/stage.h"

namespace ls::jobs {

struct CalibrateDirectionsOptions {
  std::filesystem::path stage_file;  // Its camera took the photographs.
  std::filesystem::path images_dir;  // One photograph per LED.
  // The spheres' outlines: found in a reference shot (the spheres brighter than the background;
  // default images_dir/reference.{exr,png,jpg} or ref.JPG), or given as `circles`: cx, cy, r per
  // sphere in pixels (x right, y down, pixel centres at +0.5).
  std::filesystem::path reference;
  std::vector<double> circles;
  int spheres = 2;               // Spheres to look for in the reference shot.
  double sphere_radius_m = 0.0;  // Needed with a perspective camera.
  double sphere_z_m = 0.0;       // The spheres' centres' z (orthographic camera).
  double blob_fraction = 0.25;   // capture::HighlightOptions::blob_fraction.
  double saturation = 0.0;       // Clipped value of the images (0: none).
  std::filesystem::path out;     // Calibrated stage file to write.
  // Empty when valid, else what is wrong, naming the flag.
  std::string validate() const;
};

struct CalibrateDirectionsSummary {
  Stage nominal;     // As read from stage_file.
  Stage calibrated;  // Written to out when `written`.
  // The outlines found in the reference shot (empty when given as circles).
  std::vector<capture::SphereOutline> found_outlines;
  capture::DirectionCalibration calibration;  // One estimate per photograph (led_index set).
  capture::StageUpdate update;
  bool written = false;  // False when no LED direction was calibrated: nothing written.
};

// InputError for bad options, unreadable files, photographs that do not match the stage, or no
// sphere in the reference shot. Progress: "calibrate directions", one unit per photograph.
CalibrateDirectionsSummary calibrate_directions(const CalibrateDirectionsOptions& options,
                                                const ProgressFn& progress = {});

struct CalibrateIntensitiesOptions {
  std::filesystem::path stage_file;  // LED directions already calibrated.
  std::filesystem::path white_dir;   // One photograph per LED of the white plane.
  double albedo = 1.0;               // Reflectance of the target (1: relative to it).
  double plane_z_m = 0.0;            // The plane's z (it faces the camera).
  double saturation = 0.0;           // Clipped value of the images (0: none).
  std::filesystem::path flat_field;  // The flat fields' image (empty: out with .flatfield.exr).
  std::filesystem::path out;         // Calibrated stage file to write.
  // Empty when valid, else what is wrong: outputs go into folders that exist (a typo in a path
  // is not a new folder).
  std::string validate() const;
  std::filesystem::path flat_field_file() const;  // flat_field, or its default.
};

struct CalibrateIntensitiesSummary {
  Stage nominal;     // As read from stage_file.
  Stage calibrated;  // Written to out when `written`; names flat_field_file().
  capture::IntensityCalibration calibration;  // One estimate per photograph (led_index set).
  capture::StageUpdate update;
  std::filesystem::path flat_field;  // Where the flat fields are (or would have been) written.
  bool written = false;              // False when no LED intensity was calibrated: nothing written.
};

// InputError for bad options, unreadable files or photographs that do not match the stage.
// Progress: "calibrate intensities", one unit per photograph.
CalibrateIntensitiesSummary calibrate_intensities(const CalibrateIntensitiesOptions& options,
                                                  const ProgressFn& progress = {});

struct CalibrateCameraOptions {
  std::filesystem::path images_dir;  // Photographs of the chessboard, several tilted poses.
  std::string board = "9x6";         // Inner corners, WxH (W != H).
  double square_mm = 30.0;
  bool square_pixels = false;        // Fit one focal length (fx = fy).
  std::filesystem::path stage_file;  // With out: the stage to update.
  std::filesystem::path out;         // Stage file to write with the fitted fov_y_deg (optional).
  // Empty when valid, else what is wrong, naming the flag.
  std::string validate() const;
};

struct CalibrateCameraSummary {
  capture::CameraCalibration calibration;
  bool written = false;  // out written: stage_file with calibration.fov_y_deg().
};

// "WxH" inner corners and the square size as a board; InputError naming --board otherwise.
capture::ChessboardSpec parse_chessboard(const std::string& text, double square_mm);

// InputError for bad options, unreadable images, or (checked before the fit) a stage whose camera
// is not the photographs' size. A failed fit is no error: calibration.ok is false and nothing is
// written. Progress: "read chessboard views", one unit per photograph.
CalibrateCameraSummary calibrate_camera(const CalibrateCameraOptions& options,
                                        const ProgressFn& progress = {});

}  // namespace ls::jobs
