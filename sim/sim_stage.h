#pragma once
// The simulated stage: the scene, the dome's LEDs and a camera with a response curve, shot noise,
// read noise, dark current, a bit depth and saturation. It implements the same LightController and
// Camera interfaces as the hardware back-ends, so the sequencer cannot tell it apart.
#include <memory>
#include <vector>

#include "lightstage/hardware.h"
#include "lightstage/stage.h"
#include "sim/scene.h"

namespace ls::sim {

// Per-pixel surface hits for the stage's camera (computed once per scene and camera), with the
// materials at scene time 0.
std::vector<SurfaceHit> trace_camera(const Scene& scene, const CameraSpec& camera);
// The same hits with the materials at scene time `time_s` (seconds).
std::vector<SurfaceHit> trace_camera(const Scene& scene, const CameraSpec& camera, double time_s);
// Re-evaluates the time-varying materials of `hits` (from trace_camera of the same scene) at scene
// time `time_s`: geometry does not change, only materials with a process do.
std::vector<SurfaceHit> at_time(const Scene& scene, std::vector<SurfaceHit> hits, double time_s);

// Whether `position` sees a distant light along `dir_in_stage` (shadow ray against all geometry;
// hits nearer than 0.2 mm are the surface the point lies on). Prepares the scene on every call:
// for single queries. render_one_light and render_ground_truth prepare it once and offset their
// shadow rays along the surface normal instead.
bool visible(const Scene& scene, const Eigen::Vector3d& position, const Eigen::Vector3d& dir);

// Noise-free radiance image of the scene lit by one distant LED of unit irradiance (at normal
// incidence) along dir_in_stage: L_o = f_r * cos(theta_i) * V. This is exactly the ideal R(x, l).
Image render_one_light(const Scene& scene, const std::vector<SurfaceHit>& hits,
                       const Eigen::Vector3d& dir_in_stage);

// Noise-free radiance image under one LED at a finite position (a point source, near field):
// x is lit from the direction toward the LED with irradiance (d0 / |P - x|)^2 times the irradiance
// at the origin, d0 = |P|, so a unit LED keeps Led::intensity's meaning (irradiance at the origin,
// facing the LED); L_o = f_r * cos(theta_i) * (d0 / r)^2 * V, the shadow ray ending at the LED.
// render_ground_truth integrates environment maps, which are light at infinity: it has no near
// LEDs, and captures of near LEDs agree with it only as far as the dome approximates infinity.
Image render_one_near_light(const Scene& scene, const std::vector<SurfaceHit>& hits,
                            const Eigen::Vector3d& led_position_in_stage);

// render_one_near_light at distance_m * dir_in_stage when the LED has a distance, otherwise
// render_one_light along dir_in_stage (bit for bit).
Image render_one_led(const Scene& scene, const std::vector<SurfaceHit>& hits, const Led& led);

class SimStage {
 public:
  SimStage(Stage stage, Scene scene, uint64_t seed);
  ~SimStage();

  LightController& lights();
  Camera& camera();
  const Stage& stage() const;
  const Scene& scene() const;
  // Each frame is rendered at its FrameRequest::scene_time_s. The stage caches the hits and the
  // one-light images of one scene time (the latest frame's, initially 0): frames of one time step
  // share them, and the next time step replaces them. A scene without time-varying materials
  // keeps one cache for all times.
  const std::vector<SurfaceHit>& hits() const;  // At scene_time_s().
  double scene_time_s() const;
  void set_scene_time(double time_s);
  // The noise-free one-light image of LED `led_index` (the ideal R(x, l), ignoring set_dead_led),
  // rendered on first use and cached (within 1 GiB: the least recently used are dropped at the
  // start of a capture, so a reference stays valid until the next one); near-field
  // (render_one_near_light) when the LED has a distance_m, distant otherwise. At scene_time_s(), or
  // at `time_s` (which moves the cache).
  const Image& one_light_image(int led_index);
  const Image& one_light_image(int led_index, double time_s);
  // The cache's budget (default 1 GiB) and how many images it holds now.
  void set_one_light_cache_bytes(std::size_t bytes);
  int cached_one_light_images() const;

  // Failure injection for tests: the camera times out on these sequence keys (once each), or
  // after `frames` more successful frames (forever, until cleared with a negative count).
  void inject_timeouts(std::vector<uint64_t> sequence_keys);
  void inject_timeout_after(int frames);
  void set_dead_led(int led_index, bool dead);
  // Frame faults for the capture's checks, on the frame whose sequence key is given, for its first
  // `shots` shots: kStale delivers the previous frame again (an earlier trigger's buffer), kTorn
  // the previous frame's rows from half the height down (a partial transfer), kWrongLed the frame
  // lit by the next LED (index + 1) instead of the one switched on.
  enum class FrameFault { kStale, kTorn, kWrongLed };
  void inject_frame_fault(uint64_t sequence_key, FrameFault fault, int shots = 1);
  // The dome's output drifting: every LED's irradiance times (1 + per_frame * frames delivered
  // since this call), as LEDs warming up or a sagging supply do.
  void set_output_drift(double per_frame);
  // The physical dome changed after calibration (an LED dimmed, knocked or remounted): LED
  // `led_index` now gives intensity_factor times its irradiance, from dir_in_stage. The stage
  // passed in, and any field built before, still describe it as it was.
  void perturb_led(int led_index, double intensity_factor, const Eigen::Vector3d& dir_in_stage);
  // An LED lit whatever the controller says (a stuck driver); -1 for none.
  void set_stuck_led(int led_index);
  // camera.sync.trigger "line": the controller's pulses no longer reach the camera's input.
  void set_trigger_wire_broken(bool broken);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace ls::sim
