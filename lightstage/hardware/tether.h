#pragma once
// A camera on USB as libgphoto2 sees it, narrowed to what a dome's capture needs: its settings,
// a shot, the files it adds and their download. A seam, so that the capture's logic
// (tethered_camera.h) is tested against a fake that behaves as a DSLR does (sim/dslr_tether.h):
// a shot takes time, its files appear as events, a busy camera refuses, a camera can vanish.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/hardware.h"

namespace ls {

// The camera refuses for now (still writing the last shot to its card): try again shortly.
class TetherBusy : public HardwareError {
 public:
  using HardwareError::HardwareError;
};

struct TetherFile {
  std::string folder;  // On the camera, e.g. "/store_00020001/DCIM/100CANON".
  std::string name;    // e.g. "IMG_0042.CR2".
};

struct TetherSetting {
  std::string value;                 // As the camera shows it ("1/125", "100", "RAW").
  std::vector<std::string> choices;  // Empty: free text or a range.
};

struct TetherEvent {
  enum class Kind { kTimeout, kFileAdded, kCaptureComplete, kOther };
  Kind kind = Kind::kTimeout;
  TetherFile file;  // kFileAdded.
};

class Tether {
 public:
  virtual ~Tether() = default;
  virtual std::string describe() const = 0;  // "Canon EOS 80D (usb:001,007)".
  // A configuration widget's value and choices; nullopt when the camera has none of that name.
  virtual std::optional<TetherSetting> setting(const std::string& name) = 0;
  virtual void set_setting(const std::string& name, const std::string& value) = 0;
  // What the next shot is for. Real cameras ignore it; the simulated one renders the scene at
  // its time and seeds its noise with its key, as the simulated stage does for every frame.
  virtual void prepare(const FrameRequest& request) { (void)request; }
  virtual void trigger() = 0;  // Starts a shot; TetherBusy when the camera cannot yet.
  virtual TetherEvent wait_event(double timeout_s) = 0;
  virtual std::vector<std::uint8_t> download(const TetherFile& file) = 0;
  virtual void remove(const TetherFile& file) = 0;
  // All of them throw HardwareError when the camera is gone (unplugged, asleep, switched off).
};

// libgphoto2: the camera named by `device` (its model as libgphoto2 lists it, or its port, e.g.
// "usb:001,007"; empty: the only one). HardwareError naming `stage_source`'s camera.device (or
// camera.backend when no camera is attached at all) otherwise.
std::unique_ptr<Tether> open_gphoto2_tether(const std::string& device,
                                            const std::string& stage_source);
// "Canon EOS 80D (usb:001,007)" for each camera libgphoto2 detects (USB only: sends nothing on a
// network).
std::vector<std::string> list_gphoto2_cameras();

}  // namespace ls
