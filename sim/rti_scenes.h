#pragma once
// Small simulated RTI scenes and the dome that lights them, for compact-field tests, the
// leave-lights-out evaluation and `lightstage bench compact`.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/stage.h"
#include "sim/calibration_targets.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"

namespace ls::sim {

// Simulated RTI scenes, seen by the camera of rti_dome_stage (orthographic):
//   matte    - a Lambertian sphere in front of a Lambertian backdrop;
//   glossy   - the same sphere with a Torrance-Sparrow lobe (k_s 0.5, m 0.2);
//   shadowed - a smaller sphere close to the backdrop, casting shadows on it.
enum class RtiScene { kMatte, kGlossy, kShadowed };
const char* to_string(RtiScene scene);
Scene rti_scene(RtiScene scene);

// An RTI dome: `count` LEDs on a Fibonacci spiral over the camera's hemisphere (+Z), at least
// min_elevation_deg above the image plane; camera width = height = resolution.
Stage rti_dome_stage(int count = 150, double min_elevation_deg = 10.0, int resolution = 64);

// An RTI dome as real ones are, its LEDs near the object: `leds` LEDs on a Fibonacci spiral at
// least 15 deg above the table, each radius_m from the origin within 0.3% (a real dome is not a
// perfect sphere), so each pixel sees its own light direction and distance; a flat Lambertian
// backdrop in z = 0 filling an orthographic width x height view 0.36 radius_m high; and two mirror
// spheres resting on it near the lower corners (radius 0.04 radius_m), what RTI sets put in every
// frame to locate their lights. The spheres are black but for their mirror reflection and shadow
// the backdrop.
struct NearRtiDome {
  Stage stage;  // The truth: every LED with its distance_m; unit irradiance at the origin.
  Scene scene;  // The backdrop, then the spheres.
  std::vector<MirrorBall> balls;
  Eigen::Vector3d backdrop_normal{0, 0, 1};
};
// fov_y_deg > 0: a pinhole camera instead, on the axis as high as sees the same 0.36 radii.
NearRtiDome near_rti_dome(int leds = 41, int width = 480, int height = 270, double radius_m = 1.0,
                          double fov_y_deg = 0.0, uint64_t seed = 1);

// The dome's images, value per unit of the LED's irradiance at the origin: the backdrop as the
// simulator renders near LEDs (1/r^2, its own direction, the spheres' shadows) plus each
// sphere's mirror image of the LED (a 5 mm disc, reflectance 0.6: its flux, spread by the lens
// about the point where the sphere mirrors the LED's centre).
class NearRtiRenderer {
 public:
  explicit NearRtiRenderer(const NearRtiDome& dome);
  Image render(int led);

 private:
  const NearRtiDome& dome_;
  SimStage backdrop_;
  MirrorSphereRenderer mirrors_;
};

}  // namespace ls::sim
