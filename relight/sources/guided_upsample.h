#pragma once
// An image made on a field reduced by `factor` (capture/reduced_field.h: each pixel the mean of a
// factor x factor block) brought back to the field's size with the field's own detail, from a
// guide known at both sizes (the same linear function of the field: relit under some weights):
//   out(x) += up(low)(x) * (guide(x) + e) / (up(guide_low)(x) + e)
// per channel; up() interpolates bilinearly between the blocks' centres; e is 3% of the guide's
// mean (a dark pixel's noise is not carried: it takes about the interpolated value; 0.1% made the
// shadows of a 64^2 reduction speckle), and the ratio is at most factor^2 (no pixel of a block is
// brighter than that many times its mean). Where `low` is the guide times
// something smooth (a sun lighting the scene as the LEDs around it do, its shadows and highlights
// where the LEDs' are not), the result is that times the full-size guide: the texture and the
// normals' detail come from the guide, the sun's shadows and highlights from `low`, sharp to a
// block.
#include "lightstage/image.h"

namespace ls::relight {

// low and guide_low: the reduced size, guide and out the full size; 3 channels each.
void add_guided_upsample(const Image& low, const Image& guide_low, const Image& guide, int factor,
                         Image& out);

}  // namespace ls::relight
