#pragma once
// Capture back-ends by name: a stage file's camera.backend ("sim", "aravis", "v4l2", ...) picks
// one. Each back-end registers itself (sim/sim_backend.h, lightstage/hardware/backends.h) and the
// app calls one function that registers them all, so nothing that captures includes a back-end.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lightstage/hardware.h"
#include "lightstage/stage.h"

namespace ls {

// What a back-end needs to open its devices for one session.
struct BackendRequest {
  const Stage& stage;
  std::filesystem::path input_file;  // The back-end's own input (a scene); empty: its default.
  uint64_t seed = 1;                 // Noise seed (simulated back-ends).
};

// The opened devices. They may share one owner (the simulated stage owns both), hence shared_ptr.
struct OpenedBackend {
  std::shared_ptr<LightController> lights;
  std::shared_ptr<Camera> camera;
  // True for a simulated clock: no settling sleeps, time steps rendered at their plan time rather
  // than waited for (a simulated stage that runs in real time says false).
  bool simulated_time = false;
};

struct Backend {
  std::string name;
  std::string description;  // One line, for messages and --help.
  // The file of the back-end's own input (the simulated stage's scene), kept in the session under
  // this name so that the session resumes anywhere. Empty: the back-end takes no input file.
  std::string input_file_name;
  // Opens the devices, LEDs off. Device problems are HardwareErrors naming the device; a bad
  // input file is an InputError naming it.
  std::function<OpenedBackend(const BackendRequest&)> open;
};

class BackendRegistry {
 public:
  // A second back-end of the same name replaces the first (registration is idempotent).
  void add(Backend backend);
  // Throws InputError naming `stage_source`'s camera.backend and the registered names.
  const Backend& find(const std::string& name, const std::string& stage_source) const;
  bool contains(const std::string& name) const;
  std::vector<std::string> names() const;

 private:
  std::vector<Backend> backends_;
};

// The process's registry, filled by the app at start-up (app/cli/register_backends.h).
BackendRegistry& backend_registry();

class Session;
// The devices of an existing session, as a resumed capture and `play` open them: its back-end,
// its stage, its seed and its own copy of the back-end's input file (the simulated stage's scene).
OpenedBackend open_session_backend(const Session& session);

}  // namespace ls
