#pragma once
// A DSLR or mirrorless camera as the sequencer's Camera: each frame one shot at the shutter speed
// and ISO nearest the request (from the camera's own choices, reported as shot), its files
// downloaded, the raw one decoded by LibRaw (raw_photo.h) and handed on with the file itself, which
// the session keeps beside its frames. A camera the stage gives 8-bit codes (camera.bit_depth 8)
// is a JPEG camera: its JPEGs are decoded instead, their curve recovered at build as for any
// 8-bit camera (camera.response "recover"). Over a Tether: libgphoto2, or the simulated DSLR.
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lightstage/hardware.h"
#include "lightstage/hardware/tether.h"
#include "lightstage/stage.h"

namespace ls {

class TetheredCamera : public Camera {
 public:
  // Sets camera.gphoto2.settings, then checks the shutter and ISO widgets. HardwareError naming
  // the camera and the stage field when the camera has no such setting or refuses the value.
  TetheredCamera(const CameraSpec& spec, std::unique_ptr<Tether> tether,
                 const std::string& stage_source);

  CameraInfo info() const override;
  // CameraTimeout when no file arrives within the exposure plus camera.timeout_s; HardwareError
  // (naming the camera) when it is gone.
  CapturedFrame capture(const FrameRequest& request) override;

  // camera.gphoto2.settings as the camera reports them once set, then its aperture, image format
  // and the like where it has them.
  std::vector<std::pair<std::string, std::string>> reported_settings() const override;

 private:
  // A widget exposure or gain is set through: its name, value now, and choices.
  struct Widget {
    std::string name, value;
    std::vector<std::string> choices;
  };
  std::string choose(const Widget& widget, double wanted,
                     bool (*parse)(const std::string&, double&), double& chosen) const;
  void set_if_changed(Widget& widget, const std::string& value);
  void trigger_when_ready(double deadline_s);

  CameraSpec spec_;
  std::unique_ptr<Tether> tether_;
  std::string name_;
  std::vector<std::pair<std::string, std::string>> accepted_;
  Widget shutter_, iso_;
};

// "1/125", "0.5", "2", "30s", "2.0000s" in seconds; false for "bulb", "Auto" and the like.
bool parse_shutter_seconds(const std::string& text, double& seconds);
// "100", "ISO 100"; false for "Auto".
bool parse_iso(const std::string& text, double& iso);

}  // namespace ls
