#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "lightstage/image.h"

namespace ls {

// An EXR of named channels (maps written by lightstage): the pixels in the order of `names` (EXR
// files store channels sorted by name, not as written), bit-exact, with the header's string
// attributes. InputErrors name the file and the channel, e.g. "maps.exr: channel 'model':
// missing (not model maps from 'lightstage fit'?)" for kind "model maps", origin
// "'lightstage fit'". With exact, a file holding other channels too is refused. Names from
// `required` on are optional: read as 0 where the file lacks them (maps written before they were
// added).
struct NamedChannelFile {
  Image image;
  ExrAttributes attributes;
  const std::string* attribute(const std::string& name) const;  // Null when absent.
};
// Rows [y0, y1) only (y1 < 0: to the last) when given: a band of a file larger than memory.
NamedChannelFile read_named_channels(const std::filesystem::path& path,
                                     const std::vector<std::string>& names, const std::string& kind,
                                     const std::string& origin, bool exact,
                                     size_t required = SIZE_MAX, int y0 = 0, int y1 = -1);

// An EXR's size and channel names as its header lists them; InputError naming the file when it
// cannot be opened.
struct ExrLayout {
  int width = 0, height = 0;
  std::vector<std::string> channel_names;
};
ExrLayout exr_layout(const std::filesystem::path& path);
std::vector<std::string> exr_channel_names(const std::filesystem::path& path);

// Channels [first, first + channels) of `maps`, each value through `transform` (non-finite
// values 0): a preview's values.
Image channel_preview(const Image& maps, int first, int channels,
                      const std::function<float(float)>& transform);

// A PNG preview beside `path` (STEM.NAME.png) of the maps written to `path`, written a band of
// rows at a time as they are: each band's preview values from `values` (channel_values: some of
// its channels through a transform).
class PreviewRowWriter {
 public:
  using Values = std::function<Image(const Image& maps)>;
  PreviewRowWriter(const std::filesystem::path& path, const std::string& name, int width,
                   int height, int channels, Values values);
  void write_rows(const Image& maps) { file_.write_rows(values_(maps)); }
  void commit() { file_.commit(); }
  ImageRowWriter& file() { return file_; }

 private:
  static std::filesystem::path png_beside(std::filesystem::path path, const std::string& name);
  Values values_;
  ImageRowWriter file_;
};
// Each preview's next rows from the same maps, the files encoded side by side: a whole frame's
// dozen PNGs were a third of a fit's writing time one after another.
void write_preview_rows(const std::vector<std::unique_ptr<PreviewRowWriter>>& previews,
                        const Image& maps);
// channel_preview of channels [first, first + channels) through `transform`.
PreviewRowWriter::Values channel_values(int first, int channels,
                                        const std::function<float(float)>& transform);

// A PNG preview of channels [first, first + channels) of `maps` (the channels written to `path`),
// each value through `transform` (non-finite values black), written beside `path` as
// STEM.NAME.png.
void write_channel_preview(const std::filesystem::path& path, const std::string& name,
                           const Image& maps, int first, int channels,
                           const std::function<float(float)>& transform);

}  // namespace ls
