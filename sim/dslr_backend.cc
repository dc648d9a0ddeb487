#include "sim/dslr_backend.h"

#include <cmath>

#include "lightstage/errors.h"

namespace ls::sim {

namespace {

// The stage the simulator renders: 14-bit RGB at the camera's size (binned 2x2, each pixel's
// sample fills its block of sites), its radiometric scale such that a decoded value (black
// removed, white = 1) means the same radiance as the stage's camera says.
Stage sensor_stage_of(const Stage& stage) {
  Stage sensor = stage;
  CameraSpec& c = sensor.camera;
  c.backend = "sim";
  c.bit_depth = kSimulatedDslrRawBits;
  c.channels = 3;
  c.radiometric_scale = stage.camera.radiometric_scale / (1.0 - c.simulated.black_level);
  return sensor;
}

}  // namespace

std::shared_ptr<SimulatedDslrDome> open_simulated_dslr_dome(const Stage& stage, const Scene& scene,
                                                            uint64_t seed) {
  if (stage.camera.channels != 3) {
    throw InputError(stage.source + ": camera.channels: a DSLR's raw files decode to 3 channels");
  }
  auto dome = std::make_shared<SimulatedDslrDome>();
  dome->sensor_stage = std::make_unique<SimStage>(sensor_stage_of(stage), scene, seed);
  SimStage& sim = *dome->sensor_stage;
  for (const int id : stage.camera.simulated.dead_led_ids) {
    if (stage.led_index(id) >= 0) sim.set_dead_led(stage.led_index(id), true);
  }

  // The board: channel -> LED as the stage wires them.
  std::vector<int> led_of_channel;
  for (size_t i = 0; i < stage.leds.size(); ++i) {
    const int channel = stage.leds[i].board_channel >= 0 ? stage.leds[i].board_channel : int(i);
    if (channel >= int(led_of_channel.size())) led_of_channel.resize(size_t(channel) + 1, -1);
    led_of_channel[size_t(channel)] = int(i);
  }
  dome->board_levels.assign(stage.leds.size(), 0.0);
  SimulatedDslrDome* d = dome.get();
  dome->board = std::make_unique<LedBoardEmulator>(
      int(led_of_channel.size()),
      [d, led_of_channel](int channel, double level) {
        const int led = led_of_channel[size_t(channel)];
        if (led < 0) return;
        d->board_levels[size_t(led)] = level;
        LightController& lights = d->sensor_stage->lights();
        if (level == 0.0 || level == 1.0) {
          lights.set_light(led, level > 0);
        } else {
          lights.set_levels(d->board_levels);
        }
      },
      [d] {
        std::fill(d->board_levels.begin(), d->board_levels.end(), 0.0);
        d->sensor_stage->lights().all_off();
      });

  const unsigned black_dn = unsigned(
      std::lround(stage.camera.simulated.black_level * ((1u << kSimulatedDslrRawBits) - 1u)));
  const int pixel_sites = stage.camera.tether.raw.mode == RawDecodeOptions::Mode::kBin2x2 ? 2 : 1;
  auto dslr = std::make_unique<SimulatedDslr>(sim.camera(), kSimulatedDslrRawBits, black_dn,
                                              pixel_sites, stage.camera.simulated.real_time);
  dome->dslr = dslr.get();
  dome->camera = std::make_unique<TetheredCamera>(stage.camera, std::move(dslr), stage.source);
  Stage wired = stage;
  wired.led_driver.backend = "serial";
  wired.led_driver.port = dome->board->port();
  wired.led_driver.startup_s = 1.0;
  dome->lights = std::make_unique<SerialLights>(wired);
  return dome;
}

void register_dslr_backend(BackendRegistry& registry) {
  Backend backend;
  backend.name = "sim-dslr";
  backend.description =
      "the simulated stage as a DSLR dome: raw files through LibRaw, LEDs on a serial board";
  backend.input_file_name = "scene.json";
  backend.open = [](const BackendRequest& request) {
    const Scene scene =
        request.input_file.empty() ? default_scene() : load_scene(request.input_file);
    const std::shared_ptr<SimulatedDslrDome> dome =
        open_simulated_dslr_dome(request.stage, scene, request.seed);
    OpenedBackend opened;
    opened.lights = std::shared_ptr<LightController>(dome, dome->lights.get());
    opened.camera = std::shared_ptr<Camera>(dome, dome->camera.get());
    opened.simulated_time = !request.stage.camera.simulated.real_time;
    return opened;
  };
  registry.add(std::move(backend));
}

}  // namespace ls::sim
