#pragma once
// A sample of a field's object pixels, for what is estimated from a few thousand pixels of the
// data (its noise, the noise a fit assumes): the same pixels whatever frame surrounds the object,
// so that a set cropped to its object and the whole photographs give the same estimate.
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"

namespace ls::capture {

// Object pixels: those whose brightest sample (luminance, over the lights) is above
// kObjectFraction of the brightest in the fields. The sample takes rows spread evenly between
// the first and last rows that hold object pixels, adding rows until it holds `wanted` object
// pixels (or every such row), and packs their object pixels, row by row, into a field of
// kSampleWidth columns (the last row's remainder zero: no signal). Every field of `fields` (the
// steps of a time series: one size, one set of lights) gives the same pixels, one after the
// other. Reads each field once, in bands within `band_bytes`. Empty (height 0) when no pixel
// has signal.
inline constexpr double kObjectFraction = 0.02;
inline constexpr int kSampleWidth = 1024;
ReflectanceField object_sample(const std::vector<FieldStream*>& fields, long wanted,
                               std::size_t band_bytes);

}  // namespace ls::capture
