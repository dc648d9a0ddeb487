// Decoding a DSLR's raw file (lightstage/raw_photo.h): a 24-megapixel (6000x4000) 14-bit DNG of a
// smooth gradient with noise, demosaiced (AHD) and binned 2x2. Counters: megapixels per second of
// the sensor. The DNG is uncompressed, so this is LibRaw's unpacking and interpolation, not a
// maker's compression; a CR2/NEF adds its lossless-JPEG decode.
#include <benchmark/benchmark.h>

#include <random>

#include "lightstage/raw_photo.h"
#include "sim/dng_file.h"

namespace {

std::vector<uint8_t> sensor_dng(int width, int height) {
  ls::RawFrame rgb;
  rgb.width = width;
  rgb.height = height;
  rgb.channels = 3;
  rgb.pixels.resize(size_t(width) * height * 3);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 8.0);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double v = 512 + 12000.0 * (x + y + 1000 * c) / (width + height + 2000) + noise(rng);
        rgb.pixels[(size_t(y) * width + x) * 3 + c] = uint16_t(std::clamp(v, 0.0, 16383.0));
      }
    }
  }
  return ls::sim::encode_dng(ls::sim::bayer_mosaic(rgb, 512, 16383));
}

void BM_DecodeRaw24MP(benchmark::State& state) {
  static const std::vector<uint8_t> dng = sensor_dng(6000, 4000);
  ls::RawDecodeOptions options;
  options.mode = state.range(0) == 0 ? ls::RawDecodeOptions::Mode::kDemosaic
                                     : ls::RawDecodeOptions::Mode::kBin2x2;
  for (auto _ : state) {
    ls::DecodedRaw decoded = ls::decode_raw_photo(dng, "bench.dng", options);
    benchmark::DoNotOptimize(decoded.frame.pixels.data());
  }
  state.SetLabel(ls::to_string(options.mode));
  state.counters["sensor_MP_per_s"] =
      benchmark::Counter(24.0 * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DecodeRaw24MP)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
