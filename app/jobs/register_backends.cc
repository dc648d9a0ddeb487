#include "app/jobs/register_backends.h"

#include "lightstage/backend_registry.h"
#include "lightstage/hardware/backends.h"
#include "sim/sim_backend.h"

namespace ls::jobs {

void register_backends() {
  sim::register_backend(backend_registry());
  register_hardware_backends(backend_registry());
}

}  // namespace ls::jobs
