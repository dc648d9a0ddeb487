#pragma once
// The simulated stage posing as a DSLR dome, the capture back-end "sim-dslr": its LEDs on a serial
// board (the lsled1 emulator behind a pseudo-terminal, driven through SerialLights), its camera a
// SimulatedDslr behind the gphoto2 back-end's TetheredCamera, every frame a DNG decoded by LibRaw.
// The whole DSLR path, judged against the simulator's ground truth. The sensor is 14-bit with the
// stage's simulated black level; camera.gphoto2.raw.decode "bin2x2" makes it twice the camera's
// width and height, each pixel's sample filling its 2x2 block (bayer_mosaic).
#include <cstdint>
#include <memory>
#include <vector>

#include "lightstage/backend_registry.h"
#include "lightstage/hardware/serial_lights.h"
#include "lightstage/hardware/tethered_camera.h"
#include "sim/dslr_tether.h"
#include "sim/led_board_emulator.h"
#include "sim/sim_stage.h"

namespace ls::sim {

// Members in the order they are built; destroyed in reverse (the lights' last OFF reaches a board
// that is still there).
struct SimulatedDslrDome {
  std::unique_ptr<SimStage> sensor_stage;
  std::vector<double> board_levels;  // By LED index, as the board last set them.
  std::unique_ptr<LedBoardEmulator> board;
  SimulatedDslr* dslr = nullptr;  // Owned by camera.
  std::unique_ptr<TetheredCamera> camera;
  std::unique_ptr<SerialLights> lights;
};

constexpr int kSimulatedDslrRawBits = 14;

std::shared_ptr<SimulatedDslrDome> open_simulated_dslr_dome(const Stage& stage, const Scene& scene,
                                                            uint64_t seed);

void register_dslr_backend(BackendRegistry& registry);

}  // namespace ls::sim
