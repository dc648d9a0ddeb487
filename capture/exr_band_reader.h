#pragma once
// Reads rows of a many-channel OpenEXR file (a reflectance field: 3 channels per LED) into
// pixel-major floats. OpenEXR stores each row channel by channel and, asked for interleaved pixels
// (as OpenImageIO asks), converts value by value at the pixel's stride: more time than the rest
// of a relighting. Here rows are read as the file holds them into a small buffer (at most 8 MiB
// and a quarter of the rows asked for): uncompressed float rows as raw bytes, others through
// OpenEXR into the same [row][channel][x] layout; then transposed in blocks, in parallel.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace ls::capture {

class ExrBandReader {
 public:
  // channels: the field's channel names; to_pixel_index[i]: where channel i goes in a pixel's
  // values (a permutation of 0..channels-1).
  ExrBandReader(const std::filesystem::path& path, const std::vector<std::string>& channels,
                const std::vector<int>& to_pixel_index);
  ~ExrBandReader();
  ExrBandReader(const ExrBandReader&) = delete;
  ExrBandReader& operator=(const ExrBandReader&) = delete;

  // Rows [y0, y1) of the data window (counted from its top) into dst (width * channels floats a
  // row). InputError naming the file and rows when OpenEXR cannot read them, or when a value is
  // not finite.
  void read(int y0, int y1, float* dst);

 private:
  struct File;
  std::unique_ptr<File> file_;
};

}  // namespace ls::capture
