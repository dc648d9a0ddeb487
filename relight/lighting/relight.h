#pragma once
// Relighting a reflectance field: I(x) = sum_l R(x, l) * E_l, per channel.
#include <span>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/image.h"
#include "relight/lighting/light_cells.h"

namespace ls::relight {

// Streams the field once (row tiles in parallel, no allocation in the loop). Output: 3-channel
// linear radiance image. Throws InputError unless E has 3 * field.num_lights() entries (weights
// computed for another stage).
Image relight(const capture::ReflectanceField& field, const LightWeights& weights);

// Same, into a caller-owned image (reused across frames, e.g. a rotation sequence).
void relight_into(const capture::ReflectanceField& field, std::span<const float> irradiance_rgb,
                  Image& out);

// Rows of a field as its file holds them (capture::FieldStream::read_rows_planar) relit into
// the same rows of `out` (the whole frame, 3 channels, sized by the caller): the same sums in the
// same order as relight_into, so the same bytes.
void relight_rows_into(const capture::PlanarRows& rows, std::span<const float> irradiance_rgb,
                       Image& out);

}  // namespace ls::relight
