#pragma once
// Reads rows of a many-channel OpenEXR file (a reflectance field: 3 channels per LED) into
// pixel-major floats. OpenEXR stores each row channel by channel and, asked for interleaved pixels
// (as OpenImageIO asks), converts value by value at the pixel's stride: more time than the rest
// of a relighting. Here rows are read as the file holds them into a small buffer (at most 8 MiB
// and a quarter of the rows asked for): uncompressed float or half rows straight from the file by
// pread (halves converted, F16C where the CPU has it), rows in parallel; others through
// OpenEXR into the same [row][channel][x] layout; then transposed in blocks, in parallel.
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace ls::capture {

// A piece of rows as the file holds them: [row][channel][x], `rows` rows of `width` pixels; the
// values of channel c of a pixel go to its value index to_pixel_index[c] (light * 3 + colour).
// Floats in `values`, checked finite; or, for a half field read where the CPU converts halves
// (F16C), the file's own half rows as stored (`halves`, rows `half_row_bytes` apart, not aligned;
// value = half x half_scale), so that a consumer converts them as it sums
// (capture/half_storage.h). Those are not checked: a consumer that sums them finds a non-finite
// value in its sums, and must refuse it naming `source` (the file).
struct PlanarRows {
  const float* values;
  int first_row, rows, width;
  std::span<const int> to_pixel_index;
  const char* halves = nullptr;
  std::size_t half_row_bytes = 0;
  float half_scale = 1;
  std::string_view source = {};
};
using PlanarVisitor = std::function<void(const PlanarRows&)>;

class ExrBandReader {
 public:
  // channels: the field's channel names; to_pixel_index[i]: where channel i goes in a pixel's
  // values (a permutation of 0..channels-1); value_scale: the field's value = the stored one x
  // this (capture/half_storage.h). Float or half channels alike are read as floats.
  ExrBandReader(const std::filesystem::path& path, const std::vector<std::string>& channels,
                const std::vector<int>& to_pixel_index, float value_scale = 1);
  ~ExrBandReader();
  ExrBandReader(const ExrBandReader&) = delete;
  ExrBandReader& operator=(const ExrBandReader&) = delete;

  // Rows [y0, y1) of the data window (counted from its top) into dst (width * channels floats a
  // row). InputError naming the file and rows when OpenEXR cannot read them, or when a value is
  // not finite.
  void read(int y0, int y1, float* dst);
  // Rows [y0, y1) in pieces of about 8 MiB, untransposed (a consumer that sums over each pixel's
  // values, as relighting does, needs no pixel-major copy); the same errors.
  void read_planar(int y0, int y1, const PlanarVisitor& visit);

 private:
  struct File;
  std::unique_ptr<File> file_;
};

}  // namespace ls::capture
