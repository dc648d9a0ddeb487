#include "lightstage/hardware/backends.h"

#include <algorithm>
#include <filesystem>

#include "lightstage/errors.h"
#include "lightstage/hardware/aravis_camera.h"
#include "lightstage/hardware/gpiod_lights.h"
#include "lightstage/hardware/serial_lights.h"
#include "lightstage/hardware/tethered_camera.h"
#include "lightstage/hardware/v4l2_camera.h"

namespace ls {

bool is_hardware_backend(const std::string& backend) {
  return backend == "aravis" || backend == "v4l2" || backend == "gphoto2";
}

std::unique_ptr<LightController> open_lights(const Stage& stage) {
  if (stage.led_driver.serial()) return std::make_unique<SerialLights>(stage);
  return std::make_unique<GpioLights>(stage, make_gpiod_line_driver("lightstage"));
}

namespace {

InputError unknown_backend(const CameraSpec& spec, const std::string& stage_source) {
  return InputError(stage_source + ": camera.backend: expected \"aravis\", \"v4l2\" or " +
                    "\"gphoto2\" for real " + "hardware (\"sim\" is the simulated stage), got \"" +
                    spec.backend + "\"");
}

}  // namespace

std::unique_ptr<Camera> open_camera(const CameraSpec& spec, const std::string& stage_source) {
  try {
    if (spec.backend == "aravis") return std::make_unique<AravisCamera>(spec);
    if (spec.backend == "v4l2") return std::make_unique<V4l2Camera>(spec);
    if (spec.backend == "gphoto2") {
      return std::make_unique<TetheredCamera>(
          spec, open_gphoto2_tether(spec.device_id, stage_source), stage_source);
    }
  } catch (const InputError& e) {
    throw InputError(stage_source + ": " + e.what());
  }
  throw unknown_backend(spec, stage_source);
}

Hardware open_hardware(const Stage& stage) {
  if (!is_hardware_backend(stage.camera.backend)) throw unknown_backend(stage.camera, stage.source);
  const CameraSync& sync = stage.camera.sync;
  if (stage.camera.backend != "aravis" &&
      (sync.line_triggered() || !sync.exposure_active_output.empty())) {
    throw InputError(stage.source + ": camera.sync: a trigger line or an exposure-active output " +
                     "needs a GenICam camera (camera.backend \"aravis\"), got camera.backend \"" +
                     stage.camera.backend + "\"");
  }
  Hardware hw;
  hw.lights = open_lights(stage);
  hw.camera = open_camera(stage.camera, stage.source);
  wire_trigger(stage.camera, *hw.lights, *hw.camera);
  return hw;
}

void register_hardware_backends(BackendRegistry& registry) {
  for (const char* name : {"aravis", "v4l2", "gphoto2"}) {
    Backend backend;
    backend.name = name;
    backend.description =
        std::string(name) + " camera, LEDs on GPIO lines (libgpiod) or a serial board (led_driver)";
    backend.open = [](const BackendRequest& request) {
      Hardware hw = open_hardware(request.stage);
      return OpenedBackend{std::move(hw.lights), std::move(hw.camera), /*simulated_time=*/false};
    };
    registry.add(std::move(backend));
  }
}

DeviceList list_devices(bool list_aravis) {
  DeviceList out;
  out.gpio_chips = list_gpio_chips();
  if (list_aravis) {
    for (const auto& d : discover_aravis_cameras()) {
      out.aravis_cameras.push_back(d.id + "  (" + d.vendor + " " + d.model + ", serial " +
                                   d.serial + ", " + d.protocol +
                                   (d.address.empty() ? "" : " " + d.address) + ")");
    }
  }
  out.gphoto2_cameras = list_gphoto2_cameras();
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("video", 0) == 0) out.video_devices.push_back(entry.path().string());
    if (name.rfind("ttyACM", 0) == 0 || name.rfind("ttyUSB", 0) == 0) {
      out.serial_ports.push_back(entry.path().string());
    }
  }
  std::sort(out.video_devices.begin(), out.video_devices.end());
  std::sort(out.serial_ports.begin(), out.serial_ports.end());
  return out;
}

}  // namespace ls
