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
// noisier than stated).
ReflectanceField read_reduced_field(FieldStream& stream, int factor, std::size_t band_bytes,
                                    const ProgressFn& progress = {});

// The same in bands, none held after its visit (what the reduced field's sources read): each a
// band of the reduced field (first_row() and frame_height() in its rows) made from a band of the
// file's rows of at most band_bytes; `also`, when given, sees the file's own rows first, as
// read_rows_planar gives them (what else a caller makes at the full size in the same pass).
// `stream` must outlive the bands; the header of what they visit is reduced_header's.
FieldBands reduced_bands(FieldStream& stream, int factor, std::size_t band_bytes,
                         ProgressFn progress = {}, PlanarVisitor also = {});
// The header (no values) of the file's field reduced by `factor`: its size, lights, attributes and
// the noise of the mean.
ReflectanceField reduced_header(const ReflectanceField& header, int factor);

}  // namespace ls::capture
