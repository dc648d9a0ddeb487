#pragma once
// Sequencer options for tests against the simulated stage: no waiting between frames.

#include "lightstage/controller/sequencer.h"

namespace ls::testing {

inline SequencerOptions instant_sequencer() {
  SequencerOptions options;
  options.sleep = [](double) {};
  return options;
}

}  // namespace ls::testing
