#pragma once
// Small simulated RTI scenes and the dome that lights them, for compact-field tests, the
// leave-lights-out evaluation and `lightstage bench compact`.
#include <Eigen/Core>

#include "lightstage/stage.h"
#include "sim/scene.h"

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

}  // namespace ls::sim
