#pragma once
// Camera intrinsics from photographs of a chessboard: OpenCV finds the inner corners of
// each view (findChessboardCornersSB, sub-pixel) and calibrateCamera fits a pinhole with radial
// and tangential distortion to all views. The result feeds capture::ViewCamera (fx, fy, cx, cy).
//
// Image coordinates as in light_calibration.h: pixel (i, j) covers [i, i+1) x [j, j+1), its
// centre at (i + 0.5, j + 0.5). (OpenCV puts pixel centres at integers; the conversion is here.)
#include <string>
#include <vector>

#include "lightstage/image.h"

namespace ls::capture {

struct ChessboardSpec {
  int inner_cols = 9;  // Inner corners along a row (OpenCV's pattern width).
  int inner_rows = 6;
  double square_m = 0.03;  // Printed square size, metres (sets the scale of the board poses only).
  // Throws InputError naming the field ("chessboard: board: expected ..., got ...").
  void check() const;
};

struct CameraCalibrationOptions {
  bool fix_aspect_ratio = false;  // Fit fx = fy (square pixels) instead of both.
  bool zero_tangential = false;   // Fit no tangential distortion (p1 = p2 = 0).
  bool fit_k3 = false;            // The sixth-order radial term: only for wide-angle lenses.
  int min_views = 3;              // Fewer usable views: the calibration is refused (ok = false).
};

struct CameraViewResult {
  std::string image;
  bool found = false;
  double rms_reprojection_px = 0;  // After the fit; 0 when not found.
};

struct CameraCalibration {
  bool ok = false;
  std::string problem;  // Why not ok.
  int width = 0, height = 0;
  double fx = 0, fy = 0;                // Focal lengths, pixels.
  double cx = 0, cy = 0;                // Principal point, pixels (centre-at-half convention).
  std::vector<double> distortion;       // OpenCV order: k1, k2, p1, p2, k3.
  double rms_reprojection_px = 0;       // Over all corners of all used views.
  std::vector<CameraViewResult> views;  // One per image, in order.

  // The vertical field of view the focal length implies, degrees (CameraSpec::fov_y_deg).
  double fov_y_deg() const;
};

// One image per view (any channels; luminance is used). Views where the board is not found are
// reported in `views` and left out. Images must share one size (InputError naming the image).
CameraCalibration calibrate_camera(const std::vector<const Image*>& images,
                                   const std::vector<std::string>& names,
                                   const ChessboardSpec& board,
                                   const CameraCalibrationOptions& options);

}  // namespace ls::capture
