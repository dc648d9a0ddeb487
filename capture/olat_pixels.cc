#include "capture/olat_pixels.h"

#include <algorithm>
#include <cmath>

#include "lightstage/errors.h"

namespace ls::capture {

std::unique_ptr<image_file::Reader> open_olat_image(const std::filesystem::path& path,
                                                    const std::string& at) {
  std::string error;
  auto in = image_file::open(path, error);
  if (!in) throw InputError(at + ": image: cannot read " + path.string() + ": " + error);
  return in;
}

ImageHeader header_of(const image_file::Reader& in) {
  const image_file::Spec& spec = in.spec();
  return {spec.width, spec.height, spec.channels, spec.format};
}

void check_decoded(image_file::Reader& in, const std::string& at,
                   const std::filesystem::path& image) {
  const std::string message = in.error();
  if (message.find("Premature end") != std::string::npos) {
    throw InputError(at + ": image: " + image.string() + " is cut short (" + message + ")");
  }
}

void check_like_first(const ImageHeader& first, const std::string& first_at,
                      const std::filesystem::path& first_image, const ImageHeader& h,
                      const std::string& at, const std::filesystem::path& image) {
  const auto size = [](const ImageHeader& i) {
    return std::to_string(i.width) + "x" + std::to_string(i.height);
  };
  if (h.width != first.width || h.height != first.height) {
    throw InputError(at + ": image size: expected " + size(first) + " like " + first_at + " (" +
                     first_image.string() + "), got " + size(h) + " (" + image.string() + ")");
  }
  const auto format = [](const ImageHeader& i) {
    return std::string(image_file::sample_name(i.format)) + (i.channels < 3 ? " grey" : " colour");
  };
  if (format(h) != format(first)) {
    throw InputError(at + ": image format: expected " + format(first) + " like " + first_at + " (" +
                     first_image.string() + "), got " + format(h) + " (" + image.string() +
                     "): a set's images come from one camera and one export");
  }
}

bool is_integer_format(image_file::Sample format) {
  return format == image_file::Sample::kUInt8 || format == image_file::Sample::kUInt16;
}

int max_code_of(image_file::Sample format) {
  return format == image_file::Sample::kUInt8 ? 255 : 65535;
}

Linearizer::Linearizer(TransferCurve curve, double gamma) : curve_(curve), gamma_(gamma) {
  for (int bits : {8, 16}) {
    const int max_code = (1 << bits) - 1;
    std::vector<float>& table = bits == 8 ? table8_ : table16_;
    table.resize(max_code + 1);
    for (int code = 0; code <= max_code; ++code)
      table[code] = float(apply(double(code) / max_code));
  }
}

const std::vector<float>* Linearizer::table(image_file::Sample format) const {
  if (format == image_file::Sample::kUInt8) return &table8_;
  if (format == image_file::Sample::kUInt16) return &table16_;
  return nullptr;
}

double Linearizer::apply(double v) const {
  switch (curve_) {
    case TransferCurve::kSrgb:
      return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
    case TransferCurve::kGamma:
      return std::pow(v, gamma_);
    case TransferCurve::kLinear:
      break;
  }
  return v;
}

long long linearise_pixels(const float* raw, const ImageHeader& h, std::size_t pixels,
                           std::size_t first_pixel, const float* mask, const Linearizer& linearizer,
                           bool zero_saturated, float* rgb, float* saturated, const std::string& at,
                           const std::filesystem::path& image) {
  const bool integer = is_integer_format(h.format);
  const std::vector<float>* table = linearizer.table(h.format);
  const int max_code = max_code_of(h.format);
  long long saturated_count = 0;
  for (std::size_t p = 0; p < pixels; ++p) {
    const bool inside = mask == nullptr || mask[p] > 0;
    for (int c = 0; c < 3; ++c) {
      const int source_channel = h.channels < 3 ? 0 : c;
      float v = raw[p * h.channels + source_channel];
      if (!std::isfinite(v)) {
        const std::size_t at_pixel = first_pixel + p;
        throw InputError(at + ": image: " + image.string() + " has a non-finite value at pixel (" +
                         std::to_string(at_pixel % h.width) + ", " +
                         std::to_string(at_pixel / h.width) + ")");
      }
      bool clipped = false;
      if (integer) {
        const int code = std::clamp(int(std::lround(v * max_code)), 0, max_code);
        clipped = code == max_code && inside;
        if (clipped) {
          if (saturated != nullptr) saturated[p * 3 + c] = 1.0f;
          ++saturated_count;
        }
        v = (*table)[code];
      }
      if (!inside || (zero_saturated && clipped)) v = 0.0f;
      rgb[p * 3 + c] = std::max(v, 0.0f);
    }
  }
  return saturated_count;
}

Image read_linear_rows(const std::filesystem::path& image, const std::string& at,
                       const Linearizer& linearizer, int y0, int y1) {
  const auto in = open_olat_image(image, at);
  const ImageHeader h = header_of(*in);
  y1 = std::min(y1, h.height);
  Image out(h.width, std::max(0, y1 - y0), 3);
  constexpr int kBandRows = 64;
  std::vector<float> raw(std::size_t(h.width) * kBandRows * h.channels);
  std::vector<float> rgb(std::size_t(h.width) * kBandRows * 3);
  for (int b0 = 0; b0 < y1; b0 += kBandRows) {
    const int b1 = std::min(y1, b0 + kBandRows);
    if (!in->read_rows(b0, b1, image_file::Sample::kFloat, raw.data())) {
      throw InputError(at + ": image: cannot decode " + image.string() + ": " + in->error());
    }
    if (b1 <= y0) continue;
    const std::size_t pixels = std::size_t(b1 - b0) * h.width;
    linearise_pixels(raw.data(), h, pixels, std::size_t(b0) * h.width, nullptr, linearizer, false,
                     rgb.data(), nullptr, at, image);
    const int from = std::max(b0, y0);
    std::copy(rgb.begin() + std::ptrdiff_t(std::size_t(from - b0) * h.width * 3),
              rgb.begin() + std::ptrdiff_t(pixels * 3),
              out.pixels.begin() + std::ptrdiff_t(std::size_t(from - y0) * h.width * 3));
  }
  return out;
}

}  // namespace ls::capture
