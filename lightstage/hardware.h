#pragma once
// The hardware seen by the sequencer. Back-ends (simulated stage, libgpiod, Aravis) implement
// these; the sequencer cannot tell them apart.
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "lightstage/image.h"

namespace ls {

struct CameraSpec;

// Switches LEDs. Indices are positions in Stage::leds.
class LightController {
 public:
  virtual ~LightController() = default;
  virtual int num_lights() const = 0;
  virtual void set_light(int led_index, bool on) = 0;  // Throws HardwareError.
  // Lights several LEDs at once, LED l for the share level[l] (0..1) of every moment: on/off lines
  // switched in a period far shorter than the exposure, or a dimmable driver's level. What the
  // dome plays an environment map with (`lightstage play`); all_off() ends it. Throws
  // HardwareError when the controller cannot (the default).
  virtual void set_levels(const std::vector<double>& level);
  // What implementations check first: one level per LED, each in [0, 1]; HardwareError naming
  // `who` and the LED index otherwise.
  static void check_levels(const std::vector<double>& level, int num_lights,
                           const std::string& who);
  // The period of that modulation (software PWM), 0 when continuous: an exposure must span many
  // periods (1/N of a period is the error of a level over N of them).
  virtual double level_period_s() const { return 0.0; }
  // Throws HardwareError when the lights failed on their own since set_levels (a PWM thread's line
  // error: every LED is then off); nothing otherwise.
  virtual void verify_levels() {}
  // Pulses the output wired to the camera's trigger input (camera.sync.trigger "line"), rising
  // edge first. Throws HardwareError when the controller has no such line (the default).
  virtual void pulse_trigger();
  // Must not throw: it runs on every exit path, including signal handling and errors.
  virtual void all_off() noexcept = 0;
};

struct CameraInfo {
  std::string id;
  std::string model;
  int width = 0;
  int height = 0;
  int channels = 0;
  int bit_depth = 0;
};

struct FrameRequest {
  double exposure_s = 0.01;
  double gain = 1.0;
  // Stable identity of this frame within the capture plan. Hardware ignores it; the simulator seeds
  // its noise with it, so a resumed capture reproduces an uninterrupted one bit for bit.
  uint64_t sequence_key = 0;
  double scene_time_s = 0.0;  // Plan time of this frame (the simulator renders the scene then).
};

// When a frame was taken, for the record: host times in nanoseconds since the Unix epoch
// (CLOCK_REALTIME), the camera's own clock as it stamps its frames. 0: not known.
struct FrameTiming {
  int64_t led_on_ns = 0;     // Its LED switched on (0 for a dark frame),
  int64_t requested_ns = 0;  // the frame asked of the camera (the software trigger),
  int64_t delivered_ns = 0;  // the frame received,
  int64_t led_off_ns = 0;    // its LED switched off: a lit frame lies within [on, off].
  uint64_t sensor_ns = 0;    // The camera's timestamp of the frame (GenICam: its exposure).
};

struct CapturedFrame {
  RawFrame raw;
  double exposure_s = 0.0;  // As reported by the camera after the request.
  double gain = 1.0;
  FrameTiming timing;  // The camera sets sensor_ns; the sequencer the host times.
  // The file as the camera wrote it (a DSLR's raw file), which the session keeps beside the frame;
  // empty for cameras that deliver pixels.
  std::string original_name;  // e.g. "IMG_0042.CR2".
  std::vector<std::uint8_t> original_file;
};

class Camera {
 public:
  virtual ~Camera() = default;
  virtual CameraInfo info() const = 0;
  // Throws CameraTimeout when no frame arrives in time, HardwareError for other faults.
  virtual CapturedFrame capture(const FrameRequest& request) = 0;
  // camera.sync.trigger "line": capture() arms the camera for its frame and calls `pulse` (the
  // controller pulsing the line wired to the camera's trigger input) instead of triggering by
  // software. Throws HardwareError when the camera takes no trigger line (the default).
  virtual void set_trigger_line(const std::function<void()>& pulse);
  // The camera's settings as it reports them (a DSLR's aperture, image format, ...), for the
  // session's record; none by default.
  virtual std::vector<std::pair<std::string, std::string>> reported_settings() const { return {}; }
};

// Wires the camera's trigger to the controller's trigger line when the spec asks for it
// (camera.sync.trigger "line"); nothing otherwise. Both must outlive the capture.
void wire_trigger(const CameraSpec& spec, LightController& lights, Camera& camera);

}  // namespace ls
