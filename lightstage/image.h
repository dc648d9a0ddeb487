#pragma once
// Images in memory and on disk. Everything in memory is linear, scene-referred float; 8-bit output
// exists only for previews. Row 0 is the top row. Image I/O libraries stay in image.cc.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "lightstage/image_file.h"

namespace ls {

// A float image with interleaved channels: pixels[(y * width + x) * channels + c].
struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<float> pixels;
  std::vector<std::string> channel_names;  // Optional; written to EXR when present.

  Image() = default;
  Image(int width, int height, int channels, float fill = 0.0f);

  float& at(int x, int y, int c) { return pixels[(size_t(y) * width + x) * channels + c]; }
  float at(int x, int y, int c) const { return pixels[(size_t(y) * width + x) * channels + c]; }
  size_t num_pixels() const { return size_t(width) * height; }
};

// A camera frame as the sensor delivered it: integer digital numbers (DN), interleaved channels.
struct RawFrame {
  int width = 0;
  int height = 0;
  int channels = 0;
  int bit_depth = 16;  // Valid DN are 0 .. 2^bit_depth - 1.
  std::vector<uint16_t> pixels;

  uint16_t at(int x, int y, int c) const { return pixels[(size_t(y) * width + x) * channels + c]; }
  uint16_t max_value() const { return uint16_t((1u << bit_depth) - 1u); }
};

enum class ExrPixelType { kFloat, kHalf };

// Reads any format image_file.h reads (EXR incl. DWAB, Radiance HDR, PNG, JPEG, TIFF) as linear
// float. 8/16-bit sRGB-encoded files are returned as stored (normalised to [0,1]), not linearised:
// callers that import photographs undo their transfer curve explicitly. Throws InputError naming
// the file.
Image read_image(const std::filesystem::path& path);
// The same as 8-bit codes (an 8-bit file's as stored, others' [0, 1] scaled to 0..255),
// interleaved: what a preview holds, without a float a value.
struct ImageCodes {
  int width = 0, height = 0, channels = 0;
  std::vector<uint8_t> codes;
};
ImageCodes read_image_codes(const std::filesystem::path& path);

// Named string attributes of an EXR header (e.g. {"lightstage:fit_noise", "{...json...}"}).
using ExrAttributes = std::vector<std::pair<std::string, std::string>>;

// Writes an OpenEXR (zip) with the image's channel names (or R,G,B,A / Y) and the given string
// attributes. Atomic: temp file + fsync + rename.
void write_exr(const std::filesystem::path& path, const Image& image,
               ExrPixelType type = ExrPixelType::kFloat, const ExrAttributes& attributes = {});

// Tone-mapped 8-bit sRGB preview: value * 2^exposure_stops, clamped, sRGB-encoded. Atomic.
void write_png_preview(const std::filesystem::path& path, const Image& image,
                       double exposure_stops = 0.0);

// An 8-bit RGB image (rows top to bottom, 3 bytes a pixel), its format from the extension: a
// .jpg at `jpeg_quality` (1..100) with chroma not subsampled (4:4:4: for planes of coefficients,
// not photographs), a .png lossless. Atomic.
void write_rgb8(const std::filesystem::path& path, int width, int height, const uint8_t* rgb,
                int jpeg_quality = 95);

// A PNG of integer codes as given (no transfer curve applied): 8- or 16-bit, 1 to 4 channels
// interleaved, rows top to bottom; 8-bit codes above 255 are clamped. Atomic.
void write_png_codes(const std::filesystem::path& path, int width, int height, int channels,
                     int bits, const uint16_t* codes);

// The sRGB transfer curve (IEC 61966-2-1): linear [0, 1] <-> display-referred [0, 1]. Both clamp
// their input to [0, 1] first, and NaN gives 0: a preview or a display shows black, never NaN.
float srgb_encode(float linear);
float srgb_decode(float encoded);
// The 8-bit sRGB code (0..255, rounded) of a linear display value: what an 8-bit image holds.
inline float srgb8_code(float linear) { return std::round(255.0f * srgb_encode(linear)); }

// Luminance (relative, Y of CIE XYZ) of linear RGB with the Rec. 709 / sRGB primaries: the
// weights of R, G and B (they sum to 1), and the weighted sum in float and in double.
inline constexpr double kLuminanceWeights[3] = {0.2126, 0.7152, 0.0722};
inline float luminance(const float* rgb) {
  return float(kLuminanceWeights[0]) * rgb[0] + float(kLuminanceWeights[1]) * rgb[1] +
         float(kLuminanceWeights[2]) * rgb[2];
}
inline double luminance(double r, double g, double b) {
  return kLuminanceWeights[0] * r + kLuminanceWeights[1] * g + kLuminanceWeights[2] * b;
}
inline double luminance(const Eigen::Vector3d& rgb) { return luminance(rgb.x(), rgb.y(), rgb.z()); }

// Exposure (in stops) that puts the image's 99th-percentile luminance near white.
double auto_exposure_stops(const Image& image, double percentile = 0.99);

// A file as written: its size and the CRC-32 (zlib's) of its bytes, for checking it later.
struct StoredFile {
  uint64_t bytes = 0;
  uint32_t crc32 = 0;
};

// Raw frames are stored as 16-bit PNG (lossless). Writing is atomic and durable: the data goes to a
// temporary name, is fsync'ed, then renamed, so a killed process never leaves a half frame. The
// folder must exist (it is not created).
StoredFile write_raw_frame(const std::filesystem::path& path, const RawFrame& frame);
RawFrame read_raw_frame(const std::filesystem::path& path, int bit_depth);
// CRC-32 as zlib computes it (the checksum PNG and gzip use).
uint32_t crc32_of(const void* data, size_t size);

// Writes `contents` to `path` atomically (temp + fsync + rename). Throws StorageError on failure.
void write_file_atomic(const std::filesystem::path& path, const std::string& contents);
void write_file_atomic(const std::filesystem::path& path, const void* data, size_t size);

// The same for a file written piece by piece (larger than memory): bytes go to a temporary
// sibling, commit() makes it durable and renames it over `path`; destroyed before commit(), the
// temporary file is removed, so no partial file is ever left at `path`. StorageError naming the
// path when a write fails (a full disk fails here, not silently later).
class AtomicFileWriter final : public image_file::Sink {
 public:
  explicit AtomicFileWriter(const std::filesystem::path& path);
  ~AtomicFileWriter() override;
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;
  void write(const void* data, size_t size);
  // At `offset` (a header's table filled in after the rows; the next write() is unaffected).
  void write_at(uint64_t offset, const void* data, size_t size) override;
  void commit();
  // A write, the fsync or the rename failed: an encoder that wraps the error in its own message
  // (an InputError) is reporting a StorageError.
  bool failed() const { return failed_; }

 private:
  [[noreturn]] void fail(int error);

  std::filesystem::path path_, temp_;
  int fd_ = -1;
  bool failed_ = false;
};

// An image written a band of rows at a time, top to bottom, never held whole (maps of a field
// larger than memory): the format from the extension, OpenEXR (float, zip, the
// attributes in its header) as write_exr writes it, or an 8-bit PNG preview as write_png_preview
// writes it (exposure 0), the same bytes. Atomic like AtomicFileWriter: nothing at `path` until
// commit(); StorageError naming the path when a write fails.
class ImageRowWriter {
 public:
  ImageRowWriter(const std::filesystem::path& path, int width, int height, int channels,
                 const std::vector<std::string>& channel_names = {},
                 const ExrAttributes& attributes = {});
  ~ImageRowWriter();
  ImageRowWriter(const ImageRowWriter&) = delete;
  ImageRowWriter& operator=(const ImageRowWriter&) = delete;
  // The next rows: the image's width and channels, rows.height of them; a PNG's values times
  // 2^exposure_stops.
  void write_rows(const Image& rows, double exposure_stops = 0.0);
  void commit();
  const std::filesystem::path& path() const;

 private:
  struct Output;
  std::unique_ptr<Output> output_;
};

// The rows of `first` with `extra_channels` more after each pixel's, from `extra` (the same width
// and height; empty: zeros), written to `file` a few rows at a time: a band's interleaved copy made
// at once cost as much as its encoding (fresh pages). Without extra channels, `first` as it is.
void write_rows_beside(ImageRowWriter& file, const Image& first, const Image& extra,
                       int extra_channels);

// Commits each writer in turn, all or none: when one fails (a full disk), the files already
// committed are removed before its error goes on, so that a failed run leaves no maps without
// their previews, nor previews without their maps.
void commit_together(const std::vector<ImageRowWriter*>& writers);

}  // namespace ls
