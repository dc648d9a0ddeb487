#include "relight/lighting/relight.h"

#include <immintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>
#include <vector>

#include "capture/half_storage.h"
#include "lightstage/errors.h"

namespace ls::relight {

namespace {

// Values per chunk: 8 lights x RGB. A fixed-size inner loop over independent accumulator lanes
// vectorises without reassociating sums (no -ffast-math needed), and 24 is a multiple of 3 so lane
// k always holds channel k % 3.
constexpr int kChunk = 24;

inline void shade_pixel(const float* __restrict values, const float* __restrict irradiance_rgb,
                        int count, float* __restrict out_rgb) {
  float acc[kChunk] = {};
  int i = 0;
  for (; i + kChunk <= count; i += kChunk) {
    for (int k = 0; k < kChunk; ++k) acc[k] += values[i + k] * irradiance_rgb[i + k];
  }
  // The tail is a whole number of lights (count is a multiple of 3).
  for (int k = 0; i + k < count; ++k) acc[k] += values[i + k] * irradiance_rgb[i + k];
  float r = 0, g = 0, b = 0;
  for (int k = 0; k < kChunk; k += 3) {
    r += acc[k];
    g += acc[k + 1];
    b += acc[k + 2];
  }
  out_rgb[0] = r;
  out_rgb[1] = g;
  out_rgb[2] = b;
}

// Bytes ahead of the sums that a row's halves are fetched from memory. The hardware prefetcher
// alone leaves a core's pass at ~11 GB/s where it can sum ~30 (bench_relight BM_RelightHalfRows):
// ~16 KiB covers memory latency at that rate. The file's planes lie in the order they are summed
// (give or take a light's three channels), so this runs on into the next planes and rows.
constexpr std::size_t kPrefetchBytes = std::size_t(16) << 10;

// lane[0..8) += (half x inv_scale) * w: halves_to_floats' product, then the float path's.
__attribute__((target("avx2,f16c"))) inline void add_eight_halves(const char* halves, __m256 s,
                                                                  __m256 weight, float* lane) {
  const __m256 v =
      _mm256_mul_ps(_mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(halves))), s);
  _mm256_storeu_ps(lane, _mm256_add_ps(_mm256_loadu_ps(lane), _mm256_mul_ps(v, weight)));
}

// lane[x] += (half x inv_scale) * w over a plane of halves (not aligned): the products and sums of
// the float path after halves_to_floats, in the same order, so the same bits.
__attribute__((target("avx2,f16c"))) void add_half_plane(const char* plane, std::size_t width,
                                                         float inv_scale, float w, float* lane) {
  const __m256 s = _mm256_set1_ps(inv_scale), weight = _mm256_set1_ps(w);
  std::size_t x = 0;
  // A prefetch a 64-byte line of halves (past the end of the rows: a prefetch does not fault).
  for (; x + 32 <= width; x += 32) {
    _mm_prefetch(plane + 2 * x + kPrefetchBytes, _MM_HINT_T0);
    for (std::size_t k = x; k < x + 32; k += 8)
      add_eight_halves(plane + 2 * k, s, weight, lane + k);
  }
  for (; x + 8 <= width; x += 8) add_eight_halves(plane + 2 * x, s, weight, lane + x);
  for (; x < width; ++x) {
    float v = 0;
    capture::halves_to_floats(plane + 2 * x, 1, inv_scale, &v);
    lane[x] += v * w;
  }
}

}  // namespace

void relight_into(const capture::ReflectanceField& field, std::span<const float> irradiance_rgb,
                  Image& out) {
  if (irradiance_rgb.size() != 3 * size_t(field.num_lights())) {
    throw InputError(field.source + ": lights: the field has " +
                     std::to_string(field.num_lights()) + " lights but the weights have " +
                     std::to_string(irradiance_rgb.size() / 3) + " (computed for another stage?)");
  }
  const int width = field.width(), height = field.height();
  if (out.width != width || out.height != height || out.channels != 3 ||
      out.pixels.size() != size_t(width) * height * 3) {
    out = Image(width, height, 3);
  }
  out.channel_names = {"R", "G", "B"};
  if (width == 0 || height == 0) return;
  const int count = 3 * field.num_lights();
  // Tiles of at least ~256 KiB of field so task overhead stays negligible on small fields.
  const size_t row_bytes = size_t(width) * count * sizeof(float);
  const int rows_per_tile =
      std::max<int>(1, int((size_t(256) << 10) / std::max<size_t>(row_bytes, 1)));
  float* out_pixels = out.pixels.data();
  tbb::parallel_for(tbb::blocked_range<int>(0, height, rows_per_tile),
                    [&](const tbb::blocked_range<int>& rows) {
                      for (int y = rows.begin(); y < rows.end(); ++y) {
                        const float* values = field.pixel(0, y);
                        float* out_row = out_pixels + size_t(y) * width * 3;
                        for (int x = 0; x < width; ++x) {
                          shade_pixel(values + size_t(x) * count, irradiance_rgb.data(), count,
                                      out_row + 3 * size_t(x));
                        }
                      }
                    });
}

void relight_rows_into(const capture::PlanarRows& rows, std::span<const float> irradiance_rgb,
                       Image& out) {
  const int count = int(rows.to_pixel_index.size());
  if (irradiance_rgb.size() != size_t(count)) {
    throw InputError("relight: the field has " + std::to_string(count / 3) +
                     " lights but the weights have " + std::to_string(irradiance_rgb.size() / 3));
  }
  LS_CHECK(out.width == rows.width && out.channels == 3 && rows.first_row + rows.rows <= out.height,
           "relight_rows_into: the output is not the frame");
  // The plane holding each value index, so that values are summed in shade_pixel's order: value i
  // into lane i % kChunk, lanes then summed per colour.
  std::vector<int> plane_of(size_t(count), 0);
  for (int c = 0; c < count; ++c) plane_of[size_t(rows.to_pixel_index[size_t(c)])] = c;
  const size_t width = size_t(rows.width);
  std::atomic<bool> non_finite{false};
  // Halves come unchecked (PlanarRows): a value that is not finite makes every sum it enters not
  // finite (inf x 0 and inf - inf are NaN), so the sums find it. Floats were checked as read.
  const bool check_sums = rows.halves != nullptr;
  tbb::parallel_for(0, rows.rows, [&](int row) {
    thread_local std::vector<float> acc;  // [lane][x]
    acc.assign(kChunk * width, 0.0f);
    if (rows.halves != nullptr) {  // The file's half rows, converted as they are summed.
      const char* planes = rows.halves + size_t(row) * rows.half_row_bytes;
      for (int i = 0; i < count; ++i) {
        add_half_plane(planes + size_t(plane_of[size_t(i)]) * width * 2, width, rows.half_scale,
                       irradiance_rgb[size_t(i)], acc.data() + size_t(i % kChunk) * width);
      }
    } else {
      const float* planes = rows.values + size_t(row) * count * width;
      for (int i = 0; i < count; ++i) {
        const float* __restrict plane = planes + size_t(plane_of[size_t(i)]) * width;
        float* __restrict lane = acc.data() + size_t(i % kChunk) * width;
        const float w = irradiance_rgb[size_t(i)];
        for (size_t x = 0; x < width; ++x) lane[x] += plane[x] * w;
      }
    }
    // Each colour's lanes summed into its first (c < 3) in shade_pixel's order, a lane at a time
    // across the row: a pixel at a time, the 24 lanes a row apart cost a third of the pass. A lane
    // starts at +0 and so is never -0: starting from lane c rather than 0 + lane c is the same.
    for (int c = 0; c < 3; ++c) {
      float* __restrict sum = acc.data() + size_t(c) * width;
      for (int k = c + 3; k < kChunk; k += 3) {
        const float* __restrict lane = acc.data() + size_t(k) * width;
        for (size_t x = 0; x < width; ++x) sum[x] += lane[x];
      }
    }
    float* out_row = out.pixels.data() + size_t(rows.first_row + row) * width * 3;
    int not_finite = 0;
    for (size_t x = 0; x < width; ++x) {
      const float r = acc[x], g = acc[width + x], b = acc[2 * width + x];
      out_row[3 * x] = r;
      out_row[3 * x + 1] = g;
      out_row[3 * x + 2] = b;
      if (check_sums) not_finite |= int(!std::isfinite(r + g + b));
    }
    if (not_finite != 0) non_finite = true;
  });
  if (non_finite) {
    throw InputError(std::string(rows.source) + ": the reflectance field holds non-finite values");
  }
}

Image relight(const capture::ReflectanceField& field, const LightWeights& weights) {
  Image out;
  relight_into(field, weights.irradiance_rgb, out);
  return out;
}

}  // namespace ls::relight
