#include "capture/object_sample.h"

#include <algorithm>
#include <cmath>

#include "lightstage/image.h"

namespace ls::capture {

namespace {

// Per pixel of `field`, its brightest finite luminance over the lights.
std::vector<float> brightest_per_pixel(FieldStream& field, std::size_t band_bytes) {
  const int width = field.width(), height = field.height(), lights = field.header().num_lights();
  std::vector<float> brightest(std::size_t(width) * std::size_t(height), 0.0f);
  const int rows = std::max(1, field.rows_within(band_bytes));
  std::vector<float> band;
  for (int y0 = 0; y0 < height; y0 += rows) {
    const int y1 = std::min(height, y0 + rows);
    band.resize(std::size_t(y1 - y0) * std::size_t(width) * std::size_t(lights) * 3);
    field.read_rows_into(y0, y1, band.data());
    for (std::size_t p = 0; p < std::size_t(y1 - y0) * std::size_t(width); ++p) {
      float best = 0;
      for (int l = 0; l < lights; ++l) {
        const float value = luminance(&band[(p * std::size_t(lights) + std::size_t(l)) * 3]);
        if (std::isfinite(value)) best = std::max(best, value);
      }
      brightest[std::size_t(y0) * std::size_t(width) + p] = best;
    }
  }
  return brightest;
}

}  // namespace

ReflectanceField object_sample(const std::vector<FieldStream*>& fields, long wanted,
                               std::size_t band_bytes) {
  const FieldStream& first = *fields.front();
  const int width = first.width(), height = first.height();
  // Object pixels: by the brightest pixel of all steps; a pixel is the object's in any step.
  std::vector<float> brightest(std::size_t(width) * std::size_t(height), 0.0f);
  for (FieldStream* field : fields) {
    const std::vector<float> step = brightest_per_pixel(*field, band_bytes);
    for (std::size_t p = 0; p < step.size(); ++p) brightest[p] = std::max(brightest[p], step[p]);
  }
  const float peak = *std::max_element(brightest.begin(), brightest.end());
  const float threshold = float(kObjectFraction) * peak;
  std::vector<int> per_row(std::size_t(height), 0);
  int top = -1, bottom = -1;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x)
      per_row[size_t(y)] += brightest[size_t(y) * width + x] > threshold;
    if (per_row[size_t(y)] > 0) {
      if (top < 0) top = y;
      bottom = y;
    }
  }
  if (!(peak > 0) || top < 0) return {};
  // k rows spread evenly over [top, bottom], k the fewest that hold `wanted` object pixels.
  const int span = bottom - top + 1;
  std::vector<int> rows;
  for (int k = std::min(4, span);; k = std::min(span, 2 * k)) {
    rows.clear();
    long pixels = 0;
    for (int j = 0; j < k; ++j) {
      rows.push_back(top + int((j + 0.5) * span / k));
      pixels += per_row[size_t(rows.back())];
    }
    if (pixels >= wanted || k == span) break;
  }
  long pixels = 0;
  for (const int y : rows) pixels += per_row[size_t(y)];
  const int steps = int(fields.size());
  const int sample_rows = int((pixels * steps + kSampleWidth - 1) / kSampleWidth);
  ReflectanceField sample(kSampleWidth, sample_rows, first.header().lights());  // Zeros.
  const std::size_t pixel_values = std::size_t(first.header().num_lights()) * 3;
  std::vector<float> row(std::size_t(width) * pixel_values);
  long packed = 0;
  for (FieldStream* field : fields) {
    for (const int y : rows) {
      field->read_rows_into(y, y + 1, row.data());
      for (int x = 0; x < width; ++x) {
        if (!(brightest[size_t(y) * width + x] > threshold)) continue;
        std::copy_n(&row[size_t(x) * pixel_values], pixel_values,
                    sample.pixel(int(packed % kSampleWidth), int(packed / kSampleWidth)));
        ++packed;
      }
    }
  }
  return sample;
}

}  // namespace ls::capture
