// Chessboard intrinsics on views rendered by the simulator's pinhole camera: the recovered focal
// length and principal point are compared with the CameraSpec that rendered them.
#include "capture/camera_calibration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "lightstage/errors.h"
#include "sim/calibration_targets.h"

namespace ls {
namespace {

CameraSpec pinhole_camera() {
  CameraSpec c;
  c.width = 640;
  c.height = 480;
  c.fov_y_deg = 40.0;
  c.distance_m = 1.0;
  return c;
}

struct Views {
  sim::Chessboard board;
  std::vector<Image> images;
  std::vector<std::string> names;
};

// Nine poses around the stage centre, tilted up to 35 deg (the focal length is only observable
// through the board's foreshortening), with the sensor's blur, noise and 12 bits.
Views render_views(const CameraSpec& camera) {
  Views v;
  const double tilts[][2] = {{0, 0},   {30, 0},   {-30, 0},  {0, 30},   {0, -30},
                             {25, 25}, {-25, 25}, {25, -35}, {-20, -20}};
  const double shifts[][2] = {{0, 0},     {0.03, 0.02}, {-0.03, 0.02},  {0.04, -0.02}, {-0.04, 0},
                              {0, -0.03}, {0.02, 0.03}, {-0.02, -0.02}, {0.03, 0}};
  sim::SensorModel sensor;
  for (int i = 0; i < 9; ++i) {
    const sim::BoardPose pose = sim::board_facing_camera(
        v.board, Eigen::Vector3d(shifts[i][0], shifts[i][1], 0.0), tilts[i][0], tilts[i][1]);
    v.images.push_back(sim::apply_sensor(sim::render_chessboard(v.board, pose, camera), sensor,
                                         /*seed=*/40 + i));
    v.names.push_back("board" + std::to_string(i));
  }
  return v;
}

capture::ChessboardSpec spec_of(const sim::Chessboard& b) {
  return {b.inner_cols, b.inner_rows, b.square_m};
}

struct IntrinsicsError {
  int found = 0;
  double focal_rel = 0;  // Worst of fx, fy, relative.
  double principal_px = 0;
  double fov_y_deg = 0;
  double rms_px = 0;
};

IntrinsicsError calibrate_and_compare(const Views& views, const CameraSpec& camera,
                                      const capture::CameraCalibrationOptions& options,
                                      const char* label) {
  std::vector<const Image*> images;
  for (const Image& im : views.images) images.push_back(&im);
  const capture::CameraCalibration cal =
      capture::calibrate_camera(images, views.names, spec_of(views.board), options);
  EXPECT_TRUE(cal.ok) << cal.problem;
  IntrinsicsError e;
  for (const auto& view : cal.views) e.found += view.found;
  const double true_f =
      0.5 * camera.height / std::tan(0.5 * camera.fov_y_deg * std::numbers::pi / 180.0);
  e.focal_rel = std::max(std::abs(cal.fx / true_f - 1), std::abs(cal.fy / true_f - 1));
  e.principal_px = std::hypot(cal.cx - 0.5 * camera.width, cal.cy - 0.5 * camera.height);
  e.fov_y_deg = cal.fov_y_deg();
  e.rms_px = cal.rms_reprojection_px;
  std::printf(
      "%s: %d of %zu views: fx %.3f fy %.3f (truth %.3f, worst %.4f%%), principal point (%.3f, "
      "%.3f) (truth (%d, %d), off by %.3f px), fov_y %.4f deg (truth %.1f), k1 %.5f, RMS "
      "reprojection %.4f px\n",
      label, e.found, views.images.size(), cal.fx, cal.fy, true_f, 100 * e.focal_rel, cal.cx,
      cal.cy, camera.width / 2, camera.height / 2, e.principal_px, e.fov_y_deg, camera.fov_y_deg,
      cal.distortion.empty() ? 0.0 : cal.distortion[0], e.rms_px);
  return e;
}

TEST(CameraCalibrationSim, FocalLengthAndPrincipalPointFromChessboardViews) {
  const CameraSpec camera = pinhole_camera();
  const Views views = render_views(camera);
  // The general model: fx, fy, cx, cy, k1, k2, p1, p2.
  const IntrinsicsError general = calibrate_and_compare(views, camera, {}, "general");
  // Measured: 9 of 9 views, focal 0.26% off, principal point 1.49 px, fov_y 40.015 deg, RMS
  // reprojection 0.093 px (0.24 px without cornerSubPix).
  EXPECT_EQ(general.found, 9);
  EXPECT_LT(general.focal_rel, 0.006);
  EXPECT_LT(general.principal_px, 3.0);
  EXPECT_NEAR(general.fov_y_deg, camera.fov_y_deg, 0.1);
  EXPECT_LT(general.rms_px, 0.15);
  // Square pixels and no tangential distortion, as the simulator's camera has.
  capture::CameraCalibrationOptions constrained;
  constrained.fix_aspect_ratio = true;
  constrained.zero_tangential = true;
  const IntrinsicsError square = calibrate_and_compare(views, camera, constrained, "square");
  // Measured: focal 0.053% off, principal point 0.98 px, fov_y 39.980 deg, RMS 0.096 px.
  EXPECT_LT(square.focal_rel, 0.0015);
  EXPECT_LT(square.principal_px, 2.0);
  EXPECT_NEAR(square.fov_y_deg, camera.fov_y_deg, 0.05);
  EXPECT_LT(square.rms_px, 0.15);
}

TEST(CameraCalibrationSim, ViewsWithoutTheBoardAreReportedAndTooFewRefused) {
  const CameraSpec camera = pinhole_camera();
  const Views views = render_views(camera);
  const Image blank(camera.width, camera.height, 3, 0.3f);
  std::vector<const Image*> images = {&views.images[0], &blank, &views.images[1]};
  const capture::CameraCalibration cal =
      capture::calibrate_camera(images, {"board0", "blank", "board1"}, spec_of(views.board), {});
  EXPECT_FALSE(cal.ok);
  EXPECT_NE(cal.problem.find("found in 2 of 3"), std::string::npos) << cal.problem;
  EXPECT_FALSE(cal.views[1].found);
  EXPECT_TRUE(cal.views[0].found);
  // Bad input names the field.
  capture::ChessboardSpec square{6, 6, 0.03};
  EXPECT_THROW(capture::calibrate_camera(images, {"a", "b", "c"}, square, {}), InputError);
  const Image small(32, 32, 3);
  std::vector<const Image*> mixed = {&views.images[0], &small};
  EXPECT_THROW(capture::calibrate_camera(mixed, {"board0", "small"}, spec_of(views.board), {}),
               InputError);
}

}  // namespace
}  // namespace ls
