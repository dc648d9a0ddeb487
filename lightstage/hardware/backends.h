#pragma once
// Real hardware for a stage: LEDs on GPIO lines or a serial board, with an Aravis, V4L2 or
// libgphoto2 camera, registered as the capture back-ends "aravis", "v4l2" and "gphoto2"
// (lightstage/backend_registry.h).
#include <memory>
#include <string>
#include <vector>

#include "lightstage/backend_registry.h"
#include "lightstage/hardware.h"
#include "lightstage/stage.h"

namespace ls {

struct Hardware {
  std::unique_ptr<LightController> lights;
  std::unique_ptr<Camera> camera;
};

// Registers "aravis", "v4l2" and "gphoto2", opened through open_hardware().
void register_hardware_backends(BackendRegistry& registry);

// True for the back-ends open_hardware() builds ("aravis", "v4l2", "gphoto2").
bool is_hardware_backend(const std::string& backend);

// The LEDs on GPIO lines (libgpiod) or on a serial board (stage.led_driver), all switched off.
std::unique_ptr<LightController> open_lights(const Stage& stage);
// The camera named by stage.camera.backend. Throws InputError for an unknown or "sim" back-end.
std::unique_ptr<Camera> open_camera(const CameraSpec& spec, const std::string& stage_source);
// LEDs first (so they are off before the camera starts), then the camera. Every device problem is a
// HardwareError naming the device before anything is captured.
Hardware open_hardware(const Stage& stage);

// What `lightstage devices` prints. Listing cameras runs Aravis discovery, which BROADCASTS on
// every network interface: pass list_aravis only on the user's request.
struct DeviceList {
  std::vector<std::string> gpio_chips;
  std::vector<std::string> aravis_cameras;
  std::vector<std::string> video_devices;
  std::vector<std::string> gphoto2_cameras;  // USB cameras libgphoto2 detects.
  std::vector<std::string> serial_ports;     // /dev/ttyACM*, /dev/ttyUSB*: LED boards.
};
DeviceList list_devices(bool list_aravis);

}  // namespace ls
