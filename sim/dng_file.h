#pragma once
// A camera's raw photograph as a DNG (Adobe's raw format, a TIFF with a colour filter array): what
// the simulated DSLR writes (sim/dslr_tether.h) and the raw-decoding tests decode, so that both go
// through LibRaw as a real camera's files do. Written through libtiff.
#include <cstdint>
#include <string>
#include <vector>

#include "lightstage/image.h"

namespace ls::sim {

// Sensor sites behind an RGGB Bayer filter: row 0 is R G R G ..., row 1 is G B G B ...
struct BayerImage {
  int width = 0;                // Sites; even.
  int height = 0;               // Sites; even.
  std::vector<uint16_t> sites;  // Row-major sensor DN.
  unsigned black_level = 0;     // DN of no light.
  unsigned white_level = 4095;  // DN at which a site clips.
  std::string make = "lightstage";
  std::string model = "simulated DSLR";
  double exposure_s = 0.0;  // Written to EXIF when > 0.
  int iso = 0;              // Idem.
};

// The sites behind an RGGB filter of a 3-channel frame (camera RGB, DN). pixel_sites 1: the
// sensor is the frame's size, each site its own pixel's colour. pixel_sites 2: the sensor is twice
// the frame's width and height and each pixel's 2x2 block of sites sees that pixel (the
// simulator's pixel is one sample standing for its area; binned 2x2, the block is that area).
BayerImage bayer_mosaic(const RawFrame& rgb, unsigned black_level, unsigned white_level,
                        int pixel_sites = 1);

// An uncompressed 16-bit DNG 1.4 with the black and white levels, an identity colour matrix and
// EXIF exposure time and ISO. Throws InputError when libtiff fails.
std::vector<uint8_t> encode_dng(const BayerImage& image);

}  // namespace ls::sim
