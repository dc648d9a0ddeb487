#pragma once
// Fills ls::backend_registry() with every capture back-end this build has: the simulated stage
// ("sim") and real hardware ("aravis", "v4l2"). Idempotent.
namespace ls::cli {

void register_backends();

}  // namespace ls::cli
