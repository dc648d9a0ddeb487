#include "sim/sim_backend.h"

#include "lightstage/errors.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"

namespace ls::sim {

void register_backend(BackendRegistry& registry) {
  Backend backend;
  backend.name = "sim";
  backend.description = "the physically based simulated stage (a scene file, or the demo scene)";
  backend.input_file_name = "scene.json";
  backend.open = [](const BackendRequest& request) {
    const Scene scene =
        request.input_file.empty() ? default_scene() : load_scene(request.input_file);
    auto stage = std::make_shared<SimStage>(request.stage, scene, request.seed);
    for (const int id : request.stage.camera.simulated.dead_led_ids) {
      const int led = request.stage.led_index(id);
      if (led < 0) {
        throw InputError(request.stage.source + ": camera.simulated_sensor.dead_leds: LED id " +
                         std::to_string(id) + " is not in \"leds\"");
      }
      stage->set_dead_led(led, true);
    }
    OpenedBackend opened;
    // Aliasing pointers: the LEDs and the camera live as long as the stage that owns them.
    opened.lights = std::shared_ptr<LightController>(stage, &stage->lights());
    opened.camera = std::shared_ptr<Camera>(stage, &stage->camera());
    opened.simulated_time = !request.stage.camera.simulated.real_time;
    wire_trigger(request.stage.camera, *opened.lights, *opened.camera);
    return opened;
  };
  registry.add(std::move(backend));
}

}  // namespace ls::sim
