#pragma once
// Leave-lights-out evaluation of compact fields (issue 7), and the small simulated RTI scenes it
// runs on in tests and in `lightstage bench compact`.
//
// Protocol: hold out every `every`-th valid LED (those with index % every == offset), build the
// representation from the others, relight it under a unit point light at each held-out LED's
// direction, and compare with the held-out image (the field's own samples: for a simulated scene
// with noise, they carry the noise too). PSNR is over all held-out images together, with the peak
// = the largest reference value; SSIM is the mean over held-out images and channels of the
// standard SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5, K1 = 0.01, K2 = 0.03) with
// the same peak as dynamic range.
#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"
#include "lightstage/stage.h"
#include "relight/lighting/compact_field.h"
#include "sim/scene.h"

namespace ls::sim {

// Mean SSIM over the channels of two same-size images, with `peak` as the dynamic range.
double ssim(const Image& actual, const Image& reference, double peak);

// A field with only the given lights (indices into field.lights()), values copied.
capture::ReflectanceField select_lights(const capture::ReflectanceField& field,
                                        const std::vector<int>& light_indices);

struct LeaveLightsOutOptions {
  int every = 5;  // Hold out LEDs with index % every == offset.
  int offset = 2;
  // Held-out LEDs must also have dir.z above this (RTI bases only know the camera's hemisphere).
  double min_dir_z = -1.0;
  // Called with the representation built from the training LEDs (e.g. to time its relighting).
  std::function<void(const relight::CompactField&)> inspect;
};

struct LeaveLightsOutResult {
  std::string name;
  double psnr_db = 0;
  double ssim = 0;
  double bytes_per_pixel = 0;
  double build_s = 0;
  int held_out = 0;
  int training = 0;
};

using CompactBuilder =
    std::function<std::unique_ptr<relight::CompactField>(const capture::ReflectanceField&)>;

LeaveLightsOutResult leave_lights_out(const capture::ReflectanceField& field,
                                      const CompactBuilder& build,
                                      const LeaveLightsOutOptions& options = {});

// Simulated RTI scenes, 64 x 64 by default, seen by an orthographic camera:
//   matte    - a Lambertian sphere in front of a Lambertian backdrop;
//   glossy   - the same sphere with a Torrance-Sparrow lobe (k_s 0.5, m 0.2);
//   shadowed - a smaller sphere close to the backdrop, casting shadows on it.
enum class RtiScene { kMatte, kGlossy, kShadowed };
const char* to_string(RtiScene scene);
Scene rti_scene(RtiScene scene);

// An RTI dome: `count` LEDs on a Fibonacci spiral over the camera's hemisphere (+Z), at least
// min_elevation_deg above the image plane; camera width = height = resolution.
Stage rti_dome_stage(int count = 150, double min_elevation_deg = 10.0, int resolution = 64);

// The ideal field R(x, l) (render_one_light) plus Gaussian noise of variance
// read_variance + shot_variance_per_unit * max(v, 0), recorded in field.noise as measured.
capture::ReflectanceField render_noisy_field(const Stage& stage, const Scene& scene,
                                             const capture::FieldNoise& noise, uint64_t seed);

}  // namespace ls::sim
