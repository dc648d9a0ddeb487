#pragma once
// The stage description: the dome's LEDs, the camera and the capture plan.
// Frames (DESIGN.md): right-handed stage frame, +Y up, the camera on +Z looking toward -Z, the
// stage centre at the origin. An LED direction is the unit vector from the origin toward the LED.
#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lightstage/raw_photo.h"

namespace ls {

struct Led {
  int id = 0;                             // Stable id used in file names and manifests.
  Eigen::Vector3d dir_in_stage{0, 1, 0};  // Unit vector from the origin toward the LED.
  std::optional<double> distance_m;       // Set when the stage file gives a position.
  Eigen::Vector3d color_gain{1, 1, 1};    // Calibrated RGB balance of this LED (relative).
  double intensity = 1.0;  // Calibrated irradiance at the origin, facing the LED (E units).
  std::string gpio_chip;   // For the gpiod back-end, e.g. "gpiochip0".
  int gpio_line = -1;
  bool active_low = false;
  int board_channel = -1;  // For a serial LED board: its output; -1: the LED's index in "leds".

  // The irradiance at the origin per channel: intensity * color_gain.
  Eigen::Vector3d irradiance_rgb() const { return intensity * color_gain; }
};

struct ExposureStep {
  double exposure_s = 0.01;
  double gain = 1.0;  // Linear sensor gain (1 = native).
};

// How the camera maps light to digital numbers; capture/ inverts it.
struct CameraResponse {
  enum class Kind { kLinear, kGamma, kTable, kRecover };
  Kind kind = Kind::kLinear;
  double gamma = 1.0;                // kGamma: DN/max = x^(1/gamma), x the normalised exposure.
  std::filesystem::path table_file;  // kTable: text file, one linear value per DN (per channel).
};

// Parameters of the simulated sensor; real back-ends ignore them.
struct SimulatedSensor {
  double full_well_e = 20000.0;       // Electrons at saturation (gain 1).
  double read_noise_e = 4.0;          // Gaussian read noise, electrons RMS.
  double dark_current_e_per_s = 5.0;  // Thermal electrons per second of exposure.
  double black_level = 0.01;          // Offset as a fraction of full scale, before the response.
  // Each frame takes its exposure time, as on a real camera (to try interrupting a capture, or
  // timing); false: frames come as fast as they render.
  bool real_time = false;
  // LEDs (by id) that never light, to try the dead-LED check on (a burnt-out LED, a loose wire).
  std::vector<int> dead_led_ids;
};

// How the controller and the camera keep time (docs/hardware.md, "Synchronisation"). The wiring
// each mode expects is described there; the simulator and Aravis' fake camera stand in for it in
// the tests.
struct CameraSync {
  // "software": the camera is triggered over its link. "line": the controller pulses its output
  // gpio_chip/gpio_line for pulse_us, wired to the camera's trigger input `input` (rising edge).
  std::string trigger = "software";
  std::string input = "Line0";
  std::string gpio_chip;
  int gpio_line = -1;
  double pulse_us = 100;  // Microseconds.
  // A camera output (e.g. "Line1") set to ExposureActive, wired to the LED drivers' enable: an LED
  // lights only while the controller selects it and the sensor integrates. "": none (an LED is lit
  // from before its bracket to after it).
  std::string exposure_active_output;
  bool line_triggered() const { return trigger == "line"; }
};

// A camera tethered through libgphoto2 (camera.backend "gphoto2"; stage file "camera":
// {"gphoto2": {...}}): how lightstage sets it up and decodes its files.
struct TetherSpec {
  // Camera configuration set before the first shot, by libgphoto2's widget names and values as
  // `gphoto2 --list-config` / `--get-config` show them: {"f-number": "f/8", "imageformat": "RAW"}.
  std::vector<std::pair<std::string, std::string>> settings;
  double base_iso = 100;  // The ISO of gain 1: a bracket step of gain g shoots at g * base_iso.
  // The widgets exposure and gain are set through (names differ by maker).
  std::string shutter_setting = "shutterspeed";
  std::string iso_setting = "iso";
  RawDecodeOptions raw;  // Demosaiced or binned, one white balance for the session.
  // A shot's files are deleted from the camera's card once downloaded and kept in the session.
  bool delete_from_camera = true;
};

struct CameraSpec {
  std::string backend = "sim";  // sim | aravis | v4l2 | gphoto2 | sim-dslr
  std::string device_id;        // Back-end specific (Aravis id, /dev/videoN).
  int width = 256;
  int height = 256;
  int channels = 3;
  int bit_depth = 12;
  std::vector<ExposureStep> bracket;  // Shortest first is customary; any order is accepted.
  CameraResponse response;
  // Radiance (stage units) that reads full scale, dark-subtracted, after 1 s at gain 1. Converts
  // the merged camera signal to radiance; 1.0 means "the field is in relative camera units".
  double radiometric_scale = 1.0;
  // Geometry: on +Z looking toward -Z. fov_y_deg == 0 means orthographic.
  double fov_y_deg = 0.0;
  double distance_m = 4.0;      // Perspective: camera centre at (0, 0, distance_m).
  double ortho_height_m = 2.4;  // Orthographic: height of the view at the origin.
  double timeout_s = 5.0;       // One frame; then CameraTimeout.
  int retries = 2;              // Retries of a timed-out frame before the session stops.
  CameraSync sync;
  SimulatedSensor simulated;
  TetherSpec tether;  // gphoto2 and sim-dslr.
};

struct CapturePlan {
  std::vector<int> led_order;  // LED ids in capture order; empty = file order.
  int dark_frames = 2;         // Dark frames per exposure step per time step (averaged).
  double settle_s = 0.0;       // Wait after switching an LED before exposing.
  int time_steps = 1;          // Captures of a changing scene.
  double interval_s = 0.0;     // Nominal time between time steps.
  // Or the scene time of each step (seconds, >= 0, increasing); when set, time_steps is its size
  // and interval_s is not used.
  std::vector<double> times_s;
  // Drift watch: the reference LED (an id; -1 none) is shot again, its whole bracket, before the
  // first LED of every time step, after every `reference_every` LEDs and after the last (frame
  // repeats 1, 2, ... of that LED). Its output over those shots tells how the dome's output (or
  // the camera's gain) drifted; `lightstage build --correct-drift` divides it out.
  int reference_led = -1;
  int reference_every = 20;
  // Exposures chosen per LED (by LED id: indices into camera.bracket, ascending), e.g. by
  // choose_led_exposures from an earlier session: the fewest that cover the scene's range under
  // that LED. An LED not listed is shot at the whole bracket. Stage file: "led_exposures":
  // [{"led": 12, "exposures": [0, 1]}, ...].
  std::map<int, std::vector<int>> led_exposures;
  // Reference shots per time step (0 without a reference LED), for `leds` LEDs in the order.
  int reference_shots(int leds) const;

  // Scene time of time step t, seconds: times_s[t], or t * interval_s.
  double step_time_s(int t) const;
  // Time from step t's start to the next step's; 0 for the last step (nothing follows it).
  double step_interval_s(int t) const;
};

// Calibration results applied when a field is built (`lightstage calibrate intensities` writes
// them). Stage file: "calibration": {"flat_field": "cal.flatfield.exr", "reference_z_m": 0}.
struct StageCalibration {
  // Side car holding each LED's flat field (one channel "ledNNN.Y" per LED over the camera's view,
  // capture/light_calibration.h); resolved against the stage file's folder. Empty: none.
  std::filesystem::path flat_field;
  // Near LEDs (Led::distance_m): a pixel's surface point is taken where its camera ray meets the
  // plane z = reference_z_m (metres, stage frame).
  double reference_z_m = 0.0;
};

// What switches the LEDs of a real dome: GPIO lines (Led::gpio_chip, gpio_line) or a board on a
// serial line speaking the README's lsled1 protocol (Led::board_channel). Stage file:
// "led_driver": {"backend": "serial", "port": "/dev/ttyACM0", "baud": 115200}.
struct LedDriverSpec {
  std::string backend = "gpio";  // gpio | serial
  std::string port;              // serial: the board's device, e.g. /dev/ttyACM0.
  int baud = 115200;
  std::string protocol = "lsled1";  // The only one so far.
  double timeout_s = 1.0;           // For the board's reply to one command.
  double startup_s = 3.0;  // A board that resets when its port opens (an Arduino) answers after.
  bool serial() const { return backend == "serial"; }
};

struct Stage {
  std::string name = "stage";
  std::vector<Led> leds;
  LedDriverSpec led_driver;
  CameraSpec camera;
  CapturePlan plan;
  StageCalibration calibration;
  // Directions further than this from every LED are not covered by the dome (0 = automatic: the
  // largest nearest-neighbour angle between LEDs).
  double coverage_radius_deg = 0.0;
  std::string source = "<built-in>";  // File it came from, for messages.

  int led_index(int id) const;             // Index into leds, or -1.
  std::vector<int> capture_order() const;  // Indices into leds, in plan order.
  // The bracket steps LED `led_index` is shot at (plan.led_exposures, else all), ascending.
  std::vector<int> exposures_of(int led_index) const;
  std::vector<Eigen::Vector3d> led_directions() const;
};

// Loads and validates a stage file (JSON). Every problem is an InputError of the form
// "<file>: <field>: <what was expected>, got <what was found>".
Stage load_stage(const std::filesystem::path& path);
// InputError naming the stage file and the field when a file the stage names (the flat field, a
// response table) is not there: what a capture's build will read.
void require_stage_files(const Stage& stage);
Stage parse_stage(std::string_view json_text, const std::string& source_name);
std::string stage_to_json(const Stage& stage);  // Round-trips through parse_stage.

// The built-in dome: a frequency-5 geodesic sphere cut below -11.5 degrees elevation (about 150
// LEDs: the upper hemisphere and one ring below it), a 12-bit camera and a 3-step bracket.
Stage default_stage();

// LED layouts. Elevation is measured from the horizontal plane (y = 0) toward +Y.
std::vector<Eigen::Vector3d> geodesic_dome_directions(int frequency, double min_elevation_deg);
std::vector<Eigen::Vector3d> fibonacci_dome_directions(int count, double min_elevation_deg);
// A stage like default_stage() with the given LED directions.
Stage stage_with_directions(const std::vector<Eigen::Vector3d>& dirs_in_stage);

}  // namespace ls
