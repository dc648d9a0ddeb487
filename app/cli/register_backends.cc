#include "app/cli/register_backends.h"

#include "lightstage/backend_registry.h"
#include "lightstage/hardware/backends.h"
#include "sim/dslr_backend.h"
#include "sim/sim_backend.h"

namespace ls::cli {

void register_backends() {
  sim::register_backend(backend_registry());
  register_hardware_backends(backend_registry());
  sim::register_dslr_backend(backend_registry());
}

}  // namespace ls::cli
