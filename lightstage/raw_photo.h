#pragma once
// Camera raw files (CR2/CR3, NEF, ARW, DNG, ...) decoded by LibRaw to linear sensor values: the
// black level subtracted, the white level mapped to 65535, no gamma, no automatic brightness, no
// colour matrix (camera RGB) and one fixed white balance, the same for every file of a session. A
// channel whose sensor sites clipped reads 65535, so that the HDR merge and the import censor it
// as they do any saturated code.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "lightstage/image.h"

namespace ls {

struct RawDecodeOptions {
  // kDemosaic: LibRaw's AHD interpolation at the sensor's size. kBin2x2: each 2x2 Bayer block
  // becomes one pixel (its red, the mean of its two greens, its blue): half the size, no
  // interpolation, four sites' noise averaged in green.
  enum class Mode { kDemosaic, kBin2x2 };
  Mode mode = Mode::kDemosaic;
  // Multipliers of camera R, G, B (dimensionless, > 0). Values above 1 push unclipped values
  // toward 65535, where they read as saturated: scale them so the largest is 1.
  std::array<double, 3> white_balance{1.0, 1.0, 1.0};
};

struct DecodedRaw {
  RawFrame frame;            // 3 channels (camera R, G, B), bit_depth 16: 65535 = the white level.
  std::string camera;        // "Make Model" as the file says.
  double black_level = 0.0;  // Mean black level over the CFA channels, sensor DN.
  double white_level = 0.0;  // Sensor DN that clips.
  double exposure_s = 0.0;   // From the file's metadata; 0 when it has none.
  double iso = 0.0;          // Idem.
  std::array<int64_t, 3> saturated_pixels{0, 0, 0};  // Output pixels censored, per channel.
};

// True for the extensions of raw formats (case-insensitive): .dng .cr2 .cr3 .crw .nef .nrw .arw
// .srf .sr2 .raf .orf .rw2 .pef .srw .3fr .iiq .erf .kdc .mos .mrw .x3f.
bool is_raw_photo_name(const std::filesystem::path& path);

// Throws InputError naming the file (or `source_name`) and what LibRaw reported.
DecodedRaw decode_raw_photo(const std::filesystem::path& path,
                            const RawDecodeOptions& options = {});
DecodedRaw decode_raw_photo(const std::vector<std::uint8_t>& bytes, const std::string& source_name,
                            const RawDecodeOptions& options = {});

// "demosaic" / "bin2x2".
const char* to_string(RawDecodeOptions::Mode mode);

}  // namespace ls
