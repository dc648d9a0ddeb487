#pragma once
// What the OLAT importers do to each image's pixels, shared by the whole-image import
// (olat_images.cc) and the band reader (olat_bands.cc) so that both give the same values: open
// and check an image, undo its transfer curve, mask, count and (optionally) zero saturated codes.
#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "capture/olat_import.h"
#include "lightstage/image.h"
#include "lightstage/image_file.h"

namespace ls::capture {

struct ImageHeader {
  int width = 0, height = 0, channels = 0;
  image_file::Sample format = image_file::Sample::kOther;
};

// InputError naming `at` (the .lp line or file) and the image when it cannot be opened.
std::unique_ptr<image_file::Reader> open_olat_image(const std::filesystem::path& path,
                                                    const std::string& at);
ImageHeader header_of(const image_file::Reader& in);
bool is_integer_format(image_file::Sample format);
// The largest code of an integer format (255 or 65535).
int max_code_of(image_file::Sample format);

// After a read that succeeded: libjpeg reports a file cut short only as a warning (and fills the
// rest grey), which is an InputError here naming `at` and the image. Other decoder warnings (e.g.
// extraneous bytes, common in camera files) pass.
void check_decoded(image_file::Reader& in, const std::string& at,
                   const std::filesystem::path& image);

// InputError naming `at` and both images when `h` is not the size or the pixel format (bit
// depth; grey or colour) of `first`, the set's first image named by first_at and first_image: a
// set mixing them was not taken by one camera in one export, and would be linearised unlike.
void check_like_first(const ImageHeader& first, const std::string& first_at,
                      const std::filesystem::path& first_image, const ImageHeader& h,
                      const std::string& at, const std::filesystem::path& image);

// Code (normalised to [0, 1]) -> linear value, tabulated per code for 8- and 16-bit files.
class Linearizer {
 public:
  Linearizer(TransferCurve curve, double gamma);
  // Null for float files: they are linear already.
  const std::vector<float>* table(image_file::Sample format) const;
  // The linear value of an integer format's largest code: where its files clip.
  float ceiling(image_file::Sample format) const {
    return (*table(format))[size_t(max_code_of(format))];
  }

 private:
  double apply(double v) const;
  TransferCurve curve_;
  double gamma_;
  std::vector<float> table8_, table16_;
};

// Pixels as read (normalised floats, h.channels each; grey feeds all three channels, alpha and
// extra channels are ignored) -> linear RGB >= 0 in rgb (3 per pixel). mask: null, or 1/0 per
// pixel (0: set to 0). Saturated samples (integer files at their largest code, inside the mask)
// are counted, marked in `saturated` (3 per pixel, may be null) and, with zero_saturated, set to
// 0. first_pixel: the index of raw's first pixel in its image (for messages). A non-finite value
// is an InputError naming `at`, the image and the pixel.
long long linearise_pixels(const float* raw, const ImageHeader& h, std::size_t pixels,
                           std::size_t first_pixel, const float* mask, const Linearizer& linearizer,
                           bool zero_saturated, float* rgb, float* saturated, const std::string& at,
                           const std::filesystem::path& image);

// Rows [y0, y1) of an image (`at`: the line naming it, for messages), linear RGB at its own size,
// no mask: what an import's spheres are found in (capture/sphere_lights.h).
Image read_linear_rows(const std::filesystem::path& image, const std::string& at,
                       const Linearizer& linearizer, int y0, int y1);

}  // namespace ls::capture
