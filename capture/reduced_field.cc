#include "capture/reduced_field.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <numeric>
#include <vector>

#include "capture/field_file.h"
#include "lightstage/errors.h"

namespace ls::capture {

int reduction_factor(int width, int height, int num_lights, std::size_t bytes) {
  int factor = 1;
  while (factor < std::max(width, height) &&
         ReflectanceField::bytes_for((width + factor - 1) / factor, (height + factor - 1) / factor,
                                     num_lights) > bytes) {
    factor *= 2;
  }
  return factor;
}

ReflectanceField reduced_header(const ReflectanceField& header, int factor) {
  LS_CHECK(factor >= 1, "reduced field: factor " + std::to_string(factor));
  ReflectanceField out =
      ReflectanceField::without_values((header.width() + factor - 1) / factor,
                                       (header.height() + factor - 1) / factor, header.lights());
  copy_attributes(header, out);
  out.noise.read_variance /= double(factor) * factor;
  out.noise.shot_variance_per_unit /= double(factor) * factor;
  return out;
}

FieldBands reduced_bands(FieldStream& stream, int factor, std::size_t band_bytes,
                         ProgressFn progress, BandVisitor also) {
  return [&stream, factor, band_bytes, progress = std::move(progress),
          also = std::move(also)](const BandVisitor& visit) {
    const ReflectanceField frame = reduced_header(stream.header(), factor);
    const int width = stream.width(), height = stream.height();
    const std::size_t values = std::size_t(frame.num_lights()) * 3;
    // Whole blocks of rows a band, and whole tile rows where the file is tiled.
    const int alignment = std::lcm(factor, stream.row_alignment());
    const int rows = std::max(alignment, stream.rows_within(band_bytes) / alignment * alignment);
    ReflectanceField reduced;
    stream.bands(rows)([&](const ReflectanceField& band) {
      const int y0 = band.first_row();
      const int block_rows = (band.height() + factor - 1) / factor;
      shape_band(frame, y0 / factor, y0 / factor + block_rows, reduced);
      tbb::parallel_for(tbb::blocked_range<int>(0, block_rows), [&](const auto& range) {
        std::vector<double> sum(values);
        for (int by = range.begin(); by < range.end(); ++by) {
          const int ya = by * factor, yb = std::min(band.height(), ya + factor);
          for (int bx = 0; bx < frame.width(); ++bx) {
            const int xa = bx * factor, xb = std::min(width, xa + factor);
            std::fill(sum.begin(), sum.end(), 0.0);
            for (int y = ya; y < yb; ++y) {
              for (int x = xa; x < xb; ++x) {
                const float* v = band.pixel(x, y);
                for (std::size_t i = 0; i < values; ++i) sum[i] += v[i];
              }
            }
            const double n = double(yb - ya) * (xb - xa);
            float* o = reduced.pixel(bx, by);
            for (std::size_t i = 0; i < values; ++i) o[i] = float(sum[i] / n);
          }
        }
      });
      if (also) also(band);
      visit(reduced);
      report(progress, "read reduced (rows)", y0 + band.height(), height);
    });
  };
}

ReflectanceField read_reduced_field(FieldStream& stream, int factor, std::size_t band_bytes,
                                    const ProgressFn& progress) {
  const ReflectanceField header = reduced_header(stream.header(), factor);
  ReflectanceField out(header.width(), header.height(), header.lights());
  copy_attributes(header, out);
  reduced_bands(stream, factor, band_bytes, progress)([&](const ReflectanceField& band) {
    std::copy(band.values().begin(), band.values().end(), out.pixel(0, band.first_row()));
  });
  return out;
}

}  // namespace ls::capture
