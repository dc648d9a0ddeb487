#pragma once
// Checks of frames as they arrive: what a frame should look like, judged before it is
// saved, so that the sequencer can shoot it again. Pure functions of the frames; the sequencer
// acts.
#include <functional>
#include <string>
#include <vector>

#include "lightstage/image.h"

namespace ls {

// The camera's response inverted: a digital number of channel c -> normalised linear exposure
// (capture/response.h). Empty: the camera is taken as linear (DN / full scale).
using DnToLinear = std::function<double(int dn, int channel)>;

// Light in a dark frame (an LED stuck on, light through a gap): over a 16 x 16 grid of regions
// (a strided sample of at most ~64k pixels), the brightest region's mean exceeds the median
// region's by more than max_fraction of full scale. Hot pixels, isolated, hardly move a region's
// mean; light spread evenly over the whole view is not told from a higher black level. "" when
// the frame is dark.
std::string dark_frame_problem(const RawFrame& frame, double max_fraction);

// One frame of an LED's bracket, with the time step's mean dark frame at its exposure (DN).
struct BracketFrame {
  const RawFrame* raw = nullptr;
  double exposure_s = 0.0;  // As the camera reported it.
  double gain = 1.0;
  const std::vector<float>* dark = nullptr;
  int exposure_index = 0;  // In the stage's bracket, for messages.
};

// The frames of one LED's bracket must agree once each is made linear, dark-subtracted and divided
// by its exposure times gain: the same light, longer. Each pair is compared over a 16 x 16 grid of
// regions (unsaturated values of a strided sample); a region disagrees when the mean difference is
// beyond 5 standard errors (its noise), 10% of the signal and 2 DN of the shorter exposure. A pair
// disagrees when at least 2% of the regions that hold signal (and at least two) do. A frame is bad
// when it disagrees with every other frame of the bracket (with two frames, both are). What this
// catches: a torn or partial frame, a stale frame (the previous trigger's), a frame from another
// LED, a wrong exposure. Returns one entry per frame, "" for a good one; all "" when the bracket
// cannot be judged (fewer than two frames, no dark reference, frames of different sizes).
std::vector<std::string> bracket_problems(const std::vector<BracketFrame>& frames,
                                          const DnToLinear& to_linear);

}  // namespace ls
