#include "lightstage/exr_channels.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"

namespace ls {

namespace fs = std::filesystem;

const std::string* NamedChannelFile::attribute(const std::string& name) const {
  for (const auto& [key, value] : attributes) {
    if (key == name) return &value;
  }
  return nullptr;
}

ExrLayout exr_layout(const fs::path& path) {
  const std::string name = path.string();
  if (!fs::exists(path)) throw InputError(name + ": file not found");
  std::string error;
  const auto in = image_file::open(path, error);
  if (!in) throw InputError(name + ": cannot read: " + error);
  return {in->spec().width, in->spec().height, in->spec().channel_names};
}

std::vector<std::string> exr_channel_names(const fs::path& path) {
  return exr_layout(path).channel_names;
}

NamedChannelFile read_named_channels(const fs::path& path, const std::vector<std::string>& names,
                                     const std::string& kind, const std::string& origin, bool exact,
                                     size_t required, int y0, int y1) {
  const std::string name = path.string();
  if (!fs::exists(path)) throw InputError(name + ": file not found");
  std::string error;
  const auto in = image_file::open(path, error);
  if (!in) throw InputError(name + ": cannot read " + kind + ": " + error);
  const image_file::Spec& spec = in->spec();
  const int count = int(names.size());
  std::vector<int> file_channel(count, -1);
  for (int c = 0; c < count; ++c) {
    for (int f = 0; f < spec.channels; ++f) {
      if (spec.channel_names[f] == names[c]) file_channel[c] = f;
    }
    if (file_channel[c] < 0 && size_t(c) < required) {
      throw InputError(name + ": channel '" + names[c] + "': missing (not " + kind + " from " +
                       origin + "?)");
    }
  }
  const int found =
      int(std::count_if(file_channel.begin(), file_channel.end(), [](int f) { return f >= 0; }));
  if (exact && spec.channels != found) {
    throw InputError(name + ": channels: expected " + std::to_string(found) + " (" + kind +
                     "), got " + std::to_string(spec.channels));
  }
  if (spec.width <= 0 || spec.height <= 0) throw InputError(name + ": image has no pixels");
  if (y1 < 0) y1 = spec.height;
  LS_CHECK(0 <= y0 && y0 < y1 && y1 <= spec.height, "rows out of the image");
  Image raw(spec.width, y1 - y0, spec.channels);
  if (!in->read_rows(y0, y1, image_file::Sample::kFloat, raw.pixels.data())) {
    throw InputError(name + ": cannot read pixels (truncated or corrupt file?): " + in->error());
  }
  NamedChannelFile out;
  for (const image_file::Attribute& a : spec.attributes) {
    if (const std::string* text = a.text()) out.attributes.emplace_back(a.name, *text);
  }
  out.image = Image(spec.width, y1 - y0, count);
  out.image.channel_names = names;
  for (size_t i = 0; i < raw.num_pixels(); ++i) {
    for (int c = 0; c < count; ++c) {
      out.image.pixels[i * count + c] =
          file_channel[c] < 0 ? 0.0f : raw.pixels[i * spec.channels + file_channel[c]];
    }
  }
  return out;
}

Image channel_preview(const Image& maps, int first, int channels,
                      const std::function<float(float)>& transform) {
  Image image(maps.width, maps.height, channels);
  for (size_t i = 0; i < maps.num_pixels(); ++i) {
    for (int c = 0; c < channels; ++c) {
      const float v = maps.pixels[i * maps.channels + first + c];
      image.pixels[i * channels + c] = std::isfinite(v) ? transform(v) : 0.0f;
    }
  }
  return image;
}

fs::path PreviewRowWriter::png_beside(fs::path path, const std::string& name) {
  path.replace_extension(name + ".png");
  return path;
}

PreviewRowWriter::PreviewRowWriter(const fs::path& path, const std::string& name, int width,
                                   int height, int channels, Values values)
    : values_(std::move(values)), file_(png_beside(path, name), width, height, channels) {}

PreviewRowWriter::Values channel_values(int first, int channels,
                                        const std::function<float(float)>& transform) {
  return [=](const Image& maps) { return channel_preview(maps, first, channels, transform); };
}

void write_preview_rows(const std::vector<std::unique_ptr<PreviewRowWriter>>& previews,
                        const Image& maps) {
  tbb::parallel_for(size_t(0), previews.size(), [&](size_t i) { previews[i]->write_rows(maps); });
}

void write_channel_preview(const fs::path& path, const std::string& name, const Image& maps,
                           int first, int channels, const std::function<float(float)>& transform) {
  PreviewRowWriter preview(path, name, maps.width, maps.height, channels,
                           channel_values(first, channels, transform));
  preview.write_rows(maps);
  preview.commit();
}

}  // namespace ls
