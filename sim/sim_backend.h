#pragma once
// The simulated stage as the capture back-end "sim": a session's scene is its input file
// (scene.json in the session; the built-in demo scene when there is none).
#include "lightstage/backend_registry.h"

namespace ls::sim {

void register_backend(BackendRegistry& registry);

}  // namespace ls::sim
