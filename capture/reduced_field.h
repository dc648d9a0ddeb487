#pragma once
// A field larger than memory seen whole at a reduced resolution (the viewer): each pixel
// the mean of a factor x factor block of the file's pixels (blocks at the right and bottom edges
// hold what is left). Radiance sums linearly, so a relit reduced field is the mean of the full
// field's relit blocks; what depends on where a pixel is (the view, near-LED geometry) uses
// normalised image coordinates and carries over. For viewing: the fits and the CLI's relighting
// read the full field.
#include <cstddef>
#include <functional>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/progress.h"

namespace ls::capture {

// The smallest power-of-two factor (1 when it fits) whose reduced field takes at most `bytes`.
int reduction_factor(int width, int height, int num_lights, std::size_t bytes);

// The file's field reduced by `factor`, read band by band (bands of at most band_bytes, whole
// blocks of rows); progress "read reduced (rows)" after each band. Its noise is the mean's of
// factor^2 pixels: both variances divided by factor^2 (edge blocks, with fewer pixels, are a little
// noisier than stated). `also`, when given, sees each band of the file's pixels after it is reduced
// (what else a caller makes at the full size in the same pass).
ReflectanceField read_reduced_field(FieldStream& stream, int factor, std::size_t band_bytes,
                                    const ProgressFn& progress = {}, const BandVisitor& also = {});

}  // namespace ls::capture
