#pragma once
// Calibration targets photographed on the simulated stage, so light calibration can be checked
// against truth: a real dome is never where its drawing says, so the simulated one is not either
// (perturb_stage), and the targets are rendered under the perturbed ("true") LEDs.
//
//  * Mirror spheres: a true mirror (constant reflectance: chrome's Fresnel curve is nearly flat
//    at the angles that matter, and it would only scale the highlight, not move it) reflecting
//    LEDs of finite size: a ball of radius led_radius_m that looks like a disc of uniform
//    radiance. A delta-sharp BRDF cannot show a point light at all, and a glossy lobe would move
//    the highlight's centroid off the mirror direction, so a finite mirror-reflected source is the
//    honest target. Pixels are supersampled (box filter).
//  * A matte white plane facing the camera: Lambertian, lit by each LED with its beam
//    non-uniformity and, for LEDs at a finite distance, the 1/r^2 falloff and the local cosine.
//  * A printed chessboard at any pose, for camera intrinsics (capture/camera_calibration.h).
//  * A sensor: optical blur, shot and read noise, clipping at full scale, quantisation.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/stage.h"

namespace ls::sim {

struct StagePerturbation {
  double direction_sigma_deg = 2.0;     // Each LED moves by a random rotation of this RMS angle.
  double intensity_jitter = 0.10;       // Uniform in [-j, +j], relative.
  double color_jitter = 0.10;           // Per channel, uniform in [-j, +j], relative.
  std::optional<double> dome_radius_m;  // Set: LEDs at this distance from the origin (near field).
  double beam_gradient_per_m = 0.3;     // Beam non-uniformity across the target, RMS per metre.
  uint64_t seed = 1;
};

// The LED's beam over the target plane z = 0: b(x, y) = 1 + gx x + gy y + k (x^2 + y^2), x, y in
// metres (stage frame); b(0, 0) = 1 so the LED's intensity stays its irradiance at the origin.
struct LedBeam {
  double gx = 0, gy = 0, k = 0;
  double at(double x, double y) const { return 1.0 + gx * x + gy * y + k * (x * x + y * y); }
};

struct PerturbedStage {
  Stage truth;                 // Directions, distances, intensities and colours as built.
  std::vector<LedBeam> beams;  // One per LED.
};

PerturbedStage perturb_stage(const Stage& nominal, const StagePerturbation& perturbation);

struct MirrorBall {
  Eigen::Vector3d center{0, 0, 0};
  double radius_m = 0.1;
};

struct SensorModel {
  double full_scale = 1.0;     // Radiance that reads full scale.
  double full_well_e = 20000;  // Electrons at full scale.
  double read_noise_e = 4.0;
  int bit_depth = 12;
  double blur_sigma_px = 0.7;  // Gaussian optical blur (lens and demosaicing), pixels.
};

// Blur, noise, clipping and quantisation; the result is in radiance units again, with clipped
// pixels exactly at full_scale.
Image apply_sensor(const Image& radiance, const SensorModel& sensor, uint64_t seed);

// Mirror spheres seen by the stage's camera. The rays are traced once (per pixel, supersample^2
// samples), then each LED image costs only the pixels near its highlight.
class MirrorSphereRenderer {
 public:
  MirrorSphereRenderer(std::vector<MirrorBall> balls, const CameraSpec& camera,
                       int supersample = 4);
  ~MirrorSphereRenderer();
  MirrorSphereRenderer(const MirrorSphereRenderer&) = delete;
  MirrorSphereRenderer& operator=(const MirrorSphereRenderer&) = delete;

  // Radiance image of the balls lit by one LED (RGB, stage radiance units). A distant LED (no
  // distance_m) is a disc of angular radius led_radius_m / 1 m; either way its radiance is set so
  // that its irradiance at the origin is led.irradiance_rgb().
  Image render_led(const Led& led, double led_radius_m, double reflectance) const;
  // The balls under a uniform environment of the given radiance, on a black background: the
  // reference shot from which their outlines are fitted.
  Image render_reference(double environment_radiance, double reflectance) const;

 private:
  struct Rays;
  std::vector<MirrorBall> balls_;
  int width_ = 0, height_ = 0;
  std::unique_ptr<Rays> rays_;
};

struct WhitePlaneTarget {
  Eigen::Vector3d center{0, 0, 0};  // Faces +Z (the camera); covers the whole view.
  double albedo = 0.8;
};

// Radiance image of the white plane lit by one LED of the perturbed stage (its beam applied).
Image render_white_plane(const WhitePlaneTarget& target, const Led& led, const LedBeam& beam,
                         const CameraSpec& camera);

// A printed chessboard on a flat card: inner_cols x inner_rows inner corners (OpenCV's pattern
// size), squares square_m wide, a white margin of one square around the pattern. Board frame: the
// first inner corner at the origin, x along the columns, y along the rows, the card in z = 0 and
// its printed side facing -z.
struct Chessboard {
  int inner_cols = 9;
  int inner_rows = 6;
  double square_m = 0.03;
  double black_radiance = 0.05;
  double white_radiance = 0.9;
};

// Where the board is: stage_from_board maps board coordinates to the stage frame.
struct BoardPose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation{0, 0, 0};
};

// A pose that shows the board's printed side to the stage's camera (on +Z): the board centred
// at `center_in_stage`, tilted by tilt_x_deg about the stage X axis and tilt_y_deg about Y.
BoardPose board_facing_camera(const Chessboard& board, const Eigen::Vector3d& center_in_stage,
                              double tilt_x_deg, double tilt_y_deg);

// Radiance image (RGB, grey) of the chessboard seen by the stage's camera (orthographic or
// pinhole, as the simulator), supersample^2 samples per pixel (box filter), on a black background.
Image render_chessboard(const Chessboard& board, const BoardPose& pose, const CameraSpec& camera,
                        int supersample = 4);

}  // namespace ls::sim
