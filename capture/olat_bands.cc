#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>

#include "capture/olat_images.h"
#include "capture/olat_pixels.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"

namespace ls::capture {

namespace fs = std::filesystem;

struct OlatBands::Images {
  OlatImageSet set;
  OlatImportOptions options;
  Linearizer linearizer;
  std::vector<std::unique_ptr<image_file::Reader>> in;
  std::vector<ImageHeader> headers;
  int next_row = 0;

  Images(OlatImageSet image_set, const OlatImportOptions& import_options)
      : set(std::move(image_set)),
        options(import_options),
        linearizer(set.transfer, options.gamma),
        in(set.lights.size()),
        headers(set.lights.size()) {}

  // Every image opened (again) at its top, checked against the first one's size.
  void open_all() {
    tbb::parallel_for(0, int(set.lights.size()), [&](int l) {
      const OlatLight& light = set.lights[size_t(l)];
      in[size_t(l)].reset();
      in[size_t(l)] = open_olat_image(light.image, light.where);
      headers[size_t(l)] = header_of(*in[size_t(l)]);
    });
    for (size_t l = 1; l < headers.size(); ++l) {
      check_like_first(headers[0], set.lights[0].where, set.lights[0].image, headers[l],
                       set.lights[l].where, set.lights[l].image);
    }
    next_row = 0;
  }
};

std::unique_ptr<OlatBands> open_olat_bands(OlatImageSet set, const OlatImportOptions& options) {
  // Lights placed from spheres or a stage: an import's work (spheres need every image read first).
  if (int(set.lights.size()) > OlatBands::kMaxOpenImages || !options.spheres.outlines.empty() ||
      !options.stage_file.empty()) {
    return nullptr;
  }
  ReflectanceField header = images_header(set, options);
  auto images = std::make_unique<OlatBands::Images>(std::move(set), options);
  images->open_all();
  if (images->headers[0].width != header.width() || images->headers[0].height != header.height()) {
    return nullptr;  // Downsized on import: whole images are needed.
  }
  // Each light's ceiling, as import_images gives it: an integer file clips at its largest code.
  for (size_t l = 0; l < images->headers.size(); ++l) {
    const ImageHeader& h = images->headers[l];
    if (!is_integer_format(h.format)) continue;
    header.lights()[l].saturates_at =
        images->linearizer.ceiling(h.format) * images->set.lights[l].intensity_rgb.cwiseInverse();
  }
  return std::make_unique<OlatBands>(std::move(images), std::move(header));
}

OlatBands::OlatBands(std::unique_ptr<Images> images, ReflectanceField header)
    : images_(std::move(images)), header_(std::move(header)) {}

OlatBands::~OlatBands() = default;

int OlatBands::rows_within(std::size_t bytes) const {
  // The band, and per decoding thread a row of the image as read and as linear RGB.
  const int channels = images_->headers[0].channels;
  const std::size_t row_bytes =
      std::size_t(width()) * sizeof(float) *
      (3 * std::size_t(header_.num_lights()) + 2 * (std::size_t(channels) + 3));
  return ls::rows_within(bytes, row_bytes, height());
}

void OlatBands::read_rows(int y0, int y1, ReflectanceField& band) {
  shape_band(header_, y0, y1, band);
  Images& images = *images_;
  if (y0 < images.next_row) images.open_all();
  const std::size_t pixels = std::size_t(width()) * std::size_t(y1 - y0);
  const std::size_t stride = 3 * std::size_t(header_.num_lights());
  float* values = band.pixel(0, 0);
  struct Buffers {
    std::vector<float> raw, rgb;
  };
  tbb::enumerable_thread_specific<Buffers> buffers;
  tbb::parallel_for(0, header_.num_lights(), [&](int l) {
    const OlatLight& light = images.set.lights[size_t(l)];
    const ImageHeader& h = images.headers[size_t(l)];
    Buffers& b = buffers.local();
    b.raw.resize(pixels * size_t(h.channels));
    b.rgb.resize(3 * pixels);
    if (!images.in[size_t(l)]->read_rows(y0, y1, image_file::Sample::kFloat, b.raw.data())) {
      throw InputError(light.where + ": image: cannot decode " + light.image.string() + " (rows " +
                       std::to_string(y0) + "-" + std::to_string(y1 - 1) +
                       "): " + images.in[size_t(l)]->error());
    }
    check_decoded(*images.in[size_t(l)], light.where, light.image);
    const std::size_t first = std::size_t(y0) * std::size_t(width());
    const float* mask = images.set.mask.empty() ? nullptr : images.set.mask.data() + first;
    linearise_pixels(b.raw.data(), h, pixels, first, mask, images.linearizer,
                     images.options.zero_saturated, b.rgb.data(), nullptr, light.where,
                     light.image);
    const Eigen::Vector3f inverse_intensity = light.intensity_rgb.cwiseInverse();
    float* out = values + 3 * std::size_t(l);
    for (std::size_t p = 0; p < pixels; ++p) {
      for (int c = 0; c < 3; ++c)
        out[p * stride + size_t(c)] = b.rgb[3 * p + size_t(c)] * inverse_intensity[c];
    }
  });
  images.next_row = y1;
}

}  // namespace ls::capture
