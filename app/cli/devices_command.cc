// lightstage devices: what hardware is present. lightstage check: can a stage's hardware be opened.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>

#include "app/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/hardware/backends.h"

namespace ls::cli {

namespace {

void print_list(const char* title, const std::vector<std::string>& items, const char* none) {
  std::printf("%s:\n", title);
  if (items.empty()) std::printf("  (%s)\n", none);
  for (const auto& s : items) std::printf("  %s\n", s.c_str());
}

struct CheckRequest {
  std::filesystem::path stage_file;
  bool blink = false;
  double blink_s = 0.3;
  bool frame = true;
};

int check_stage(const CheckRequest& request) {
  const Stage stage = load_stage(request.stage_file);
  if (!is_hardware_backend(stage.camera.backend)) {
    std::printf("%s: camera.backend \"%s\" is simulated: no hardware to check\n",
                stage.source.c_str(), stage.camera.backend.c_str());
    return 0;
  }
  // Opening requests every LED line (all off) and opens the camera; any failure throws a
  // HardwareError that names the device (exit 3).
  Hardware hw = open_hardware(stage);
  if (stage.led_driver.serial()) {
    std::printf("LEDs: %d on the board on %s, switched off\n", hw.lights->num_lights(),
                stage.led_driver.port.c_str());
  } else {
    std::printf("LEDs: %d lines requested and switched off\n", hw.lights->num_lights());
  }
  const CameraInfo info = hw.camera->info();
  std::printf("camera: %s (%s) %dx%d, %d channel(s), %d bit\n", info.id.c_str(), info.model.c_str(),
              info.width, info.height, info.channels, info.bit_depth);
  if (request.frame && !stage.camera.bracket.empty()) {
    FrameRequest r;
    r.exposure_s = stage.camera.bracket.front().exposure_s;
    r.gain = stage.camera.bracket.front().gain;
    const CapturedFrame f = hw.camera->capture(r);
    std::printf("camera: test frame %dx%d, exposure %.6g s (asked %.6g s), gain %.4g\n",
                f.raw.width, f.raw.height, f.exposure_s, r.exposure_s, f.gain);
  }
  if (request.blink) {
    for (int i = 0; i < hw.lights->num_lights(); ++i) {
      std::printf("blink LED %d\n", stage.leds[i].id);
      std::fflush(stdout);
      hw.lights->set_light(i, true);
      std::this_thread::sleep_for(std::chrono::duration<double>(request.blink_s));
      hw.lights->set_light(i, false);
      std::this_thread::sleep_for(std::chrono::duration<double>(request.blink_s / 2));
    }
  }
  hw.lights->all_off();
  std::printf("%s: hardware OK\n", stage.source.c_str());
  return 0;
}

}  // namespace

void add_devices_command(CLI::App& app) {
  auto no_cameras = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(
      "devices",
      "List the hardware present: GPIO chips (libgpiod), GenICam cameras (Aravis discovery, "
      "which broadcasts on every network interface), V4L2 video devices, DSLRs on USB "
      "(libgphoto2) and serial ports for LED boards.");
  cmd->add_flag("--no-cameras", *no_cameras,
                "Skip Aravis camera discovery (sends nothing on the network).");
  add_quiet_flag(*cmd);
  cmd->callback([no_cameras] {
    const DeviceList list = list_devices(/*list_aravis=*/!*no_cameras);
    print_list("GPIO chips", list.gpio_chips, "none: no /dev/gpiochip*");
    if (*no_cameras) {
      std::printf("Aravis cameras:\n  (not searched: --no-cameras)\n");
    } else {
      print_list("Aravis cameras", list.aravis_cameras, "none found");
    }
    print_list("V4L2 devices", list.video_devices, "none: no /dev/video*");
    print_list("gphoto2 cameras (USB)", list.gphoto2_cameras, "none detected");
    print_list("Serial ports (LED boards)", list.serial_ports,
               "none: no /dev/ttyACM*, /dev/ttyUSB*");
  });
}

void add_check_command(CLI::App& app) {
  auto request = std::make_shared<CheckRequest>();
  auto* cmd = app.add_subcommand(
      "check",
      "Check that a stage's hardware can be opened: every LED's GPIO line (requested and "
      "switched off) or its serial board, and the camera (opened, one test frame; a DSLR "
      "takes one shot). --blink lights each LED once.");
  cmd->add_option("stage", request->stage_file, "Stage file (JSON).")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_flag("--blink", request->blink, "Switch each LED on once, in stage-file order.");
  cmd->add_option("--blink-seconds", request->blink_s, "How long each LED stays on.")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  cmd->add_flag("!--no-frame", request->frame, "Do not capture a test frame.");
  add_quiet_flag(*cmd);
  cmd->callback([request] {
    const int code = check_stage(*request);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace ls::cli
