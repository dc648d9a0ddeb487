#pragma once
// GenICam cameras (GigE Vision, USB3 Vision) through Aravis. Aravis and GLib types stay in
// aravis_camera.cc (STYLE.md rule 7).
//
// NETWORK: opening a camera by an id Aravis does not know, and discover_aravis_cameras(), broadcast
// on every interface. Ids starting with "Fake_" open Aravis' in-process fake camera with only the
// Fake interface enabled: nothing is sent on any network; tests use those.
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "lightstage/hardware.h"
#include "lightstage/stage.h"

namespace ls {

struct AravisOptions {
  int n_buffers = 4;  // Stream buffer pool.
};

// A camera opened by CameraSpec::device_id, set to the spec's size and pixel format (mono for 1
// channel, a Bayer pattern demosaiced to RGB for 3; 8 to 16 bits), triggered by software or by an
// input line (camera.sync), an output line at ExposureActive when asked for. Exposure and
// gain are set per request and read back; the frame reports what the camera actually used. Gain is
// linear (1 = native) and maps to the camera's Gain feature in dB (SFNC). Throws InputError for an
// empty device id, HardwareError when the camera cannot be opened or configured.
class AravisCamera : public Camera {
 public:
  explicit AravisCamera(const CameraSpec& spec, const AravisOptions& options = {});
  ~AravisCamera() override;
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  CameraInfo info() const override;
  // Throws CameraTimeout when no complete frame arrives within spec.timeout_s (plus the exposure),
  // HardwareError when the camera refuses a setting or its control connection is lost.
  CapturedFrame capture(const FrameRequest& request) override;
  // camera.sync.trigger "line": the camera is armed for each frame and `pulse` fires its trigger
  // input (the controller's line); the camera was set to that input when opened.
  void set_trigger_line(const std::function<void()>& pulse) override;

  std::string pixel_format() const;
  int incomplete_frames() const;  // Frames dropped as incomplete since opening.
  // Sets any GenICam feature from its string form (enumerations included), e.g. ("TriggerSource",
  // "Line1") to expose on a hardware trigger line. Throws HardwareError naming the feature.
  void set_feature(const std::string& name, const std::string& value);
  std::string feature(const std::string& name) const;  // A feature's string form.
  // Executes a GenICam command feature (e.g. "AcquisitionStop"). Throws HardwareError.
  void execute_command(const std::string& name);
  // In-process fake camera only: how often it polls its software trigger (Aravis default 25 Hz).
  void set_fake_trigger_frequency(double hz);
  // In-process fake camera only: its frames arrive empty, though marked complete (a transfer cut
  // short), until called again with false.
  void set_fake_frames_empty(bool empty);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct AravisDeviceInfo {
  std::string id, vendor, model, serial, protocol, address;
};
// Lists the cameras Aravis finds. BROADCASTS on every network interface: only on the user's
// request.
std::vector<AravisDeviceInfo> discover_aravis_cameras();

// ---- Pure helpers, exposed for tests
// --------------------------------------------------------------

// GenICam pixel format names that deliver (channels, bit_depth), in order of preference.
std::vector<std::string> aravis_pixel_format_candidates(int channels, int bit_depth);
// Bits per pixel of a supported (unpacked) GenICam format, or 0 when unsupported.
int genicam_format_bit_depth(const std::string& pixel_format);
// Decodes one image: Mono* as is, Bayer* demosaiced to RGB. Throws HardwareError when the buffer is
// smaller than width * height pixels.
RawFrame decode_genicam_image(const void* data, size_t size, const std::string& pixel_format,
                              int width, int height);

}  // namespace ls
