#include "capture/reduced_field.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <numeric>
#include <string>
#include <vector>

#include "capture/field_file.h"
#include "capture/half_storage.h"
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

namespace {

// Adds a piece of the file's rows (as it holds them) to `sums`, [block row][value][block column]
// of the band of rows that starts at y0: each value summed down its block's rows a column at a
// time, then across (whole rows at once: a block at a time is a strided add per value, most of
// the reduced read), channels in parallel.
void add_block_sums(const PlanarRows& piece, int factor, int y0, int reduced_width,
                    std::size_t values, std::vector<double>& sums) {
  const int count = int(piece.to_pixel_index.size());
  const std::size_t width = std::size_t(piece.width);
  tbb::parallel_for(0, count, [&](int c) {
    thread_local std::vector<float> converted;  // A plane of halves as floats.
    thread_local std::vector<double> columns;   // The plane's sums down a block's rows.
    const std::size_t value = std::size_t(piece.to_pixel_index[std::size_t(c)]);
    columns.assign(width, 0.0);
    for (int r = 0; r < piece.rows; ++r) {
      const float* plane = nullptr;
      if (piece.halves != nullptr) {
        converted.resize(width);
        if (!halves_to_floats(piece.halves + std::size_t(r) * piece.half_row_bytes + c * width * 2,
                              width, piece.half_scale, converted.data())) {
          throw InputError(std::string(piece.source) +
                           ": the reflectance field holds non-finite values");
        }
        plane = converted.data();
      } else {
        plane = piece.values + (std::size_t(r) * count + std::size_t(c)) * width;
      }
      for (std::size_t x = 0; x < width; ++x) columns[x] += double(plane[x]);
      const int y = piece.first_row + r;
      if ((y - y0 + 1) % factor != 0 && r + 1 < piece.rows) continue;
      // The block row's last row, or the piece's: its columns into the blocks.
      double* block_row =
          sums.data() + (std::size_t((y - y0) / factor) * values + value) * reduced_width;
      for (std::size_t bx = 0; bx < std::size_t(reduced_width); ++bx) {
        const std::size_t xa = bx * factor, xb = std::min(width, xa + factor);
        double sum = 0;
        for (std::size_t x = xa; x < xb; ++x) sum += columns[x];
        block_row[bx] += sum;
      }
      std::fill(columns.begin(), columns.end(), 0.0);
    }
  });
}

}  // namespace

// The file's rows as it holds them (read_rows_planar), summed plane by plane: a pixel-major band
// would transpose every value first, a third of the time of a sun's sources on a 12-megapixel set.
FieldBands reduced_bands(FieldStream& stream, int factor, std::size_t band_bytes,
                         ProgressFn progress, PlanarVisitor also) {
  return [&stream, factor, band_bytes, progress = std::move(progress),
          also = std::move(also)](const BandVisitor& visit) {
    const ReflectanceField frame = reduced_header(stream.header(), factor);
    const int width = stream.width(), height = stream.height();
    const std::size_t values = std::size_t(frame.num_lights()) * 3;
    // Whole blocks of rows a band, and whole tile rows where the file is tiled; within band_bytes
    // of sums, which are doubles (at factor 1 twice a band of the file's floats).
    const int alignment = std::lcm(factor, stream.row_alignment());
    const int within = stream.rows_within(factor == 1 ? band_bytes / 2 : band_bytes);
    const int rows = std::max(alignment, within / alignment * alignment);
    ReflectanceField reduced;
    std::vector<double> sums;
    for (int y0 = 0; y0 < height; y0 += rows) {
      const int y1 = std::min(height, y0 + rows);
      const int block_rows = (y1 - y0 + factor - 1) / factor;
      sums.assign(std::size_t(block_rows) * std::size_t(frame.width()) * values, 0.0);
      stream.read_rows_planar(y0, y1, [&](const PlanarRows& piece) {
        if (also) also(piece);
        add_block_sums(piece, factor, y0, frame.width(), values, sums);
      });
      shape_band(frame, y0 / factor, y0 / factor + block_rows, reduced);
      tbb::parallel_for(0, block_rows, [&](int by) {
        const int block_height = std::min(y1, y0 + (by + 1) * factor) - (y0 + by * factor);
        for (int bx = 0; bx < frame.width(); ++bx) {
          const double n =
              double(block_height) * (std::min(width, (bx + 1) * factor) - bx * factor);
          const double* sum = sums.data() + std::size_t(by) * values * frame.width() + bx;
          float* o = reduced.pixel(bx, by);
          for (std::size_t i = 0; i < values; ++i) o[i] = float(sum[i * frame.width()] / n);
        }
      });
      visit(reduced);
      report(progress, "read reduced (rows)", y1, height);
    }
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
